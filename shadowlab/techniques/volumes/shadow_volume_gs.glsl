// Stencil shadow volumes, GPU-silhouette path: a geometry shader over GL_TRIANGLES_ADJACENCY
// emits the volume's sides, near caps and far caps directly (Brabec & Seidel 2003; Stich,
// Wächter & Keller, GPU Gems 3 ch. 11). Silhouette rule, the same as shadowlab/adjacency.py:
//   lit-only (closed meshes): a lit face extrudes each edge whose neighbour is not lit;
//   two-sided (open meshes, light inside): every face, turned to face the light, extrudes each
//   edge whose neighbour faces the other way (a boundary edge's "neighbour" is the face itself
//   walked backwards, so boundary edges are always extruded).
// u_stage: STAGE_VOLUME emits sides, near caps of lit faces and far caps; STAGE_FLIPPED_CAPS
// emits the near caps of unlit faces in two-sided mode, in their stored order (drawn with
// swapped stencil ops). The depth pre-pass is drawn by the CPU path's program (shared vertex
// stage). Python twin of the stage ids: shadowlab/techniques/volumes/shadow_volume.py (GS_STAGE_*).
#include "shadow_volume_common.glsl"
#define STAGE_VOLUME 1
#define STAGE_FLIPPED_CAPS 2

uniform int u_stage;
uniform bool u_two_sided;
uniform bool u_caps;       // z-fail: draw near and far caps
uniform bool u_far_cap;    // false for lights at infinity: the far cap collapses to a point

// The vertex stage is in shadow_volume_common.glsl (shared with the CPU path).

#ifdef GEOMETRY_SHADER
layout(triangles_adjacency) in;
layout(triangle_strip, max_vertices = 24) out;
in vec3 v_pos[];
in vec4 v_surface[];
in vec4 v_extruded[];

// Same test as shadowlab/adjacency.py facing(): front side towards the light.
bool faces_light(vec3 a, vec3 b, vec3 c) {
    vec3 n = cross(b - a, c - a);
    return at_infinity() ? dot(n, -light_direction) > 0.0 : dot(n, light_position) - dot(n, a) > 0.0;
}

void emit_tri(vec4 a, vec4 b, vec4 c) {
    emit_position(a); EmitVertex();
    emit_position(b); EmitVertex();
    emit_position(c); EmitVertex();
    EndPrimitive();
}

// Side quad of the directed edge p -> q (as a light-facing face walks it), facing outwards, as
// the two triangles (q, p, p') and (q, p', q') — exactly the CPU path's triangles.
// sp, sq: clip positions of p and q; ep, eq: of their extrusions.
void emit_side(vec4 sp, vec4 sq, vec4 ep, vec4 eq) {
    emit_tri(sq, sp, ep);
    emit_tri(sq, ep, eq);
}

void main() {
    vec3 v[3] = vec3[3](v_pos[0], v_pos[2], v_pos[4]);
    vec3 opp[3] = vec3[3](v_pos[1], v_pos[3], v_pos[5]);
    vec4 s[3] = vec4[3](v_surface[0], v_surface[2], v_surface[4]);
    vec4 e[3] = vec4[3](v_extruded[0], v_extruded[2], v_extruded[4]);
    bool lit = faces_light(v[0], v[1], v[2]);
    if (u_stage == STAGE_FLIPPED_CAPS) {
        if (u_two_sided && u_caps && !lit) emit_tri(s[0], s[1], s[2]);
        return;
    }
    if (!lit && !u_two_sided) return;
    for (int k = 0; k < 3; ++k) {
        int k1 = (k + 1) % 3;
        bool other = faces_light(v[k1], v[k], opp[k]);  // the neighbour walks the edge backwards
        if (other != lit) {
            if (lit) emit_side(s[k], s[k1], e[k], e[k1]); else emit_side(s[k1], s[k], e[k1], e[k]);
        }
    }
    if (u_caps) {
        if (lit) emit_tri(s[0], s[1], s[2]);
        if (u_far_cap) {
            if (lit) emit_tri(e[0], e[2], e[1]);
            else emit_tri(e[0], e[1], e[2]);
        }
    }
}
#endif

#ifdef FRAGMENT_SHADER
void main() {}
#endif
