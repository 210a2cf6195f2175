// Hierarchical shadow volumes, pass "classify" (2 of 2): every (volume triangle, tile) pair,
// looped over by one invocation per span (a run of at most SPAN tiles of one tile row).
// Against the tile's pixel centres and its surface depth range [zmin, zmax] (Aila &
// Akenine-Möller 2004, section 3), the triangle
//   (a) covers none of the tile's pixel centres, or lies wholly on the side of the depth range
//       where it is not counted: no effect;
//   (b) covers every pixel centre (the tile's corner centres lie inside every edge by the
//       margin; the polygon is convex) and lies wholly on its counting side: it adds its ±1 to
//       every pixel of the tile, so to the tile's count;
//   (c) otherwise: the tile is a boundary tile, counted per pixel.
// The triangle's depth range over the tile is first bounded by its plane at the tile's corner
// centres (cheap, loose for steep planes); where that settles nothing, by the exact range over
// the part of the (frustum-clipped) triangle inside the tile grown by the coverage margin.
// Depth tests are "<" against the pre-pass depth: a fragment passes where its depth is below
// the surface's. Fragment depths are clamped to [0, 1] (far=clamp clamps; elsewhere the clip
// volume keeps them inside), and a bound that reaches 1 ties with nothing stored below it. A
// z-fail near cap lying on the visible surface ties with it: where every surface pixel of the
// tile shows that very triangle (the pre-pass's triangle per pixel), the cap fails the depth
// test at each and is counted.
#include "hierarchical_volume_common.glsl"

#ifdef COMPUTE_SHADER
#include "hierarchical_volume_pairs.glsl"
layout(local_size_x = 64) in;
uniform int u_spans;
uniform float u_depth_rel;      // error bound of a window depth taken at a corner

// 0: no effect, 1: counted at every pixel of the tile, 2: boundary; from the depth range
// [zlo, zhi] of the triangle's fragments in the tile (bounds already widened by their error).
int verdict(float zlo, float zhi, vec2 zb, bool on_fail, bool full) {
    zlo = clamp(zlo, 0.0, 1.0);
    zhi = clamp(zhi, 0.0, 1.0);
    bool all_pass = zhi < zb.x;                    // below every surface depth of the tile
    bool all_fail = zlo > zb.y || zlo == 1.0;      // at or beyond every one of them
    if (on_fail ? all_pass : all_fail) return 0;   // never counted here
    if (full && (on_fail ? all_fail : all_pass)) return 1;
    return 2;
}

// The window-depth range (x: min, y: max) of the triangle tri[i] inside the window rectangle
// [lo, hi] (pixels); x > y when nothing of it is inside. Depth is affine over the triangle in
// window coordinates, so its extremes over the convex intersection lie at the intersection's
// corners: the polygon's corners inside the rectangle, its edges' crossings of the rectangle's
// sides (depth interpolated along the edge, well conditioned even for slivers) and the
// rectangle's corners inside the polygon (the plane, with its error bound). Every test leans
// towards including a candidate (TOUCH pixels): an extra one only widens the range.
#define TOUCH 1e-3
void extend(inout vec2 range, float z) {
    range = vec2(min(range.x, z), max(range.y, z));
}
vec2 exact_range(int i, int n, int flags, vec2 lo, vec2 hi) {
    vec2 range = vec2(2.0, -1.0);
    for (int k = 0; k < n; ++k) {
        vec3 a = tri[i].vert[k].xyz, b = tri[i].vert[(k + 1) % n].xyz;
        if (all(greaterThanEqual(a.xy, lo - TOUCH)) && all(lessThanEqual(a.xy, hi + TOUCH)))
            extend(range, a.z);
        for (int side = 0; side < 4; ++side) {
            int axis = side / 2;                   // 0: x = const, 1: y = const
            float c = (side % 2 == 0) ? lo[axis] : hi[axis];
            float da = a[axis] - c, db = b[axis] - c;
            if (da * db >= 0.0) continue;          // no crossing inside the edge (ends: above)
            float s = da / (da - db);
            float other = mix(a[1 - axis], b[1 - axis], s);
            if (other >= lo[1 - axis] - TOUCH && other <= hi[1 - axis] + TOUCH)
                extend(range, mix(a.z, b.z, s));
        }
    }
    for (int corner = 0; corner < 4; ++corner) {
        vec2 p = vec2((corner & 1) != 0 ? hi.x : lo.x, (corner & 2) != 0 ? hi.y : lo.y);
        bool inside = true;
        if ((flags & FLAG_NO_EDGES) == 0)
            for (int j = 0; j < n; ++j) {
                vec4 e = tri[i].edge[j];
                if (e.x * p.x + e.y * p.y + e.z < -TOUCH) inside = false;
            }
        if (!inside) continue;
        if ((flags & FLAG_NO_PLANE) != 0) return vec2(0.0, 1.0);   // no plane to take it from: unsure
        vec4 pl = tri[i].plane;
        float z = pl.x * p.x + pl.y * p.y + pl.z;
        extend(range, z - pl.w);
        extend(range, z + pl.w);
    }
    return range;
}

