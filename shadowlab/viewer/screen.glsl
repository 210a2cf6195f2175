// The viewer's window: one picture (an RGB texture, one texel per image pixel) over the whole
// window, texel for pixel, scaled only when the window's framebuffer is larger than the image.
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
uniform sampler2D u_image;
uniform vec2 u_scale;  // texels per window pixel (1 when the window is the image's size)
out vec4 f_color;
void main() {
    f_color = vec4(texelFetch(u_image, ivec2(gl_FragCoord.xy * u_scale), 0).rgb, 1.0);
}
#endif
