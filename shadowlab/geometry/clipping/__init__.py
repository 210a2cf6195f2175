"""Exact shadow polygons in object space: every receiver triangle clipped against the shadow of
every caster triangle from one light, by three interchangeable back-ends behind one entry point,
:func:`fragment_triangles` (``clipper=``, :data:`CLIPPERS`).

The contract every back-end keeps: the same fragments, bit for bit, in the same order (caster
runs in order, pairs caster-major and receiver-ascending, each fragment fan-triangulated) — each
forms every quantity by the same IEEE operations on the same operands as the one-pair reference,
so the choice changes the time, never the shadow. tests/geometry/test_batch_clipping.py holds
them to each other.

- :mod:`.scalar` — the one-pair clipper (Sutherland–Hodgman against the caster's shadow frustum,
  with an explicit tolerance ε): the reference, a Python loop.
- :mod:`.batch` — the same clipping on numpy padded arrays for many pairs at once, after a bulk
  culling (:func:`candidate_pairs`) of the (receiver, caster) pairs.
- :mod:`.compiled` — culling and clipping in one numba loop that never holds the pairs: the
  default, several times faster than the batch back-end.

The runs of casters are shared among threads (the result does not depend on how many); the
fragments held are bounded by ``memory_limit`` (:class:`FragmentMemoryError` beyond it).
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..frusta import side_planes
from ..triangles import triangle_planes
from ..vectors import dot3
from . import batch as batch_
from . import scalar

#: Receiver/caster pair tests of the bulk culling per step (bounds its temporaries, ~200 MB).
PAIR_TESTS_PER_STEP = 1 << 22
#: Candidate pairs clipped together (bounds the batch clipper's temporaries, ~150 MB).
CLIP_BATCH = 1 << 16
#: The preprocessing's back-ends, fastest first: compiled (numba) culling and clipping, numpy
#: batch clipping, the one-pair clipper in a Python loop (the reference). Same fragments.
CLIPPERS = ("compiled", "batch", "scalar")

#: Bytes a fragment triangle holds while the fragments are gathered: float64 vertices (72),
#: their float32 copy (36) and the receiver ids (12).
BYTES_PER_FRAGMENT_TRIANGLE = 120


class FragmentMemoryError(MemoryError):
    """The fragments outgrew the ``memory_limit`` :func:`fragment_triangles` was given."""


@dataclass
class FragmentTriangles:
    """The exact shadow of one light as triangles: ``triangles`` (T, 3, 3) float64, the index
    into the receiver triangles (T,) each lies on, and how many candidate pairs were clipped and
    how many gave a fragment."""

    triangles: np.ndarray
    receiver: np.ndarray
    pairs: int
    fragments: int


def candidate_pairs(rec: np.ndarray, cas: np.ndarray, light_h: np.ndarray, eps: float,
                    casters: slice | None = None) -> np.ndarray:
    """(receiver, caster) index pairs (N, 2), caster-major and receiver-ascending, whose shadow
    and receiver can overlap, culled in bulk and conservatively: some receiver vertex behind (or
    on) the caster's plane, and no side plane of the caster's frustum with every receiver vertex
    outside it. ``casters`` restricts the test to a range of caster triangles (indices stay
    global).

    The same pairs as testing the three vertices of every receiver against every caster's four
    planes (tests/geometry/test_batch_clipping.py holds it to that), found in two stages: each receiver's
    bounding sphere against the four planes (one float32 matrix product for all pairs), which
    only drops pairs the vertex test drops too, then the vertex test on the pairs left."""
    casters = casters or slice(0, len(cas))
    c0 = casters.start or 0
    cas = cas[casters]
    if len(rec) == 0 or len(cas) == 0:
        return np.zeros((0, 2), np.int64)
    n, d = triangle_planes(cas)
    sign = np.where(n @ light_h[:3] + d * light_h[3] >= 0, 1.0, -1.0)  # light on the positive side
    planes = side_planes(cas, light_h)  # (C, 3, 4): the frustum's side planes, inward
    # Stage 1: spheres (centre q, radius r) around the receivers. For a unit normal,
    # n·v + d ≤ n·q + d + r for every vertex v, so a sphere wholly outside a plane (or wholly
    # in front of the caster) has all its vertices there. The product runs in float32 (half the
    # memory traffic of the largest array). Its rounding is below 6 float32 ulps of
    # |n|·|q| + |d| per value, and the radius's below 2 √3 ulps of the largest coordinate, so
    # ``slack``, 64 ulps of the largest coordinate or offset, keeps the sphere test from ever
    # dropping a pair the vertex test keeps.
    centre = rec.mean(axis=1)
    radius = np.sqrt(np.max(np.sum((rec - centre[:, None]) ** 2, axis=2), axis=1))
    front = np.concatenate([sign[:, None] * n, (sign * d)[:, None]], axis=1)  # (C, 4), light side positive
    stacked = np.concatenate([front[:, None], planes], axis=1).reshape(-1, 4)  # (4C, 4)
    magnitude = 1.0 + max(float(np.abs(rec).max()), float(np.abs(stacked[:, 3]).max()))
    slack = 64 * float(np.finfo(np.float32).eps) * magnitude
    homogeneous = np.concatenate([centre, np.ones((len(rec), 1))], axis=1).T.astype(np.float32)
    value = (stacked.astype(np.float32) @ homogeneous).reshape(len(cas), 4, len(rec))
    reach = (radius + slack).astype(np.float32)
    maybe = value[:, 0] < eps + reach  # some point of the sphere behind (or on) the caster's plane
    for k in (1, 2, 3):  # no side plane with the whole sphere outside
        maybe &= value[:, k] >= -(eps + reach)
    ci, ri = np.nonzero(maybe)
    # Stage 2: the vertex test on the pairs left (the definition above).
    v = rec[ri]  # (N, 3, 3)
    dist = dot3(front[ci, None, :3], v) + front[ci, 3, None]
    behind = (dist < eps).any(axis=1)
    side = dot3(planes[ci, :, None, :3], v[:, None]) + planes[ci, :, 3][:, :, None]
    outside = (side < -eps).all(axis=2).any(axis=1)
    keep = behind & ~outside
    return np.stack([ri[keep], ci[keep] + c0], axis=1)


def fragment_triangles(rec: np.ndarray, cas: np.ndarray, light_h: np.ndarray, eps: float,
                       clipper: str = "compiled", progress: Callable[[int, int], None] | None = None,
                       memory_limit: int | None = None, threads: int | None = None) -> FragmentTriangles:
    """Every receiver triangle (R, 3, 3) clipped against the shadow of every caster triangle
    (C, 3, 3) from ``light_h``: the bulk culling (:func:`candidate_pairs`) a run of casters at a
    time, each run's pairs clipped ``CLIP_BATCH`` at a time, so the pairs are never all held;
    the fragments are fan-triangulated in pair order.

    ``clipper='compiled'`` (the default) culls and clips each run of casters in one call of
    :func:`shadowlab.geometry.clipping.compiled.fragment_run`; ``'batch'`` uses
    :func:`candidate_pairs` and :func:`shadowlab.geometry.clipping.batch.shadow_fragments`;
    both share the runs of casters among ``threads`` threads (default: the cores this process
    may use; numpy and the compiled kernel work outside the GIL) — the result does not depend
    on how many; ``'scalar'``
    runs the one-pair :func:`~shadowlab.geometry.clipping.scalar.shadow_fragment` in a Python
    loop, on one thread (the reference: kept for tests and before/after experiments).
    ``progress(done, total)`` is called as the casters are done. The fragments may take at most
    ``memory_limit`` bytes (None: no limit; the technique passes a share of the memory
    available at its setup); beyond it :class:`FragmentMemoryError` says so."""
    if clipper not in CLIPPERS:
        raise ValueError(f"clipper must be one of {', '.join(CLIPPERS)}, not {clipper!r}")
    light_h = np.asarray(light_h, np.float64)
    threads = 1 if clipper == "scalar" else max(1, threads or len(os.sched_getaffinity(0)))
    step = max(1, PAIR_TESTS_PER_STEP // max(1, len(rec)))
    if threads > 1:  # at least two runs a thread, so that the threads finish together
        step = max(1, min(step, -(-len(cas) // (2 * threads))))
    starts = range(0, len(cas), step)

    if clipper == "compiled":
        culling = _CompiledCulling(rec, cas, light_h, eps)

    def one_run(c0: int):
        if clipper == "compiled":
            return (c0,) + culling.run(c0, min(c0 + step, len(cas)))
        found = candidate_pairs(rec, cas, light_h, eps, slice(c0, c0 + step))
        tris, owners, fragments = [], [], 0
        for b0 in range(0, len(found), CLIP_BATCH):
            batch = found[b0:b0 + CLIP_BATCH]
            t, row, n = _clip(rec, cas, batch, light_h, eps, clipper)
            tris.append(t)
            owners.append(batch[row, 0])
            fragments += n
        return c0, len(found), tris, owners, fragments

    tris, owners = [], []
    pairs = fragments = held = 0
    with ThreadPoolExecutor(max_workers=threads) as pool:
        for c0, n_pairs, t, o, n_frag in (pool.map(one_run, starts) if threads > 1 else map(one_run, starts)):
            pairs += n_pairs
            fragments += n_frag
            tris += t
            owners += o
            held += sum(len(x) for x in t) * BYTES_PER_FRAGMENT_TRIANGLE
            if memory_limit is not None and held > memory_limit:
                raise FragmentMemoryError(f"the exact shadow fragments outgrew {memory_limit / 2**30:.1f} GiB "
                                          f"after {pairs} candidate pairs")
            if progress is not None:
                progress(min(c0 + step, len(cas)), len(cas))
    triangles = np.concatenate(tris) if tris else np.zeros((0, 3, 3))
    receiver = np.concatenate(owners) if owners else np.zeros(0, np.int64)
    return FragmentTriangles(triangles, receiver, pairs, fragments)


class _CompiledCulling:
    """What the compiled kernel (:func:`shadowlab.geometry.clipping.compiled.fragment_run`)
    needs once per light: the casters' planes and frusta, the receivers' spheres."""

    def __init__(self, rec, cas, light_h, eps):
        from . import compiled as cc

        self.kernel = cc.fragment_run
        self.rec, self.cas = np.ascontiguousarray(rec, np.float64), np.ascontiguousarray(cas, np.float64)
        self.light_h, self.eps = np.ascontiguousarray(light_h, np.float64), float(eps)
        if len(rec) == 0 or len(cas) == 0:
            return
        n, d = triangle_planes(cas)
        sign = np.where(n @ light_h[:3] + d * light_h[3] >= 0, 1.0, -1.0)  # as in candidate_pairs
        self.front = np.ascontiguousarray(np.concatenate([sign[:, None] * n, (sign * d)[:, None]], axis=1))
        self.sides = np.ascontiguousarray(side_planes(cas, light_h))
        self.centre = rec.mean(axis=1)
        radius = np.sqrt(np.max(np.sum((rec - self.centre[:, None]) ** 2, axis=2), axis=1))
        # The sphere test in float64: its values round by a few ulps of |n|·|q| + |d|, the
        # radius by a few ulps of the largest coordinate; 64 ulps of the largest magnitude
        # keeps it from dropping a pair the vertex test keeps (see candidate_pairs).
        magnitude = 1.0 + max(float(np.abs(rec).max()), float(np.abs(self.front[:, 3]).max()),
                              float(np.abs(self.sides[..., 3]).max()))
        self.reach = radius + 64 * float(np.finfo(np.float64).eps) * magnitude

    def run(self, c0: int, c1: int):
        """Casters c0..c1: (pairs, [fan triangles], [their receivers], fragments)."""
        if len(self.rec) == 0 or len(self.cas) == 0:
            return 0, [], [], 0
        tris, owner, pairs, fragments = self.kernel(self.rec, self.cas, self.front, self.sides, self.centre,
                                                    self.reach, self.light_h, self.eps, c0, c1)
        return pairs, [tris], [owner], fragments


def _clip(rec, cas, batch, light_h, eps, clipper):
    """Fragments of the (receiver, caster) pairs ``batch`` (N, 2), fan-triangulated: triangles
    (T, 3, 3), the batch row (T,) of each, and how many pairs gave a fragment."""
    if clipper == "batch":
        frags = batch_.shadow_fragments(batch_.full(rec[batch[:, 0]]), batch_.full(cas[batch[:, 1]]), light_h, eps)
        t, row = batch_.fan_triangles(frags)
        return t, row, int(np.count_nonzero(frags.count))
    t, row = [], []
    for k, (r, c) in enumerate(batch):
        frag, _ = scalar.shadow_fragment(rec[r], cas[c], light_h, eps)
        if len(frag):
            t.append(scalar.triangulate(frag))
            row.append(np.full(len(frag) - 2, k))
    t_all = np.concatenate(t) if t else np.zeros((0, 3, 3))
    return t_all, (np.concatenate(row) if row else np.zeros(0, np.int64)), len(t)
