// Percentage-closer soft shadows (Fernando 2005, "Percentage-Closer Soft Shadows", SIGGRAPH
// sketch; NVIDIA whitepaper "Integrating Realistic Soft Shadows into Your Game Engine", 2008) over
// the G-buffer: one visibility value per screen pixel. The map is one perspective view from the
// area light's centre: window depth d, linear depth z = n f / (f - d (f - n)) along its axis.
// PCSS's parallel planes are planes parallel to the light: "height" h is the distance from the
// light's plane along u_height_axis (rect, disc: the normal; sphere: the map's axis). With the
// receiver P at height h_r and X_i = centre + u_light_extents · offset_i the points of a fixed
// stratified pattern on the light (offsets in the unit square centred on 0, or the
// unit-diameter disc), a tap "through height h" is the map texel of the point at height h on the
// segment P → X_i: the light seen from P, cut by the plane at height h (a copy of the light
// scaled by (h_r - h) / h_r), projected from the light's centre into the map:
//   1. blocker search: the average height h_b of the taps through u_search_height (the
//      casters' lowest height: the largest slice, which holds every other) closer than the
//      receiver; none → lit;
//   2.-3. penumbra estimate and PCF (Reeves et al. 1987): the taps through h_b, the blocker
//      plane: tap i is lit when the ray from P to X_i passes the blockers. With the map's axis
//      along the light's normal (h = linear depth) these are Fernando's regions exactly: search
//      light_uv · (z_r - n) / z_r, PCF light_uv · (z_r - z_b) / z_b · n / z_r (the penumbra
//      w = (z_r - z_b) · light / z_b projected into the map), light_uv the light's extent at the
//      near plane n. A fitted frustum may look along an axis far from the light's normal (47° in
//      scene soft_banding): depth along that axis is no height above the light, the light's own
//      corners lie at depths of the order of the blockers', and the affine near-plane regions
//      were wrong there.
// Depth comparisons use the receiver's plane (Isidoro 2006, receiver plane depth bias): the
// receiver's window depth is extrapolated along its plane to the centre of each tap's texel
// (where the stored depth was rasterised), then u_bias subtracted.
// Empty texels (still at the depth pass's clear value u_empty_depth: nothing between the light
// and the far plane there) never block, in the search and in the PCF alike. They must not be
// compared with the receiver's plane: extrapolated across a wide search region (a wide map
// along a tilted axis), the plane's depth passes the far plane (≥ 1) towards its horizon, so a
// cleared 1.0 would count as a blocker at the far plane and pull the average blocker behind
// the receiver — the kernel collapsed to 0 and the shadow came out hard.
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
#include "lights.glsl"
#define LIT 1.0
#define SHADOWED 0.0
#define HALF_TEXEL 0.5                   // texel centres are at integer + 0.5 (GL 4.5 core §8.14)

#include "gbuffer_fetch.glsl"
uniform sampler2D u_map;                 // window depth from the light's centre
uniform mat4 u_light_matrix;             // bias · projection · view
uniform float u_near;                    // the map's near and far planes (linear depth)
uniform float u_far;
uniform mat2 u_light_uv;                 // the light's extents at the near plane, uv units (fixed PCF)
uniform mat2x3 u_light_extents;          // the light's two extents, world (columns)
uniform vec3 u_height_axis;              // unit, world: height h = dot(p - centre, axis)
uniform vec3 u_height_axis_view;         // the same in the map's view space
uniform vec2 u_proj_scale;               // proj[0][0], proj[1][1]: view x, y = (2 uv - 1) z / scale
uniform float u_search_height;           // the blocker search's slice (> 0)
uniform float u_bias;                    // constant, window depth
uniform float u_empty_depth;             // the map's clear value: no geometry in this texel
uniform int u_receiver_plane;            // 1: compare each tap with the receiver's plane
uniform float u_texel_angle;             // world size of a texel per unit distance
uniform int u_search;                    // 1: PCSS; 0: fixed-size PCF of u_fixed_scale · light_uv
uniform float u_fixed_scale;
uniform float u_basis_switch;           // receiver tangent t1 = N × helper_a if |N.x| < this,
uniform vec3 u_basis_helper_a;           // else N × helper_b (area_lights.basis's choice)
uniform vec3 u_basis_helper_b;
uniform int u_one_sided;                 // rect, disc: points behind the emitting plane see none
uniform vec3 u_light_normal;
uniform int u_blocker_samples;
uniform int u_filter_samples;
uniform vec2 u_blocker_offsets[BLOCKER_SAMPLES];
uniform vec2 u_filter_offsets[FILTER_SAMPLES];
out float out_visibility;

