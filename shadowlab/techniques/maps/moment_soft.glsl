// Moment soft shadow mapping (Peters, Münstermann, Wetzstein & Klein, "Beyond Hard Shadows:
// Moment Shadow Maps for Single Scattering, Soft Shadows and Translucent Occluders", I3D 2016,
// its section on moment soft shadow mapping; the extended version, JCGT 6(1) 2017) over the G-buffer: one
// visibility value per screen pixel from the summed-area table (SAT, moment_soft_sat.glsl) of a
// four-moment shadow map (filtered_depth.glsl with HEIGHT_DEPTH: moments of the normalised
// height above the light's plane, in the optimised basis of Peters & Klein 2015).
//
// PCSS's steps (Fernando 2005) with the moments in place of the taps:
//   1. blocker search: the moments averaged over the search region (one SAT rectangle: 4 taps)
//      give the canonical three-point distribution of the Hamburger 4MSM (msm.glsl) with one
//      point at the receiver's depth t; the average blocker depth is the mean of its other
//      support points in front of t, weighted by their weights (the paper's estimate), plus a
//      small fully-lit bias ε · t (10⁻³ in the authors' published shader code) that pulls it to the receiver where almost
//      nothing blocks; no weight in front of t: lit;
//   2. penumbra estimate, parallel planes (as pcss.glsl): the filter region is the light seen
//      from P cut by the plane at the blockers' height h_b, projected from the light's centre;
//   3. the 4-moment reconstruction (msm.glsl) on the moments averaged over the filter region:
//      one SAT rectangle with fractional edges (16 taps), so a penumbra narrower than a texel
//      still grows continuously.
// Regions: the heights h are measured from the light's centre along u_height_axis (a one-sided
// light's normal), the light's corners are centre + u_light_extents · (±½, ±½); the region at
// height h is the map rectangle bounding the four points at height h on the segments from P to
// the corners (a copy of the light scaled by (h_r - h) / h_r), projected into the map; for a
// disc or a sphere it bounds the square around the disc. Because the moments are heights, a
// receiver parallel to the light has one depth t across any region (no self-shadowing of a
// floor, whatever the map's axis); a tilted receiver is compared at its plane's lowest depth
// over the region (u_receiver_plane: the lower envelope of Isidoro 2006's receiver plane).
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
#include "lights.glsl"
#include "msm.glsl"
#define LIT 1.0
#define SHADOWED 0.0
#define CORNERS 4                        // the light's corners, and a region's bounding box
#define FAR_TEXEL 1e30                   // beyond any map coordinate: the empty bounding box

#include "gbuffer_fetch.glsl"
#ifdef SAT_FIXED
uniform usampler2D u_sat;                // the SAT in 32-bit fixed point (sums modulo 2³²)
#define SAT_VALUE uvec4
#else
uniform sampler2D u_sat;                 // the SAT in float32
#define SAT_VALUE vec4
#endif
uniform float u_sat_step;                // SAT_FIXED: one fixed-point step, in moment units (else 1)
uniform mat4 u_light_matrix;             // bias · projection · view of the map
uniform mat2x3 u_light_extents;          // the light's two extents, world (columns)
uniform vec3 u_height_axis;              // unit, world: height h = dot(p - centre, axis)
uniform float u_search_height;           // the blocker search's slice (> 0)
uniform vec2 u_height_range;             // heights (lowest, highest): depth z = (h - x) / (y - x)
uniform mat4 u_dequantize;               // the optimised basis back to b = (z, z², z³, z⁴) ...
uniform vec4 u_quantize_offset;          // ... b = u_dequantize · (stored - offset)
uniform float u_moment_bias;             // α: b' = (1 - α) b + α · u_moment_bias_target
uniform vec4 u_moment_bias_target;
uniform float u_bias;                    // constant depth bias, normalised height units
uniform float u_lit_bias;                // ε of the blocker average (ε t + Σ w z) / (ε + Σ w)
uniform float u_min_filter;              // the smallest filter region's side, texels
uniform int u_receiver_plane;            // 1: compare at the receiver plane's lowest depth
uniform float u_texel_angle;             // world size of a texel per unit distance
uniform float u_basis_switch;            // receiver tangent t1 = N × helper_a if |N.x| < this,
uniform vec3 u_basis_helper_a;           // else N × helper_b (area_lights.basis's choice)
uniform vec3 u_basis_helper_b;
uniform int u_search;                    // 1: blocker search; 0: a fixed region of u_fixed_filter
uniform float u_fixed_filter;            // texels (side of the fixed region)
uniform int u_one_sided;                 // rect, disc: points behind the emitting plane see none
uniform vec3 u_light_normal;
out float out_visibility;

const vec2 CORNER[CORNERS] = vec2[](vec2(-0.5, -0.5), vec2(0.5, -0.5), vec2(-0.5, 0.5), vec2(0.5, 0.5));

