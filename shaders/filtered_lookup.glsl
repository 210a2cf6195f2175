// Filtered shadow maps (VSM: Donnelly & Lauritzen 2006; ESM: Annen et al. 2008), two programs:
// with BLUR defined, one direction of the separable box filter over one face of the moments
// atlas; otherwise the lookup over the G-buffer, one visibility value per screen pixel.
// The atlas holds u_faces faces (1, or 6 for a point light's cube, chosen by the major axis of
// the light-to-point vector as in shadow_lookup.glsl); face f has u_light_matrix[f] = bias ·
// projection · view, its view u_light_view[f], and occupies u_face_rect[f] (texels). Depth t is
// linear in [0, 1] over the fitted near/far planes, as in filtered_depth.glsl.
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
#define HALF_TEXEL 0.5                   // texel centres are at integer + 0.5 (GL 4.5 core §8.14)

#ifdef BLUR
// Box filter of 2 u_radius + 1 texels along u_direction, taps clamped to the face u_rect (x0,
// y0, width, height) so that a cube face never reads its neighbour. Weights are 1 / taps and
// accumulated one by one: an ESM average of values up to exp(88) never overflows.
uniform sampler2D u_moments;
uniform ivec2 u_direction;
uniform int u_radius;
uniform ivec4 u_rect;
out vec2 out_moments;
void main() {
    ivec2 t = ivec2(gl_FragCoord.xy);
    ivec2 lo = u_rect.xy, hi = u_rect.xy + u_rect.zw - 1;
    float w = 1.0 / float(2 * u_radius + 1);
    vec2 sum = vec2(0.0);
    for (int i = -u_radius; i <= u_radius; ++i)
        sum += w * texelFetch(u_moments, clamp(t + i * u_direction, lo, hi), 0).rg;
    out_moments = sum;
}
#else
#include "lights.glsl"
#define LIT 1.0
#define MAX_FACES 6

uniform sampler2D u_position;            // G-buffer world position, w = 1 where covered
uniform sampler2D u_moments;             // filtered moments, bilinear sampling
uniform vec2 u_atlas_size;               // atlas width, height in texels
uniform int u_faces;
uniform mat4 u_light_matrix[MAX_FACES];
uniform mat4 u_light_view[MAX_FACES];
uniform vec4 u_face_rect[MAX_FACES];
uniform float u_near;
uniform float u_far;
uniform int u_esm;
uniform float u_exponent;                // ESM: c
uniform float u_min_variance;            // VSM: σ² never below this (linear depth units²)
uniform float u_bleed_reduction;         // VSM: p_max mapped through linstep(this, 1, p_max)
out float out_visibility;

#include "cube_face.glsl"

// Chebyshev's one-sided upper bound on P(z >= t) (Donnelly & Lauritzen 2006, §3.1), then the
// light-bleeding reduction linstep(u_bleed_reduction, 1, p_max) (Lauritzen, GPU Gems 3 ch. 8).
float vsm(vec2 m, float t) {
    if (t <= m.x) return LIT;
    float variance = max(m.y - m.x * m.x, u_min_variance);
    float d = t - m.x;
    float p_max = variance / (variance + d * d);
    return clamp((p_max - u_bleed_reduction) / (LIT - u_bleed_reduction), 0.0, LIT);
}

// exp(-c t) · E[exp(c z)] (Annen et al. 2008, eq. 5), in log space: exp(-c t) alone would be
// a float32 denormal (exp(-88) < 1.2e-38) and could flush to 0.
float esm(float e, float t) {
    return clamp(exp(log(e) - u_exponent * t), 0.0, LIT);
}

void main() {
    vec4 p4 = texelFetch(u_position, ivec2(gl_FragCoord.xy), 0);
    out_visibility = LIT;
    if (p4.w == 0.0) return;
    vec3 P = p4.xyz;
    int f = face_of(P);
    vec4 s = u_light_matrix[f] * vec4(P, 1.0);
    if (s.w <= 0.0) return;              // behind the light's centre of projection
    vec3 c = s.xyz / s.w;
    if (any(lessThan(c.xy, vec2(0.0))) || any(greaterThan(c.xy, vec2(1.0)))) return;  // outside the map
    float t = (-(u_light_view[f] * vec4(P, 1.0)).z - u_near) / (u_far - u_near);
    if (t < 0.0 || t > 1.0) return;      // outside the fitted depth range: nothing casts there
    // Bilinear sample (moments filter linearly), its footprint kept inside this face.
    vec2 inner = u_face_rect[f].xy + vec2(HALF_TEXEL);
    vec2 atlas = clamp(u_face_rect[f].xy + c.xy * u_face_rect[f].zw, inner,
                       inner + u_face_rect[f].zw - vec2(2.0 * HALF_TEXEL));
    vec2 m = texture(u_moments, atlas / u_atlas_size).rg;
    out_visibility = u_esm == 1 ? esm(m.x, t) : vsm(m, t);
}
#endif
#endif
