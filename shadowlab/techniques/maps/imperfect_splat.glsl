// Imperfect shadow maps (Ritschel et al. 2008), the splat pass: the scene's point set (points
// sampled on the casters, shadowlab/techniques/maps/imperfect_map.py) drawn as GL_POINTS of one
// pixel each through one face's light matrix (projection · view, u_light_view_proj) into that
// face's rect of the atlas, with a depth test (nearest wins). The colour target (R32F) keeps the
// winner's window depth, which the pull-push pass reads; texels no point reached keep the clear
// value, the hole marker (CLEAR_DEPTH = 1: a depth past every receiver, so an unfilled hole is
// lit). Points outside a face's clip volume are discarded by clipping (a point is clipped whole),
// so none lands in a neighbouring face's rect. A point of size 1 covers the one texel whose
// centre lies within half a texel of it: the texel it falls in (GL 4.5 core §14.4).
uniform mat4 u_light_view_proj;

#ifdef VERTEX_SHADER
in vec3 in_pos;
void main() {
    gl_Position = u_light_view_proj * vec4(in_pos, 1.0);
    gl_PointSize = 1.0;                  // one texel (the pass enables GL_PROGRAM_POINT_SIZE)
}
#endif

#ifdef FRAGMENT_SHADER
out float out_depth;
void main() {
    out_depth = gl_FragCoord.z;          // window depth in [0, 1], as a depth texture would hold it
}
#endif
