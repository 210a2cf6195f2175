// Shared shading (docs/architecture.md#the-shading-pass-shadowlabgpushadingpy), one pass per light, summed with additive blending:
//   I = λ · ( A + (1 − sh)·D + sh·sc + (1 − shade)·S ),  sh = density·(1 − v), shade = 1 − v.
// Every technique is shaded by this same program; only the visibility image v differs.
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
#include "lights.glsl"
#define MATERIAL_DIFFUSE 0   // rgb = k_D, a = receives (1) or not (0)
#define MATERIAL_SPECULAR 1  // rgb = k_S, a = shininess s
#define MATERIAL_AMBIENT 2   // rgb = k_A

#include "gbuffer_fetch.glsl"
uniform sampler2D u_materials;   // one column per object, rows as above
uniform sampler2D u_visibility;  // this light's visibility image, 1 = lit
uniform sampler2D u_weight;      // where the light is drawn (read only when u_weighted): a shadow budget's drop=unlit
uniform bool u_weighted;
uniform vec3 u_eye;
uniform float u_density;
uniform vec3 u_shadow_color;
out vec4 out_color;

void main() {
    ivec2 px = gbuffer_pixel();
    ivec2 ids = gbuffer_ids();
    if (ids.y < 0) discard;
    vec3 P;
    gbuffer_position(P);           // covered: the ids say so
    vec3 V = normalize(u_eye - P);
    vec3 N = gbuffer_normal_towards(V);  // two-sided surfaces
    vec4 kd = texelFetch(u_materials, ivec2(ids.x, MATERIAL_DIFFUSE), 0);
    vec4 ks = texelFetch(u_materials, ivec2(ids.x, MATERIAL_SPECULAR), 0);
    vec3 ka = texelFetch(u_materials, ivec2(ids.x, MATERIAL_AMBIENT), 0).rgb;
    float v = kd.a > 0.0 ? texelFetch(u_visibility, px, 0).r : 1.0;
    vec3 L = light_dir_to(P);
    float ndl = dot(N, L);
    vec3 D = kd.rgb * light_color * max(ndl, 0.0);
    vec3 S = ndl > 0.0 ? ks.rgb * light_color * pow(max(dot(N, normalize(L + V)), 0.0), ks.a) : vec3(0.0);
    vec3 A = ka * light_ambient;
    float sh = u_density * (1.0 - v);
    float shade = 1.0 - v;
    out_color = vec4(light_footprint(P) * (A + (1.0 - sh) * D + sh * u_shadow_color + (1.0 - shade) * S), 1.0);
    if (u_weighted) out_color.rgb *= texelFetch(u_weight, px, 0).r;
}
#endif
