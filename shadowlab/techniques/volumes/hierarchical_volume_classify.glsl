// Hierarchical shadow volumes, pass "classify" (2 of 2): every (volume triangle,
// tile) pair, looped over by one invocation per span (a run of at most SPAN tiles of one tile
// row). Against the tile's pixel centres and its
// surface depth range [zmin, zmax] (Aila & Akenine-Möller 2004, section 3), the triangle
//   (a) covers none of the tile's pixel centres, or lies wholly on the side of the depth range
//       where it is not counted: no effect;
//   (b) covers every pixel centre (the tile's corner centres lie inside every edge by the
//       margin; the polygon is convex) and lies wholly on its counting side: it adds its ±1 to
//       every pixel of the tile, so to the tile's count;
//   (d) otherwise: the tile is a boundary tile, counted per pixel.
// The triangle's depth range over the tile is first bounded by its plane at the tile's corner
// centres (cheap, loose for steep planes); where that settles nothing, by the exact range over
// the part of the triangle inside the tile (grown by the coverage margin): the triangle is
// clipped in homogeneous clip space (double precision) to the tile's four sides and the near
// (and for far=finite the far) plane, and window depth z/w is taken at the resulting corners
// (depth is affine over the triangle, so its extremes are there). Depth tests are "<" against
// the pre-pass depth: a fragment passes where its depth is below the surface's. Fragment depths
// are clamped to [0, 1] (far=clamp clamps; elsewhere the clip volume keeps them inside), and a
// bound that reaches 1 ties with nothing stored below it. A z-fail near cap lying on the visible
// surface ties with it: where every surface pixel of the tile shows that very triangle (the
// pre-pass's triangle per pixel), the cap fails the depth test at each and is counted.
#include "hierarchical_volume_common.glsl"

#ifdef COMPUTE_SHADER
#include "hierarchical_volume_pairs.glsl"
layout(local_size_x = 64) in;
uniform int u_spans;
uniform bool u_clip_far;        // far=finite: the far plane clips the volumes too
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
// [lo, hi] (pixels), by clipping its clip-space corners; x > y when nothing of it is inside.
vec2 exact_range(int i, vec2 lo, vec2 hi) {
    dvec4 poly[MAX_CLIP], next[MAX_CLIP];
    for (int k = 0; k < 3; ++k) poly[k] = dvec4(tri[i].clip[k]);
    int n = 3;
    dvec2 ndc_lo = dvec2(lo) / dvec2(u_size) * 2.0 - 1.0, ndc_hi = dvec2(hi) / dvec2(u_size) * 2.0 - 1.0;
    int planes = u_clip_far ? 6 : 5;
    for (int p = 0; p < planes && n > 0; ++p) {
        // keep dot(pl, v) >= 0: x >= lo.x w, x <= hi.x w, y >= lo.y w, y <= hi.y w, near, far
        dvec4 pl = p == 0 ? dvec4(1, 0, 0, -ndc_lo.x) : p == 1 ? dvec4(-1, 0, 0, ndc_hi.x)
                 : p == 2 ? dvec4(0, 1, 0, -ndc_lo.y) : p == 3 ? dvec4(0, -1, 0, ndc_hi.y)
                 : p == 4 ? dvec4(0, 0, 1, 1) : dvec4(0, 0, -1, 1);
        // the near plane first would be safer for w, but every plane here is linear in
        // homogeneous coordinates, and the result is the same set: order does not matter
        int m = 0;
        for (int k = 0; k < n; ++k) {
            dvec4 a = poly[k], b = poly[(k + 1) % n];
            double da = dot(pl, a), db = dot(pl, b);
            if (da >= 0.0 && m < MAX_CLIP) next[m++] = a;
            if ((da >= 0.0) != (db >= 0.0) && m < MAX_CLIP) next[m++] = a + (da / (da - db)) * (b - a);
        }
        n = m;
        for (int k = 0; k < n; ++k) poly[k] = next[k];
    }
    vec2 range = vec2(2.0, -1.0);
    for (int k = 0; k < n; ++k) {
        if (!(poly[k].w > 0.0)) return vec2(0.0, 1.0);   // cannot happen past the near plane: unsure
        float z = float(0.5 + 0.5 * poly[k].z / poly[k].w);
        range = vec2(min(range.x, z), max(range.y, z));
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
        vec2 r = exact_range(i, lo - m, hi + m);
        if (r.x > r.y) return;                     // (a) nothing of it over the tile's centres
        v = verdict(r.x - u_depth_rel, r.y + u_depth_rel, zb, on_fail, full);
    }
    if (v == 0) return;                            // (a) never counted here
    if (v == 1)
        atomicAdd(tile_count[t], info.z);          // (b) counted at every pixel of the tile
    else
        atomicOr(tile_boundary[t], 1u);            // (d)
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
