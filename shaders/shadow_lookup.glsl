// Shadow-map lookup over the G-buffer: one visibility value per screen pixel (DESIGN §2.2).
// u_light_matrix = bias · projection · view of the light (classic formulation: Everitt,
// Rege & Cebenoyan 2001), so light-space coordinates land in [0, 1]^3.
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
uniform sampler2D u_position;     // G-buffer world position, w = 1 where covered
uniform sampler2D u_shadow_map;   // window depth of the nearest caster, nearest filtering
uniform mat4 u_light_matrix;
uniform float u_bias;             // constant bias in window-depth units
#define LIT 1.0
#define SHADOWED 0.0
out float out_visibility;

void main() {
    vec4 p = texelFetch(u_position, ivec2(gl_FragCoord.xy), 0);
    out_visibility = LIT;
    if (p.w == 0.0) return;
    vec4 s = u_light_matrix * vec4(p.xyz, 1.0);
    if (s.w <= 0.0) return;                       // behind the light's centre of projection
    vec3 c = s.xyz / s.w;
    if (any(lessThan(c, vec3(0.0))) || any(greaterThan(c, vec3(1.0)))) return;  // outside the frustum
    float stored = texture(u_shadow_map, c.xy).r;
    out_visibility = (c.z - u_bias <= stored) ? LIT : SHADOWED;
}
#endif
