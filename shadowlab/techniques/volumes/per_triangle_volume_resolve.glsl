// Per-triangle shadow volumes, pass 5: the merge per sample. A slot is blocked when a leaf test
// hit it or when any node above it — its leaf cluster, or a tile at any level — was accepted
// wholly inside some triangle's volume (one flag per node: the tile-level set).
#include "per_triangle_volume_common.glsl"

#ifdef COMPUTE_SHADER
layout(local_size_x = LOCAL_SIZE) in;
uniform int u_slots;

void main() {
    int s = INVOCATION_INDEX;
    if (s >= u_slots) return;
    int k = sample_cluster[s];
    if (k == NO_CLUSTER) {
        result[s] = 0u;
        return;
    }
    int tile = s / (TILE * TILE);
    ivec2 t = ivec2(tile % u_tiles.x, tile / u_tiles.x);
    uint hit = blocked[s] | node_flag[node_index(0, t, k)];
    for (int l = 1; l < u_levels; ++l) {
        t /= u_level_fanout[l];
        hit |= node_flag[node_index(l, t, 0)];
    }
    result[s] = hit != 0u ? 1u : 0u;
}
#endif
