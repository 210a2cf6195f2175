"""The exact visible fraction of a planar area light from a point: the area of the union of the
occluders' central projections onto the light's plane, in numba kernels, no GL.

The geometry of the ``exact_soft`` technique; the kernels are compiled with the lab's settings
(:mod:`shadowlab.util.compiled`: ``nogil``, numpy's error model, no fastmath).

The definition (docs/metrics.md) read as geometry: from a point P, each occluding triangle is
centrally projected onto the light's plane; the union of the projections, together with the part
of the light below P's tangent plane, intersected with the light's emitting polygon L, is what P
cannot see:

    V(P) = 1 − area((∪ projections ∪ below-horizon) ∩ L) / area(L),   V = 0 behind the light.

This is the shapely oracle of tests/soft_oracle.py computed in compiled code, per point
(:func:`visibility_points`, over points[start::step] so that the caller can split the points
over the cores like :mod:`shadowlab.truth.compiled`):

1. **Cull** (conservative, exact): a bounding-volume hierarchy over the casters' triangles
   (median splits, :func:`build_bvh`, in ``setup``) is walked with the frustum from P to the
   light — the planes through P and each edge of a polygon containing L, the light's plane, P's
   plane parallel to it and P's tangent plane; a node or triangle wholly outside one of them
   cannot project into the visible part of L. Triangles whose plane passes through P (P's own
   surface, coplanar neighbours: the oracle's test, 1e-12 relative) project to a segment and
   are skipped; so are the back faces of closed, outward-oriented meshes (``obj.edges.closed``,
   positive signed volume) when the eye is outside the mesh's box: every point the camera sees
   is then outside the solid or on its surface (its camera-facing normal the outward one), and a
   segment from there above P's horizon that meets the solid enters it through a face turned
   towards P first (the ray-casting argument behind back-face culling), so the front faces'
   projections already cover the back faces'. For points on the mesh itself only when it is
   convex and the G-buffer saw the face's outer side: the exact point is the pixel's ray on the
   plane of the triangle the G-buffer saw, which at a concave edge can lie just beyond it,
   inside the solid (seen on a torus: a few of its own points went wrong when its back faces
   were culled).
2. **Clip** each candidate (Sutherland & Hodgman 1974) to the slab 0 ≤ d ≤ d_P(1 − 1e-9) (d the
   height above the light's plane: the oracle's slab, same margin) and to P's upper half-space
   (X − P)·N ≥ 0 (what lies below P's tangent plane projects below the horizon line, which is
   hidden anyway), then **project** it from P onto the light's plane: y = P + s (X − P),
   s = d_P / (d_P − d) (a convex polygon stays convex: every point is in front of P).
3. **Union area** by Green's theorem: area(L ∩ ∪Q_i) = ½ ∮ x dy − y dx over its boundary, which
   is made of (a) the parts of each polygon's edges inside L and outside every other polygon,
   and (b) the parts of L's edges inside some polygon. Each part of a segment a + t(b − a) of
   parameter length τ contributes ½ τ (a × b) (the cross product of its two endpoints'
   positions, origin at the light's centre), so only the uncovered parameter measure of each
   edge is needed: the coverage of an edge by a convex polygon is one interval (Cyrus & Beck
   1978 parametric clipping against the polygon's edges, strictly inside); a uniform grid over
   the light picks the polygons each edge is tested against.
   The union of the (above-horizon) projections is then cut from L' = L ∩ above-horizon:
   V = (area(L') − area(L ∩ ∪Q_i)) / area(L).

Coincident edges, made exact instead of left to rounding. A boundary part counted twice, or
dropped by both of two polygons, is an error of order (edge length × distance from the origin),
not of rounding size, so every coincidence the geometry produces by construction is decided
symbolically: (i) an edge shared by two triangles of a mesh is clipped with its endpoints in a
canonical (lexicographic) order, so both triangles get bit-identical cut points, projections and
2D endpoints; the two copies are then exactly collinear (cross products exactly 0), and the
rule is that of the classic polygon-union sweep — opposite directions (neighbouring front faces):
both kept, they cancel; the same direction (a silhouette seen through two faces of an open
mesh): the overlap counted once, by the polygon with the lower index. (ii) Edges in P's tangent
plane (vertices within 1e-12 × the scene's scale of it are snapped onto it: a box standing on
the receiver P lies on) all project onto the horizon line; they are marked and treated as
exactly collinear with each other by the same rule. What remains — edges of different objects
that happen to be collinear from P (T-junctions, a caster edge projecting onto an edge of the
light) — is a set of points P of measure zero and is left to floating point. Two numerical
guards go with the rules: the 2D box tests that skip far pairs are widened by 1e-9 of the light's
size (horizon edges are collinear by construction, not to the last bit), and polygon edges of
rounding size (two cut points a few ulps apart) bound nothing, since their direction is noise.
The clipping frustum runs through a polygon 1e-6 larger than a rect light, so that its cut
edges never lie on the light's own edges; it also keeps every projected coordinate bounded
(unclipped, a triangle reaching P's parallel plane projects ~1e9 away through the slab margin).
"""
from __future__ import annotations

