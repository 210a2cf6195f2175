"""Exact shadow polygons, culled and clipped in compiled code (numba): the culling of
:func:`shadowlab.geometry.clipping.candidate_pairs` and the clipping of
:func:`shadowlab.geometry.clipping.scalar.shadow_fragment`, for a run of casters against every
receiver, in one pass that never holds the pairs.

Why numba here, after the numpy batch clipper (:mod:`.batch`): the padded-array
clipper spends most of its time building temporaries for tens of thousands of pairs, and the
bulk culling tests every (receiver, caster) pair — millions — as dense matrices. A compiled loop
touches each pair once with early exits and keeps a polygon in a few registers, which is what
the issue's 100× asks for on two cores. numba compiles from the same Python source (no C
toolchain on the user's machine), caches the machine code on disk (``cache=True``: the first
call on a fresh install compiles for a few seconds, later processes load it), and releases the
GIL (``nogil``), so the technique's threads share the casters.

Same bits: every quantity is formed by the same IEEE operations on the same operands, in the
same order, as in the one-pair reference — :func:`~shadowlab.geometry.vectors.dot3` and
:func:`~shadowlab.geometry.vectors.dot4` sums left to right, Newell's normal and the vertex
centre summed in vertex order, the frustum planes as
:func:`~shadowlab.geometry.frusta.side_planes` builds them. numba does not contract ``a*b + c``
into fused multiply-adds unless asked (``fastmath`` is off), so the fragments equal the scalar
clipper's bit for bit; ``tests/geometry/test_batch_clipping.py`` holds the three back-ends to it.

Polygons live in fixed buffers of :data:`MAX_VERTS` vertices (see there why that is enough).
"""
from __future__ import annotations

import time

import numpy as np
from numba import njit

#: Largest input polygon (receiver or caster) the clipper takes; the scenes give it triangles.
MAX_POLYGON = 8
#: Vertex slots of a polygon buffer. A convex polygon gains at most one vertex per split: the
#: caster (≤ 8) cut by the receiver's plane has ≤ 9 edges, so the receiver (≤ 8) meets ≤ 10
#: splits and ends with ≤ 18 vertices.
MAX_VERTS = 32


@njit(cache=True, nogil=True, inline="always")
def _dot3(a0, a1, a2, b0, b1, b2):
    return a0 * b0 + a1 * b1 + a2 * b2


@njit(cache=True, nogil=True)
def _plane_of(poly, k, out):
    """Newell's plane of poly[:k] into out (4,) (unit n, d); zero for a degenerate polygon."""
    n0 = n1 = n2 = 0.0
    c0 = c1 = c2 = 0.0
    for i in range(k):
        j = i + 1 if i + 1 < k else 0
        v0, v1, v2 = poly[i, 0], poly[i, 1], poly[i, 2]
        b0, b1, b2 = poly[j, 0], poly[j, 1], poly[j, 2]
        n0 += (v1 - b1) * (v2 + b2)
        n1 += (v2 - b2) * (v0 + b0)
        n2 += (v0 - b0) * (v1 + b1)
        c0 += v0
        c1 += v1
        c2 += v2
    count = max(k, 1)
    c0 /= count
    c1 /= count
    c2 /= count
    length = np.sqrt(_dot3(n0, n1, n2, n0, n1, n2))
    if length > 0:
        n0 /= length
        n1 /= length
        n2 /= length
        out[0], out[1], out[2] = n0, n1, n2
        out[3] = -_dot3(n0, n1, n2, c0, c1, c2)
    else:
        out[0] = out[1] = out[2] = out[3] = 0.0


@njit(cache=True, nogil=True)
def _area(poly, k):
    """Area of the planar polygon poly[:k] (half the norm of the summed cross products)."""
    if k < 3:
        return 0.0
    t0 = t1 = t2 = 0.0
    for i in range(k):
        j = i + 1 if i + 1 < k else 0
        a0, a1, a2 = poly[i, 0], poly[i, 1], poly[i, 2]
        b0, b1, b2 = poly[j, 0], poly[j, 1], poly[j, 2]
        t0 += a1 * b2 - a2 * b1
        t1 += a2 * b0 - a0 * b2
        t2 += a0 * b1 - a1 * b0
    return 0.5 * np.sqrt(_dot3(t0, t1, t2, t0, t1, t2))


