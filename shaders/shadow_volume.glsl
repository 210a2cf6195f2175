// Stencil shadow volumes, CPU-silhouette path: each vertex is a world point and a flag saying
// whether it is extruded to infinity. The same program draws the depth pre-pass and the near
// caps from the same vertex buffer, so a cap's depth equals the surface's bit for bit and
// z-fail sees no self-shadowing.
#include "shadow_volume_common.glsl"

#ifdef VERTEX_SHADER
in vec3 in_pos;
in float in_extrude;  // 0: surface point, 1: extruded to infinity
invariant gl_Position;
void main() {
    gl_Position = in_extrude > 0.0 ? extruded_clip(in_pos) : surface_clip(in_pos);
}
#endif

#ifdef FRAGMENT_SHADER
void main() {}
#endif
