// Hierarchical shadow volumes, pass "classify" (1 of 2): one invocation per volume triangle. Its
// clip positions are the per-pixel stage's own (surface_clip / extruded_clip of
// shadow_volume_clip.glsl: points at infinity have w = 0); it is clipped in homogeneous clip
// space (double precision) to the near plane, the four side planes and, for a finite
// projection, the far plane; the clipped polygon's corners and edges, its window-depth plane and error
// bounds, its counting rule and its tile box are stored, and the tiles it may reach, row by row,
// are cut into spans of at most SPAN tiles appended to the span list (an atomic counter; a full
// list is counted, never dropped: the technique grows it and runs again).
//
// The depth plane: the triangle's corners c0, c1, c2 (4-vectors) span a 3-dimensional subspace
// of homogeneous space; its normal n (the generalised cross product, n_k = (−1)^k times the
// 3×3 minor without column k) has n · c = 0 for every point of the triangle, hence for the
// normalised device coordinates (x, y, z) of every fragment n0 x + n1 y + n2 z + n3 = 0: window
// depth is affine in window position, and the plane needs no division by w (w = 0 is fine).
#include "shadow_volume_clip.glsl"
#include "hierarchical_volume_common.glsl"

#ifdef COMPUTE_SHADER
#include "hierarchical_volume_pairs.glsl"
#ifndef SPAN
#error "SPAN: tiles per span (shadowlab.techniques.volumes.hierarchical_volume)"
#endif
layout(local_size_x = 64) in;
uniform int u_triangles;
uniform int u_span_capacity;
uniform bool u_clip_far;        // far=finite: the far plane clips the volumes too
uniform float u_margin_px;      // coverage margin (pixels): rasterisation's sub-pixel rounding
uniform float u_depth_rel;      // depth error bound, relative to the plane's terms
uniform float u_depth_px;       // depth error bound, in pixels of position uncertainty

double det3(dvec3 a, dvec3 b, dvec3 c) {
    return dot(a, cross(b, c));
}

// A triangle that cannot be set up reliably: boundary on every tile with a surface.
void store_uncertain(int i, int side) {
    for (int k = 0; k < MAX_POLY; ++k) tri[i].edge[k] = vec4(0.0);
    for (int k = 0; k < MAX_POLY; ++k) tri[i].vert[k] = vec4(0.0);
    tri[i].plane = vec4(0.0);
    tri[i].margin = vec4(0.0);
    tri[i].box = ivec4(0, 0, u_tiles.x - 1, u_tiles.y - 1);
    tri[i].info = ivec4(0, side, 0, FLAG_UNCERTAIN | FLAG_NO_EDGES | FLAG_NO_PLANE);
}

