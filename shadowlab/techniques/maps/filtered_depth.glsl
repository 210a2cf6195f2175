// Filtered shadow maps, moments pass: casters rendered from the light into one face of the
// moments atlas (u_variant: VARIANT_VSM / _ESM / _EVSM2 / _EVSM4 / _MSM, #defined by the Python
// side from one table). Depth z is linear in [0, 1] over the face's fitted near/far planes:
// z = (d - near) / (far - near), d the distance along the view's axis (-z in view space).
// VSM (Donnelly & Lauritzen 2006, §3): stores the moments (z, z²); the second moment gets
// ¼ (∂z/∂x² + ∂z/∂y²) added (their §3.3 "biasing"), the variance of the depth over the
// fragment's own footprint on a sloped caster, so a surface's own filter never reads as occluded.
// ESM (Annen et al. 2008, §3): stores exp(c z); with z in [0, 1] and c <= 88 it stays below
// float32's 3.4e38 (exp(88.7) overflows).
// EVSM (Lauritzen & McCool 2008; Lauritzen 2007 §4.6): z' = u_warp.x z + u_warp.y in [-1, 1],
// p = exp(c+ z'), n = -exp(-c- z'); stores (p, p²) (evsm2) or (p, p², n, n²) (evsm4), each
// second moment biased by the squared derivatives of its warped depth as VSM's.
// MSM (Peters & Klein 2015, Hamburger 4MSM): stores b = (z, z², z³, z⁴), through the affine
// storage transform u_quantize · b + u_quantize_offset (their §4: the optimised 16-bit
// quantisation; identity and zero for float storage).
// HEIGHT_DEPTH (a define; moment_soft, Peters et al. 2016 with PCSS's parallel planes): depth is
// instead the height above the area light's plane, z = (dot(p - u_height_origin, u_height_axis)
// - u_near) / (u_far - u_near), clamped to [0, 1] — u_near, u_far are then the lowest and highest
// heights of the scene, and a receiver parallel to the light has one depth across any filter.
uniform mat4 u_light_view_proj;
uniform mat4 u_light_view;
uniform float u_near;                  // the face's fitted near and far planes (world units)
uniform float u_far;
uniform int u_variant;                 // VARIANT_* of the map
uniform float u_exponent;              // ESM's c
uniform float u_derivative_weight;     // VSM, EVSM: weight of the squared depth derivatives (¼)
uniform vec2 u_warp;                   // EVSM: z' = u_warp.x z + u_warp.y (2, -1)
uniform vec2 u_exponents;              // EVSM: (c+, c-)
uniform mat4 u_quantize;               // MSM: storage transform of the moments
uniform vec4 u_quantize_offset;        // MSM: its offset
uniform float u_moment_max;            // EVSM: the storage format's largest finite value
#ifdef HEIGHT_DEPTH
uniform vec3 u_height_origin;          // the light's centre (world)
uniform vec3 u_height_axis;            // unit, world: height h = dot(p - origin, axis)
#endif

#ifdef VERTEX_SHADER
in vec3 in_pos;
out float v_depth;                     // linear depth in [0, 1]
void main() {
#ifdef HEIGHT_DEPTH
    v_depth = (dot(in_pos - u_height_origin, u_height_axis) - u_near) / (u_far - u_near);
#else
    vec4 view = u_light_view * vec4(in_pos, 1.0);
    v_depth = (-view.z - u_near) / (u_far - u_near);
#endif
    gl_Position = u_light_view_proj * vec4(in_pos, 1.0);
}
#endif

#ifdef FRAGMENT_SHADER
in float v_depth;
out vec4 out_moments;

// (w, w² + ¼ (∂w/∂x² + ∂w/∂y²)): a depth's first two moments with the §3.3 footprint bias.
vec2 biased_moments(float w) {
    float dx = dFdx(w), dy = dFdy(w);
    return vec2(w, w * w + u_derivative_weight * (dx * dx + dy * dy));
}

void main() {
    float z = v_depth;
#ifdef HEIGHT_DEPTH
    z = clamp(z, 0.0, 1.0);            // heights are affine in world space: interpolated exactly, clamped here
#endif
    out_moments = vec4(0.0);
    if (u_variant == VARIANT_ESM) {
        out_moments.x = exp(u_exponent * z);
    } else if (u_variant == VARIANT_VSM) {
        out_moments.xy = biased_moments(z);
    } else if (u_variant == VARIANT_MSM) {
        float z2 = z * z;
        out_moments = u_quantize * vec4(z, z2, z2 * z, z2 * z2) + u_quantize_offset;
    } else {                           // EVSM: positive warp, and the negative one for evsm4
        float warped = u_warp.x * z + u_warp.y;
        out_moments.xy = biased_moments(exp(u_exponents.x * warped));
        out_moments.zw = biased_moments(-exp(-u_exponents.y * warped));
        // At the exponent bound exp(2c) is the format's maximum; the footprint bias on a steep
        // caster can push the second moment past it (inf, then NaN in the lookup): saturate.
        out_moments = clamp(out_moments, -u_moment_max, u_moment_max);
    }
}
#endif
