// Shadow-map lookup over the G-buffer: one visibility value per screen pixel (docs/architecture.md).
// The map is an atlas of u_faces faces (1, or 6 for a point light's cube); face f has the light
// matrix u_light_matrix[f] = bias · projection · view (classic formulation: Everitt, Rege &
// Cebenoyan 2001) and occupies u_face_rect[f] = (x0, y0, width, height) of the atlas, in texels.
// Depth offsets: constant u_bias (window depth), constant u_bias_world (a world distance: the
// receiver moved that far towards the light, converted to window depth at the receiver, so that
// it means the same distance whatever the near plane), slope-scaled u_slope_scale · (depth change
// over one texel on the receiver's plane), and normal offset (the lookup point moved along the
// normal by u_normal_offset texels). u_depth_comparison chooses what each tap compares against:
// - DEPTH_COMPARISON_POINT: the point's own window depth (every variant but the two below);
// - DEPTH_COMPARISON_RECEIVER_PLANE (Isidoro 2006, "Shadow mapping: GPU-based tips and
//   techniques", GDC: receiver plane depth bias): the receiver's window depth extrapolated along
//   its plane (dz/du, dz/dv in map space, receiver_plane_gradient) to the centre of the tap's
//   texel, where the stored depth was rasterised; then u_bias subtracted;
// - DEPTH_COMPARISON_ADAPTIVE (Dou, Yan, Kerzner, Dai & Wyman 2014, "Adaptive depth bias for
//   shadow maps", I3D / JCGT 3(4)): the ray from the light through the centre of the tap's texel
//   is intersected with the receiver's tangent plane (in world space, through the inverse light
//   matrix); that point's window depth bounds the depth of a false occluder in the texel, and
//   the adaptive bias is the point's depth minus it plus the adaptive epsilon: u_adaptive_epsilon
//   × u_scene_extent (world units) moved along the ray towards the light, converted to window
//   depth at the intersection (so it follows a perspective map's depth compression); u_bias is
//   added on top (0 gives the paper's form).
// With u_oriented (oriented depth bias: Fatnassi 2023, "Shadow Techniques from Final Fantasy XVI",
// Square Enix, §4) the bias takes the sign g_orientation of the visible side's orientation to the
// light: +1 where the G-buffer normal turned towards the camera (u_eye) faces the light, the
// receiver moved towards it as usual; -1 where it faces away, the receiver moved away from the
// light by the same bias (ref = receiver + bias), which keeps it in its own object's shadow.
// The two per-tap comparisons need a depth test per texel: not with FILTER_HW (the Python side
// refuses the combination). Filtering: texel-exact PCF over (2r+1)² texels (r = 0: nearest),
// or, with FILTER_HW, the hardware 2x2 bilinear comparison (sampler2DShadow).
// With THRESHOLDS defined (the exact bias optimiser, shadowlab/tuning/exact_bias.py) the pass
// writes, instead of the visibility, the terms of one tap's comparison ref = receiver - bias <=
// stored with bias = u_bias + extra: (receiver, stored depth at tap u_tap, extra, COMPARED) — with
// w = -COMPARED (ORIENTED_AWAY) where the oriented bias moves the receiver away from the light:
// there the comparison is ref = receiver + bias <= stored —
// receiver and extra are the tap's own with the per-tap comparisons (the receiver plane's depth
// at the tap's texel centre; the adaptive bias of that texel) — or
// w = LIT_ANYWAY where the point is lit whatever the bias (no G-buffer point, behind the light's
// centre of projection, outside the map). Every term is computed by the same code as the lookup.
// With CASCADES defined (cascaded shadow maps, shadowlab/techniques/maps/cascaded_map.py) the faces
// are the cascades of a directional light: the face is chosen by the point's camera view depth
// against u_cascade_far, and with u_blend_start[f] < u_cascade_far[f] the visibility blends
// linearly into the next cascade over [u_blend_start[f], u_cascade_far[f]] (the view-depth
// splits of Zhang et al. 2006; blending as in Engel 2006, "Cascaded shadow maps", ShaderX5).
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
#include "lights.glsl"
#define LIT 1.0
#define SHADOWED 0.0
#define DEPTH_COMPARISON_POINT 0
#define DEPTH_COMPARISON_RECEIVER_PLANE 1
#define DEPTH_COMPARISON_ADAPTIVE 2
#define NEAR_DEPTH 0.0                   // window depths of a face's near and far planes
#define FAR_DEPTH 1.0
#ifndef MAX_FACES
#error "MAX_FACES: the map toolkit's atlas size (shadowlab.techniques.maps.toolkit.ATLAS_DEFINES)"
#endif