import numpy as np

from ..util.compiled import JIT as _JIT
from ..util.compiled import njit

#: Relative margin below P's parallel plane where triangles are cut (the oracle's SLAB_MARGIN).
SLAB_MARGIN = 1e-9
#: Relative tolerance of the oracle's "triangle plane through P" test.
THROUGH_P = 1e-12
#: Vertices within this × max(1, |P|∞) of P's tangent plane are snapped onto it (horizon edges).
HORIZON_SNAP = 1e-12
#: Most vertices of a clipped triangle (3 + one per clipping plane: slab bottom and top, ≤ 8
#: frustum sides, horizon).
MAX_VERTS = 16
#: Relative margin of the clipping frustum's polygon outside a rect light's.
CULL_MARGIN = 1e-6
#: Slack of the 2D box tests between edges and polygons, × the light's circumradius.
BOX_SLACK = 1e-9
#: The union's grid: none up to GRID_MIN polygons, then ~√n × √n cells, at most GRID_MAX².
GRID_MIN = 24
GRID_MAX = 64
#: Triangles per leaf of the bounding-volume hierarchy.
LEAF_SIZE = 4


def disc_polygon(radius: float, sides: int) -> np.ndarray:
    """The regular ``sides``-gon (sides, 2), CCW, centred at 0, with the disc's area π r²
    (circumradius r·√(2π / (k sin(2π/k))), as tests/soft_oracle.py builds it)."""
    ang = 2.0 * np.pi * np.arange(sides) / sides
    r = radius * np.sqrt(2.0 * np.pi / (sides * np.sin(2.0 * np.pi / sides)))
    return np.stack([r * np.cos(ang), r * np.sin(ang)], axis=1)


def disc_error_bound(sides: int) -> float:
    """Upper bound on |V_polygon − V_disc| for the equal-area ``sides``-gon standing for a disc:
    area(polygon Δ disc) / area(disc) (both lights have the same area and see the same occluded
    region, so their visible fractions differ by at most the area where they differ). In closed
    form for the unit disc: the polygon's apothem a = R cos φ (φ = π/k, R its circumradius) is
    below 1 < R; in each half-sector the polygon leaves the circle between the angles α = acos a
    and φ from the edge's normal, with area ½ a² (tan φ − tan α) − ½ (φ − α) outside; the
    symmetric difference is twice the 2k half-sectors' (equal areas: as much inside as outside).
    6.2e-4 at k = 64, 3.9e-5 at 256, 2.4e-6 at 1024 (the oracle's)."""
    k = int(sides)
    phi = np.pi / k
    big_r = np.sqrt(2.0 * np.pi / (k * np.sin(2.0 * phi)))
    a = big_r * np.cos(phi)
    alpha = np.arccos(min(1.0, a))
    outside = 2 * k * 0.5 * (a * a * (np.tan(phi) - np.tan(alpha)) - (phi - alpha))
    return float(2.0 * outside / np.pi)


def cull_polygon(light_poly: np.ndarray) -> np.ndarray:
    """A convex polygon (≤ 8 vertices, CCW) strictly containing the light polygon, for the culling
    and clipping frustum: the polygon itself scaled by 1 + CULL_MARGIN about its centre up to 8
    sides (its edges stay off the light's: no edge cut by the frustum is collinear with one of
    the light's), else the regular octagon around its circumcircle."""
    if len(light_poly) <= 8:
        return np.ascontiguousarray(light_poly * (1.0 + CULL_MARGIN))
    r = float(np.sqrt((light_poly ** 2).sum(axis=1)).max()) / np.cos(np.pi / 8)
    ang = 2.0 * np.pi * np.arange(8) / 8
    return np.ascontiguousarray(np.stack([r * np.cos(ang), r * np.sin(ang)], axis=1))


