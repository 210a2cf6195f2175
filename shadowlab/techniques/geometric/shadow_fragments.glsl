// Exact shadow fragments (object space, precomputed per static light) drawn through the camera.
// Each fragment belongs to one receiver triangle; a pixel takes it only if the G-buffer saw that
// very triangle there, so fragments never z-fight with their receiver and never land on
// anything else.
uniform mat4 u_view_proj;

#ifdef VERTEX_SHADER
in vec3 in_pos;
in int in_triangle;
flat out int v_triangle;
void main() {
    v_triangle = in_triangle;
    gl_Position = u_view_proj * vec4(in_pos, 1.0);
}
#endif

#ifdef FRAGMENT_SHADER
uniform isampler2D u_ids;   // G-buffer (object id, triangle id)
uniform float u_shadowed;   // visibility written inside a fragment
flat in int v_triangle;
out float out_visibility;
void main() {
    if (texelFetch(u_ids, ivec2(gl_FragCoord.xy), 0).y != v_triangle) discard;
    out_visibility = u_shadowed;
}
#endif
