// Hierarchical shadow volumes, per-pixel stage: the plain stencil volume's CPU-path program
// (shadow_volume.glsl: triangles of world points flagged as surface points or points at
// infinity, the vertex stage shared through shadow_volume_common.glsl) with a fragment stage
// that keeps only the fragments in boundary tiles (u_mask_tiles). The same program draws the
// depth pre-pass (mask off) and every volume pass, so caps tie with the surface bit for bit as
// in the plain volume. The pre-pass also writes the scene triangle each pixel shows (its
// primitive in the pre-pass's one draw of every scene triangle) to its own target; colour writes
// are off in every other pass.
#include "shadow_volume_common.glsl"
#include "hierarchical_volume_common.glsl"

#ifdef GEOMETRY_SHADER
layout(triangles) in;
layout(triangle_strip, max_vertices = 3) out;
in vec4 v_surface[];
in vec4 v_extruded[];
in float v_extrude[];
void main() {
    for (int i = 0; i < 3; ++i) {
        emit_position(v_extrude[i] > 0.0 ? v_extruded[i] : v_surface[i]);
        gl_PrimitiveID = gl_PrimitiveIDIn;
        EmitVertex();
    }
    EndPrimitive();
}
#endif

#ifdef FRAGMENT_SHADER
uniform bool u_mask_tiles;   // false: every fragment (pre-pass, the plain figure in stats)
out float out_triangle;      // pre-pass: the triangle drawn (exact in float32 below 2^24)
void main() {
    out_triangle = float(gl_PrimitiveID);
    if (u_mask_tiles && tile_boundary[tile_of_pixel(ivec2(gl_FragCoord.xy))] == 0u)
        discard;             // a tile the tile-level pass settled: no per-pixel work
}
#endif
