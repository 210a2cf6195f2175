"""Row kernels in compiled code (numba), bit for bit the numpy broadcasts they replace: a rect
light's jittered sample points (:func:`rect_samples`) and a point light's per-row vectors
(:func:`vector_minus_rows`, :func:`fill_rows`). Used by the scene's lights; the truth's kernels
(:mod:`shadowlab.truth.compiled`) warm them with the rest."""
from __future__ import annotations

from ..util.compiled import JIT as _JIT
from ..util.compiled import njit


@njit(**_JIT)
def rect_samples(jitter, lo, size, position, u, v, out):
    """Writes (M, N, 3) float64 points of a rect light at the jittered strata into ``out``:
    ``uv = lo + jitter · size`` (jitter (M, N, 2), lo and size (N, 2)), then ``(position +
    (uv0 − ½)·u) + (uv1 − ½)·v`` — :meth:`shadowlab.scene.area_lights.RectLight._surface` on
    numpy's ``lo + rng.random(...) · size``, bit for bit."""
    for i in range(jitter.shape[0]):
        for j in range(jitter.shape[1]):
            a = (lo[j, 0] + jitter[i, j, 0] * size[j, 0]) - 0.5
            b = (lo[j, 1] + jitter[i, j, 1] * size[j, 1]) - 0.5
            for k in range(3):
                out[i, j, k] = (position[k] + a * u[k]) + b * v[k]


@njit(**_JIT)
def vector_minus_rows(vec, rows, out):
    """``out[i] = vec − rows[i]`` (float32 (3,) minus float32 (K, 3), in float32): numpy's
    broadcast ``vec - rows`` — a point light's shadow-ray directions — without its per-row
    three-element inner loops."""
    v0, v1, v2 = vec[0], vec[1], vec[2]
    for i in range(rows.shape[0]):
        out[i, 0] = v0 - rows[i, 0]
        out[i, 1] = v1 - rows[i, 1]
        out[i, 2] = v2 - rows[i, 2]


@njit(**_JIT)
def fill_rows(vec, out):
    """``out[i] = vec`` for every row (K, 3): ``np.broadcast_to(vec, (K, 3)).copy()``."""
    v0, v1, v2 = vec[0], vec[1], vec[2]
    for i in range(out.shape[0]):
        out[i, 0] = v0
        out[i, 1] = v1
        out[i, 2] = v2