@njit(cache=True, nogil=True)
def _split(poly, k, plane, eps, outside, out, d, side, scratch):
    """The part of poly[:k] with distance ≥ −ε (or, with ``outside``, ≤ ε) to ``plane`` into
    out; returns its vertex count (0: empty). scalar.split, one part."""
    any_in = False
    any_out = False
    for i in range(k):
        d[i] = _dot3(poly[i, 0], poly[i, 1], poly[i, 2], plane[0], plane[1], plane[2]) + plane[3]
        s = 1 if d[i] > eps else (-1 if d[i] < -eps else 0)
        side[i] = s
        if s < 0:
            any_out = True
        if s > 0:
            any_in = True
    whole = (not any_out) if not outside else (any_out and not any_in)
    nothing = (any_out and not any_in) if not outside else (not any_out)
    if whole:
        for i in range(k):
            out[i, 0], out[i, 1], out[i, 2] = poly[i, 0], poly[i, 1], poly[i, 2]
        return k
    if nothing:
        return 0
    m = 0  # the part's vertices and crossings, untidied, into scratch
    for i in range(k):
        j = i + 1 if i + 1 < k else 0
        sp = side[i]
        if (sp <= 0) if outside else (sp >= 0):
            scratch[m, 0], scratch[m, 1], scratch[m, 2] = poly[i, 0], poly[i, 1], poly[i, 2]
            m += 1
        if sp * side[j] < 0:
            t = d[i] / (d[i] - d[j])
            for c in range(3):
                scratch[m, c] = poly[i, c] + t * (poly[j, c] - poly[i, c])
            m += 1
    # _tidy: drop vertices within ε of their (untidied) predecessor; under 3 left → empty.
    n = 0
    for i in range(m):
        p = i - 1 if i > 0 else m - 1
        e0 = scratch[i, 0] - scratch[p, 0]
        e1 = scratch[i, 1] - scratch[p, 1]
        e2 = scratch[i, 2] - scratch[p, 2]
        if np.sqrt(_dot3(e0, e1, e2, e0, e1, e2)) > eps:
            out[n, 0], out[n, 1], out[n, 2] = scratch[i, 0], scratch[i, 1], scratch[i, 2]
            n += 1
    return n if n >= 3 else 0


@njit(cache=True, nogil=True)
def _side_planes(poly, k, light_h, planes):
    """frusta.side_planes of poly[:k] into planes[:k] (inward, unit n; zero when degenerate)."""
    point = light_h[3] != 0
    l0 = l1 = l2 = 0.0
    if point:
        l0, l1, l2 = light_h[0] / light_h[3], light_h[1] / light_h[3], light_h[2] / light_h[3]
    c0 = c1 = c2 = 0.0
    for i in range(k):
        c0 += poly[i, 0]
        c1 += poly[i, 1]
        c2 += poly[i, 2]
    c0 /= k
    c1 /= k
    c2 /= k
    for i in range(k):
        j = i + 1 if i + 1 < k else 0
        if point:
            a0, a1, a2 = poly[i, 0] - l0, poly[i, 1] - l1, poly[i, 2] - l2
            b0, b1, b2 = poly[j, 0] - l0, poly[j, 1] - l1, poly[j, 2] - l2
        else:
            a0, a1, a2 = poly[j, 0] - poly[i, 0], poly[j, 1] - poly[i, 1], poly[j, 2] - poly[i, 2]
            b0, b1, b2 = light_h[0], light_h[1], light_h[2]
        n0 = a1 * b2 - a2 * b1
        n1 = a2 * b0 - a0 * b2
        n2 = a0 * b1 - a1 * b0
        length = np.sqrt(_dot3(n0, n1, n2, n0, n1, n2))
        if length > 0:
            n0 /= length
            n1 /= length
            n2 /= length
        else:
            n0 = n1 = n2 = 0.0
        d = -_dot3(n0, n1, n2, poly[i, 0], poly[i, 1], poly[i, 2])
        inward = -1.0 if _dot3(n0, n1, n2, c0, c1, c2) + d < 0 else 1.0
        planes[i, 0], planes[i, 1], planes[i, 2], planes[i, 3] = n0 * inward, n1 * inward, n2 * inward, d * inward


