// Shadow-map ray tracing (SMRT) over one depth map from an area light's centre, as Unreal Engine 5
// traces its virtual shadow maps (r.Shadow.Virtual.SMRT.*; Blender EEVEE-Next's "shadow map
// raytracing" is the same idea): per pixel, u_rays rays from the receiver P to points X on the
// light; each marches u_samples + 1 points of the segment, projected from the light's centre into
// the map, and is counted blocked when it crosses the depth map's surface (taken as a height field
// seen from the centre) between two steps. See shadowlab/techniques/maps/smrt.py for the rule.
//
// Conventions here: window depth d in [0, 1] grows away from the light (UE's is reversed); t is the
// ray parameter over the whole segment, R(t) = mix(P, X, t): 0 at the receiver, 1 at the light
// point. The march goes from the light's end towards the receiver, at
//   t_i = t_start + (t_end - t_start) · ((N - 1 - i + o) / N)²,  i = 0..N-1,   t_N = t_start
// (UE's quadratic spacing: dense near the receiver; o in [0, 1) the step offset, jittered per ray or
// ½), t_end where the segment reaches the map's near plane (points nearer the light than it are in
// no texel), t_start the end of the screen-space trace (0 when off).
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
#include "lights.glsl"
#include "gbuffer_fetch.glsl"
#define LIT 1.0
#define SHADOWED 0.0
#define HALF_TEXEL 0.5                   // texel centres are at integer + 0.5 (GL 4.5 core §8.14)
#define SHAPE_RECT 0
#define SHAPE_DISC 1
#define SHAPE_SPHERE 2
#define PI 3.14159265358979
#define COMPARE_TOLERANCE 1.05           // UE's tolerance: a crossing within 1.05 x the ray's depth step
#define NEAR_MARGIN 1.001                // the ray stops just past the map's near plane

uniform sampler2D u_map;                 // window depth from the light's centre
uniform mat4 u_light_matrix;             // bias · projection · view
uniform mat4 u_light_view;               // view: linear depth along the map's axis = -(view · p).z
uniform float u_near;                    // the map's near plane (linear depth)
uniform float u_bias;                    // constant, window depth
uniform float u_max_slope;               // |d window depth / dt| of an extrapolated occluder, at most
uniform float u_texel_angle;             // world size of a texel per unit distance from the light
uniform float u_basis_switch;            // receiver tangent t1 = N × helper_a if |N.x| < this,
uniform vec3 u_basis_helper_a;           // else N × helper_b (area_lights.basis's choice)
uniform vec3 u_basis_helper_b;
uniform int u_shape;                     // SHAPE_*
uniform mat2x3 u_light_extents;          // rect: its edges u, v; disc: two orthogonal diameters
uniform float u_light_radius;            // sphere
uniform int u_one_sided;                 // rect, disc: points behind the emitting plane see none
uniform vec3 u_light_normal;
uniform int u_rays;
uniform int u_samples;
uniform int u_jitter;                    // 1: per-pixel hashed jitter in each stratum and step offset
uniform vec2 u_strata_lo[RAYS];          // equal-area strata of the unit square (area_lights.strata)
uniform vec2 u_strata_size[RAYS];
uniform float u_screen_ray;              // screen trace length, x the receiver's camera distance
uniform mat4 u_camera_view_proj;
uniform vec3 u_camera_eye;
uniform float u_pixel_angle;             // a pixel's world size per unit camera distance
out float out_visibility;

