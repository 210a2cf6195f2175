// Per-triangle shadow volumes, pass 1 (per frame): the hierarchy over the view samples. With
// LEAVES, one work group per leaf tile (TILE × TILE invocations, one per sample slot) splits its
// samples into CLUSTERS depth clusters — logarithmic slices of the tile's own range of distances
// from the eye, after the view-sample clusters of Sintorn et al. 2014 — and writes each
// cluster's bounding box of the ray origins and lists its slots together in tile_order (in
// whatever order the atomics give: the samples pass tests them all); it also clears the slots'
// hit bits and the leaves' flags. Without LEAVES, one invocation per tile of level u_level (≥ 1)
// unites the boxes of its child tiles (the clusters of a leaf tile, or 4 × 4 tiles of the level
// below: u_level_fanout). Min and max are taken exactly, by atomics on order-preserving integer
// keys of the float32 coordinates.
#include "per_triangle_volume_common.glsl"

#ifdef COMPUTE_SHADER
#ifdef LEAVES
layout(local_size_x = TILE_SLOTS) in;   // TILE², a define: GLSL 4.30 takes no expression here
uniform vec3 u_eye;                      // the camera's eye, world (the depth used for clusters)
shared uint s_depth_lo, s_depth_hi;
shared uint s_lo[3 * CLUSTERS], s_hi[3 * CLUSTERS], s_count[CLUSTERS], s_first[CLUSTERS], s_fill[CLUSTERS];

// Order-preserving key of a float (negative floats reversed below the positive ones).
uint key_of(float f) {
    uint b = floatBitsToUint(f);
    return (b & 0x80000000u) != 0u ? ~b : (b | 0x80000000u);
}
float float_of(uint k) {
    return uintBitsToFloat((k & 0x80000000u) != 0u ? (k & 0x7fffffffu) : ~k);
}

void main() {
    int tile = int(gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x);
    if (tile >= u_tiles.x * u_tiles.y) return;  // uniform over the group: no barrier is skipped by part of it
    int i = int(gl_LocalInvocationIndex);
    int s = tile * TILE * TILE + i;
    if (i == 0) {
        s_depth_lo = 0xffffffffu;
        s_depth_hi = 0u;
    }
    if (i < CLUSTERS) {
        for (int a = 0; a < 3; ++a) {
            s_lo[3 * i + a] = 0xffffffffu;
            s_hi[3 * i + a] = 0u;
        }
        s_count[i] = 0u;
        s_fill[i] = 0u;
        node_flag[u_level_offset[0] + tile * CLUSTERS + i] = 0u;
    }
    blocked[s] = 0u;
    memoryBarrierShared();
    barrier();
    vec4 o = ray_origin[s];
    bool valid = o.w != NO_RAY;
    float depth = distance(o.xyz, u_eye);  // >= 0: its bits order as the floats
    if (valid) {
        atomicMin(s_depth_lo, floatBitsToUint(depth));
        atomicMax(s_depth_hi, floatBitsToUint(depth));
    }
    memoryBarrierShared();
    barrier();
    int k = 0;
#if CLUSTERS > 1
    float lo = uintBitsToFloat(s_depth_lo), hi = uintBitsToFloat(s_depth_hi);
    if (valid && lo > 0.0 && hi > lo)
        k = clamp(int(float(CLUSTERS) * log(depth / lo) / log(hi / lo)), 0, CLUSTERS - 1);
#endif
    sample_cluster[s] = valid ? k : NO_CLUSTER;
    if (valid) {
        for (int a = 0; a < 3; ++a) {
            atomicMin(s_lo[3 * k + a], key_of(o[a]));
            atomicMax(s_hi[3 * k + a], key_of(o[a]));
        }
        atomicAdd(s_count[k], 1u);
    }
    memoryBarrierShared();
    barrier();
    if (i == 0) {  // each cluster's first place in the tile's order
        uint first = 0u;
        for (int c = 0; c < CLUSTERS; ++c) {
            s_first[c] = first;
            first += s_count[c];
        }
    }
    memoryBarrierShared();
    barrier();
    if (valid) tile_order[tile * TILE * TILE + int(s_first[k] + atomicAdd(s_fill[k], 1u))] = s;
    if (i < CLUSTERS) {
        int n = u_level_offset[0] + tile * CLUSTERS + i;
        uint count = s_count[i];
        vec3 lo3 = vec3(0.0), hi3 = vec3(0.0);
        if (count > 0u) {
            lo3 = vec3(float_of(s_lo[3 * i]), float_of(s_lo[3 * i + 1]), float_of(s_lo[3 * i + 2]));
            hi3 = vec3(float_of(s_hi[3 * i]), float_of(s_hi[3 * i + 1]), float_of(s_hi[3 * i + 2]));
        }
        node_box[2 * n] = vec4(lo3, float(count));
        node_box[2 * n + 1] = vec4(hi3, float(s_first[i]));
    }
}
#else
layout(local_size_x = LOCAL_SIZE) in;
uniform int u_level;                     // the level built (>= 1)

void main() {
    int t = INVOCATION_INDEX;
    ivec2 size = u_level_size[u_level];
    if (t >= size.x * size.y) return;
    ivec2 tile = ivec2(t % size.x, t / size.x);
    int below = u_level - 1;
    ivec2 child_size = u_level_size[below];
    vec3 lo = vec3(0.0), hi = vec3(0.0);
    float count = 0.0;
    int fanout = u_level_fanout[u_level];
    for (int j = 0; j < fanout; ++j) {
        for (int i = 0; i < fanout; ++i) {
            ivec2 c = tile * fanout + ivec2(i, j);
            if (c.x >= child_size.x || c.y >= child_size.y) continue;
            for (int k = 0; k < u_level_per_tile[below]; ++k) {
                int n = node_index(below, c, k);
                vec4 clo = node_box[2 * n];
                if (clo.w == 0.0) continue;  // empty
                vec3 chi = node_box[2 * n + 1].xyz;
                lo = count == 0.0 ? clo.xyz : min(lo, clo.xyz);
                hi = count == 0.0 ? chi : max(hi, chi);
                count += clo.w;
            }
        }
    }
    int n = node_index(u_level, tile, 0);
    node_box[2 * n] = vec4(lo, count);
    node_box[2 * n + 1] = vec4(hi, 0.0);
    node_flag[n] = 0u;
}
#endif
#endif
