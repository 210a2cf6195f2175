// Projective shadow textures (Segal et al. 1992, "Fast shadows and lighting effects using
// texture mapping"; Nguyen 1999, "Casting shadows on volumes"; Akenine-Möller et al., Real-Time
// Rendering 4th ed. §7.2), the lookup program: over the G-buffer, it projects one caster's
// shadow image (projective_mask.glsl) onto the receivers. It writes 1 − mask(P) where P
// takes this caster's image and 1 elsewhere; the pass blends it multiplicatively into the
// visibility target (dst = dst · src), one pass per caster.
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
#include "gbuffer_fetch.glsl"
uniform sampler2D u_receives;            // texel (i, 0): 1 where object i may take caster images
uniform sampler2D u_mask;                // this caster's shadow image (nearest or bilinear)
uniform mat4 u_light_matrix;             // bias · projection · view: world → projective (s, t, r, q)
uniform int u_caster;                    // this caster's object id (it never takes its own image)
uniform int u_clip;                      // 1: only points beyond the caster take its image
uniform vec3 u_box_min;                  // the caster's axis-aligned bounding box
uniform vec3 u_box_max;
uniform vec4 u_light;                    // homogeneous light: (L, 1), or (−direction, 0) at infinity
uniform float u_segment_end;             // the light is at P + u_segment_end · (towards-light vector)
uniform float u_parallel;                // |component| below which the ray runs parallel to a slab
uniform float u_lit;                     // visibility of an unshadowed point (1)
out float out_visibility;

#define BASE_LEVEL 0.0                   // the shadow image has no mipmaps: sample its level 0

// True when the segment from P towards the light, P + t·d for t in [0, u_segment_end] (d = L − P
// for a light at a position, −direction at infinity), meets the caster's bounding box: the
// slab method (Kay & Kajiya 1986). A component of d that is (nearly) zero keeps P's own
// coordinate, which must then lie within that slab.
bool segment_meets_box(vec3 P, vec3 d) {
    float t_near = 0.0, t_far = u_segment_end;
    for (int i = 0; i < 3; ++i) {
        if (abs(d[i]) < u_parallel) {
            if (P[i] < u_box_min[i] || P[i] > u_box_max[i]) return false;
        } else {
            float a = (u_box_min[i] - P[i]) / d[i], b = (u_box_max[i] - P[i]) / d[i];
            t_near = max(t_near, min(a, b));
            t_far = min(t_far, max(a, b));
        }
    }
    return t_near <= t_far;
}

void main() {
    out_visibility = u_lit;
    vec3 P;
    bool covered = gbuffer_position(P);
    int id = gbuffer_ids().x;
    if (!covered || id < 0) return;                               // nothing visible here
    if (id == u_caster) return;                                   // no self-shadowing (by construction)
    if (texelFetch(u_receives, ivec2(id, 0), 0).r == 0.0) return; // not a receiver of caster images
    vec4 s = u_light_matrix * vec4(P, 1.0);
    if (u_clip == 1) {
        if (s.w <= 0.0) return;                                   // behind the light's centre of projection
        if (!segment_meets_box(P, u_light.xyz - u_light.w * P)) return;  // not beyond the caster
    }
    if (s.w == 0.0) return;                                       // on the light's plane: no projection
    // clip off: the divide by s.w mirrors points behind the light into the image (back-projection)
    vec2 st = s.xy / s.w;
    if (any(lessThan(st, vec2(0.0))) || any(greaterThan(st, vec2(1.0)))) return;  // outside the image
    // explicit level: implicit derivatives are undefined after the non-uniform returns above
    out_visibility = u_lit - textureLod(u_mask, st, BASE_LEVEL).r;
}
#endif
