"""The ground truth's per-ray arithmetic in compiled code (numba), bit for bit the numpy it
replaces.

Issue 27, "a faster truth": the sampled soft truth, and the hard truth end to end at one light,
ran well below raw Embree's rays/s over the same rays (``experiments/gt_throughput.py``); the
difference was numpy work around the Embree calls.

What is compiled, and why: everything around the Embree calls that runs once per pixel or once
per light sample — the frame's exact hit points (:meth:`shadowlab.gpu.frame.Frame.compute_exact_points`),
the offset ray origins (:func:`shadowlab.truth.tracing.offset_points`), a rect light's jittered samples
(:meth:`shadowlab.scene.area_lights.RectLight.sample_for`), the sampled truth's horizon test and
segment set-up (:func:`shadowlab.truth.area.area_chunk_rays`) and its per-pixel count of
unoccluded rays, and the hard lights' shadow-ray directions
(:meth:`shadowlab.scene.lights.PointLight.shadow_rays` and the directional lights'). In numpy
each of those is a chain of (M, N, 3) temporaries, or a broadcast whose inner loop runs over
three elements per row; here each value is formed once, in a loop that touches every input
once, into output arrays allocated by numpy (whose allocator reuses freed memory: arrays
allocated inside a kernel page-fault fresh memory on every call, which cost more than the
arithmetic). The kernels release the GIL (``nogil``): the sampled truth's worker threads
overlap them with Embree, and the per-frame passes over every pixel run in row bands on the
cores (:func:`in_parts`).

Same bits: every value is formed by the same IEEE operations on the same operands, in the same
order, as the numpy expression it replaces (quoted at each kernel). numba does not contract
``a*b + c`` into fused multiply-adds unless asked (``fastmath`` is off), and ``error_model=
"numpy"`` makes x/0 give ±inf and 0/0 NaN as numpy does, instead of raising. One order is not
obvious: numpy's ``einsum("ij,ij->i", a, b)`` over three columns sums ``(a0·b0 + a2·b2) +
a1·b1`` (its two-lane SIMD inner loop; :func:`dot3_einsum`), and the kernels that replace an
``einsum`` use that order; tests/truth/test_compiled_truth.py and tests/truth/test_ground_truth.py hold
every kernel to its numpy reference bit for bit.

The random stream is not touched: the jitter is still drawn by numpy's Generator
(``rng.random((M, N, 2))``), so the samples are the same numbers as before.

The kernels are compiled on first use and cached on disk (``cache=True``); :func:`warm` compiles
or loads them once per process, outside any timed region.
"""
from __future__ import annotations

import time

import numpy as np

from ..geometry.rows import fill_rows, rect_samples, vector_minus_rows
from ..util.compiled import JIT as _JIT
from ..util.compiled import in_parts, njit, split  # noqa: F401  (the truth's passes split with these)

@njit(inline="always", **_JIT)
def dot3_einsum(a0, a1, a2, b0, b1, b2):
    """a·b summed as numpy's ``einsum("ij,ij->i")`` sums three columns: (a0 b0 + a2 b2) + a1 b1."""
    return (a0 * b0 + a2 * b2) + a1 * b1


@njit(inline="always", **_JIT)
def _np_maximum(a, b):
    """``np.maximum(a, b)`` on two floats: NaN if either is NaN."""
    return a if (a >= b or a != a) else b


@njit(inline="always", **_JIT)
def _offset_point(p0, p1, p2, n0, n1, n2, extent, offset_scale, out, i):
    """Writes float32 ``float32(N · (offset_scale · max(|P|∞, extent)) + P)`` into ``out[i]``
    (the truth's ray origin, :func:`shadowlab.truth.tracing.offset_points`): the row maximum taken
    column by column (NaN-propagating, like ``np.maximum``), the product and sum in float64,
    rounded once. Returns 1 if the origin holds a NaN, else 0."""
    s = _np_maximum(_np_maximum(_np_maximum(abs(p0), abs(p1)), abs(p2)), extent) * offset_scale
    o0 = n0 * s + p0
    o1 = n1 * s + p1
    o2 = n2 * s + p2
    out[i, 0], out[i, 1], out[i, 2] = np.float32(o0), np.float32(o1), np.float32(o2)
    return 1 if (o0 != o0 or o1 != o1 or o2 != o2) else 0


