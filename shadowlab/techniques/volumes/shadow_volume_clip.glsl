// Clip positions of shadow-volume vertices: surface points (w = 1) and points pushed to infinity
// away from the light (w = 0). Included by shadow_volume_common.glsl (the vertex stage of both
// silhouette paths) and by compute programs that must reproduce those positions
// (hierarchical_volume_triangles.glsl); it has no stage sections, so a compute program can
// include it.
#include "lights.glsl"
// View and projection stay separate: for a point at infinity the projection then gives
// z_clip = (ε − 1)·z_view against w_clip = −z_view, one rounding apart, so Everitt & Kilgard's ε
// keeps it inside the far plane. Through a combined float32 view-projection matrix the
// rounding error of z_clip exceeds ε for directions far from the view axis, and pieces of
// the far cap are clipped away (seen on the light-close hard case).
uniform mat4 u_view;
uniform mat4 u_proj;

bool at_infinity() {
    return light_type == LIGHT_DIRECTIONAL || light_type == LIGHT_TARGET_DIRECT;
}

// A surface point (w = 1).
vec4 surface_clip(vec3 p) {
    return u_proj * (u_view * vec4(p, 1.0));
}

// The point pushed to infinity away from the light (w = 0).
vec4 extruded_clip(vec3 p) {
    return u_proj * (u_view * vec4(at_infinity() ? light_direction : p - light_position, 0.0));
}
