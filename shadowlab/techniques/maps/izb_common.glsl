// The irregular z-buffer's buffers (Johnson, Lee, Mark & Hunt 2005, "The irregular z-buffer";
// Aila & Laine 2004, "Alias-free shadow maps"), shared by its three programs: izb_insert.glsl
// (the samples into per-texel lists), izb_raster.glsl (the casters rasterised in light space:
// (triangle, texel) pairs) and izb_test.glsl (each pair's triangle against its texel's samples).
// Python twin of the bindings and counter slots: shadowlab/techniques/maps/irregular_zbuffer.py.
//! glsl 430
#define NO_NODE (-1)                     // the end of a list, an empty texel
#define NO_RAY (-1.0)                    // ray_origin[k].w of a ray not to trace
// Counter slots (uint each): what the passes did, read back after each render.
#define COUNTER_NODES 0                  // nodes asked for (= rays inside the grid)
#define COUNTER_NODE_OVERFLOW 1          // rays that found the node pool full
#define COUNTER_OUTSIDE 2                // rays outside every face's grid (must stay 0)
#define COUNTER_PAIRS 3                  // (triangle, non-empty texel) pairs rasterised
#define COUNTER_TESTS 4                  // triangle-segment tests
#define COUNTER_HITS 5                   // tests that found the segment blocked
#define COUNTER_PENDING 6                // pairs whose list walk stopped at WALK_BUDGET (izb_test.glsl)

// Ray k: origin (xyz) and tfar (w; NO_RAY: skip), direction (xyz), the sample it belongs to.
// Sample s is bit s % u_samples_per_pixel of word s / u_samples_per_pixel of `blocked`.
layout(std430, binding = 0) readonly buffer RayOrigins { vec4 ray_origin[]; };
layout(std430, binding = 1) readonly buffer RayDirections { vec4 ray_direction[]; };
layout(std430, binding = 2) readonly buffer RaySamples { int ray_sample[]; };
layout(std430, binding = 3) buffer Heads { int head[]; };              // per atlas texel: first node
layout(std430, binding = 4) buffer Nodes { ivec2 node[]; };            // (ray, next node)
layout(std430, binding = 5) buffer Blocked { uint blocked[]; };        // per pixel: a bit per sample
layout(std430, binding = 6) buffer Counters { uint counter[]; };
layout(std430, binding = 7) buffer RayTexels { int ray_texel[]; };     // per ray: its atlas texel (statistics)
layout(std430, binding = 8) readonly buffer Triangles { vec4 triangle_vertex[]; };  // 3 per caster triangle
layout(std430, binding = 9) buffer Pairs { ivec2 pair[]; };             // (triangle, atlas texel)
layout(std430, binding = 10) buffer Continuations { int continuation[]; };  // per pair: the next node to walk

uniform int u_samples_per_pixel;

// A compute invocation's index in a dispatch of (x, y) work groups laid out row by row: the
// dispatches are split over y beyond the 65535 work groups GL guarantees in x (GL 4.6 core,
// table 23.64). A macro, so that the programs without a compute stage never see it.
#define INVOCATION_INDEX int(gl_GlobalInvocationID.y * gl_NumWorkGroups.x * uint(LOCAL_SIZE) + gl_GlobalInvocationID.x)
uniform vec2 u_atlas_size;               // atlas width, height in texels (the map toolkit's name)
