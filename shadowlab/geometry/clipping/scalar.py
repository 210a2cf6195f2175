"""Exact object-space shadow polygons: convex clipping in float64 with an explicit tolerance ε.

For one convex caster polygon C, one convex receiver polygon R and a light l (homogeneous: a
point (L, 1) or a direction (−d, 0)), the part of R in C's shadow is

    R ∩ {behind C's plane, seen from the light} ∩ {inside every side plane of C's shadow frustum}

where each side plane passes through the light and one edge of C (Atherton, Weiler & Greenberg
1978; Chin & Feiner 1989, shadow volume BSP trees). Clipping R by these half-spaces in turn
(Sutherland & Hodgman 1974) yields exactly the polygon described as "R's vertices inside the
frustum, R's edges' crossings of the side planes, and the light rays through C's vertices that
hit R, ordered into a convex polygon": those are the vertices a convex clip produces. The parts
of R cut off at each step are convex too, and together with the shadow fragment they tile R.

Every predicate classifies a point by its signed distance to a plane with tolerance ε: within
±ε a point is *on* the plane (kept by both sides, never split; a polygon wholly on a plane is
not behind it). ε is in world units. How to choose it (measured by
``experiments/sp_epsilon_sweep.py``, receiver of size 4, random rotations):
- ε must exceed the rounding error of the distances, a few ulps of the coordinates' magnitude:
  at ε ≤ 1e-15 the clipper splits at rounding noise and leaves zero-area sliver pieces (areas
  stay exact to ~1e-15, but slivers are junk geometry);
- ε must stay below the smallest gap that matters: a caster δ above its receiver loses its
  shadow once ε > δ, and a light φ above a receiver's plane once ε > sin φ.
The default, 1e-9 × the scene's size, sits six orders of magnitude above the rounding and
below any gap a scene of ordinary units models.
"""
from __future__ import annotations

import numpy as np

from ..frusta import side_planes
from ..vectors import dot3, dot4


def plane_of(poly: np.ndarray) -> np.ndarray:
    """The plane (n, d), unit n, of a convex polygon (K, 3) (Newell's method, robust to
    collinear leading vertices); zero for a degenerate polygon."""
    from .batch import full, planes_of

    return planes_of(full(np.asarray(poly, np.float64)[None]))[0]