@njit(cache=True, nogil=True)
def _light_value(plane, light_h):
    return plane[0] * light_h[0] + plane[1] * light_h[1] + plane[2] * light_h[2] + plane[3] * light_h[3]


@njit(cache=True, nogil=True)
def _fragment(receiver, kr, caster, kc, light_h, eps, work, out):
    """shadow_fragment's fragment of convex receiver[:kr] behind convex caster[:kc] into out;
    returns its vertex count (0: no shadow). ``work`` holds the scratch buffers."""
    pr, pc, d, side, scratch, cast_part, current, nxt, planes = work
    _plane_of(receiver, kr, pr)
    _plane_of(caster, kc, pc)
    if (pr[0] == 0 and pr[1] == 0 and pr[2] == 0) or (pc[0] == 0 and pc[1] == 0 and pc[2] == 0):
        return 0  # degenerate polygon
    tol = eps * (1.0 if light_h[3] == 0 else abs(light_h[3]))
    value_r = _light_value(pr, light_h)
    if abs(value_r) <= tol:
        return 0  # the light lies in the receiver's plane
    if value_r < 0:
        for c in range(4):
            pr[c] = -pr[c]
    value_c = _light_value(pc, light_h)
    if value_c < 0:
        for c in range(4):
            pc[c] = -pc[c]
    if abs(value_c) <= tol:
        return 0  # the light lies in the caster's plane: edge-on
    kc = _split(caster, kc, pr, eps, False, cast_part, d, side, scratch)
    if kc == 0 or _area(cast_part, kc) <= eps * eps:
        return 0
    k = _split(receiver, kr, pc, eps, True, current, d, side, scratch)
    if k == 0 or _area(current, k) <= eps * eps:
        return 0
    _side_planes(cast_part, kc, light_h, planes)
    for e in range(kc):
        k = _split(current, k, planes[e], eps, False, nxt, d, side, scratch)
        current, nxt = nxt, current
        if k == 0:
            return 0
    if _area(current, k) <= eps * eps:
        return 0
    for i in range(k):
        out[i, 0], out[i, 1], out[i, 2] = current[i, 0], current[i, 1], current[i, 2]
    return k


@njit(cache=True, nogil=True)
def _work():
    """Scratch buffers for :func:`_fragment`."""
    return (np.empty(4), np.empty(4), np.empty(MAX_VERTS), np.empty(MAX_VERTS, np.int64),
            np.empty((2 * MAX_VERTS, 3)), np.empty((MAX_VERTS, 3)), np.empty((MAX_VERTS, 3)),
            np.empty((MAX_VERTS, 3)), np.empty((MAX_VERTS, 4)))


@njit(cache=True, nogil=True)
def _one_fragment(receiver, caster, light_h, eps):
    out = np.empty((MAX_VERTS, 3))
    k = _fragment(receiver, len(receiver), caster, len(caster), light_h, eps, _work(), out)
    return out[:k].copy()


def shadow_fragment(receiver: np.ndarray, caster: np.ndarray, light_h: np.ndarray, eps: float) -> np.ndarray:
    """The compiled clipper on one pair of convex polygons (K, 3) and (J, 3), K, J ≤
    :data:`MAX_POLYGON`: the fragment (M, 3) of
    :func:`shadowlab.geometry.clipping.scalar.shadow_fragment` ((0, 3) when there is no shadow),
    for tests that compare the back-ends polygon by polygon."""
    receiver, caster = np.ascontiguousarray(receiver, np.float64), np.ascontiguousarray(caster, np.float64)
    if len(receiver) > MAX_POLYGON or len(caster) > MAX_POLYGON:
        raise ValueError(f"the compiled clipper takes polygons of at most {MAX_POLYGON} vertices")
    if len(receiver) < 3 or len(caster) < 3:
        return np.zeros((0, 3))
    return _one_fragment(receiver, caster, np.ascontiguousarray(light_h, np.float64), float(eps))


_warm_ms: float | None = None