def build_bvh(tris: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A bounding-volume hierarchy over triangles (T, 3, 3): recursive median splits of the
    centroids along the longest axis of their box, leaves of ≤ LEAF_SIZE triangles. Returns the
    triangle order (T,), node boxes lo, hi (K, 3) and node links (K, 3) int64: (first child or −1
    for a leaf, start into the ordered triangles, count); a node's children are
    consecutive (second = first + 1)."""
    cent = tris.mean(axis=1)
    lo_t, hi_t = tris.min(axis=1), tris.max(axis=1)
    order = np.arange(len(tris))
    nodes_lo, nodes_hi, links = [], [], []

    def make(start, stop):
        k = len(links)
        idx = order[start:stop]
        nodes_lo.append(lo_t[idx].min(axis=0) if len(idx) else np.zeros(3))
        nodes_hi.append(hi_t[idx].max(axis=0) if len(idx) else np.zeros(3))
        links.append([-1, start, stop - start])
        return k

    root = make(0, len(tris))
    stack = [root]
    while stack:
        k = stack.pop()
        _, start, count = links[k]
        if count <= LEAF_SIZE:
            continue
        idx = order[start:start + count]
        span = cent[idx].max(axis=0) - cent[idx].min(axis=0)
        axis = int(np.argmax(span))
        order[start:start + count] = idx[np.argsort(cent[idx, axis], kind="stable")]
        mid = start + count // 2
        left = make(start, mid)
        make(mid, start + count)
        links[k][0] = left
        stack.extend([left, left + 1])
    return (order, np.asarray(nodes_lo, np.float64).reshape(-1, 3), np.asarray(nodes_hi, np.float64).reshape(-1, 3),
            np.asarray(links, np.int64).reshape(-1, 3))


def scratch_buffers(cap: int, nodes: int) -> tuple:
    """One part's scratch buffers of :func:`visibility_points` (its arguments ``px`` … ``stamp``,
    in order) for up to ``cap`` candidate polygons per point and a hierarchy of ``nodes`` nodes
    (:func:`build_bvh`)."""
    return (np.empty((cap, MAX_VERTS)), np.empty((cap, MAX_VERTS)), np.empty(cap, np.int64),
            np.empty((cap, MAX_VERTS), np.bool_), np.empty((cap, 4)), np.empty(cap + 2), np.empty(cap + 2),
            np.empty(2 * nodes + 2, np.int64), np.empty(GRID_MAX ** 2 + 1, np.int64),
            np.empty(GRID_MAX ** 2 + 1, np.int64), np.empty(16 * cap + 64, np.int64), np.empty(cap + 2, np.int64))


# ------------------------------------------------------------------------------ kernels
@njit(inline="always", **_JIT)
def _less(ax, ay, az, bx, by, bz):
    """Lexicographic a < b: the canonical order of an edge's endpoints."""
    if ax != bx:
        return ax < bx
    if ay != by:
        return ay < by
    return az < bz


@njit(**_JIT)
def _clip3(src, sval, n, thr, dst, dval, keep_ge):
    """Sutherland–Hodgman in 3D: the part of polygon ``src`` (n, 3) whose per-vertex value
    ``sval`` is ≥ thr (``keep_ge``) or ≤ thr (otherwise) into ``dst``/``dval``; returns its
    vertex count. A cut point is computed from the edge's endpoints in lexicographic order (the
    same bits for both triangles sharing the edge) and gets the value thr exactly."""
    m = 0
    for i in range(n):
        j = i + 1 if i + 1 < n else 0
        va, vb = sval[i], sval[j]
        ina = va >= thr if keep_ge else va <= thr
        inb = vb >= thr if keep_ge else vb <= thr
        if ina:
            dst[m, 0], dst[m, 1], dst[m, 2] = src[i, 0], src[i, 1], src[i, 2]
            dval[m] = va
            m += 1
        if ina != inb:
            if _less(src[i, 0], src[i, 1], src[i, 2], src[j, 0], src[j, 1], src[j, 2]):
                p, q, vp, vq = i, j, va, vb
            else:
                p, q, vp, vq = j, i, vb, va
            s = (thr - vp) / (vq - vp)
            for k in range(3):
                dst[m, k] = src[p, k] + s * (src[q, k] - src[p, k])
            dval[m] = thr
            m += 1
    return m