def signed(plane: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Signed distances of (K, 3) points to ``plane`` (scaled by |n|)."""
    return dot3(pts, plane[:3]) + plane[3]


def split(poly: np.ndarray, plane: np.ndarray, eps: float) -> tuple[np.ndarray, np.ndarray]:
    """Split a convex polygon (K, 3) by ``plane`` into its parts with distance ≥ −ε (inside)
    and ≤ ε (outside); points within ε of the plane belong to both. Empty parts are (0, 3)."""
    if len(poly) == 0:
        return poly, poly
    d = signed(plane, poly)
    side = np.where(d > eps, 1, np.where(d < -eps, -1, 0))
    if np.all(side >= 0):
        return poly, np.zeros((0, 3))
    if np.all(side <= 0):
        return np.zeros((0, 3)), poly
    inside, outside = [], []
    k = len(poly)
    for i in range(k):
        j = (i + 1) % k
        p, sp, dp = poly[i], side[i], d[i]
        if sp >= 0:
            inside.append(p)
        if sp <= 0:
            outside.append(p)
        sq = side[j]
        if sp * sq < 0:  # a proper crossing: both parts get the intersection point
            t = dp / (dp - d[j])
            x = p + t * (poly[j] - p)
            inside.append(x)
            outside.append(x)
    return _tidy(np.array(inside), eps), _tidy(np.array(outside), eps)


def _tidy(poly: np.ndarray, eps: float) -> np.ndarray:
    """Drop consecutive duplicates; polygons with fewer than 3 vertices become empty."""
    if len(poly) == 0:
        return np.zeros((0, 3))
    step = poly - np.roll(poly, 1, axis=0)
    keep = np.sqrt(dot3(step, step)) > eps
    if not keep.any():
        return np.zeros((0, 3))
    poly = poly[keep]
    return poly if len(poly) >= 3 else np.zeros((0, 3))


def area(poly: np.ndarray) -> float:
    """Area of a planar polygon (K, 3)."""
    if len(poly) < 3:
        return 0.0
    total = np.cross(poly, np.roll(poly, -1, axis=0)).sum(axis=0)
    return 0.5 * float(np.sqrt(dot3(total, total)))


def frustum_planes(caster: np.ndarray, light_h: np.ndarray) -> np.ndarray:
    """Side planes (K, 4) of the shadow frustum from the light through the caster's edges, each
    oriented so that the frustum's inside is positive (:func:`shadowlab.geometry.frusta.side_planes`,
    the definition the bulk pair culling shares)."""
    return side_planes(np.asarray(caster, np.float64)[None], light_h)[0]


def oriented_to_light(plane: np.ndarray, light_h: np.ndarray) -> np.ndarray:
    """``plane`` with its sign chosen so that the light is on the positive side."""
    return plane if dot4(plane, light_h) >= 0 else -plane


def light_side_value(plane: np.ndarray, light_h: np.ndarray) -> float:
    """How far the light is on the positive side of ``plane`` (0: the light lies in it)."""
    return float(dot4(plane, light_h))


def shadow_fragment(receiver: np.ndarray, caster: np.ndarray, light_h: np.ndarray, eps: float
                    ) -> tuple[np.ndarray, list[np.ndarray]]:
    """The part of convex ``receiver`` (K, 3) in the shadow of convex ``caster`` (J, 3) from
    ``light_h``, and the convex lit pieces that, with it, tile the receiver.

    Returns (fragment, lit_pieces); the fragment is (0, 3) when there is no shadow.
    """
    empty = np.zeros((0, 3))
    pr, pc = plane_of(receiver), plane_of(caster)
    if not pr[:3].any() or not pc[:3].any():
        return empty, [receiver]  # degenerate polygon
    scale_r = abs(light_side_value(pr, light_h))
    if scale_r <= eps * (1.0 if light_h[3] == 0 else abs(light_h[3])):
        return empty, [receiver]  # the light lies in the receiver's plane: it cannot see it
    pr = oriented_to_light(pr, light_h)
    pc = oriented_to_light(pc, light_h)
    if abs(light_side_value(pc, light_h)) <= eps * (1.0 if light_h[3] == 0 else abs(light_h[3])):
        return empty, [receiver]  # the light lies in the caster's plane: edge-on, casts nothing
    # Only the caster's part on the light's side of the receiver's plane can shadow it.
    caster, _ = split(caster, pr, eps)
    if len(caster) == 0 or area(caster) <= eps * eps:
        return empty, [receiver]
    # Only the receiver's part behind the caster's plane (seen from the light) can be shadowed.
    front, behind = split(receiver, pc, eps)  # the light's side of the caster, and the rest
    if len(behind) == 0 or area(behind) <= eps * eps:
        return empty, [receiver]
    pieces = [front] if len(front) and area(front) > eps * eps else []
    current = behind
    for plane in frustum_planes(caster, light_h):
        inside, outside = split(current, plane, eps)
        if len(outside) and area(outside) > eps * eps:
            pieces.append(outside)
        current = inside
        if len(current) == 0:
            break
    if len(current) == 0 or area(current) <= eps * eps:
        return empty, pieces if pieces else [receiver]
    return current, pieces


def triangulate(poly: np.ndarray) -> np.ndarray:
    """Fan triangulation of a convex polygon (K, 3) → (K−2, 3, 3)."""
    if len(poly) < 3:
        return np.zeros((0, 3, 3))
    idx = np.arange(1, len(poly) - 1)
    return np.stack([np.broadcast_to(poly[0], (len(idx), 3)), poly[idx], poly[idx + 1]], axis=1)