#include "gbuffer_fetch.glsl"
#ifdef FILTER_HW
uniform sampler2DShadow u_map;           // comparison sampler, linear filtering
#else
uniform sampler2D u_map;                 // window depth of the comparison layer
#endif
uniform vec2 u_atlas_size;               // atlas width, height in texels
uniform int u_faces;
uniform mat4 u_light_matrix[MAX_FACES];
uniform vec4 u_face_rect[MAX_FACES];
uniform float u_bias;
uniform float u_bias_world;              // world distance towards the light (0: none)
uniform float u_slope_scale;
uniform float u_normal_offset;           // texels
uniform float u_texel_world;             // orthographic maps: world size of a texel
uniform float u_texel_angle;             // perspective maps: world size of a texel per unit distance
uniform int u_kernel_radius;
uniform int u_depth_comparison;          // DEPTH_COMPARISON_*
uniform mat4 u_light_matrix_inverse[MAX_FACES];  // adaptive: map (u, v, window depth) -> world
uniform float u_adaptive_epsilon;        // adaptive: epsilon as a fraction of the scene's extent
uniform float u_scene_extent;            // adaptive: the diagonal of the scene's bounds, world
uniform int u_oriented;                  // oriented bias: 1 = the bias's sign follows the orientation
uniform vec3 u_eye;                      // oriented bias: the camera's position (the visible side)
#ifdef CASCADES
uniform vec4 u_view_depth;               // camera view depth of P = dot(u_view_depth, vec4(P, 1))
uniform float u_cascade_far[MAX_FACES];  // far split of each cascade (view depth)
uniform float u_blend_start[MAX_FACES];  // view depth where blending into the next cascade starts
uniform float u_cascade_texel[MAX_FACES];  // world size of a texel of each cascade
#endif
#ifdef THRESHOLDS
#ifdef FILTER_HW
#error "THRESHOLDS: the hardware comparison has no per-tap terms"
#endif
#ifdef CASCADES
#error "THRESHOLDS: one face per point (a cascade blend compares in two)"
#endif
#define COMPARED 1.0
#define ORIENTED_AWAY -1.0
#define LIT_ANYWAY 0.0
uniform ivec2 u_tap;                     // the tap whose stored depth is written, texels
out vec4 out_terms;
vec4 g_terms = vec4(0.0, 0.0, 0.0, LIT_ANYWAY);
#else
out float out_visibility;
#endif

// The oriented bias's sign at this fragment: +1 (towards the light), or -1 where u_oriented is set
// and the visible side faces away from the light (set by main before any lookup).
float g_orientation = 1.0;

#include "cube_face.glsl"
#include "atlas.glsl"

#include "receiver_plane.glsl"
#include "world_bias.glsl"

// The uv of the centre of atlas texel t of face f.
vec2 texel_centre_uv(int f, ivec2 t) {
    return (vec2(t) + vec2(HALF_TEXEL) - u_face_rect[f].xy) / u_face_rect[f].zw;
}

// The world point of face f's map coordinates m = (u, v, window depth).
vec3 from_map(int f, vec3 m) {
    vec4 w = u_light_matrix_inverse[f] * vec4(m, 1.0);
    return w.xyz / w.w;
}

// Adaptive depth bias (Dou et al. 2014) of the receiver point Q (normal N, map coordinates c)
// at the tap whose texel centre is uv: the window depth of Q minus that of X, the intersection
// of the light's ray through the texel centre with Q's tangent plane (the deepest a false
// occluder in that texel can be: the receiver's own surface, rasterised at the centre), plus
// the adaptive epsilon in window depth. Where the ray misses the plane in front of the light
// (edge-on, or behind the centre of projection) X is Q itself: no offset, only the epsilon.
float adaptive_bias(int f, vec3 Q, vec3 N, vec3 c, vec2 uv) {
    vec3 A = from_map(f, vec3(uv, NEAR_DEPTH));
    vec3 B = from_map(f, vec3(uv, FAR_DEPTH));
    vec3 ray = B - A;                    // away from the light, through the texel centre
    vec3 X = Q;
    float depth = c.z;
    float along = dot(ray, N);
    if (abs(along) > 0.0) {
        vec3 hit = A + ray * (dot(Q - A, N) / along);
        vec4 h = u_light_matrix[f] * vec4(hit, 1.0);
        if (h.w > 0.0) {
            X = hit;
            depth = h.z / h.w;
        }
    }
    // Epsilon: X moved by eps (world) towards the light along the ray, as a window-depth change.
    float epsilon = -window_change(f, X, -normalize(ray) * (u_adaptive_epsilon * u_scene_extent));
    return (c.z - depth) + epsilon;
}