@njit(**_JIT)
def covered_above_rows(covered, out):
    """Writes into ``out`` (H + 1,) int64 the covered pixels above each row of ``covered``
    (H, W) bool and, last, their total: where each row band of :func:`exact_points` starts
    (``concatenate([[0], cumsum(count_nonzero(covered, axis=1))])`` in one pass)."""
    total = 0
    for r in range(covered.shape[0]):
        out[r] = total
        for c in range(covered.shape[1]):
            if covered[r, c]:
                total += 1
    out[covered.shape[0]] = total


@njit(**_JIT)
def exact_points(covered, triangle_id, object_id, col_term, row_term, unit, numerator, tri_valid, eye,
                 extent, offset_scale, r0, r1, i0, index, objects, points, normals, valid, origins):
    """Exact float64 hits of the pixel-centre camera rays with the planes of the triangles the
    G-buffer saw, at the covered pixels of rows r0..r1 in row-major order, written from entry
    ``i0`` (the covered pixels above row r0) into ``index`` (M,) int64 (into the flattened
    image), ``objects`` (M,) (the pixel's ``object_id``), ``points`` (M, 3), ``normals`` (M, 3)
    turned to the camera, ``valid`` (M,) bool and — in the same pass, while the point is in
    registers — the truth's float32 ray ``origins`` (M, 3) at ``offset_scale``
    (:func:`_offset_point`); M = the number of covered pixels. Row bands are independent
    (:func:`in_parts`). Returns how many origins hold a NaN (the caller then forms all of them
    with the numpy formula, :func:`offset_points`).

    Bit for bit :func:`shadowlab.gpu.frame.plane_hits` on the rays ``col_term[col] + row_term[row]``:
    ``denom = einsum(d, n)``, ``t = numerator[tri] / denom``, ``p = d·t + eye``, the normal
    negated where denom > 0, valid = non-degenerate triangle & t > 0 & t < ∞."""
    w = covered.shape[1]
    i = i0
    bad = 0
    for r in range(r0, r1):
        for c in range(w):
            if not covered[r, c]:
                continue
            tri = triangle_id[r, c]
            d0 = col_term[c, 0] + row_term[r, 0]
            d1 = col_term[c, 1] + row_term[r, 1]
            d2 = col_term[c, 2] + row_term[r, 2]
            n0, n1, n2 = unit[tri, 0], unit[tri, 1], unit[tri, 2]
            denom = dot3_einsum(d0, d1, d2, n0, n1, n2)
            t = numerator[tri] / denom
            index[i] = r * w + c
            objects[i] = object_id[r, c]
            p0 = d0 * t + eye[0]
            p1 = d1 * t + eye[1]
            p2 = d2 * t + eye[2]
            points[i, 0], points[i, 1], points[i, 2] = p0, p1, p2
            if denom > 0:
                n0, n1, n2 = -n0, -n1, -n2
            normals[i, 0], normals[i, 1], normals[i, 2] = n0, n1, n2
            valid[i] = tri_valid[tri] and t > 0 and t < np.inf
            bad += _offset_point(p0, p1, p2, n0, n1, n2, extent, offset_scale, origins, i)
            i += 1
    return bad


@njit(**_JIT)
def offset_points(points, normals, extent, offset_scale, out):
    """Writes float32 ``float32(N · (offset_scale · max(|P|∞, extent)) + P)`` into ``out`` (K, 3):
    the row maximum taken column by column as :func:`shadowlab.truth.tracing.offset_points` takes it
    (NaN-propagating, like ``np.maximum``), the product and sum in float64, rounded once.
    Returns how many rows hold a NaN; given any (a point with no hit), the caller uses the
    numpy formula instead: which NaN (its sign) an operation on two NaNs returns depends on the
    operand order the compiler picks (and in numpy on the row's place in the array), and the
    reference's bits are pinned NaNs included."""
    bad = 0
    for i in range(points.shape[0]):
        bad += _offset_point(points[i, 0], points[i, 1], points[i, 2], normals[i, 0], normals[i, 1], normals[i, 2],
                             extent, offset_scale, out, i)
    return bad


