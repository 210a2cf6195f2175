// Vertex stage of a screen-covering pass; include it in full-screen programs.
#ifdef VERTEX_SHADER
in vec2 in_pos;
void main() {
    gl_Position = vec4(in_pos, 0.0, 1.0);
}
#endif
