// Projected planar shadows (Blinn 1988, "Me and my (fake) shadow"): every caster vertex is
// flattened onto a receiver's plane by the planar projection matrix u_plane_projection
// (M = (p·l) I − l pᵀ for the plane p = (n, d) and the homogeneous light l), then drawn through
// the camera as a darkening layer: the visibility target is multiplied by u_keep (= 1 − opacity).
// With CLIP_LIGHT, casters are clipped to the slab between the plane through the light
// (parallel to the receiver) and the receiver's plane (gl_ClipDistance), so geometry beyond the
// light or below the receiver casts nothing; without it, points past the light project with
// w ≤ 0 — anti-shadows and false shadows.
uniform mat4 u_view_proj;
uniform mat4 u_plane_projection;
uniform vec4 u_light_plane;     // receiver-parallel plane through the light; > 0 towards the receiver
uniform vec4 u_receiver_plane;  // the receiver's plane; > 0 on the light's side

#ifdef VERTEX_SHADER
in vec3 in_pos;
#ifdef CLIP_LIGHT
out float gl_ClipDistance[2];
#endif
void main() {
    vec4 p = vec4(in_pos, 1.0);
#ifdef CLIP_LIGHT
    gl_ClipDistance[0] = dot(u_light_plane, p);
    gl_ClipDistance[1] = dot(u_receiver_plane, p);
#endif
    gl_Position = u_view_proj * (u_plane_projection * p);
}
#endif

#ifdef FRAGMENT_SHADER
uniform float u_keep;
out float out_keep;
void main() {
    out_keep = u_keep;
}
#endif