@njit(**_JIT)
def segment_rays(samples, facing, points, normals, origins, counts, org, dirs):
    """The sampled truth's shadow segments for M points and their N light samples each: writes
    the live samples per point into ``counts`` (M,) int64 and the rays into ``org`` and ``dirs``
    (at least K × 3, float32), the rays of point i consecutive and in sample order (point-major,
    as ``np.nonzero`` orders them); returns K.

    A sample is live if ``facing[i, j]`` and it lies strictly above the point's tangent plane:
    ``einsum(samples − point, normal) > 0`` (:func:`shadowlab.scene.area_lights.above_horizon`).
    Its ray starts at the point's float32 origin, direction ``float32(sample − float64(origin))``
    (reaching the sample at t = 1) — the numpy reference's ``(target − org).astype(float32)``."""
    m, n = samples.shape[0], samples.shape[1]
    kk = 0
    for i in range(m):
        p0, p1, p2 = points[i, 0], points[i, 1], points[i, 2]
        n0, n1, n2 = normals[i, 0], normals[i, 1], normals[i, 2]
        o0, o1, o2 = origins[i, 0], origins[i, 1], origins[i, 2]
        f0, f1, f2 = np.float64(o0), np.float64(o1), np.float64(o2)
        c = 0
        for j in range(n):
            if not facing[i, j]:
                continue
            s0, s1, s2 = samples[i, j, 0], samples[i, j, 1], samples[i, j, 2]
            if not dot3_einsum(s0 - p0, s1 - p1, s2 - p2, n0, n1, n2) > 0:
                continue
            org[kk, 0], org[kk, 1], org[kk, 2] = o0, o1, o2
            dirs[kk, 0] = np.float32(s0 - f0)
            dirs[kk, 1] = np.float32(s1 - f1)
            dirs[kk, 2] = np.float32(s2 - f2)
            kk += 1
            c += 1
        counts[i] = c
    return kk


@njit(**_JIT)
def unoccluded_counts(counts, hit, out):
    """Writes per point (M,) int64 into ``out`` how many of its ``counts[i]`` consecutive rays
    Embree's occlusion query left unblocked (``hit == -1``, embreex's mark for a ray that
    reached its tfar)."""
    k = 0
    for i in range(counts.shape[0]):
        free = 0
        for _ in range(counts[i]):
            if hit[k] == -1:
                free += 1
            k += 1
        out[i] = free


_warm_ms: float | None = None


def warm() -> float:
    """Compile the kernels, or load them from numba's on-disk cache, once per process, so that
    no timed pass pays for it; returns the milliseconds that took (0 after the first call)."""
    global _warm_ms
    if _warm_ms is not None:
        return 0.0
    t0 = time.perf_counter()
    f64, f32 = np.zeros((1, 3)), np.zeros((1, 3), np.float32)
    exact_points(np.ones((1, 1), bool), np.zeros((1, 1), np.int32), np.zeros((1, 1), np.int32), f64, f64, f64 + 1,
                 np.ones(1), np.ones(1, bool), np.zeros(3), 1.0, 1e-6, 0, 1, 0, np.zeros(1, np.int64),
                 np.zeros(1, np.int32), f64.copy(), f64.copy(), np.zeros(1, bool), f32.copy())
    covered_above_rows(np.ones((1, 1), bool), np.zeros(2, np.int64))
    offset_points(f64, f64, 1.0, 1e-6, f32.copy())
    s = np.zeros((1, 1, 3))
    rect_samples(np.zeros((1, 1, 2)), np.zeros((1, 2)), np.ones((1, 2)), np.zeros(3), np.ones(3), np.ones(3), s)
    counts = np.zeros(1, np.int64)
    segment_rays(s, np.ones((1, 1), bool), f64, f64 + 1, f32, counts, f32.copy(), f32.copy())
    unoccluded_counts(counts, np.full(1, -1, np.int32), counts.copy())
    vector_minus_rows(np.zeros(3, np.float32), f32, f32.copy())
    fill_rows(np.zeros(3, np.float32), f32.copy())
    _warm_ms = 1e3 * (time.perf_counter() - t0)
    return _warm_ms