vec3 to_map(vec3 p) {                    // (u, v, window depth)
    vec4 s = u_light_matrix * vec4(p, 1.0);
    return s.xyz / s.w;
}

// The region at height h for a receiver P at height h_r (h <= h_r): (x0, y0, x1, y1) in texels
// of the map, unclamped.
vec4 region(vec3 P, float h_r, float h, vec2 size) {
    float s = clamp((h_r - h) / h_r, 0.0, 1.0);
    vec2 lo = vec2(FAR_TEXEL), hi = vec2(-FAR_TEXEL);
    for (int k = 0; k < CORNERS; ++k) {
        vec2 uv = to_map(mix(P, light_position + u_light_extents * CORNER[k], s)).xy;
        lo = min(lo, uv);
        hi = max(hi, uv);
    }
    return vec4(lo, hi) * size.xyxy;
}

// S(p): the sum over the texels [0, p.x) × [0, p.y) (0 on the table's lower and left edges).
SAT_VALUE sat_at(ivec2 p) {
    if (p.x <= 0 || p.y <= 0) return SAT_VALUE(0);
    return texelFetch(u_sat, p - 1, 0);
}

// The sum over the texels [a.x, b.x) × [a.y, b.y), in moment units. Fixed point: the four
// corners combine in modular uint arithmetic, exact while the rectangle's sum is below 2³².
vec4 rect_sum(SAT_VALUE s00, SAT_VALUE s10, SAT_VALUE s01, SAT_VALUE s11) {
    return vec4(s11 - s10 - s01 + s00) * u_sat_step;
}

// The moments averaged over the whole texels that the region r (texels) touches: 4 taps
// (the blocker search; rounding outwards keeps every blocker of the region in it).
vec4 outer_average(vec4 r, ivec2 size) {
    ivec2 a = clamp(ivec2(floor(r.xy)), ivec2(0), size - 1);
    ivec2 b = clamp(ivec2(ceil(r.zw)), a + 1, size);
    vec4 sum = rect_sum(sat_at(a), sat_at(ivec2(b.x, a.y)), sat_at(ivec2(a.x, b.y)), sat_at(b));
    return sum / float((b.x - a.x) * (b.y - a.y));
}

// The moments averaged over the region r (texels, x0 < x1, y0 < y1, inside the map) with
// fractional edges: the texels it covers in part count by the part covered. Along x, with
// i0 = floor(x0), i1 = floor(x1): ∫ = (1 - fract x0) · column i0 + columns [i0 + 1, i1) +
// fract x1 · column i1 (also right for i0 = i1, the middle term then being minus column i0);
// in 2D the product of the two: 9 rectangles from the table at the 4 × 4 boundaries (16 taps).
vec4 fractional_average(vec4 r, ivec2 size) {
    ivec2 i0 = ivec2(floor(r.xy)), i1 = ivec2(floor(r.zw));
    vec2 f0 = r.xy - vec2(i0), f1 = r.zw - vec2(i1);
    ivec4 xs = clamp(ivec4(i0.x, i0.x + 1, i1.x, i1.x + 1), 0, size.x);
    ivec4 ys = clamp(ivec4(i0.y, i0.y + 1, i1.y, i1.y + 1), 0, size.y);
    vec3 wx = vec3(1.0 - f0.x, 1.0, f1.x), wy = vec3(1.0 - f0.y, 1.0, f1.y);
    SAT_VALUE s[16];                     // s[4 j + k] = S(xs[j], ys[k])
    for (int j = 0; j < 4; ++j)
        for (int k = 0; k < 4; ++k) s[4 * j + k] = sat_at(ivec2(xs[j], ys[k]));
    vec4 sum = vec4(0.0);
    for (int j = 0; j < 3; ++j)
        for (int k = 0; k < 3; ++k)
            sum += wx[j] * wy[k] * rect_sum(s[4 * j + k], s[4 * j + k + 4], s[4 * j + k + 1], s[4 * j + k + 5]);
    return sum / ((r.z - r.x) * (r.w - r.y));
}

// Averaged stored moments → biased moments b of z (Peters & Klein 2015, §4 and Algorithm 2).
vec4 biased(vec4 stored) {
    vec4 b = u_dequantize * (stored - u_quantize_offset);
    return mix(b, u_moment_bias_target, u_moment_bias);
}

