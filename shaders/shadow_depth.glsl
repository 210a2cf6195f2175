// Shadow-map depth pass (Williams 1978): casters rendered from the light; depth only.
uniform mat4 u_light_view_proj;

#ifdef VERTEX_SHADER
in vec3 in_pos;
void main() {
    gl_Position = u_light_view_proj * vec4(in_pos, 1.0);
}
#endif

#ifdef FRAGMENT_SHADER
void main() {}
#endif