void main() {
    int i = INVOCATION_INDEX;
    if (i >= u_triangles) return;
    vec4 c[3];
    for (int k = 0; k < 3; ++k) {
        vec4 v = tri_vertex[3 * i + k];
        c[k] = v.w > 0.0 ? extruded_clip(v.xyz) : surface_clip(v.xyz);
    }
    // Two bit-identical corners (a directional light's side triangle (b, a', b'): a' and b' are
    // the same point at infinity): zero area in every rasteriser, no fragment, no effect.
    if (c[0] == c[1] || c[1] == c[2] || c[2] == c[0]) return;
    int rule = tri_rule[i];
    int side = (rule & RULE_ZFAIL) != 0 ? 1 : 0;

    // Clip (Sutherland-Hodgman, keeping dot(plane, v) >= 0).
    dvec4 poly[MAX_POLY], next[MAX_POLY];
    for (int k = 0; k < 3; ++k) poly[k] = dvec4(c[k]);
    int n = 3;
    bool overflow = false;
    int planes = u_clip_far ? 6 : 5;
    for (int p = 0; p < planes && n > 0; ++p) {
        dvec4 pl = p == 0 ? dvec4(0, 0, 1, 1) : p == 1 ? dvec4(1, 0, 0, 1) : p == 2 ? dvec4(-1, 0, 0, 1)
                 : p == 3 ? dvec4(0, 1, 0, 1) : p == 4 ? dvec4(0, -1, 0, 1) : dvec4(0, 0, -1, 1);
        int m = 0;
        for (int k = 0; k < n; ++k) {
            dvec4 a = poly[k], b = poly[(k + 1) % n];
            double da = dot(pl, a), db = dot(pl, b);
            if (da >= 0.0) {
                if (m == MAX_POLY) { overflow = true; break; }
                next[m++] = a;
            }
            if ((da >= 0.0) != (db >= 0.0)) {
                if (m == MAX_POLY) { overflow = true; break; }
                next[m++] = a + (da / (da - db)) * (b - a);
            }
        }
        n = m;
        for (int k = 0; k < n; ++k) poly[k] = next[k];
    }
    if (n < 3 && !overflow) return;   // nothing of it inside the view frustum: no fragment

    // Window coordinates of the clipped polygon; its orientation (GL: front = counter-clockwise).
    dvec2 size = dvec2(u_size);
    dvec2 q[MAX_POLY];
    double wmin = 1e300LF, cmax = 0.0;
    for (int k = 0; k < 3; ++k)
        cmax = max(cmax, double(max(max(abs(c[k].x), abs(c[k].y)), max(abs(c[k].z), abs(c[k].w)))));
    for (int k = 0; k < n; ++k) wmin = min(wmin, poly[k].w);
    bool rows = false;              // per tile row, only the tiles the polygon reaches
    float margin = 0.0;
    if (overflow || !(wmin > 0.0) || wmin < 1e-12 * cmax) {
        atomicAdd(counter[COUNTER_UNCERTAIN], 1u);
        store_uncertain(i, side);
    } else {
        double area = 0.0;
        dvec2 lo = dvec2(1e300LF), hi = dvec2(-1e300LF);
        for (int k = 0; k < n; ++k) {
            q[k] = (poly[k].xy / poly[k].w + 1.0) * 0.5 * size;
            lo = min(lo, q[k]);
            hi = max(hi, q[k]);
        }
        for (int k = 0; k < n; ++k) {
            dvec2 a = q[k], b = q[(k + 1) % n];
            area += a.x * b.y - a.y * b.x;
        }
        area *= 0.5;
        // Front faces (counter-clockwise in window coordinates) take the face's own operations.
        bool front = area > 0.0;
        if ((rule & RULE_FLIPPED) != 0) front = !front;
        // z-pass: front +1, back −1 (on depth pass); z-fail: back +1, front −1 (on depth fail).
        int delta = side == 0 ? (front ? 1 : -1) : (front ? -1 : 1);
        int flags = 0;
        // Rasterisation rounds positions to sub-pixel precision; float32 clipping and division
        // err relative to the clip coordinates' size over w.
        rows = true;
        margin = u_margin_px + float(2.0e-6 * (size.x + size.y) * cmax / wmin);
        if (margin > 0.25 * float(u_tile)) flags |= FLAG_NO_EDGES;
        double perimeter = 0.0;
        for (int k = 0; k < n; ++k) perimeter += double(distance(vec2(q[k]), vec2(q[(k + 1) % n])));
        if (abs(area) <= 1e-9 * perimeter * perimeter) flags |= FLAG_NO_EDGES;  // orientation unsure
        if (abs(area) < 1.0) flags |= FLAG_THIN;        // too thin to cover a tile, facing unsure
        for (int k = 0; k < MAX_POLY; ++k) {
            vec4 edge = vec4(0.0, 0.0, 1.0, 0.0);      // no constraint
            if (k < n && (flags & FLAG_NO_EDGES) == 0) {
                // (float from here: window coordinates within the viewport; the margin is far larger)
                vec2 a = vec2(q[k]), e = vec2(q[(k + 1) % n] - q[k]);
                float len = sqrt(dot(e, e));
                if (len >= 1e-6) {                      // else a repeated corner: no edge
                    vec2 nrm = (area > 0.0 ? 1.0 : -1.0) * vec2(-e.y, e.x) / len;  // inward unit normal
                    edge = vec4(nrm, -dot(nrm, a), 0.0);
                }
            }
            tri[i].edge[k] = edge;
        }
        // The depth plane in window coordinates: z_w = A x_w + B y_w + C.
        dvec3 x = dvec3(c[0].x, c[1].x, c[2].x), y = dvec3(c[0].y, c[1].y, c[2].y);
        dvec3 z = dvec3(c[0].z, c[1].z, c[2].z), w = dvec3(c[0].w, c[1].w, c[2].w);
        double n0 = det3(y, z, w), n1 = -det3(x, z, w), n2 = det3(x, y, w), n3 = -det3(x, y, z);
        double A = 0.0, B = 0.0, C = 0.0, err = 0.0;
        if (abs(n2) * 1e9 <= abs(n0) + abs(n1) + abs(n3) || n2 == 0.0) {
            flags |= FLAG_NO_PLANE;                     // seen edge-on
        } else {
            A = -n0 / (n2 * size.x);
            B = -n1 / (n2 * size.y);
            C = 0.5 - 0.5 * (n3 - n0 - n1) / n2;
            // The rasteriser interpolates depth in float32 from rounded corners: an error
            // relative to the plane's terms over the viewport, plus the plane's slope times a
            // position uncertainty.
            err = u_depth_rel * (1.0 + abs(C) + abs(A) * size.x + abs(B) * size.y)
                + u_depth_px * (abs(A) + abs(B));
        }
        // the corners with their window depth (w > 0 past the near plane)
        for (int k = 0; k < MAX_POLY; ++k)
            tri[i].vert[k] = k < n ? vec4(vec2(q[k]), float(0.5 + 0.5 * poly[k].z / poly[k].w), 0.0) : vec4(0.0);
        tri[i].plane = vec4(float(A), float(B), float(C), float(err));
        tri[i].margin = vec4(margin, float((rule >> RULE_CAP_SHIFT) - 1), 0.0, 0.0);
        // Pixel bounds clamped in double to [-1, u_size] before the conversion to int (one past
        // the viewport either side keeps "covers no pixel" as it was): a huge margin or window
        // coordinate past 2^31 has no defined int (x86 gives INT_MIN, which would drop the triangle).
        ivec2 plo = max(ivec2(clamp(ceil(lo - double(margin) - 0.5), dvec2(-1.0), size)), ivec2(0));
        ivec2 phi = min(ivec2(clamp(floor(hi + double(margin) - 0.5), dvec2(-1.0), size)), u_size - 1);
        if (any(greaterThan(plo, phi))) return;         // covers no pixel centre
        tri[i].box = ivec4(plo / u_tile, phi / u_tile);
        tri[i].info = ivec4(n, side, delta, flags);
    }
    // Spans: per tile row of the box, the run of tiles whose pixel centres the polygon, grown
    // by the margin, may reach (its extent in x over the row's slab, grown by the margin in y):
    // a long thin sliver across the screen meets few tiles of its box.
    ivec4 box = tri[i].box;
    double m = double(margin);
    for (int ty = box.y; ty <= box.w; ++ty) {
        int x0 = box.x, x1 = box.z;
        if (rows) {
            double ylo = double(ty * u_tile) + 0.5 - m, yhi = double(min((ty + 1) * u_tile, u_size.y)) - 0.5 + m;
            double xmin = 1e300LF, xmax = -1e300LF;
            for (int k = 0; k < n; ++k) {
                dvec2 a = q[k], b = q[(k + 1) % n];
                double t0 = 0.0, t1 = 1.0, dy = b.y - a.y;
                if (dy == 0.0) {
                    if (a.y < ylo || a.y > yhi) continue;
                } else {
                    double ta = (ylo - a.y) / dy, tb = (yhi - a.y) / dy;
                    t0 = max(t0, min(ta, tb));
                    t1 = min(t1, max(ta, tb));
                    if (t0 > t1) continue;
                }
                double xa = a.x + t0 * (b.x - a.x), xb = a.x + t1 * (b.x - a.x);
                xmin = min(xmin, min(xa, xb));
                xmax = max(xmax, max(xa, xb));
            }
            if (xmin > xmax) continue;                 // the polygon misses this row
            // clamped in double before the conversion, as the box above
            int px0 = max(int(clamp(ceil(xmin - m - 0.5), -1.0lf, size.x)), 0);
            int px1 = min(int(clamp(floor(xmax + m - 0.5), -1.0lf, size.x)), u_size.x - 1);
            if (px0 > px1) continue;
            x0 = max(x0, px0 / u_tile);
            x1 = min(x1, px1 / u_tile);
            if (x0 > x1) continue;
        }
        int tiles = x1 - x0 + 1;
        int spans = (tiles + SPAN - 1) / SPAN;
        atomicAdd(counter[COUNTER_TILE_TESTS], uint(tiles));
        int base = int(atomicAdd(counter[COUNTER_SPANS], uint(spans)));
        for (int s = 0; s < spans; ++s)
            if (base + s < u_span_capacity)
                span[base + s] = ivec4(i, x0 + s * SPAN, ty, min(SPAN, tiles - s * SPAN));
    }
}
#endif