@njit(inline="always", **_JIT)
def _seg_in_convex(ax, ay, bx, by, qx, qy, qn, tiny):
    """Cyrus–Beck: the parameter interval (t0, t1) of a + t(b − a), 0 ≤ t ≤ 1, strictly inside
    the convex CCW polygon (qx, qy)[:qn]; empty when t0 ≥ t1. Edges of squared length ≤ ``tiny``
    (rounding-size stubs between two cut points a bit apart) bound nothing: their direction is
    noise, and the neighbouring edges bound the polygon there to within their length."""
    t0, t1 = 0.0, 1.0
    for k in range(qn):
        l = k + 1 if k + 1 < qn else 0
        ex, ey = qx[l] - qx[k], qy[l] - qy[k]
        if ex * ex + ey * ey <= tiny:
            continue
        fa = ex * (ay - qy[k]) - ey * (ax - qx[k])
        fb = ex * (by - qy[k]) - ey * (bx - qx[k])
        if fa <= 0.0 and fb <= 0.0:
            return 1.0, 0.0
        if fa > 0.0 and fb > 0.0:
            continue
        ts = fa / (fa - fb)
        if fa > 0.0:
            t1 = min(t1, ts)
        else:
            t0 = max(t0, ts)
        if t0 >= t1:
            return 1.0, 0.0
    return t0, t1


@njit(inline="always", **_JIT)
def _edge_cover(ax, ay, bx, by, horizon, i, j, px, py, pn, ph, tiny):
    """The interval of edge a → b of polygon i (``horizon``: it lies on the horizon line) covered
    by polygon j: its part strictly inside j (Cyrus–Beck), or — where the edge is collinear with
    an edge of j (exactly, or both on the horizon) — the overlap with that edge if both run the
    same way and j < i (counted once), else nothing (module docstring). Stubs of j shorter than
    √tiny are skipped (:func:`_seg_in_convex`)."""
    dx, dy = bx - ax, by - ay
    t0, t1 = 0.0, 1.0
    n = pn[j]
    for k in range(n):
        l = k + 1 if k + 1 < n else 0
        qx, qy = px[j, k], py[j, k]
        ex, ey = px[j, l] - qx, py[j, l] - qy
        if ex * ex + ey * ey <= tiny:
            continue
        fa = ex * (ay - qy) - ey * (ax - qx)
        fb = ex * (by - qy) - ey * (bx - qx)
        if (fa == 0.0 and fb == 0.0) or (horizon and ph[j, k]):
            if j < i and ex * dx + ey * dy > 0.0:
                ll = dx * dx + dy * dy
                s0 = ((qx - ax) * dx + (qy - ay) * dy) / ll
                s1 = ((px[j, l] - ax) * dx + (py[j, l] - ay) * dy) / ll
                return max(0.0, min(s0, s1)), min(1.0, max(s0, s1))
            return 1.0, 0.0
        if fa <= 0.0 and fb <= 0.0:
            return 1.0, 0.0
        if fa > 0.0 and fb > 0.0:
            continue
        ts = fa / (fa - fb)
        if fa > 0.0:
            t1 = min(t1, ts)
        else:
            t0 = max(t0, ts)
        if t0 >= t1:
            return 1.0, 0.0
    return t0, t1


@njit(inline="always", **_JIT)
def _uncovered(lo, hi, s0, s1, m):
    """Measure of [lo, hi] minus the union of the intervals [s0[k], s1[k]], k < m (sorted in
    place by start: insertion sort, m is small)."""
    for a in range(1, m):
        x0, x1 = s0[a], s1[a]
        b = a - 1
        while b >= 0 and s0[b] > x0:
            s0[b + 1], s1[b + 1] = s0[b], s1[b]
            b -= 1
        s0[b + 1], s1[b + 1] = x0, x1
    free = 0.0
    cur = lo
    for a in range(m):
        if s1[a] <= cur:
            continue
        if s0[a] >= hi:
            break
        if s0[a] > cur:
            free += s0[a] - cur
        cur = s1[a]
        if cur >= hi:
            break
    if cur < hi:
        free += hi - cur
    return free


@njit(inline="always", **_JIT)
def _cell_range(lo, hi, w0, cw, g):
    """Grid cells [c0, c1] (clamped to 0 … g − 1) that the interval [lo, hi] overlaps."""
    c0 = int((lo - w0) / cw)
    c1 = int((hi - w0) / cw)
    return min(max(c0, 0), g - 1), min(max(c1, 0), g - 1)