float linear_depth(float d) {
    return u_near * u_far / (u_far - d * (u_far - u_near));
}

vec3 to_map(vec3 p) {                    // (u, v, window depth)
    vec4 s = u_light_matrix * vec4(p, 1.0);
    return s.xyz / s.w;
}

// The nearest texel to uv (clamped to the map): its stored depth, and in `centre` the uv of its
// centre — where that depth was rasterised, so the receiver's plane is compared there.
float stored_depth(vec2 uv, out vec2 centre) {
    ivec2 size = textureSize(u_map, 0);
    ivec2 t = clamp(ivec2(floor(uv * vec2(size))), ivec2(0), size - 1);
    centre = (vec2(t) + vec2(HALF_TEXEL)) / vec2(size);
    return texelFetch(u_map, t, 0).r;
}

// The uv of the point at height h on the segment from P (height h_r > 0) to the light point
// X = centre + u_light_extents · offset (height 0); P itself where h ≥ h_r.
vec2 through(vec3 P, float h_r, vec2 offset, float h) {
    vec3 X = light_position + u_light_extents * offset;
    return to_map(mix(P, X, clamp((h_r - h) / h_r, 0.0, 1.0))).xy;
}

// The height of the surface a texel (centre uv) saw at window depth d.
float height_of(vec2 uv, float d) {
    float z = linear_depth(d);
    vec3 v = vec3((2.0 * uv - 1.0) * z / u_proj_scale, -z);   // view space: the map looks down -z
    return dot(v, u_height_axis_view);
}

// Does the stored depth block a receiver whose (plane-extrapolated, biased) depth is `ref`?
// Empty texels never do.
bool blocks(float stored, float ref) {
    return stored < ref && stored < u_empty_depth;
}

void main() {
    out_visibility = LIT;
    vec3 P;
    if (!gbuffer_position(P)) return;
    if (u_one_sided == 1 && dot(P - light_position, u_light_normal) <= 0.0) {
        out_visibility = SHADOWED;       // behind the emitting side (docs/metrics.md)
        return;
    }
    vec3 N = gbuffer_normal_towards(light_dir_to(P));  // two-sided receivers: the side facing the light
    vec4 s = u_light_matrix * vec4(P, 1.0);
    if (s.w <= 0.0) return;              // behind the light's centre of projection
    vec3 c = s.xyz / s.w;
    if (any(lessThan(c, vec3(0.0))) || any(greaterThan(c, vec3(1.0)))) return;  // outside the map

    // Receiver plane: dz/du, dz/dv of the window depth (exactly affine in uv on a plane).
    vec2 dz = vec2(0.0);
    if (u_receiver_plane == 1) {
        float texel = u_texel_angle * length(P - light_position);
        vec3 t1 = normalize(cross(N, abs(N.x) < u_basis_switch ? u_basis_helper_a : u_basis_helper_b));
        vec3 t2 = cross(N, t1);
        vec3 a = to_map(P + t1 * texel) - c;
        vec3 b = to_map(P + t2 * texel) - c;
        float det = a.x * b.y - a.y * b.x;
        if (abs(det) > 0.0)              // Cramer's rule; edge-on receivers keep dz = 0
            dz = vec2(a.z * b.y - b.z * a.y, a.x * b.z - b.x * a.z) / det;
    }

    float h_r = dot(P - light_position, u_height_axis);
    float h_b = h_r;
    if (u_search == 1) {
        if (h_r <= u_search_height) return;  // below every caster: nothing between it and the light
        // 1. Blocker search over the light seen through the lowest casters' height.
        float sum = 0.0, count = 0.0;
        for (int i = 0; i < u_blocker_samples; ++i) {
            vec2 at;
            float stored = stored_depth(through(P, h_r, u_blocker_offsets[i], u_search_height), at);
            if (blocks(stored, c.z + dot(dz, at - c.xy) - u_bias)) {
                sum += height_of(at, stored);
                count += 1.0;
            }
        }
        if (count == 0.0) return;        // no blocker: lit
        h_b = sum / count;
    }
    float lit = 0.0;
    for (int i = 0; i < u_filter_samples; ++i) {
        vec2 at;                         // 2.-3. through the blocker plane, or the fixed kernel
        vec2 uv = u_search == 1 ? through(P, h_r, u_filter_offsets[i], h_b)
                                : c.xy + u_light_uv * u_filter_offsets[i] * u_fixed_scale;
        float stored = stored_depth(uv, at);
        lit += blocks(stored, c.z + dot(dz, at - c.xy) - u_bias) ? SHADOWED : LIT;
    }
    out_visibility = lit / float(u_filter_samples);
}
#endif