// Classify the pair (triangle i, tile tc) and record its effect on the tile.
void classify(int i, ivec4 info, ivec2 tc) {
    int t = tc.y * u_tiles.x + tc.x;
    vec2 zb = tile_bounds[t];
    if (zb.x > zb.y) return;                       // no surface in the tile: nothing to count
    vec2 lo = vec2(tc * u_tile) + 0.5;             // the tile's first and last pixel centres
    vec2 hi = vec2(min((tc + 1) * u_tile, u_size)) - 0.5;
    int flags = info.w;
    if ((flags & FLAG_UNCERTAIN) != 0) {
        atomicOr(tile_boundary[t], 1u);
        return;
    }
    bool full = (flags & (FLAG_NO_EDGES | FLAG_THIN)) == 0;
    float m = tri[i].margin.x;
    if (int(tri[i].margin.y) == tile_triangle[t]) {
        // A near cap that is the very triangle every surface pixel of the tile shows: drawn by
        // the same program from the same vertices as the pre-pass, it covers those pixels with
        // their stored depth bit for bit, so the depth test fails at each (z-fail counts it).
        if (full) {
            atomicAdd(tile_count[t], info.y == 1 ? info.z : 0);
            return;
        }
        atomicOr(tile_boundary[t], 1u);
        return;
    }
    if ((flags & FLAG_NO_EDGES) == 0) {
        for (int j = 0; j < info.x; ++j) {
            vec4 e = tri[i].edge[j];
            float dmin = e.z + min(e.x * lo.x, e.x * hi.x) + min(e.y * lo.y, e.y * hi.y);
            float dmax = e.z + max(e.x * lo.x, e.x * hi.x) + max(e.y * lo.y, e.y * hi.y);
            if (dmax < -m) return;                 // (a) outside this edge at every pixel centre
            if (dmin < m) full = false;
        }
    }
    bool on_fail = info.y == 1;
    int v = 2;
    if ((flags & FLAG_NO_PLANE) == 0) {
        vec4 p = tri[i].plane;
        float zlo = p.z + min(p.x * lo.x, p.x * hi.x) + min(p.y * lo.y, p.y * hi.y) - p.w;
        float zhi = p.z + max(p.x * lo.x, p.x * hi.x) + max(p.y * lo.y, p.y * hi.y) + p.w;
        v = verdict(zlo, zhi, zb, on_fail, full);
    }
    if (v == 2) {
        // the fragments' pixel centres lie in [lo, hi]; the rasteriser's triangle differs from
        // this one by less than the margin: clip to the rectangle grown by it
        vec2 r = exact_range(i, info.x, flags, lo - m, hi + m);
        if (r.x > r.y) return;                     // (a) nothing of it over the tile's centres
        v = verdict(r.x - u_depth_rel, r.y + u_depth_rel, zb, on_fail, full);
    }
    if (v == 0) return;                            // (a) never counted here
    if (v == 1)
        atomicAdd(tile_count[t], info.z);          // (b) counted at every pixel of the tile
    else
        atomicOr(tile_boundary[t], 1u);            // (c)
}
void main() {
    int s = INVOCATION_INDEX;
    if (s >= u_spans) return;
    ivec4 sp = span[s];
    ivec4 info = tri[sp.x].info;
    for (int k = 0; k < sp.w; ++k)
        classify(sp.x, info, ivec2(sp.y + k, sp.z));
}
#endif