@njit(**_JIT)
def union_area(px, py, pn, ph, box, npoly, lx, ly, ln, s0, s1, slack, cstart, cpos, citems, stamp):
    """Area of L ∩ ∪ polygons (module docstring, step 3): polygons i < npoly with vertices
    (px, py)[i, :pn[i]] (convex, CCW), horizon-edge flags ph, boxes box[i] = (xmin, ymin, xmax,
    ymax); L the convex CCW light polygon (lx, ly)[:ln]; s0, s1 scratch (≥ npoly + 1).

    Which polygons an edge is tested against comes from a uniform grid of ~√npoly × √npoly cells
    over L's box (each polygon listed in the cells its box overlaps; an edge visits the cells of
    the box of its part inside L, each polygon once: ``stamp``), so that a finely tessellated
    caster costs about linearly in its triangles instead of quadratically; cstart, cpos (≥
    GRID_MAX² + 1), citems and stamp (≥ npoly) are scratch, and when citems is too short for
    the grid every pair is tested. The boxes only skip pairs that cannot meet, and are widened
    by ``slack``: horizon edges are collinear by construction, not to the last bit, and a box
    test that separated two of them by rounding would skip the collinear rule."""
    wx0, wy0, wx1, wy1 = np.inf, np.inf, -np.inf, -np.inf
    for k in range(ln):
        wx0, wx1 = min(wx0, lx[k]), max(wx1, lx[k])
        wy0, wy1 = min(wy0, ly[k]), max(wy1, ly[k])
    g = 1
    if npoly > GRID_MIN:
        g = min(GRID_MAX, int(np.sqrt(npoly)))
    cw, ch = (wx1 - wx0) / g, (wy1 - wy0) / g
    for c in range(g * g + 1):
        cstart[c] = 0
    for j in range(npoly):
        stamp[j] = -1
        a0, a1 = _cell_range(box[j, 0] - slack, box[j, 2] + slack, wx0, cw, g)
        b0, b1 = _cell_range(box[j, 1] - slack, box[j, 3] + slack, wy0, ch, g)
        for cy_ in range(b0, b1 + 1):
            for cx_ in range(a0, a1 + 1):
                cstart[cy_ * g + cx_ + 1] += 1
    for c in range(g * g):
        cstart[c + 1] += cstart[c]
    gridded = cstart[g * g] <= citems.shape[0]
    if gridded:
        for c in range(g * g):
            cpos[c] = cstart[c]
        for j in range(npoly):
            a0, a1 = _cell_range(box[j, 0] - slack, box[j, 2] + slack, wx0, cw, g)
            b0, b1 = _cell_range(box[j, 1] - slack, box[j, 3] + slack, wy0, ch, g)
            for cy_ in range(b0, b1 + 1):
                for cx_ in range(a0, a1 + 1):
                    c = cy_ * g + cx_
                    citems[cpos[c]] = j
                    cpos[c] += 1
    tiny = slack * slack
    tag = 0
    acc = 0.0
    for i in range(npoly + 1):
        last = i == npoly  # after the polygons' edges: the light's own edges
        n = ln if last else pn[i]
        for k in range(n):
            l = k + 1 if k + 1 < n else 0
            if last:
                ax, ay, bx, by = lx[k], ly[k], lx[l], ly[l]
                t0, t1 = 0.0, 1.0
            else:
                ax, ay, bx, by = px[i, k], py[i, k], px[i, l], py[i, l]
                if ax == bx and ay == by:
                    continue
                t0, t1 = _seg_in_convex(ax, ay, bx, by, lx, ly, ln, tiny)
                if t0 >= t1:
                    continue
            # the box of the part inside L
            qx0, qx1 = ax + t0 * (bx - ax), ax + t1 * (bx - ax)
            qy0, qy1 = ay + t0 * (by - ay), ay + t1 * (by - ay)
            ex0, ex1 = min(qx0, qx1) - slack, max(qx0, qx1) + slack
            ey0, ey1 = min(qy0, qy1) - slack, max(qy0, qy1) + slack
            tag += 1
            m = 0
            if gridded:
                a0, a1 = _cell_range(ex0, ex1, wx0, cw, g)
                b0, b1 = _cell_range(ey0, ey1, wy0, ch, g)
            else:
                a0, a1, b0, b1 = 0, 0, 0, 0
            for cy_ in range(b0, b1 + 1):
                for cx_ in range(a0, a1 + 1):
                    c = cy_ * g + cx_
                    lo_, hi_ = (cstart[c], cstart[c + 1]) if gridded else (0, npoly)
                    for q in range(lo_, hi_):
                        j = citems[q] if gridded else q
                        if j == i or stamp[j] == tag:
                            continue
                        stamp[j] = tag
                        if box[j, 0] > ex1 or box[j, 2] < ex0 or box[j, 1] > ey1 or box[j, 3] < ey0:
                            continue
                        if last:
                            c0, c1 = _seg_in_convex(ax, ay, bx, by, px[j], py[j], pn[j], tiny)
                        else:
                            c0, c1 = _edge_cover(ax, ay, bx, by, ph[i, k], i, j, px, py, pn, ph, tiny)
                        if c0 < c1 and c1 > t0 and c0 < t1:
                            s0[m], s1[m] = c0, c1
                            m += 1
            free = _uncovered(t0, t1, s0, s1, m)
            acc += ((1.0 - free) if last else free) * (ax * by - ay * bx)
    return 0.5 * acc


