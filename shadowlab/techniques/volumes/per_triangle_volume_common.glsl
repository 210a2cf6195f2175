// Per-triangle shadow volumes in compute (Sintorn, Olsson & Assarsson 2011; Sintorn, Kämpe,
// Olsson & Assarsson 2014): the buffers, counters and node layout shared by the programs
// per_triangle_volume_bounds.glsl (the hierarchy over the view samples),
// per_triangle_volume_traverse.glsl (each caster triangle's volume against the hierarchy, top
// down), per_triangle_volume_samples.glsl (the exact segment test at the leaves) and
// per_triangle_volume_resolve.glsl (tile-level and per-sample results merged per sample).
// Python twin of the bindings, counter slots and constants:
// shadowlab/techniques/volumes/per_triangle_volume.py.
//! glsl 430
#define NO_RAY (-1.0)                    // ray_origin[s].w of a sample slot without a ray
#define NO_CLUSTER (-1)                  // sample_cluster[s] of a slot without a ray
#define MAX_LEVELS 5                     // four levels of tiles and the depth clusters
// Counter slots (uint each), per level l (0 = the leaves): node tests, accepted, rejected,
// descended (= pairs appended to level l's list, counted even past its capacity); then the
// leaves' sample tests and hits, and the triangles culled.
#define COUNTER_TESTS(l) (4 * (l))
#define COUNTER_ACCEPTED(l) (4 * (l) + 1)
#define COUNTER_REJECTED(l) (4 * (l) + 2)
#define COUNTER_DESCENDED(l) (4 * (l) + 3)
#define COUNTER_SAMPLE_TESTS (4 * MAX_LEVELS)
#define COUNTER_SAMPLE_HITS (4 * MAX_LEVELS + 1)
#define COUNTER_CULLED (4 * MAX_LEVELS + 2)   // triangles culled (facing away from the light on a closed mesh)

// Sample slot s = tile · TILE² + (y % TILE) · TILE + x % TILE of pixel (x, y), tiles row by row.
layout(std430, binding = 0) readonly buffer RayOrigins { vec4 ray_origin[]; };       // origin, tfar (NO_RAY: none)
layout(std430, binding = 1) readonly buffer RayDirections { vec4 ray_direction[]; }; // direction (xyz)
layout(std430, binding = 2) buffer SampleClusters { int sample_cluster[]; };          // its depth cluster in its tile
layout(std430, binding = 3) buffer Blocked { uint blocked[]; };                      // per slot: a leaf test hit it
layout(std430, binding = 4) buffer Counters { uint counter[]; };
layout(std430, binding = 5) readonly buffer Triangles { vec4 triangle_vertex[]; };   // 3 per caster triangle
// Node n (every level, level l from u_level_offset[l]): node_box[2n] = (min corner of its
// samples' origins, samples), node_box[2n + 1] = (max corner, first: the leaves' place in
// tile_order, else 0); samples = 0: an empty node.
layout(std430, binding = 6) buffer NodeBoxes { vec4 node_box[]; };
layout(std430, binding = 7) buffer NodeFlags { uint node_flag[]; };                  // 1: inside some volume
layout(std430, binding = 8) buffer ListIn { ivec2 list_in[]; };                      // (triangle, node) to descend
layout(std430, binding = 9) buffer ListOut { ivec2 list_out[]; };                    // (triangle, node) appended
layout(std430, binding = 10) buffer Result { uint result[]; };                       // per slot: 1 = blocked
// Per leaf tile, its slots grouped by depth cluster: a leaf node's samples are
// tile_order[tile · TILE² + first ...], first = node_box[2n + 1].w, count = node_box[2n].w.
layout(std430, binding = 12) buffer TileOrder { int tile_order[]; };

// Levels, 0 = the leaves: with CLUSTERS > 1, level 0 holds CLUSTERS depth clusters per leaf
// tile and level 1 one node per leaf tile; then tiles of 4 × 4 tiles of the level below (FANOUT, Python side).
uniform ivec2 u_tiles;                   // leaf tiles across, down (TILE pixels each)
uniform int u_levels;                    // levels in all, 1 .. MAX_LEVELS
uniform int u_level_offset[MAX_LEVELS];  // first node of each level
uniform ivec2 u_level_size[MAX_LEVELS];  // tiles across, down at each level
uniform int u_level_per_tile[MAX_LEVELS];  // nodes per tile at each level (CLUSTERS or 1)
uniform int u_level_fanout[MAX_LEVELS];  // child tiles per axis of a tile of level l (>= 1) at level l - 1

// A compute invocation's index in a dispatch of (x, y) work groups laid out row by row
// (shadowlab.gpu.programs.dispatch splits large dispatches over y).
#define INVOCATION_INDEX int(gl_GlobalInvocationID.y * gl_NumWorkGroups.x * uint(LOCAL_SIZE) + gl_GlobalInvocationID.x)

// Node k of tile (x, y) of level l.
int node_index(int l, ivec2 tile, int k) {
    return u_level_offset[l] + (tile.y * u_level_size[l].x + tile.x) * u_level_per_tile[l] + k;
}
