// Filtered shadow maps (VSM, ESM, EVSM, MSM; see filtered_lookup.glsl): one direction of the
// separable box filter over one face of the moments atlas (filtered_depth.glsl writes it,
// filtered_lookup.glsl reads the result).
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
// Box filter of 2 u_radius + 1 texels along u_direction, taps clamped to the face u_rect (x0,
// y0, width, height) so that a cube face never reads its neighbour. Weights are 1 / taps and
// accumulated one by one: an ESM average of values up to exp(88) never overflows. All four
// channels are filtered (a map with fewer drops the rest); the sum is float32 and the target's
// format stores it again (16-bit maps: half floats, or MSM's quantised 16-bit UNORM).
uniform sampler2D u_moments;
uniform ivec2 u_direction;
uniform int u_radius;
uniform ivec4 u_rect;
out vec4 out_moments;
void main() {
    ivec2 t = ivec2(gl_FragCoord.xy);
    ivec2 lo = u_rect.xy, hi = u_rect.xy + u_rect.zw - 1;
    float w = 1.0 / float(2 * u_radius + 1);
    vec4 sum = vec4(0.0);
    for (int i = -u_radius; i <= u_radius; ++i)
        sum += w * texelFetch(u_moments, clamp(t + i * u_direction, lo, hi), 0);
    out_moments = sum;
}
#endif