@njit(**_JIT)
def visibility_points(points, normals, pobj, pinside, start, step, tris, tnorm, tlen, tobj, cullable, convex,
                      node_lo, node_hi, links, centre, ln_, lt, lb, lx, ly, cx, cy, light_area, light_size,
                      px, py, pn, ph, box, s0, s1, stack, cstart, cpos, citems, stamp, vout, cand):
    """V at points[start::step] (float64 (M, 3), unit camera-facing normals (M, 3); the caster
    index of each point's object, −1 for none, and whether the camera saw that surface's inner
    side, ``pinside``) into ``vout``,
    and the triangles clipped per point into ``cand`` (module docstring). Light: centre, unit
    normal ln_, axes lt, lb, polygon (lx, ly) (CCW in (t, b)), culling polygon (cx, cy);
    casters: triangles (T, 3, 3) in BVH order, their normals e1 × e2 (T, 3) and lengths,
    object ids, back-face ``cullable`` per object; the BVH
    node_lo/node_hi/links (:func:`build_bvh`). px … s1, stack: this part's scratch."""
    nl = lx.shape[0]
    nc = cx.shape[0]
    poly = np.empty((MAX_VERTS, 3))
    pval = np.empty(MAX_VERTS)
    poly2 = np.empty((MAX_VERTS, 3))
    pval2 = np.empty(MAX_VERTS)
    hv = np.empty(MAX_VERTS)
    lpx = np.empty(nl + 2)
    lpy = np.empty(nl + 2)
    planes = np.empty((nc + 3, 4))
    for idx in range(start, points.shape[0], step):
        p0, p1, p2 = points[idx, 0], points[idx, 1], points[idx, 2]
        n0, n1, n2 = normals[idx, 0], normals[idx, 1], normals[idx, 2]
        cand[idx] = 0
        dp = (p0 - centre[0]) * ln_[0] + (p1 - centre[1]) * ln_[1] + (p2 - centre[2]) * ln_[2]
        if not dp > 0.0:
            vout[idx] = 0.0
            continue
        # L' = L ∩ above P's horizon: h(u, v) = (c − P)·N + u t·N + v b·N > 0 (2D Sutherland–Hodgman)
        g0 = (centre[0] - p0) * n0 + (centre[1] - p1) * n1 + (centre[2] - p2) * n2
        gt = lt[0] * n0 + lt[1] * n1 + lt[2] * n2
        gb = lb[0] * n0 + lb[1] * n1 + lb[2] * n2
        m = 0
        for k in range(nl):
            l = k + 1 if k + 1 < nl else 0
            ha = g0 + lx[k] * gt + ly[k] * gb
            hb = g0 + lx[l] * gt + ly[l] * gb
            if ha > 0.0:
                lpx[m], lpy[m] = lx[k], ly[k]
                m += 1
            if (ha > 0.0) != (hb > 0.0):
                s = ha / (ha - hb)
                lpx[m], lpy[m] = lx[k] + s * (lx[l] - lx[k]), ly[k] + s * (ly[l] - ly[k])
                m += 1
        area_above = 0.0
        bx0, by0, bx1, by1 = np.inf, np.inf, -np.inf, -np.inf
        for k in range(m):
            l = k + 1 if k + 1 < m else 0
            area_above += lpx[k] * lpy[l] - lpx[l] * lpy[k]
            bx0, bx1 = min(bx0, lpx[k]), max(bx1, lpx[k])
            by0, by1 = min(by0, lpy[k]), max(by1, lpy[k])
        area_above *= 0.5
        if m < 3 or not area_above > 0.0:
            vout[idx] = 0.0
            continue
        top = dp * (1.0 - SLAB_MARGIN)
        scale = max(1.0, abs(p0), abs(p1), abs(p2))
        snap = HORIZON_SNAP * scale
        # culling frustum: planes (a, b, c, d) with a·x + b·y + c·z + d ≥ 0 inside
        for k in range(nc):
            l = k + 1 if k + 1 < nc else 0
            q00 = centre[0] + cx[k] * lt[0] + cy[k] * lb[0] - p0
            q01 = centre[1] + cx[k] * lt[1] + cy[k] * lb[1] - p1
            q02 = centre[2] + cx[k] * lt[2] + cy[k] * lb[2] - p2
            q10 = centre[0] + cx[l] * lt[0] + cy[l] * lb[0] - p0
            q11 = centre[1] + cx[l] * lt[1] + cy[l] * lb[1] - p1
            q12 = centre[2] + cx[l] * lt[2] + cy[l] * lb[2] - p2
            a0 = q01 * q12 - q02 * q11
            a1 = q02 * q10 - q00 * q12
            a2 = q00 * q11 - q01 * q10
            # oriented so the light's centre is inside
            sgn = a0 * (centre[0] - p0) + a1 * (centre[1] - p1) + a2 * (centre[2] - p2)
            if sgn < 0.0:
                a0, a1, a2 = -a0, -a1, -a2
            planes[k, 0], planes[k, 1], planes[k, 2] = a0, a1, a2
            planes[k, 3] = -(a0 * p0 + a1 * p1 + a2 * p2)
        # d ≥ 0 (in front of the light), d ≤ d_P, above the horizon
        planes[nc, 0], planes[nc, 1], planes[nc, 2] = ln_[0], ln_[1], ln_[2]
        planes[nc, 3] = -(ln_[0] * centre[0] + ln_[1] * centre[1] + ln_[2] * centre[2])
        planes[nc + 1, 0], planes[nc + 1, 1], planes[nc + 1, 2] = -ln_[0], -ln_[1], -ln_[2]
        planes[nc + 1, 3] = ln_[0] * p0 + ln_[1] * p1 + ln_[2] * p2
        planes[nc + 2, 0], planes[nc + 2, 1], planes[nc + 2, 2] = n0, n1, n2
        planes[nc + 2, 3] = -(n0 * p0 + n1 * p1 + n2 * p2) + snap
        npl = nc + 3
        npoly = 0
        clipped = 0
        stack[0] = 0
        sp = 1 if links[0, 2] > 0 else 0
        umbra = False
        overflow = False
        while sp > 0 and not umbra and not overflow:
            sp -= 1
            node = stack[sp]
            out = False
            for k in range(npl):
                # the box corner farthest along the plane's normal
                e = planes[k, 3]
                for r in range(3):
                    e += planes[k, r] * (node_hi[node, r] if planes[k, r] > 0.0 else node_lo[node, r])
                if e < 0.0:
                    out = True
                    break
            if out:
                continue
            child = links[node, 0]
            if child >= 0:
                stack[sp] = child
                stack[sp + 1] = child + 1
                sp += 2
                continue
            for tri in range(links[node, 1], links[node, 1] + links[node, 2]):
                if not tlen[tri] > 0.0:
                    continue
                side = ((p0 - tris[tri, 0, 0]) * tnorm[tri, 0] + (p1 - tris[tri, 0, 1]) * tnorm[tri, 1]
                        + (p2 - tris[tri, 0, 2]) * tnorm[tri, 2])
                if abs(side) <= THROUGH_P * tlen[tri] * scale:
                    continue  # its plane passes through P: a zero-area projection
                o = tobj[tri]
                if cullable[o] and side <= 0.0 and (o != pobj[idx] or (convex[o] and not pinside[idx])):
                    continue  # a back face of a closed mesh, P outside it
                out = False
                for k in range(npl):
                    all_out = True
                    for v in range(3):
                        e = (planes[k, 0] * tris[tri, v, 0] + planes[k, 1] * tris[tri, v, 1]
                             + planes[k, 2] * tris[tri, v, 2] + planes[k, 3])
                        if e >= 0.0:
                            all_out = False
                            break
                    if all_out:
                        out = True
                        break
                if out:
                    continue
                clipped += 1
                # heights above the light's plane; the slab 0 ≤ d ≤ top
                dmin, dmax = np.inf, -np.inf
                for v in range(3):
                    for r in range(3):
                        poly[v, r] = tris[tri, v, r]
                    d = ((poly[v, 0] - centre[0]) * ln_[0] + (poly[v, 1] - centre[1]) * ln_[1]
                         + (poly[v, 2] - centre[2]) * ln_[2])
                    pval[v] = d
                    dmin, dmax = min(dmin, d), max(dmax, d)
                if dmax <= 0.0 or dmin >= top:
                    continue
                nv = _clip3(poly, pval, 3, 0.0, poly2, pval2, True)
                if nv < 3:
                    continue
                nv = _clip3(poly2, pval2, nv, top, poly, pval, False)
                if nv < 3:
                    continue
                # the frustum's side planes through P (around the culling polygon, just outside
                # the light): what remains projects inside it, to bounded coordinates, and no
                # point near P's parallel plane is projected far away (ill-conditioned s)
                for k in range(nc):
                    for v in range(nv):
                        hv[v] = ((poly[v, 0] - p0) * planes[k, 0] + (poly[v, 1] - p1) * planes[k, 1]
                                 + (poly[v, 2] - p2) * planes[k, 2])
                    nv = _clip3(poly, hv, nv, 0.0, poly2, pval2, True)
                    for v in range(nv):
                        for r in range(3):
                            poly[v, r] = poly2[v, r]
                    if nv < 3:
                        break
                if nv < 3:
                    continue
                # P's upper half-space, vertices within `snap` of the tangent plane snapped onto it
                anyup = False
                for v in range(nv):
                    h = (poly[v, 0] - p0) * n0 + (poly[v, 1] - p1) * n1 + (poly[v, 2] - p2) * n2
                    if abs(h) <= snap:
                        h = 0.0
                    hv[v] = h
                    anyup = anyup or h > 0.0
                if not anyup:
                    continue
                # heights go with the points: carry d through the horizon clip by clipping d's copy
                nh = _clip3(poly, hv, nv, 0.0, poly2, pval2, True)
                if nh < 3:
                    continue
                # project from P onto the light's plane; 2D (t, b) about the centre
                if npoly == px.shape[0]:
                    overflow = True  # more polygons than the buffers hold: reported by the caller
                    break
                base = npoly
                cnt = 0
                for v in range(nh):
                    d = ((poly2[v, 0] - centre[0]) * ln_[0] + (poly2[v, 1] - centre[1]) * ln_[1]
                         + (poly2[v, 2] - centre[2]) * ln_[2])
                    s = dp / (dp - d)
                    y0 = p0 + s * (poly2[v, 0] - p0) - centre[0]
                    y1 = p1 + s * (poly2[v, 1] - p1) - centre[1]
                    y2 = p2 + s * (poly2[v, 2] - p2) - centre[2]
                    u = y0 * lt[0] + y1 * lt[1] + y2 * lt[2]
                    w = y0 * lb[0] + y1 * lb[1] + y2 * lb[2]
                    if cnt > 0 and u == px[base, cnt - 1] and w == py[base, cnt - 1]:
                        continue
                    px[base, cnt], py[base, cnt] = u, w
                    pval[cnt] = 1.0 if pval2[v] == 0.0 else 0.0  # on the horizon
                    cnt += 1
                while cnt > 1 and px[base, cnt - 1] == px[base, 0] and py[base, cnt - 1] == py[base, 0]:
                    cnt -= 1
                if cnt < 3:
                    continue
                sa = 0.0
                x0, y0_, x1, y1_ = np.inf, np.inf, -np.inf, -np.inf
                for v in range(cnt):
                    l = v + 1 if v + 1 < cnt else 0
                    sa += px[base, v] * py[base, l] - px[base, l] * py[base, v]
                    x0, x1 = min(x0, px[base, v]), max(x1, px[base, v])
                    y0_, y1_ = min(y0_, py[base, v]), max(y1_, py[base, v])
                if sa == 0.0 or x0 >= bx1 or x1 <= bx0 or y0_ >= by1 or y1_ <= by0:
                    continue
                if sa < 0.0:  # a back-facing triangle projects clockwise: reverse
                    for v in range(cnt // 2):
                        w = cnt - 1 - v
                        px[base, v], px[base, w] = px[base, w], px[base, v]
                        py[base, v], py[base, w] = py[base, w], py[base, v]
                        pval[v], pval[w] = pval[w], pval[v]
                for v in range(cnt):
                    l = v + 1 if v + 1 < cnt else 0
                    ph[base, v] = pval[v] == 1.0 and pval[l] == 1.0
                pn[base] = cnt
                box[base, 0], box[base, 1], box[base, 2], box[base, 3] = x0, y0_, x1, y1_
                npoly += 1
                # the visible part L' inside this one polygon: the point is in the umbra
                inside = True
                for k in range(m):
                    for v in range(cnt):
                        l = v + 1 if v + 1 < cnt else 0
                        ex, ey = px[base, l] - px[base, v], py[base, l] - py[base, v]
                        if ex * (lpy[k] - py[base, v]) - ey * (lpx[k] - px[base, v]) < 0.0:
                            inside = False
                            break
                    if not inside:
                        break
                if inside:
                    umbra = True
                    break
        cand[idx] = clipped
        if overflow:
            cand[idx] = -1
            vout[idx] = np.nan
            continue
        if umbra:
            vout[idx] = 0.0
            continue
        if npoly == 0:
            vout[idx] = area_above / light_area
            continue
        hidden = union_area(px, py, pn, ph, box, npoly, lx, ly, nl, s0, s1, BOX_SLACK * light_size, cstart, cpos,
                            citems, stamp)
        v = (area_above - hidden) / light_area
        vout[idx] = min(1.0, max(0.0, v))