// Visibility of the receiver point Q (normal N towards the light) in face f; texel: the world
// size of a map texel at Q. Points outside the face's map are lit.
float face_visibility(int f, vec3 Q, vec3 N, float texel) {
    vec3 c;
    if (!map_coordinates(f, Q, c)) return LIT;  // behind the light's centre of projection
    if (any(lessThan(c, vec3(0.0))) || any(greaterThan(c, vec3(1.0)))) return LIT;  // outside the map
    float extra = 0.0;                   // the bias beyond u_bias at this point
    vec2 dz = vec2(0.0), edge;           // the receiver plane's depth gradient in map space
    bool plane = false;
    if (u_slope_scale > 0.0 || u_depth_comparison == DEPTH_COMPARISON_RECEIVER_PLANE)
        plane = receiver_plane_gradient(f, Q, N, c, texel, dz, edge);
    if (u_slope_scale > 0.0) {
        // Depth change across one texel on the receiver's plane.
        vec2 texel_uv = 1.0 / u_face_rect[f].zw;
        if (plane)
            extra = u_slope_scale * (abs(dz.x) * texel_uv.x + abs(dz.y) * texel_uv.y);
        else
            extra = u_slope_scale * max(abs(edge.x), abs(edge.y));  // edge-on to the light
    }
    // Q moved u_bias_world towards the light (or, oriented and facing away, away from it)
    float world = g_orientation > 0.0 ? world_bias(f, Q, u_bias_world) : world_bias_away(f, Q, u_bias_world);
    float bias = u_bias + world + extra;
    float ref = c.z - g_orientation * bias;  // g_orientation = ±1: exact, ref = c.z ∓ bias
    vec2 atlas = atlas_texel(f, c.xy);
#ifdef FILTER_HW
    // The 2x2 bilinear footprint kept inside this face of the atlas. textureLod at level 0: this
    // runs after non-uniform control flow (early returns, the cascade choice), where texture()'s
    // implicit derivatives are undefined (GLSL 4.50 §8.9); the map has one level, so level 0 is
    // what texture() means here on any driver. One reference depth for the four texels: the
    // per-tap comparisons (receiver plane, adaptive) are refused with this filter.
    return textureLod(u_map, vec3(bilinear_inside_face(f, atlas) / u_atlas_size, ref), 0.0);
#else
    ivec2 lo = ivec2(u_face_rect[f].xy), hi = lo + ivec2(u_face_rect[f].zw) - 1;
    ivec2 t = clamp(ivec2(floor(atlas)), lo, hi);
    float lit = 0.0, n = 0.0;
    for (int dy = -u_kernel_radius; dy <= u_kernel_radius; ++dy)
        for (int dx = -u_kernel_radius; dx <= u_kernel_radius; ++dx) {
#ifdef THRESHOLDS
            ivec2 tap = clamp(t + u_tap, lo, hi);
#else
            ivec2 tap = clamp(t + ivec2(dx, dy), lo, hi);
#endif
            // The tap's receiver depth and bias beyond u_bias: ref = receiver - (u_bias + tap_extra).
            float receiver = c.z, tap_extra = world + extra, tap_ref = ref;
            if (u_depth_comparison == DEPTH_COMPARISON_RECEIVER_PLANE) {
                receiver = c.z + dot(dz, texel_centre_uv(f, tap) - c.xy);
                tap_ref = receiver - (u_bias + tap_extra);
            } else if (u_depth_comparison == DEPTH_COMPARISON_ADAPTIVE) {
                tap_extra = world + adaptive_bias(f, Q, N, c, texel_centre_uv(f, tap));
                tap_ref = receiver - (u_bias + tap_extra);
            }
            float stored = texelFetch(u_map, tap, 0).r;
#ifdef THRESHOLDS
            g_terms = vec4(receiver, stored, tap_extra, g_orientation > 0.0 ? COMPARED : ORIENTED_AWAY);
            return LIT;
#endif
            lit += tap_ref <= stored ? LIT : SHADOWED;
            n += 1.0;
        }
    return lit / n;
#endif
}

void main() {
#ifdef THRESHOLDS
    out_terms = g_terms;
#else
    out_visibility = LIT;
#endif
    vec3 P;
    if (!gbuffer_position(P)) return;
    vec3 N = gbuffer_normal_towards(light_dir_to(P));  // two-sided receivers: the side facing the light
    // Oriented bias: does the visible side (the normal turned towards the camera) face the light?
    if (u_oriented != 0 && dot(gbuffer_normal_towards(u_eye - P), light_dir_to(P)) <= 0.0)
        g_orientation = -1.0;
    float visibility;
#ifdef CASCADES
    // The first cascade whose far split lies beyond P's view depth (the last one past the far split).
    float depth = dot(u_view_depth, vec4(P, 1.0));
    int f = 0;
    while (f < u_faces - 1 && depth > u_cascade_far[f]) ++f;
    float texel = u_cascade_texel[f];
    visibility = face_visibility(f, P + N * (u_normal_offset * texel), N, texel);
    if (f < u_faces - 1 && depth > u_blend_start[f]) {
        // Linear blend into the next cascade across the end of this one's depth range.
        float w = (depth - u_blend_start[f]) / (u_cascade_far[f] - u_blend_start[f]);
        float next_texel = u_cascade_texel[f + 1];
        float next = face_visibility(f + 1, P + N * (u_normal_offset * next_texel), N, next_texel);
        visibility = mix(visibility, next, w);
    }
#else
    float texel = u_texel_world > 0.0 ? u_texel_world : u_texel_angle * length(P - light_position);
    vec3 Q = P + N * (u_normal_offset * texel);
    visibility = face_visibility(face_of(Q), Q, N, texel);
#endif
#ifdef THRESHOLDS
    out_terms = g_terms;
#else
    out_visibility = visibility;
#endif
}
#endif