// 32-bit integer hash (PCG's output permutation of an LCG step): decorrelated per pixel, ray, use.
uint hash(uint x) {
    uint state = x * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

float random01(uvec3 key) {              // in [0, 1)
    uint h = hash(key.x ^ hash(key.y ^ hash(key.z)));
    return float(h >> 8u) / 16777216.0;
}

// Shirley & Chiu's concentric map, unit square → unit disc (as area_lights.concentric_disc).
vec2 concentric(vec2 s) {
    vec2 ab = 2.0 * s - 1.0;
    if (ab.x == 0.0 && ab.y == 0.0) return vec2(0.0);
    float r, phi;
    if (abs(ab.x) > abs(ab.y)) { r = ab.x; phi = (PI / 4.0) * (ab.y / ab.x); }
    else { r = ab.y; phi = PI / 2.0 - (PI / 4.0) * (ab.x / ab.y); }
    return r * vec2(cos(phi), sin(phi));
}

// The light point of unit-square sample s, seen from P: rect — centre + edges · (s − ½); disc —
// the concentric map onto the disc; sphere — the cap P sees, uniform by area (cos θ uniform on
// [r/D, 1] about the axis centre → P, as SphereLight.sample_for).
vec3 light_point(vec3 P, vec2 s) {
    if (u_shape == SHAPE_RECT) return light_position + u_light_extents * (s - 0.5);
    vec2 d = concentric(s);
    if (u_shape == SHAPE_DISC) return light_position + u_light_extents * (0.5 * d);
    vec3 offset = P - light_position;
    float dist = length(offset);
    vec3 axis = dist > 0.0 ? offset / dist : vec3(0.0, 1.0, 0.0);
    float cos_max = dist > u_light_radius ? u_light_radius / dist : 1.0;
    float z = 1.0 - dot(d, d) * (1.0 - cos_max);
    float phi = atan(d.y, d.x);
    float sn = sqrt(max(0.0, 1.0 - z * z));
    vec3 t = normalize(cross(abs(axis.x) < u_basis_switch ? u_basis_helper_a : u_basis_helper_b, axis));
    vec3 b = cross(axis, t);
    return light_position + u_light_radius * (z * axis + sn * cos(phi) * t + sn * sin(phi) * b);
}

vec3 to_map(vec3 p) {                    // (u, v, window depth)
    vec4 s = u_light_matrix * vec4(p, 1.0);
    return s.xyz / s.w;
}

// The short screen-space trace (UE's r.Shadow.Virtual.ScreenRayLength): SCREEN_STEPS points of the
// segment P → P + L·dir, each projected into the camera; blocked where the G-buffer's surface in
// that pixel is nearer the camera than the point by more than SCREEN_TOLERANCE pixels' footprint
// (the receiver's own surface, sampled at a pixel centre) and by less than the thickness L
// (a surface far in front is taken to pass in front of the ray, not through it).
bool screen_blocked(vec3 P, vec3 dir, float L) {
    ivec2 size = textureSize(u_position, 0);
    for (int k = 1; k <= SCREEN_STEPS; ++k) {
        vec3 S = P + dir * (L * float(k) / float(SCREEN_STEPS));
        vec4 h = u_camera_view_proj * vec4(S, 1.0);
        if (h.w <= 0.0) return false;
        vec2 ndc = h.xy / h.w;
        if (any(greaterThan(abs(ndc), vec2(1.0)))) return false;  // off screen: nothing known
        ivec2 px = clamp(ivec2(floor((ndc * 0.5 + 0.5) * vec2(size))), ivec2(0), size - 1);
        vec4 G = texelFetch(u_position, px, 0);
        if (G.w == 0.0) continue;
        float dS = length(S - u_camera_eye);
        float depth = dS - length(G.xyz - u_camera_eye);  // > 0: the surface is in front of S
        if (depth > SCREEN_TOLERANCE * u_pixel_angle * dS && depth < L) return true;
    }
    return false;
}

// The map's march along P → X from t_start: true when the ray reaches the light. dz: the receiver's
// plane slope (window depth per uv) for the receiver plane depth bias; o: the step offset.
bool smrt_ray(vec3 P, vec3 X, float t_start, vec2 dz, float o) {
    float zP = -(u_light_view * vec4(P, 1.0)).z;
    float zX = -(u_light_view * vec4(X, 1.0)).z;
    float z_min = u_near * NEAR_MARGIN;
    float t_end = 1.0;
    if (zX < z_min) {
        if (zP <= z_min) return true;
        t_end = (zP - z_min) / (zP - zX);
    }
    if (t_end <= t_start) return true;
    ivec2 size = textureSize(u_map, 0);
    bool started = false;
    float history = 0.0, t_history = 0.0, slope = 0.0, prev_ref = 0.0;
    for (int i = 0; i <= u_samples; ++i) {
        float f = i == u_samples ? 0.0 : (float(u_samples - 1 - i) + o) / float(u_samples);
        float t = t_start + (t_end - t_start) * f * f;
        vec4 s = u_light_matrix * vec4(mix(P, X, t), 1.0);
        if (s.w <= 0.0) continue;
        vec3 m = s.xyz / s.w;
        if (any(lessThan(m.xy, vec2(0.0))) || any(greaterThan(m.xy, vec2(1.0)))) continue;  // no texel: skipped
        ivec2 tx = clamp(ivec2(floor(m.xy * vec2(size))), ivec2(0), size - 1);
        vec2 centre = (vec2(tx) + vec2(HALF_TEXEL)) / vec2(size);
        float stored = texelFetch(u_map, tx, 0).r;
        // The ray point's depth moved to the texel's centre along the receiver's plane slope
        // (where the stored depth was rasterised), then biased towards the light.
        float ref = m.z + dot(dz, centre - m.xy) - u_bias;
        if (!started) {                  // the first sample: a plain depth test
            started = true;
            history = stored; t_history = t; prev_ref = ref;
            if (stored < ref) return false;
            continue;
        }
        float tolerance = COMPARE_TOLERANCE * abs(ref - prev_ref);
        float compare = stored;
        if (ref - stored > tolerance) {
            // Behind the stored surface by more than one step could explain: the ray entered the
            // centre's shadow of an occluder from its side. Compare with the last surface the ray
            // passed in front of, extrapolated along the ray with its clamped slope.
            compare = history + slope * (t - t_history);
        } else if (stored != history) {
            slope = clamp((stored - history) / (t - t_history), -u_max_slope, u_max_slope);
            history = stored; t_history = t;
        }
        float behind = ref - compare;
        if (behind > 0.0 && behind < tolerance) return false;  // crossed it within this step
        prev_ref = ref;
    }
    return true;
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
    vec3 c = to_map(P);
    // Receiver plane: dz/du, dz/dv of the window depth (as pcss.glsl).
    vec2 dz = vec2(0.0);
    {
        float texel = u_texel_angle * length(P - light_position);
        vec3 t1 = normalize(cross(N, abs(N.x) < u_basis_switch ? u_basis_helper_a : u_basis_helper_b));
        vec3 t2 = cross(N, t1);
        vec3 a = to_map(P + t1 * texel) - c;
        vec3 b = to_map(P + t2 * texel) - c;
        float det = a.x * b.y - a.y * b.x;
        if (abs(det) > 0.0)
            dz = vec2(a.z * b.y - b.z * a.y, a.x * b.z - b.x * a.z) / det;
    }
    uvec2 pixel = uvec2(gl_FragCoord.xy);
    uint key = pixel.x + 65536u * pixel.y;
    float screen_length = u_screen_ray * length(P - u_camera_eye);
    float lit = 0.0;
    for (int r = 0; r < u_rays; ++r) {
        vec2 jitter = vec2(0.5);
        float offset = 0.5;
        if (u_jitter == 1) {
            jitter = vec2(random01(uvec3(key, uint(r), 0u)), random01(uvec3(key, uint(r), 1u)));
            offset = random01(uvec3(key, uint(r), 2u));
        }
        vec3 X = light_point(P, u_strata_lo[r] + jitter * u_strata_size[r]);
        vec3 toward = X - P;
        float len = length(toward);
        if (dot(toward, N) <= 0.0 || len == 0.0) continue;  // below the receiver's horizon: occluded
        float t_start = 0.0;
        if (screen_length > 0.0) {
            float L = min(screen_length, len);
            if (screen_blocked(P, toward / len, L)) continue;
            t_start = L / len;
        }
        if (smrt_ray(P, X, t_start, dz, offset)) lit += LIT;
    }
    out_visibility = lit / float(u_rays);
}
#endif
