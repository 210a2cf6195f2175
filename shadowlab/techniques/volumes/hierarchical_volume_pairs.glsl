// Hierarchical shadow volumes: the buffers of the two classification programs
// (hierarchical_volume_triangles.glsl, hierarchical_volume_classify.glsl); include it in their
// compute stage, after hierarchical_volume_common.glsl.

// One volume triangle, clipped to the view frustum and set up for the tile tests, in window
// pixel coordinates: the clipped polygon's corners (x, y, window depth); its edges (a, b, c):
// a x + b y + c is the signed distance to the edge, positive inside; its window-depth plane
// z = p.x x + p.y y + p.z and that plane's error bound (p.w); the coverage margin (margin.x, pixels) and, for a near cap, its scene triangle (margin.y,
// an integer; −1 for other triangles); its tile box (x0, y0, x1, y1, inclusive); and
// info = (edges, counting side: 0 depth pass / 1 depth fail, ±1 it adds where it counts,
// flags).
#define MAX_POLY 9               // a triangle clipped by six planes has at most 9 corners
#define FLAG_UNCERTAIN 1         // too close to degenerate: boundary on every tile of its box
#define FLAG_NO_PLANE 2          // (nearly) edge-on: no depth plane, never settled at tile level
#define FLAG_NO_EDGES 4          // edges unusable (orientation or position unsure): never settles a tile
#define FLAG_THIN 8              // under a pixel of area: never covers a tile (its facing may be unsure)
struct VolumeTriangle {
    vec4 vert[MAX_POLY];
    vec4 edge[MAX_POLY];
    vec4 plane;
    vec4 margin;
    ivec4 box;
    ivec4 info;
};
layout(std430, binding = 3) readonly buffer TriVertices { vec4 tri_vertex[]; };  // xyz, extrude flag
layout(std430, binding = 4) readonly buffer TriRules { int tri_rule[]; };        // RULE_* bits
layout(std430, binding = 5) buffer Triangles { VolumeTriangle tri[]; };
layout(std430, binding = 6) buffer Spans { ivec4 span[]; };   // (triangle, first tile x, tile y, tiles)
layout(std430, binding = 7) buffer Counters { uint counter[]; };
#define RULE_ZFAIL 1             // counted on depth fail (back +1, front −1), else on depth pass
#define RULE_FLIPPED 2           // the other face's operations (two-sided caps of unlit faces)
#define RULE_CAP_SHIFT 2         // rule >> RULE_CAP_SHIFT: a near cap's scene triangle + 1, else 0
