// Writes one value to every covered pixel (turns a stencil test into a visibility image).
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
uniform float u_value;
out float out_value;
void main() {
    out_value = u_value;
}
#endif
