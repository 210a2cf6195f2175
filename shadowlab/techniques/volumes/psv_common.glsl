// Partitioned shadow volumes (Gerhards, Mora, Aveneau & Ghazanfarpour 2015; Mora, Gerhards,
// Aveneau & Ghazanfarpour 2016): the TOP tree's buffers and node layout, shared by psv_build.glsl
// (the tree built from the caster triangles) and psv_query.glsl (each shadow ray's origin
// located in it). Python twin of the bindings, counter slots and node layout:
// shadowlab/techniques/volumes/partitioned_volume.py.
//! glsl 430
#define NONE (-1)                        // no child, no parent, an empty tree
// Node kinds (low bits of Node.flags) and flags.
#define KIND_SIDE 0                      // a shadow plane: through the light and a triangle's edge
#define KIND_CAP 1                       // a capping plane: the triangle's own plane
#define KIND_LEAF 2                      // the end of a triangle's chain: its exact test
#define KIND_MASK 3
#define FLAG_TRANSPARENT 4               // plane too close to degenerate to decide: both sides always
#define FLAG_CULLABLE 8                  // leaf: a volume inside this one may be dropped
// Children (Node.link): 0 the negative (inside) side, 1 the positive side, 2 the intersection
// child, always visited; link.w is the parent.
#define CHILD_NEG 0
#define CHILD_POS 1
#define CHILD_INTER 2
// Counter slots (uint each).
#define COUNTER_NODES 0                  // nodes taken from the pool
#define COUNTER_OVERFLOW 1               // triangles that found the pool full (the build stops)
#define COUNTER_CULLED 2                 // triangles dropped: their volume lies inside another's
#define COUNTER_SKIPPED 3                // triangles that cast nothing (no area; behind a target light's disc)
#define COUNTER_DEPTH 4                  // the deepest node (root = 1)
#define COUNTER_LEAF_TESTS 5             // exact ray/triangle tests made by the queries
#define COUNTER_STACK_OVERFLOWS 6        // queries whose stack filled up (they went on stackless)
#define COUNTER_INSERTED 7               // triangles given a chain
#define COUNTER_ROOT 8                   // the root node + 1 (0: an empty tree)
#define COUNTER_WANTING 9                // build: triangles that asked for an empty child this round
#define COUNTER_PENDING 10               // query: rays that ran out of steps this dispatch (resumed)
#define COUNTERS 11

// A node: its plane n·x + c (n unit; none for a leaf), the margin's relative part (shadow planes
// of a point light: × the query point's distance to the light), the triangle, kind and flags,
// the depth of its subtree (the least light depth of the triangles in it, as an ordered int:
// depth_key) and the links.
struct Node {
    vec4 plane;
    float rel;
    int tri;
    int flags;
    int depth;
    ivec4 link;
};

layout(std430, binding = 0) readonly buffer RayOrigins { vec4 ray_origin[]; };       // xyz, w = tfar
layout(std430, binding = 1) readonly buffer RayDirections { vec4 ray_direction[]; };
layout(std430, binding = 2) readonly buffer Triangles { vec4 triangle_vertex[]; };   // 3 per caster triangle
layout(std430, binding = 3) buffer Nodes { Node node[]; };
layout(std430, binding = 4) buffer Counters { uint counter[]; };
layout(std430, binding = 5) buffer Blocked { uint blocked[]; };      // per ray: 1 = in shadow
layout(std430, binding = 6) buffer Visits { uint visits[]; };        // per ray: nodes entered
// The build's state per triangle: its chain's planes (4 vec4) and (relative margin, flags,
// cullable, 0) staged once; where its walk resumes (node, that node's depth, the child slot it
// asks for: node · 3 + child, or ROOT_SLOT, its status); per child slot, the lowest triangle
// asking for it this round (uint, cleared to ~0).
layout(std430, binding = 7) buffer Staged { vec4 staged[]; };
layout(std430, binding = 8) buffer Walks { ivec4 walk[]; };
layout(std430, binding = 9) buffer Claims { uint claim[]; };
// The query's state per ray between dispatches: (node, from) of the stackless walk.
layout(std430, binding = 10) buffer QueryStates { ivec2 query_state[]; };
#define STAGED_PER_TRIANGLE 5
#define ROOT_SLOT (-2)                   // the child slot "the root of an empty tree"
#define STATUS_ACTIVE 0                  // still walking down
#define STATUS_INSERTED 1
#define STATUS_CULLED 2
#define STATUS_SKIPPED 3
#define STATUS_NO_POOL 4                 // won a slot but found the pool full
#define RAY_LIT 0u
#define RAY_SHADOW 1u
#define RAY_PENDING 2u                   // out of steps: resumed by the next dispatch
// Compute invocations: (x, y) work groups laid out row by row, split over y beyond the 65535
// groups GL guarantees in x (GL 4.6 core, table 23.64). A macro, seen only by compute stages.
#define INVOCATION_INDEX int(gl_GlobalInvocationID.y * gl_NumWorkGroups.x * uint(LOCAL_SIZE) + gl_GlobalInvocationID.x)

uniform int u_point;                     // 1: a light at u_light_position; 0: along u_light_direction
uniform vec3 u_light_position;
uniform vec3 u_light_direction;          // unit; the direction the light travels (lights at infinity)
uniform float u_delta;                   // the absolute margin (world units, module docstring)

// The signed distance of p to a node's plane, and the margin within which p counts as on both
// sides: the relative part grows with the distance to a point light (shadow planes are
// decided by angle there), the absolute part covers float32 evaluation.
float plane_distance(Node n, vec3 p) { return dot(n.plane.xyz, p) + n.plane.w; }
float light_distance(vec3 p) { return u_point == 1 ? distance(p, u_light_position) : 0.0; }

// Light depth: the distance to a point light, or the position along a light at infinity. A ray
// from p can only be blocked by a triangle whose nearest point is less deep than p (by the
// absolute margin): the depth of a subtree bounds what it can block (the depth information of
// Mora et al. 2016).
float light_depth(vec3 p) { return u_point == 1 ? distance(p, u_light_position) : dot(p, u_light_direction); }
// Floats as ints of the same order (for atomicMin), and back.
int depth_key(float f) { int b = floatBitsToInt(f); return b >= 0 ? b : b ^ 0x7fffffff; }
float key_depth(int k) { return intBitsToFloat(k >= 0 ? k : k ^ 0x7fffffff); }
