// Stencil shadow volumes, CPU-silhouette path: triangles of world points, each flagged as a
// surface point or a point extruded to infinity. The vertex stage is shared with the GPU path
// (shadow_volume_common.glsl); this geometry stage only picks one of the two positions. The
// same program draws the depth pre-pass and the near caps from the same vertex buffer, so a
// cap's depth equals the surface's bit for bit and z-fail sees no self-shadowing.
#include "shadow_volume_common.glsl"

#ifdef GEOMETRY_SHADER
layout(triangles) in;
layout(triangle_strip, max_vertices = 3) out;
in vec4 v_surface[];
in vec4 v_extruded[];
in float v_extrude[];
void main() {
    for (int i = 0; i < 3; ++i) {
        emit_position(v_extrude[i] > 0.0 ? v_extruded[i] : v_surface[i]);
        EmitVertex();
    }
    EndPrimitive();
}
#endif

#ifdef FRAGMENT_SHADER
void main() {}
#endif
