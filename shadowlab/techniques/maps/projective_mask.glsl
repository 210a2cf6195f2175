// Projective shadow textures (Segal et al. 1992, "Fast shadows and lighting effects using
// texture mapping"; Nguyen 1999, "Casting shadows on volumes"; Akenine-Möller et al., Real-Time
// Rendering 4th ed. §7.2), the mask program: one caster drawn alone from the light into its
// shadow image (a binary mask: u_covered where the caster covers a texel, 0 elsewhere), which
// projective_lookup.glsl then projects onto the receivers.
#include "light_vertex.glsl"            // u_light_view_proj: the caster's fitted light view
uniform float u_covered;                 // the mask's value where the caster covers a texel

#ifdef FRAGMENT_SHADER
out float out_mask;
void main() {
    out_mask = u_covered;
}
#endif
