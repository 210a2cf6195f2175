// Vertex stage of a pass drawn from a light's view: world positions through u_light_view_proj
// (projection · view of that view). Include it in programs that draw the scene's casters.
uniform mat4 u_light_view_proj;

#ifdef VERTEX_SHADER
in vec3 in_pos;
void main() {
    gl_Position = u_light_view_proj * vec4(in_pos, 1.0);
}
#endif
