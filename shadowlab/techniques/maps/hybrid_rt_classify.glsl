// Hybrid ray-traced shadows, the classification pass (shadowlab/techniques/maps/hybrid_rt.py): one
// full-screen pass over the G-buffer that compares the receiver with every texel of a
// (2r+1)² kernel of the depth atlas (r = u_spread texels around the texel holding the point),
// with the constant bias of shadow_map's bias family in its world form (u_bias: window depth,
// orthographic maps; u_bias_world: a world distance towards the light, perspective maps,
// converted at the receiver by world_bias.glsl). Writes, per pixel (RGBA32F):
//   x: the class — CLASS_LIT (every tap lit), CLASS_SHADOWED (every tap shadowed) or
//      CLASS_UNCERTAIN (the taps disagree, or the kernel reaches past the face's edge);
//   y: the nearest tap's answer (1 lit, 0 shadowed): what a dropped tile takes;
//   z: the world distance from the point towards the light over which a shadow ray must look
//      (ray shortening), or NO_DISTANCE (trace the whole segment). Any caster nearer to the light
//      than the smallest depth d_min stored in the kernel would have been rasterised into the
//      kernel's texels if it covers one of their centres (the shadow ray from P projects onto
//      P's own texel: it runs along the light's ray through P), so only the part of the ray at
//      window depth >= d_min can hold an unseen caster. z is the distance s along
//      light_dir_to(P) at which the window depth falls to d_min (solved exactly, in the form of
//      window_to_world in toolkit.py), plus a margin: u_margin_texels world texels at that point
//      (a caster thinner than a texel, or sloped across the kernel, can lie nearer the light at
//      P's uv than the stored depths say) plus the world size of the bias (u_margin_bias).
// Points without a G-buffer point, behind the light's centre of projection or outside the map
// are lit (as in shadow_lookup.glsl: the fit covers every point that can be shadowed).
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
#include "lights.glsl"
#define LIT 1.0
#define SHADOWED 0.0
#define CLASS_LIT 1.0
#define CLASS_SHADOWED 0.0
#define CLASS_UNCERTAIN 0.5
#define NO_DISTANCE -1.0
#ifndef MAX_FACES
#error "MAX_FACES: the map toolkit's atlas size (shadowlab.techniques.maps.toolkit.ATLAS_DEFINES)"
#endif

#include "gbuffer_fetch.glsl"
uniform sampler2D u_map;                 // window depth of the casters
uniform vec2 u_atlas_size;
uniform int u_faces;
uniform mat4 u_light_matrix[MAX_FACES];
uniform vec4 u_face_rect[MAX_FACES];
uniform float u_bias;                    // window depth (orthographic maps)
uniform float u_bias_world;              // world distance towards the light (perspective maps)
uniform int u_spread;                    // kernel radius r, texels
uniform float u_texel_world;             // orthographic maps: world size of a texel
uniform float u_texel_angle;             // perspective maps: world size of a texel per unit distance
uniform float u_margin_texels;           // shortening margin, world texels at the stop point
uniform float u_margin_bias;             // shortening margin, the bias's world distance
out vec4 out_class;

#include "cube_face.glsl"
#include "atlas.glsl"
#include "world_bias.glsl"

// The distance s >= 0 along the unit vector L from P at which face f's window depth has changed
// by delta (< 0: towards the light): with S = M P and m = M L, d(P + sL) - d(P) =
// s (m.z S.w - S.z m.w) / (S.w (S.w + s m.w)), solved for s. NO_DISTANCE where none does.
float distance_for(int f, vec3 P, vec3 L, float delta) {
    vec4 S = u_light_matrix[f] * vec4(P, 1.0);
    vec4 m = u_light_matrix[f] * vec4(L, 0.0);
    float den = m.z * S.w - S.z * m.w - delta * S.w * m.w;
    if (den == 0.0) return NO_DISTANCE;
    float s = delta * S.w * S.w / den;
    return s >= 0.0 ? s : NO_DISTANCE;
}

void main() {
    out_class = vec4(CLASS_LIT, LIT, NO_DISTANCE, 0.0);
    vec3 P;
    if (!gbuffer_position(P)) return;
    int f = face_of(P);
    vec3 c;
    if (!map_coordinates(f, P, c)) return;                  // behind the light's centre of projection
    if (any(lessThan(c, vec3(0.0))) || any(greaterThan(c, vec3(1.0)))) return;  // outside the map
    float ref = c.z - (u_bias + world_bias(f, P, u_bias_world));
    vec2 atlas = atlas_texel(f, c.xy);
    ivec2 lo = ivec2(u_face_rect[f].xy), hi = lo + ivec2(u_face_rect[f].zw) - 1;
    ivec2 t = clamp(ivec2(floor(atlas)), lo, hi);
    int lit = 0, taps = 0;
    bool beyond = false;                 // a tap past the face's edge: nothing known there
    float nearest_depth = 1.0;
    for (int dy = -u_spread; dy <= u_spread; ++dy)
        for (int dx = -u_spread; dx <= u_spread; ++dx) {
            ivec2 tap = t + ivec2(dx, dy);
            if (any(lessThan(tap, lo)) || any(greaterThan(tap, hi))) {
                beyond = true;
                continue;
            }
            float stored = texelFetch(u_map, tap, 0).r;
            lit += ref <= stored ? 1 : 0;
            taps += 1;
            nearest_depth = min(nearest_depth, stored);
        }
    float nearest = ref <= texelFetch(u_map, t, 0).r ? LIT : SHADOWED;
    // The map is fitted to the receivers that can be shadowed, so a caster's shadow can reach the
    // face's edge: a kernel cut by the edge has lost the taps that would disagree, so it is
    // uncertain (clamping them to the edge texel would call the rim of such a shadow sure).
    float cls = beyond ? CLASS_UNCERTAIN : (lit == taps ? CLASS_LIT : (lit == 0 ? CLASS_SHADOWED : CLASS_UNCERTAIN));
    float reach = NO_DISTANCE;
    if (cls == CLASS_UNCERTAIN) {
        vec3 L = light_dir_to(P);
        float s = distance_for(f, P, L, nearest_depth - c.z);
        if (s >= 0.0) {
            vec3 X = P + s * L;
            float texel = u_texel_world > 0.0 ? u_texel_world : u_texel_angle * length(X - light_position);
            reach = s + u_margin_texels * texel + u_margin_bias;
        }
    }
    out_class = vec4(cls, nearest, reach, 0.0);
}
#endif
