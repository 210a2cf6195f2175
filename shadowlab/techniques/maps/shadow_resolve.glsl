// Builds the comparison map of the two-layer variants from the first and second depth layers:
//   midpoint (Woo 1992): (z1 + z2) / 2;
//   dual (Weiskopf & Ertl 2003): z1 + min((z2 − z1) / 2, u_dual_offset) — the midpoint where the
//   layers are close, the first depth plus a fixed offset where they are far apart.
// Where there is no second layer, z2 is the cleared far value 1.
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
#define RESOLVE_MIDPOINT 0
#define RESOLVE_DUAL 1
uniform sampler2D u_first_layer;
uniform sampler2D u_second_layer;
uniform int u_resolve;
uniform float u_dual_offset;
void main() {
    ivec2 t = ivec2(gl_FragCoord.xy);
    float z1 = texelFetch(u_first_layer, t, 0).r;
    float z2 = texelFetch(u_second_layer, t, 0).r;
    float half_gap = 0.5 * (z2 - z1);
    gl_FragDepth = u_resolve == RESOLVE_DUAL ? z1 + min(half_gap, u_dual_offset) : z1 + half_gap;
}
#endif
