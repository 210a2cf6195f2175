// Penumbra wedges, the last pass: V = V_hard + Σ wedge contributions, clamped to [0, 1]
// (Assarsson & Akenine-Möller 2003, §4: the hard shadow from the light's centre plus the
// signed light fractions the wedges accumulated). Drawn twice under a stencil test on the hard
// shadow volume's counts: once for count == 0 (u_hard = 1), once for count != 0 (u_hard = 0).
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
#include "gbuffer_fetch.glsl"
uniform sampler2D u_wedges;      // the wedges' sum, R32F
uniform float u_hard;            // visibility of the light's centre (the stencil test decides)
uniform bool u_clamp;            // clamp to [0, 1] (the paper); false shows the raw sum
uniform vec3 u_light_centre;
uniform vec3 u_light_normal;     // unit, towards the emitting side
out float out_value;
void main() {
    vec3 P;
    gbuffer_position(P);
    float v = u_hard + texelFetch(u_wedges, gbuffer_pixel(), 0).r;
    if (dot(P - u_light_centre, u_light_normal) <= 0.0) v = 0.0;  // behind a one-sided light
    out_value = u_clamp ? clamp(v, 0.0, 1.0) : v;
}
#endif
