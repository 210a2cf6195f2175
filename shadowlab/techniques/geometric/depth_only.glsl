// Scene depth (and nothing else) through the camera: a technique's own depth pre-pass.
uniform mat4 u_view_proj;

#ifdef VERTEX_SHADER
in vec3 in_pos;
void main() {
    gl_Position = u_view_proj * vec4(in_pos, 1.0);
}
#endif

#ifdef FRAGMENT_SHADER
void main() {}
#endif