def warm() -> float:
    """Compile the kernel, or load it from numba's on-disk cache, once per process, so that the
    preprocessing's time is the work's; returns the milliseconds that took (0 after the first
    call). A fresh install compiles for several seconds; later processes load in a fraction."""
    global _warm_ms
    if _warm_ms is not None:
        return 0.0
    t0 = time.perf_counter()
    tri = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    planes = np.zeros((1, 3, 4))
    fragment_run(tri[None], tri[None] + [0, 0, 1], np.array([[0.0, 0, -1, 1]]), planes, tri.mean(0)[None],
                 np.ones(1), np.array([0.0, 0, 5, 1]), 1e-9, 0, 1)
    _warm_ms = 1e3 * (time.perf_counter() - t0)
    return _warm_ms


@njit(cache=True, nogil=True)
def fragment_run(rec, cas, front, sides, centre, reach, light_h, eps, c0, c1):
    """Cull and clip casters c0..c1 of ``cas`` (C, 3, 3) against every receiver of ``rec``
    (R, 3, 3), float64. ``front`` (C, 4): each caster's plane with the light on its positive
    side; ``sides`` (C, 3, 4): its frustum's inward side planes; ``centre`` (R, 3) and
    ``reach`` (R,): each receiver's bounding sphere, radius plus the rounding slack.

    A pair is a candidate when some receiver vertex is behind (or within ε of) the caster's
    plane and no side plane has all three vertices more than ε outside — decided first on the
    sphere (which can only drop pairs the vertex test drops), then on the vertices. Candidates
    are clipped in caster-major, receiver-ascending order. Returns the fan triangles (T, 3, 3)
    float64, the receiver (T,) of each, the number of candidate pairs and of fragments."""
    n_rec = len(rec)
    cap = 1024
    tris = np.empty((cap, 3, 3))
    owner = np.empty(cap, np.int64)
    n_tris = 0
    pairs = 0
    fragments = 0
    work = _work()
    frag = np.empty((MAX_VERTS, 3))
    for c in range(c0, c1):
        f0, f1, f2, f3 = front[c, 0], front[c, 1], front[c, 2], front[c, 3]
        for r in range(n_rec):
            q0, q1, q2, rr = centre[r, 0], centre[r, 1], centre[r, 2], reach[r]
            # Stage 1, the sphere: wholly in front of the caster, or wholly outside a side plane.
            if _dot3(f0, f1, f2, q0, q1, q2) + f3 >= eps + rr:
                continue
            out_sphere = False
            for e in range(3):
                if _dot3(sides[c, e, 0], sides[c, e, 1], sides[c, e, 2], q0, q1, q2) + sides[c, e, 3] < -(eps + rr):
                    out_sphere = True
                    break
            if out_sphere:
                continue
            # Stage 2, the vertices (the definition of a candidate pair).
            behind = False
            for v in range(3):
                if _dot3(f0, f1, f2, rec[r, v, 0], rec[r, v, 1], rec[r, v, 2]) + f3 < eps:
                    behind = True
                    break
            if not behind:
                continue
            outside = False
            for e in range(3):
                all_out = True
                for v in range(3):
                    s = _dot3(sides[c, e, 0], sides[c, e, 1], sides[c, e, 2],
                              rec[r, v, 0], rec[r, v, 1], rec[r, v, 2]) + sides[c, e, 3]
                    if not s < -eps:
                        all_out = False
                        break
                if all_out:
                    outside = True
                    break
            if outside:
                continue
            pairs += 1
            k = _fragment(rec[r], 3, cas[c], 3, light_h, eps, work, frag)
            if k == 0:
                continue
            fragments += 1
            if n_tris + k - 2 > cap:
                cap = 2 * cap + k
                grown = np.empty((cap, 3, 3))
                grown[:n_tris] = tris[:n_tris]
                tris = grown
                grown_owner = np.empty(cap, np.int64)
                grown_owner[:n_tris] = owner[:n_tris]
                owner = grown_owner
            for i in range(1, k - 1):  # fan triangulation (scalar.triangulate)
                for cc in range(3):
                    tris[n_tris, 0, cc] = frag[0, cc]
                    tris[n_tris, 1, cc] = frag[i, cc]
                    tris[n_tris, 2, cc] = frag[i + 1, cc]
                owner[n_tris] = r
                n_tris += 1
    return tris[:n_tris].copy(), owner[:n_tris].copy(), pairs, fragments
