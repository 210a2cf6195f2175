// Filtered shadow maps, moments pass: casters rendered from the light into one face of an
// RG32F (VSM) or R32F (ESM) atlas. Depth z is linear in [0, 1] over the face's fitted near/far
// planes: z = (d - near) / (far - near), d the distance along the view's axis (-z in view space).
// VSM (Donnelly & Lauritzen 2006, §3): stores the moments (z, z²); the second moment gets
// ¼ (∂z/∂x² + ∂z/∂y²) added (their §3.3 "biasing"), the variance of the depth over the
// fragment's own footprint on a sloped caster, so a surface's own filter never reads as occluded.
// ESM (Annen et al. 2008, §3): stores exp(c z); with z in [0, 1] and c <= 88 it stays below
// float32's 3.4e38 (exp(88.7) overflows).
uniform mat4 u_light_view_proj;
uniform mat4 u_light_view;
uniform float u_near;                  // the face's fitted near and far planes (world units)
uniform float u_far;
uniform int u_esm;                     // 1: exponential map, 0: variance map
uniform float u_exponent;              // ESM's c
uniform float u_derivative_weight;     // VSM: weight of the squared depth derivatives (¼)

#ifdef VERTEX_SHADER
in vec3 in_pos;
out float v_depth;                     // linear depth in [0, 1]
void main() {
    vec4 view = u_light_view * vec4(in_pos, 1.0);
    v_depth = (-view.z - u_near) / (u_far - u_near);
    gl_Position = u_light_view_proj * vec4(in_pos, 1.0);
}
#endif

#ifdef FRAGMENT_SHADER
in float v_depth;
out vec2 out_moments;
void main() {
    float z = v_depth;
    if (u_esm == 1) {
        out_moments = vec2(exp(u_exponent * z), 0.0);
    } else {
        float dx = dFdx(z), dy = dFdy(z);
        out_moments = vec2(z, z * z + u_derivative_weight * (dx * dx + dy * dy));
    }
}
#endif
