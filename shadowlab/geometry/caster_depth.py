"""The nearest caster inside a perspective light view: every caster triangle clipped to the
view's square frustum, and the smallest axial depth of what is left.

Why triangles and not bounding boxes: a perspective map's near plane must lie in front of every
caster point the view can see, or that caster is clipped and loses its shadow. Bounded by boxes,
a light that stands inside a caster's box — a lamp inside a room modelled as one mesh, a
searchlight among a city's buildings — gets a nearest depth of 0 and the near plane falls back
to its floor (far × :data:`shadowlab.geometry.frusta.MIN_NEAR_OVER_FAR`), where window depth
crowds against 1 and a window-depth bias swallows every shadow. The triangles themselves say
where the casters are: the depth reduction of Lauritzen et al.'s sample distribution shadow maps
(2011) done on the casters instead of the receivers, exactly, on the CPU, so that it is the same
on every driver.

The frustum is the view's square cone with half-angle ``atan(tan_half)`` around its axis (the
−z axis of the view matrix), cut at axial depth ``far`` (a caster beyond the farthest receiver
shadows nothing the map covers). Each triangle is clipped against the four side planes and the
far plane (Sutherland–Hodgman); its nearest depth is the smallest depth among the clipped
polygon's vertices (depth is linear, so a convex polygon's minimum lies at a vertex).

Compiled with numba (``cache=True``, as :mod:`.compiled`); :func:`nearest_depths_reference`
is the same computation in plain Python, the oracle of ``tests/geometry/test_caster_depth.py``.
"""
from __future__ import annotations

import numpy as np
from numba import njit

#: Vertex slots of a clipped triangle: 3, plus at most one per clipping plane (5).
MAX_VERTS = 8


@njit(cache=True, nogil=True)
def _nearest_depths(view_tris: np.ndarray, tan_half: float, far: float, out: np.ndarray) -> None:
    """Per triangle (view-space vertices (T, 3, 3): x, y, z with depth −z) the smallest depth of
    its part inside the frustum, or +inf when nothing of it is inside."""
    buf_a = np.empty((MAX_VERTS, 3))
    buf_b = np.empty((MAX_VERTS, 3))
    for k in range(view_tris.shape[0]):
        n = 3
        for i in range(3):
            buf_a[i, 0] = view_tris[k, i, 0]
            buf_a[i, 1] = view_tris[k, i, 1]
            buf_a[i, 2] = -view_tris[k, i, 2]  # depth along the axis
        src, dst = buf_a, buf_b
        for plane in range(5):
            m = 0
            for i in range(n):
                j = (i + 1) % n
                # signed distance to the plane, >= 0 inside: t d ∓ x, t d ∓ y, far − d
                if plane == 0:
                    fi, fj = tan_half * src[i, 2] - src[i, 0], tan_half * src[j, 2] - src[j, 0]
                elif plane == 1:
                    fi, fj = tan_half * src[i, 2] + src[i, 0], tan_half * src[j, 2] + src[j, 0]
                elif plane == 2:
                    fi, fj = tan_half * src[i, 2] - src[i, 1], tan_half * src[j, 2] - src[j, 1]
                elif plane == 3:
                    fi, fj = tan_half * src[i, 2] + src[i, 1], tan_half * src[j, 2] + src[j, 1]
                else:
                    fi, fj = far - src[i, 2], far - src[j, 2]
                if fi >= 0.0:
                    for c in range(3):
                        dst[m, c] = src[i, c]
                    m += 1
                if (fi >= 0.0) != (fj >= 0.0):
                    t = fi / (fi - fj)
                    for c in range(3):
                        dst[m, c] = src[i, c] + t * (src[j, c] - src[i, c])
                    m += 1
            n = m
            src, dst = dst, src
            if n == 0:
                break
        best = np.inf
        for i in range(n):
            # The side planes keep t·d ≥ |x| ≥ 0; a rounding residue below 0 is the apex itself.
            best = min(best, max(src[i, 2], 0.0))
        out[k] = best


def nearest_depths(triangles: np.ndarray, view: np.ndarray, tan_half: float, far: float) -> np.ndarray:
    """Float64 (T,): per world triangle of ``triangles`` (T, 3, 3) the smallest axial depth of its
    part inside the frustum of ``view`` (world → view, looking down −z) with square half-angle
    ``atan(tan_half)``, cut at depth ``far``; +inf for triangles wholly outside."""
    tris = np.ascontiguousarray(triangles, np.float64).reshape(-1, 3, 3)
    view = np.asarray(view, np.float64)
    view_tris = np.ascontiguousarray(tris @ view[:3, :3].T + view[:3, 3])
    out = np.empty(len(tris))
    if len(tris):
        _nearest_depths(view_tris, float(tan_half), float(far), out)
    return out


def nearest_depths_reference(triangles: np.ndarray, view: np.ndarray, tan_half: float, far: float) -> np.ndarray:
    """:func:`nearest_depths` in plain Python (the test oracle): each triangle clipped against
    the five planes one after the other, then the smallest depth of what is left."""
    view = np.asarray(view, np.float64)
    planes = [lambda p: tan_half * p[2] - p[0], lambda p: tan_half * p[2] + p[0],
              lambda p: tan_half * p[2] - p[1], lambda p: tan_half * p[2] + p[1], lambda p: far - p[2]]
    out = []
    for tri in np.asarray(triangles, np.float64).reshape(-1, 3, 3):
        v = tri @ view[:3, :3].T + view[:3, 3]
        poly = [np.array([p[0], p[1], -p[2]]) for p in v]
        for f in planes:
            clipped = []
            for i, a in enumerate(poly):
                b = poly[(i + 1) % len(poly)]
                fa, fb = f(a), f(b)
                if fa >= 0:
                    clipped.append(a)
                if (fa >= 0) != (fb >= 0):
                    clipped.append(a + fa / (fa - fb) * (b - a))
            poly = clipped
            if not poly:
                break
        out.append(min(max(p[2], 0.0) for p in poly) if poly else np.inf)
    return np.array(out, np.float64)
