// Clip positions of shadow-volume vertices, shared by the CPU-silhouette and GPU-silhouette
// programs: both paths must produce bit-identical vertices (and the same triangles in the same
// vertex order) so that their stencil counts, and masks, agree on every pixel.
#include "shadow_volume_clip.glsl"

#ifdef GEOMETRY_SHADER
// NEAR_CLIP (far=clamp). GL_DEPTH_CLAMP removes clipping against the near plane as well as the
// far one (ARB_depth_clamp: "no near or far plane clipping"); the lab wants only the far half.
// What ties with what: z-fail's near caps are the casters' lit faces and must tie, bit for bit,
// with the depth pre-pass where they lie on the visible surface (depth fail on equality counts
// the −1 that the far cap's +1 balances; a plane receiver is its own cap). When the pre-pass was
// drawn without depth clamp, its triangles were clipped at the near plane, while the same
// triangles as caps under depth clamp were not: one plane rasterised from differently clipped
// polygons rounds differently in the last bit, a cap came out nearer than its surface, the −1
// was lost, and false shadow appeared in scanline streaks (sv_camera_in_shadow on an NVIDIA
// H100, sv_near_plane_cut on llvmpipe; docs/hard-cases.md). So under
// far=clamp the pre-pass and every volume pass run with the same depth clamp and the same near
// plane, restored as clip distance 0 (z_c + w_c ≥ 0): geometry in front of the near plane, which
// the G-buffer never saw, is clipped in every pass alike. The technique enables
// GL_CLIP_DISTANCE0 for these programs.
#ifdef NEAR_CLIP
out float gl_ClipDistance[1];
#endif
void emit_position(vec4 clip) {
    gl_Position = clip;
#ifdef NEAR_CLIP
    gl_ClipDistance[0] = clip.z + clip.w;
#endif
}
#endif

#ifdef VERTEX_SHADER
// The one vertex stage of both shadow-volume programs: each vertex is transformed once, with
// the same code in both, so every triangle built from it (pre-pass, caps, sides) gets
// bit-identical clip positions whichever path draws it.
in vec3 in_pos;
in float in_extrude;  // CPU path: 0 = surface point, 1 = extruded to infinity
out vec3 v_pos;
out vec4 v_surface;   // clip position of the vertex
out vec4 v_extruded;  // clip position of the vertex pushed to infinity away from the light
out float v_extrude;
void main() {
    v_pos = in_pos;
    v_surface = surface_clip(in_pos);
    v_extruded = extruded_clip(in_pos);
    v_extrude = in_extrude;
}
#endif