// Step 1: from the search region's moments b and the receiver's depth t, the blockers' share
// `blocked` of the region (the weight in front of t) and their average depth (Peters et al.
// 2016 and JCGT 2017, their soft-shadow sections). The canonical three-point distribution has support t, z2, z3
// and weights w_i = E[(z - x_j)(z - x_k)] / ((x_i - x_j)(x_i - x_k)) (Lagrange: the one
// distribution on these three points with the moments 1, b1, b2).
float blocker_depth(vec4 b, float t, out float blocked) {
    float z2, z3;
    msm_support(b, t, z2, z3);
    float w2 = (t * z3 - b.x * (t + z3) + b.y) / ((z2 - t) * (z2 - z3));
    float wt = (z2 * z3 - b.x * (z2 + z3) + b.y) / ((t - z2) * (t - z3));
    float w3 = MSM_TOTAL_MASS - wt - w2;
    float in_front2 = z2 < t ? w2 : 0.0, in_front3 = z3 < t ? w3 : 0.0;
    blocked = in_front2 + in_front3;
    return (u_lit_bias * t + in_front2 * z2 + in_front3 * z3) / (u_lit_bias + blocked);
}

// The receiver plane's lowest depth over the region r (texels) minus its depth t at the centre
// c (texels), for the depth gradient g (per texel): Σ_i min(g_i (r_lo,i - c_i), g_i (r_hi,i - c_i)).
float plane_drop(vec2 g, vec4 r, vec2 c) {
    vec2 lo = g * (r.xy - c), hi = g * (r.zw - c);
    return min(lo.x, hi.x) + min(lo.y, hi.y);
}

void main() {
    out_visibility = LIT;
    vec3 P;
    if (!gbuffer_position(P)) return;
    if (u_one_sided == 1 && dot(P - light_position, u_light_normal) <= 0.0) {
        out_visibility = SHADOWED;       // behind the emitting side (docs/metrics.md)
        return;
    }
    vec4 s = u_light_matrix * vec4(P, 1.0);
    if (s.w <= 0.0) return;              // behind the light's centre of projection
    vec3 c = s.xyz / s.w;
    if (any(lessThan(c, vec3(0.0))) || any(greaterThan(c, vec3(1.0)))) return;  // outside the map
    ivec2 isize = textureSize(u_sat, 0);
    vec2 size = vec2(isize);
    vec2 ct = c.xy * size;               // the receiver in texels

    float h_r = dot(P - light_position, u_height_axis);
    float range = u_height_range.y - u_height_range.x;
    float t = (h_r - u_height_range.x) / range;

    // The depth's gradient along the receiver's plane, per texel (Cramer's rule on two tangent
    // steps of one texel's world size; edge-on receivers keep 0).
    vec2 g = vec2(0.0);
    if (u_receiver_plane == 1) {
        vec3 N = gbuffer_normal_towards(light_dir_to(P));
        float texel = u_texel_angle * length(P - light_position);
        vec3 t1 = normalize(cross(N, abs(N.x) < u_basis_switch ? u_basis_helper_a : u_basis_helper_b));
        vec3 t2 = cross(N, t1);
        vec2 a = (to_map(P + t1 * texel).xy - c.xy) * size, b = (to_map(P + t2 * texel).xy - c.xy) * size;
        vec2 dt = vec2(dot(t1, u_height_axis), dot(t2, u_height_axis)) * texel / range;
        float det = a.x * b.y - a.y * b.x;
        if (abs(det) > 0.0) g = vec2(dt.x * b.y - dt.y * a.y, a.x * dt.y - b.x * dt.x) / det;
    }

    vec4 r;
    if (u_search == 1) {
        if (h_r <= u_search_height) return;  // below every caster: nothing between it and the light
        // 1. Blocker search over the light seen through the casters' lowest height.
        vec4 rs = region(P, h_r, u_search_height, size);
        vec4 clamped = clamp(rs, vec4(0.0), size.xyxy);
        float ts = t - u_bias + plane_drop(g, clamped, ct);
        float blocked;
        float z_b = blocker_depth(biased(outer_average(clamped, isize)), ts, blocked);
        if (!(blocked > 0.0)) return;    // no weight in front of the receiver: lit
        // 2. Penumbra estimate: the region through the blockers' height.
        float h_b = clamp(u_height_range.x + clamp(z_b, 0.0, 1.0) * range, u_search_height, h_r);
        r = region(P, h_r, h_b, size);
    } else {
        r = ct.xyxy + vec4(-0.5, -0.5, 0.5, 0.5) * u_fixed_filter;
    }
    // At least u_min_filter texels a side (the paper's smallest kernel), then inside the map.
    vec2 mid = 0.5 * (r.xy + r.zw), half_side = max(0.5 * (r.zw - r.xy), vec2(0.5 * u_min_filter));
    r = vec4(mid - half_side, mid + half_side);
    r = vec4(clamp(r.xy, vec2(0.0), size - u_min_filter), clamp(r.zw, vec2(u_min_filter), size));
    r.zw = max(r.zw, r.xy + u_min_filter);
    // 3. The 4-moment reconstruction over the filter region.
    float tf = t - u_bias + plane_drop(g, r, ct);
    out_visibility = LIT - clamp(msm_shadow_intensity(biased(fractional_average(r, isize)), tf), 0.0, MSM_TOTAL_MASS);
}
#endif
