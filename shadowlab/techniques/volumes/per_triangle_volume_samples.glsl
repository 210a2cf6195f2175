// Per-triangle shadow volumes, pass 4: the leaves. One invocation per (triangle, leaf node)
// pair that the traversal could neither reject nor accept tests the triangle exactly against
// every sample of the node (its leaf tile's samples in its depth cluster) with the truth's own
// segment test (shadowlab/gpu/watertight.glsl, as the irregular z-buffer does), setting the slot's
// hit bit. Every sample of the node is tested, so the counts do not depend on scheduling.
#include "per_triangle_volume_common.glsl"

#ifdef COMPUTE_SHADER
layout(local_size_x = LOCAL_SIZE) in;
uniform int u_pairs;
#include "watertight.glsl"

void main() {
    int index = INVOCATION_INDEX;
    if (index >= u_pairs) return;
    ivec2 pair = list_in[index];
    vec3 a = triangle_vertex[3 * pair.x].xyz;
    vec3 b = triangle_vertex[3 * pair.x + 1].xyz;
    vec3 c = triangle_vertex[3 * pair.x + 2].xyz;
    int local = pair.y - u_level_offset[0];
    int tile = local / CLUSTERS;
    int n = pair.y, count = int(node_box[2 * n].w), first = int(node_box[2 * n + 1].w);
    uint tests = 0u, hits = 0u;
    for (int j = 0; j < count; ++j) {
        int s = tile_order[tile * TILE * TILE + first + j];  // the node's samples: its tile's, in its cluster
        ++tests;
        vec4 o = ray_origin[s];
        if (segment_hits(o.xyz, ray_direction[s].xyz, o.w, a, b, c)) {
            atomicOr(blocked[s], 1u);
            ++hits;
        }
    }
    atomicAdd(counter[COUNTER_SAMPLE_TESTS], tests);
    atomicAdd(counter[COUNTER_SAMPLE_HITS], hits);
}
#endif
