// Primary visibility (docs/architecture.md): one pass, pixel-centre samples, no MSAA.
// Outputs world position, geometric normal (as stored, not yet turned to the camera) and
// (object id, triangle id); triangle ids are global because the scene is one draw call.
uniform mat4 u_view_proj;

#ifdef VERTEX_SHADER
in vec3 in_pos;
in vec3 in_normal;
in int in_object;
out vec3 v_pos;
flat out vec3 v_normal;
flat out int v_object;
void main() {
    v_pos = in_pos;
    v_normal = in_normal;
    v_object = in_object;
    gl_Position = u_view_proj * vec4(in_pos, 1.0);
}
#endif

#ifdef FRAGMENT_SHADER
in vec3 v_pos;
flat in vec3 v_normal;
flat in int v_object;
layout(location = 0) out vec4 out_position;
layout(location = 1) out vec4 out_normal;
layout(location = 2) out ivec2 out_ids;
void main() {
    out_position = vec4(v_pos, 1.0);
    out_normal = vec4(v_normal, 0.0);
    out_ids = ivec2(v_object, gl_PrimitiveID);
}
#endif
