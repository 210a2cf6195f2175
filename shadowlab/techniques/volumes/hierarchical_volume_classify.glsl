// Hierarchical shadow volumes, pass "classify" (2 of 2): one invocation per (volume triangle,
// tile) pair, SPAN pairs per work group (one span). Against the tile's pixel centres and its
// surface depth range [zmin, zmax] (Aila & Akenine-Möller 2004, section 3), the triangle
//   (a) covers none of the tile's pixel centres, or lies wholly on the side of the depth range
//       where it is not counted: no effect;
//   (b) covers every pixel centre (the tile's corner centres lie inside every edge by the
//       margin; the polygon is convex) and lies wholly on its counting side: it adds its ±1 to
//       every pixel of the tile, so to the tile's count;
//   (d) otherwise: the tile is a boundary tile, counted per pixel.
// Depth tests are "<" against the pre-pass depth: a fragment passes where its depth is below
// the surface's. Fragment depths are clamped to [0, 1] (far=clamp clamps; elsewhere the clip
// volume keeps them inside), and a bound that reaches 1 ties with nothing stored below it.
#include "hierarchical_volume_common.glsl"

#ifdef COMPUTE_SHADER
#include "hierarchical_volume_pairs.glsl"
layout(local_size_x = SPAN) in;
uniform int u_spans;
void main() {
    int s = GROUP_INDEX;
    if (s >= u_spans) return;
    ivec2 sp = span[s];
    ivec4 box = tri[sp.x].box;
    ivec4 info = tri[sp.x].info;
    int bw = box.z - box.x + 1;
    int k = sp.y + int(gl_LocalInvocationID.x);
    if (k >= bw * (box.w - box.y + 1)) return;
    ivec2 tc = box.xy + ivec2(k % bw, k / bw);
    int t = tc.y * u_tiles.x + tc.x;
    vec2 zb = tile_bounds[t];
    if (zb.x > zb.y) return;                       // no surface in the tile: nothing to count
    vec2 lo = vec2(tc * u_tile) + 0.5;             // the tile's first and last pixel centres
    vec2 hi = vec2(min((tc + 1) * u_tile, u_size)) - 0.5;
    int flags = info.w;
    bool full = (flags & FLAG_NO_EDGES) == 0;
    if (full) {
        float m = tri[sp.x].margin.x;
        for (int j = 0; j < info.x; ++j) {
            vec4 e = tri[sp.x].edge[j];
            float dmin = e.z + min(e.x * lo.x, e.x * hi.x) + min(e.y * lo.y, e.y * hi.y);
            float dmax = e.z + max(e.x * lo.x, e.x * hi.x) + max(e.y * lo.y, e.y * hi.y);
            if (dmax < -m) return;                 // (a) outside this edge at every pixel centre
            if (dmin < m) full = false;
        }
    }
    if ((flags & FLAG_NO_PLANE) == 0) {
        vec4 p = tri[sp.x].plane;
        float zlo = p.z + min(p.x * lo.x, p.x * hi.x) + min(p.y * lo.y, p.y * hi.y) - p.w;
        float zhi = p.z + max(p.x * lo.x, p.x * hi.x) + max(p.y * lo.y, p.y * hi.y) + p.w;
        zlo = clamp(zlo, 0.0, 1.0);
        zhi = clamp(zhi, 0.0, 1.0);
        bool all_pass = zhi < zb.x;                // below every surface depth of the tile
        bool all_fail = zlo > zb.y || zlo == 1.0;  // at or beyond every one of them
        bool on_fail = info.y == 1;
        if (on_fail ? all_pass : all_fail) return; // (a) never counted here
        if (full && (on_fail ? all_fail : all_pass)) {
            atomicAdd(tile_count[t], info.z);      // (b) counted at every pixel of the tile
            return;
        }
    }
    atomicOr(tile_boundary[t], 1u);                // (d)
}
#endif
