"""Exact shadow polygons for many (receiver, caster) pairs at once: the clipping of
:func:`shadowlab.geometry.clipping.scalar.shadow_fragment`, step for step, on numpy arrays.

The clipper is a fixed sequence of at most ``3 + K`` half-space splits, so it vectorises over
pairs with padded arrays. It is the numpy back-end of the preprocessing (the compiled one,
:mod:`.compiled`, is the default and several times faster; this one needs no compile
step and is a second, independent implementation the tests hold the first to). Every
arithmetic result is formed by the same operation on the same operands as in the one-pair
clipper (:func:`~shadowlab.geometry.vectors.dot3` for every plane distance,
:func:`~shadowlab.geometry.vectors.dot4` for the light's side,
:func:`~shadowlab.geometry.frusta.side_planes` for the frusta), so the two give the same
fragments, and ``tests/geometry/test_batch_clipping.py`` holds them to it.

Polygons are padded: ``verts`` (P, K, 3) float64 with ``count`` (P,) int, the vertices of
polygon p in ``verts[p, :count[p]]``, in order; the padding slots hold no meaning.
A count of 0 is an empty polygon.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..frusta import side_planes
from ..vectors import dot3, dot4


@dataclass
class PaddedPolygons:
    """Convex polygons of different vertex counts: ``verts`` (P, K, 3) float64 and ``count``
    (P,) int64, vertices of polygon p in ``verts[p, :count[p]]``."""

    verts: np.ndarray
    count: np.ndarray

    def __len__(self) -> int:
        return len(self.count)

    def take(self, rows: np.ndarray) -> "PaddedPolygons":
        """The polygons at ``rows`` (indices or a bool mask)."""
        return PaddedPolygons(self.verts[rows], self.count[rows])

    def polygon(self, p: int) -> np.ndarray:
        """Polygon p as a (count, 3) array."""
        return self.verts[p, :self.count[p]]


def full(polys: np.ndarray) -> PaddedPolygons:
    """Same-size polygons (P, K, 3) as padded polygons (every slot used)."""
    polys = np.asarray(polys, np.float64)
    return PaddedPolygons(polys, np.full(len(polys), polys.shape[1], np.int64))


def _successors(a: np.ndarray, count: np.ndarray) -> np.ndarray:
    """``a`` (P, K, ...) with each used slot replaced by its cyclic successor within its polygon
    (slot count−1 by slot 0); the padding slots hold whatever follows them."""
    out = np.roll(a, -1, axis=1)
    rows = np.flatnonzero(count > 0)
    out[rows, count[rows] - 1] = a[rows, 0]
    return out


def _predecessors(a: np.ndarray, count: np.ndarray) -> np.ndarray:
    """``a`` (P, K, ...) with each used slot replaced by its cyclic predecessor within its
    polygon (slot 0 by slot count−1); the padding slots hold whatever precedes them."""
    out = np.roll(a, 1, axis=1)
    rows = np.flatnonzero(count > 0)
    out[rows, 0] = a[rows, count[rows] - 1]
    return out


def _compact(cand: np.ndarray, keep: np.ndarray) -> PaddedPolygons:
    """The kept candidate vertices (P, M, 3) of each row moved to the front, in order."""
    count = keep.sum(axis=1)
    width = int(count.max()) if len(count) else 0
    out = np.zeros((len(cand), max(width, 1), 3))
    rows, slots = np.nonzero(keep)
    pos = np.cumsum(keep, axis=1)[rows, slots] - 1
    out[rows, pos] = cand[rows, slots]
    return PaddedPolygons(out, count.astype(np.int64))


def areas(polys: PaddedPolygons) -> np.ndarray:
    """Areas (P,) of planar padded polygons, as :func:`scalar.area` computes each one:
    half the norm of the summed cross products of consecutive vertices."""
    v, count = polys.verts, polys.count
    k = v.shape[1]
    cross = np.cross(v, _successors(v, count))
    total = np.zeros((len(v), 3))
    for i in range(k):  # the rows' sums in vertex order, padding adding exact zeros
        total += np.where((i < count)[:, None], cross[:, i], 0.0)
    out = 0.5 * np.sqrt(dot3(total, total))
    return np.where(count >= 3, out, 0.0)


def split_part(polys: PaddedPolygons, planes: np.ndarray, eps: float, outside: bool = False) -> PaddedPolygons:
    """One part of each polygon split by its plane (``planes`` (P, 4)), as
    :func:`scalar.split` gives it: the part with signed distance ≥ −ε (inside), or,
    with ``outside``, ≤ ε. As there, a polygon with no vertex outside (every vertex within ε
    of the plane included) is wholly inside and not outside; one with no vertex inside is wholly
    outside; the others get their vertices on that side and the crossing points, in order, then
    lose consecutive duplicates (within ε) and, under 3 vertices, everything."""
    v, count = polys.verts, polys.count
    p_n, k = len(v), v.shape[1]
    if p_n == 0:
        return polys
    valid = np.arange(k)[None, :] < count[:, None]
    d = dot3(v, planes[:, None, :3]) + planes[:, None, 3]
    side = np.where(d > eps, 1, np.where(d < -eps, -1, 0))
    side = np.where(valid, side, 0)
    all_in = ~(valid & (side < 0)).any(axis=1)
    all_out = ~(valid & (side > 0)).any(axis=1) & ~all_in
    mixed = ~all_in & ~all_out
    whole = all_out if outside else all_in
    result = PaddedPolygons(v.copy(), np.where(whole, count, 0))
    if not mixed.any():
        return result
    m = np.flatnonzero(mixed)
    vm, cm, dm, sm = v[m], count[m], d[m], side[m]
    vj, dj, sj = _successors(vm, cm), _successors(dm, cm), _successors(sm, cm)
    valid_m = valid[m]
    crossing = valid_m & (sm * sj < 0)
    with np.errstate(divide="ignore", invalid="ignore"):  # slots with no crossing: unused
        t = dm / (dm - dj)
        x = vm + t[..., None] * (vj - vm)
    # Candidates per slot: the vertex (if on the part's side), then the crossing after it (if any).
    on_side = sm <= 0 if outside else sm >= 0
    cand = np.stack([vm, x], axis=2).reshape(len(m), 2 * k, 3)
    keep = np.stack([valid_m & on_side, crossing], axis=2).reshape(len(m), 2 * k)
    inside = _tidy(_compact(cand, keep), eps)
    width = max(result.verts.shape[1], inside.verts.shape[1])
    out = np.zeros((p_n, width, 3))
    out[:, :k] = result.verts
    out[m] = 0.0
    out[m, :inside.verts.shape[1]] = inside.verts
    count_out = result.count.copy()
    count_out[m] = inside.count
    return PaddedPolygons(out, count_out)


def _tidy(polys: PaddedPolygons, eps: float) -> PaddedPolygons:
    """:func:`scalar._tidy` per row: drop vertices within ε of their predecessor
    (cyclically, in the untidied order); fewer than 3 left → empty."""
    v, count = polys.verts, polys.count
    k = v.shape[1]
    diff = v - _predecessors(v, count)
    keep = np.sqrt(dot3(diff, diff)) > eps
    keep &= np.arange(k)[None, :] < count[:, None]
    out = _compact(v, keep)
    out.count[out.count < 3] = 0
    return out


def planes_of(polys: PaddedPolygons) -> np.ndarray:
    """Planes (P, 4) (n, d), unit n, of padded polygons, as :func:`scalar.plane_of`
    computes them (Newell's method; zero for a degenerate polygon)."""
    v, count = polys.verts, polys.count
    k = v.shape[1]
    valid = np.arange(k)[None, :] < count[:, None]
    b = _successors(v, count)
    terms = np.stack([(v[..., 1] - b[..., 1]) * (v[..., 2] + b[..., 2]),
                      (v[..., 2] - b[..., 2]) * (v[..., 0] + b[..., 0]),
                      (v[..., 0] - b[..., 0]) * (v[..., 1] + b[..., 1])], axis=-1)
    n = np.zeros((len(v), 3))
    centre = np.zeros((len(v), 3))
    for i in range(k):
        n += np.where(valid[:, i, None], terms[:, i], 0.0)
        centre += np.where(valid[:, i, None], v[:, i], 0.0)
    centre /= np.maximum(count, 1)[:, None]
    length = np.sqrt(dot3(n, n))
    ok = length > 0
    n = np.divide(n, length[:, None], out=np.zeros_like(n), where=ok[:, None])
    return np.where(ok[:, None], np.concatenate([n, -dot3(n, centre)[:, None]], axis=1), 0.0)


def frustum_planes(polys: PaddedPolygons, light_h: np.ndarray) -> np.ndarray:
    """Side planes (P, K, 4) of each polygon's shadow frustum (:func:`side_planes`, computed on
    the polygons of each vertex count together); the planes of padding slots are zero, which
    classify every point as *on* them and so leave a clip unchanged."""
    v, count = polys.verts, polys.count
    out = np.zeros((len(v), v.shape[1], 4))
    for c in np.unique(count):
        if c < 3:
            continue
        rows = np.flatnonzero(count == c)
        out[rows, :c] = side_planes(v[rows, :c], light_h)
    return out


def _oriented_to_light(planes: np.ndarray, light_h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Planes with the light on their positive side, and the light's value before orienting."""
    value = dot4(planes, light_h)
    return np.where((value >= 0)[:, None], planes, -planes), value


def shadow_fragments(receivers: PaddedPolygons, casters: PaddedPolygons, light_h: np.ndarray,
                     eps: float) -> PaddedPolygons:
    """For each row p, the part of convex ``receivers`` p in the shadow of convex ``casters`` p
    from the homogeneous light ``light_h`` — :func:`scalar.shadow_fragment`'s
    fragment, row by row (count 0: no shadow). The lit pieces are not produced."""
    light_h = np.asarray(light_h, np.float64)
    n_pairs = len(receivers)
    result = PaddedPolygons(np.zeros((n_pairs, 1, 3)), np.zeros(n_pairs, np.int64))
    if n_pairs == 0:
        return result
    tol = eps * (1.0 if light_h[3] == 0 else abs(light_h[3]))
    pr, pc = planes_of(receivers), planes_of(casters)
    alive = pr[:, :3].any(axis=1) & pc[:, :3].any(axis=1)  # degenerate polygons cast/receive nothing
    pr, value_r = _oriented_to_light(pr, light_h)
    pc, value_c = _oriented_to_light(pc, light_h)
    alive &= np.abs(value_r) > tol  # the light in the receiver's plane cannot see it
    alive &= np.abs(value_c) > tol  # the light in the caster's plane: edge-on, casts nothing
    rows = np.flatnonzero(alive)
    # Only the caster's part on the light's side of the receiver's plane can shadow it.
    caster = split_part(casters.take(rows), pr[rows], eps)
    ok = (caster.count > 0) & (areas(caster) > eps * eps)
    rows, caster = rows[ok], caster.take(ok)
    # Only the receiver's part behind the caster's plane (seen from the light) can be shadowed.
    current = split_part(receivers.take(rows), pc[rows], eps, outside=True)
    ok = (current.count > 0) & (areas(current) > eps * eps)
    rows, caster, current = rows[ok], caster.take(ok), current.take(ok)
    planes = frustum_planes(caster, light_h)
    for j in range(planes.shape[1]):
        current = split_part(current, planes[:, j], eps)
        ok = current.count > 0  # an emptied polygon stays empty: drop it from the later splits
        if not ok.all():
            rows, current, planes = rows[ok], current.take(ok), planes[ok]
    ok = (current.count > 0) & (areas(current) > eps * eps)
    rows, current = rows[ok], current.take(ok)
    out = np.zeros((n_pairs, max(current.verts.shape[1], 1), 3))
    out[rows, :current.verts.shape[1]] = current.verts
    result.count[rows] = current.count
    result.verts = out
    return result


def fan_triangles(polys: PaddedPolygons) -> tuple[np.ndarray, np.ndarray]:
    """Fan triangulation of every polygon, as :func:`scalar.triangulate` does each:
    triangles (T, 3, 3) in polygon order, and the row (T,) each came from."""
    v, count = polys.verts, polys.count
    k = v.shape[1]
    if k < 3:
        return np.zeros((0, 3, 3)), np.zeros(0, np.int64)
    i = np.arange(1, k - 1)
    keep = i[None, :] + 1 < count[:, None]  # (P, k − 2)
    rows, slots = np.nonzero(keep)
    tris = np.stack([v[rows, 0], v[rows, slots + 1], v[rows, slots + 2]], axis=1)
    return tris, rows
