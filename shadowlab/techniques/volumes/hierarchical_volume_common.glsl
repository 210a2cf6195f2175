// Hierarchical shadow volumes (Aila & Akenine-Möller 2004): the tile buffers and bindings shared
// by the programs of shadowlab/techniques/volumes/hierarchical_volume.py (its Python twin:
// BINDING, COUNTERS, NO_SURFACE, SPAN there).
//! glsl 430
#define COUNTER_SPANS 0          // spans of SPAN tiles asked for by the triangle pass
#define COUNTER_TILE_TESTS 1     // (volume triangle, tile) pairs classified
#define COUNTER_UNCERTAIN 2      // volume triangles too close to degenerate to classify (all boundary)
#define NO_SURFACE 2.0           // tile_bounds[t].x of a tile that shows no surface (min > max)

// Per tile (row-major from the bottom-left tile, window coordinates): the window-depth range
// of the pixels that hold a surface, the count the tile-level pass adds, the boundary flag.
layout(std430, binding = 0) buffer TileBounds { vec2 tile_bounds[]; };
layout(std430, binding = 1) buffer TileCount { int tile_count[]; };
layout(std430, binding = 2) buffer TileBoundary { uint tile_boundary[]; };
// Per tile: the one scene triangle every pixel holding a surface shows in the pre-pass, or
// NO_TRIANGLE (several, or none).
layout(std430, binding = 8) buffer TileTriangle { int tile_triangle[]; };
#define NO_TRIANGLE (-2)

uniform int u_tile;            // tile width and height in pixels
uniform ivec2 u_tiles;         // tiles across, up
uniform ivec2 u_size;          // viewport width, height in pixels

int tile_of_pixel(ivec2 pixel) {
    ivec2 t = pixel / u_tile;
    return t.y * u_tiles.x + t.x;
}

// A compute invocation's index (and its work group's) in a dispatch of (x, y) work groups laid
// out row by row (dispatches are split over y beyond the 65535 groups GL guarantees in x). Macros,
// so that the programs without a compute stage never see them.
#define INVOCATION_INDEX \
    int(gl_GlobalInvocationID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x)
#define GROUP_INDEX int(gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x)
