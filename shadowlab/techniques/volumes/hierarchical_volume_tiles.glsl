// Hierarchical shadow volumes, pass "tiles": per tile, the range of window depths of its pixels
// that hold a surface, read from a copy of the technique's own depth pre-pass (the depths the
// stencil pass's depth test compares with); a tile without one gets NO_SURFACE. Also the one
// scene triangle all those pixels show, if they show one, and the tile's count and boundary flag
// reset for the classification pass.
#include "hierarchical_volume_common.glsl"

#ifdef COMPUTE_SHADER
layout(local_size_x = 64) in;
uniform sampler2D u_depth;   // the pre-pass depth (24-bit fixed point read as float), no filtering
uniform sampler2D u_triangle; // the pre-pass's triangle per pixel (a float holding an integer)
void main() {
    int t = INVOCATION_INDEX;
    if (t >= u_tiles.x * u_tiles.y) return;
    ivec2 lo = ivec2(t % u_tiles.x, t / u_tiles.x) * u_tile;
    ivec2 hi = min(lo + ivec2(u_tile), u_size);
    float zmin = NO_SURFACE, zmax = -1.0;
    int sole = -1;           // -1: none seen yet
    for (int y = lo.y; y < hi.y; ++y)
        for (int x = lo.x; x < hi.x; ++x) {
            float d = texelFetch(u_depth, ivec2(x, y), 0).r;
            if (d < 1.0) {   // 1.0: the cleared value, no surface in this pixel
                zmin = min(zmin, d);
                zmax = max(zmax, d);
                int id = int(texelFetch(u_triangle, ivec2(x, y), 0).r);
                sole = sole == -1 || sole == id ? id : NO_TRIANGLE;
            }
        }
    tile_bounds[t] = vec2(zmin, zmax);
    tile_triangle[t] = sole < 0 ? NO_TRIANGLE : sole;
    tile_count[t] = 0;
    tile_boundary[t] = 0u;
}
#endif
