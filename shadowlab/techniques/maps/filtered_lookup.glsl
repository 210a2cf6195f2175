// Filtered shadow maps (VSM: Donnelly & Lauritzen 2006; ESM: Annen et al. 2008; EVSM: Lauritzen
// & McCool 2008; MSM: Peters & Klein 2015, Hamburger 4MSM): the lookup over the G-buffer, one
// visibility value per screen pixel, in the moments atlas that filtered_depth.glsl wrote and
// filtered_blur.glsl filtered.
// The atlas holds u_faces faces (1, or 6 for a point light's cube, chosen by the major axis of
// the light-to-point vector as in shadow_lookup.glsl); face f has u_light_matrix[f] = bias ·
// projection · view, its view u_light_view[f], and occupies u_face_rect[f] (texels). Depth t is
// linear in [0, 1] over the fitted near/far planes, as in filtered_depth.glsl.
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
#include "lights.glsl"
#define LIT 1.0
#define TOTAL_MASS 1.0                   // MSM: the zeroth moment b0 = E[z⁰] of any depth distribution
#ifndef MAX_FACES
#error "MAX_FACES: the map toolkit's atlas size (shadowlab.techniques.maps.toolkit.ATLAS_DEFINES)"
#endif
#define BASE_LEVEL 0.0                   // the atlas has no mipmaps: sample its level 0 explicitly

#include "gbuffer_fetch.glsl"
uniform sampler2D u_moments;             // filtered moments, bilinear sampling
uniform vec2 u_atlas_size;               // atlas width, height in texels
uniform int u_faces;
uniform mat4 u_light_matrix[MAX_FACES];
uniform mat4 u_light_view[MAX_FACES];
uniform vec4 u_face_rect[MAX_FACES];
uniform float u_near;
uniform float u_far;
uniform int u_variant;                   // VARIANT_* of the map
uniform float u_exponent;                // ESM: c
uniform float u_min_variance;            // VSM, EVSM: σ² never below this (linear depth units²)
uniform float u_bleed_reduction;         // VSM, EVSM: p_max mapped through linstep(this, 1, p_max)
uniform vec2 u_warp;                     // EVSM: z' = u_warp.x z + u_warp.y (2, -1)
uniform vec2 u_exponents;                // EVSM: (c+, c-)
uniform mat4 u_dequantize;               // MSM: inverse of the storage transform ...
uniform vec4 u_quantize_offset;          // ... b = u_dequantize · (stored - offset)
uniform float u_moment_bias;             // MSM: α
uniform vec4 u_moment_bias_target;       // MSM: b' = (1 - α) b + α · this
out float out_visibility;

#include "cube_face.glsl"
#include "atlas.glsl"
#include "msm.glsl"

// Chebyshev's one-sided upper bound on P(z >= t) (Donnelly & Lauritzen 2006, §3.1), then the
// light-bleeding reduction linstep(u_bleed_reduction, 1, p_max) (Lauritzen, GPU Gems 3 ch. 8).
// min_variance: the floor of σ² in the units of m.
float chebyshev(vec2 m, float t, float min_variance) {
    if (t <= m.x) return LIT;
    float variance = max(m.y - m.x * m.x, min_variance);
    float d = t - m.x;
    float p_max = variance / (variance + d * d);
    return clamp((p_max - u_bleed_reduction) / (LIT - u_bleed_reduction), 0.0, LIT);
}

float vsm(vec2 m, float t) {
    return chebyshev(m, t, u_min_variance);
}

// EVSM (Lauritzen & McCool 2008): Chebyshev on the warped moments with the receiver warped the
// same way; the variance floor is u_min_variance (linear depth units²) times the squared
// derivative of the warp at the receiver, dw/dz = u_warp.x · c · |w|. evsm4: the smaller bound.
// The floor is squared as (√u_min_variance · dw/dz)²: dw/dz alone reaches 2 · 40 · e^40 = 1.9e19
// at t = 1 with the default c+, and (dw/dz)² would overflow float32 if a compiler reassociated
// u_min_variance · dp · dp (GLSL allows it without `precise`).
float evsm(vec4 m, float t) {
    float warped = u_warp.x * t + u_warp.y;
    float deviation = sqrt(u_min_variance);
    float p = exp(u_exponents.x * warped);
    float dp = deviation * u_warp.x * u_exponents.x * p;
    float visibility = chebyshev(m.xy, p, dp * dp);
    if (u_variant == VARIANT_EVSM4) {
        float n = -exp(-u_exponents.y * warped);
        float dn = deviation * u_warp.x * u_exponents.y * n;
        visibility = min(visibility, chebyshev(m.zw, n, dn * dn));
    }
    return visibility;
}

// MSM, Hamburger 4MSM (Peters & Klein 2015, Algorithm 2; msm.glsl): the stored moments are
// dequantised and biased towards u_moment_bias_target, then the shadow intensity G is the weight
// of the canonical three-point distribution in front of t; visibility = 1 - clamp(G, 0, 1).
float msm(vec4 stored, float t) {
    vec4 b = u_dequantize * (stored - u_quantize_offset);
    b = mix(b, u_moment_bias_target, u_moment_bias);
    return LIT - clamp(msm_shadow_intensity(b, t), 0.0, TOTAL_MASS);
}

// exp(-c t) · E[exp(c z)] (Annen et al. 2008, eq. 5), in log space: exp(-c t) alone would be
// a float32 denormal (exp(-88) < 1.2e-38) and could flush to 0.
float esm(float e, float t) {
    return clamp(exp(log(e) - u_exponent * t), 0.0, LIT);
}

void main() {
    out_visibility = LIT;
    vec3 P;
    if (!gbuffer_position(P)) return;
    int f = face_of(P);
    vec3 c;
    if (!map_coordinates(f, P, c)) return;  // behind the light's centre of projection
    if (any(lessThan(c.xy, vec2(0.0))) || any(greaterThan(c.xy, vec2(1.0)))) return;  // outside the map
    float t = (-(u_light_view[f] * vec4(P, 1.0)).z - u_near) / (u_far - u_near);
    if (t < 0.0 || t > 1.0) return;      // outside the fitted depth range: nothing casts there
    // Bilinear sample (moments filter linearly), its footprint kept inside this face.
    vec2 atlas = bilinear_inside_face(f, atlas_texel(f, c.xy));
    // explicit level: implicit derivatives are undefined after the non-uniform returns above
    vec4 m = textureLod(u_moments, atlas / u_atlas_size, BASE_LEVEL);
    if (u_variant == VARIANT_ESM) out_visibility = esm(m.x, t);
    else if (u_variant == VARIANT_VSM) out_visibility = vsm(m.xy, t);
    else if (u_variant == VARIANT_MSM) out_visibility = msm(m, t);
    else out_visibility = evsm(m, t);
}
#endif
