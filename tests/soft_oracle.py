"""The exact visible fraction of a planar area light (rect, or disc as a polygon) from a point,
behind polygonal occluders — the oracle the sampled ground truth is tested against
(tests/truth/test_soft_truth.py), written from the definition (docs/metrics.md), independently of
shadowlab's sampling code.

From P, each occluding triangle is centrally projected onto the light's plane; the union of
the projections (shapely ``unary_union``) intersected with the light polygon is the part of
the light P cannot see. The part of the light below P's tangent plane (camera-facing normal
N_P) is hidden by P's own surface and is added as a half-plane. Then

    V(P) = 1 − area((shadows ∪ below-horizon) ∩ light) / area(light),

and V = 0 when P is not strictly on the emitting side of the one-sided light.

Central projection is only defined for the part of a triangle strictly between P's plane
parallel to the light and the light's plane (0 < d < d_P, with d the signed distance from the
light's plane towards its emitting side): nothing beyond the light or behind P can block a
segment from P to the light. Each triangle is therefore clipped (Sutherland & Hodgman 1974)
to the slab 0 ≤ d ≤ d_P·(1 − SLAB_MARGIN) before projection; what the margin drops lies within
SLAB_MARGIN·d_P of P's parallel plane and projects at least (lateral distance)/SLAB_MARGIN
away from P's foot on the light plane — off any light of ours unless an occluder comes within
~1e-9 of P, which no test scene does. Triangles whose plane passes through P (P's own surface,
coplanar neighbours) project to a segment of zero area and are skipped.

A disc is replaced by the regular polygon of DISC_SIDES sides whose radius is scaled so that it
has the disc's area (its vertices just outside the circle, its edge midpoints just inside).
The inscribed k-gon misses a fraction 1 − k·sin(2π/k)/(2π) ≈ (2π²/3)/k² ≈ 6.3e-6 of the disc
(k = 1024); the equal-area polygon differs from the disc by at most that much area (symmetric
difference), so V changes by less than 1e-5 — three orders below the sampled truth's
0.5/√N = 0.0156 at N = 1024.
"""
from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry import Polygon, box
from shapely.ops import unary_union

#: Sides of the polygon that stands for a disc light.
DISC_SIDES = 1024
#: ``frustum=True``: the grid of GEOS's fixed-precision overlay, × the light's √area (moves each
#: vertex by at most that, so V by ~1e-13 × the pieces' perimeter / √area).
FRUSTUM_GRID = 1e-13
#: Relative margin below P's parallel plane at which triangles are cut before projection.
SLAB_MARGIN = 1e-9


def _frame(light):
    """Centre (3,), unit emitting normal (3,), in-plane unit axes t, b (3,) of a planar light."""
    n = np.asarray(light.normal, np.float64)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t = np.cross(helper, n)
    t /= np.linalg.norm(t)
    return np.asarray(light.position, np.float64), n, t, np.cross(n, t)


def light_polygon(light) -> Polygon:
    """The light's emitting surface as a shapely polygon in its plane's (t, b) coordinates."""
    c, n, t, b = _frame(light)
    if light.shape == "rect":
        pts = light.corners() - c
    elif light.shape == "disc":
        ang = 2.0 * np.pi * np.arange(DISC_SIDES) / DISC_SIDES
        # inscribed polygon of radius r' with (k/2) r'^2 sin(2π/k) = π r^2: the disc's area
        r = light.radius * np.sqrt(2.0 * np.pi / (DISC_SIDES * np.sin(2.0 * np.pi / DISC_SIDES)))
        return Polygon(np.stack([r * np.cos(ang), r * np.sin(ang)], axis=1))
    else:
        raise ValueError(f"the oracle handles planar rect and disc lights, not {light.shape!r}")
    return Polygon(np.stack([pts @ t, pts @ b], axis=1))


def _clip(poly: np.ndarray, dist: np.ndarray, keep_ge: float) -> tuple[np.ndarray, np.ndarray]:
    """Sutherland–Hodgman: the part of polygon (K, 3) with per-vertex value dist (K,) ≥ keep_ge."""
    out, out_d = [], []
    k = len(poly)
    for i in range(k):
        a, b = poly[i], poly[(i + 1) % k]
        da, db = dist[i], dist[(i + 1) % k]
        if da >= keep_ge:
            out.append(a)
            out_d.append(da)
        if (da >= keep_ge) != (db >= keep_ge):
            s = (keep_ge - da) / (db - da)
            out.append(a + s * (b - a))
            out_d.append(keep_ge)
    return np.array(out).reshape(-1, 3), np.array(out_d)


def _frustum_planes(light, p: np.ndarray) -> list[np.ndarray]:
    """Inward normals (3,) of the four planes through ``p`` and the edges of the rectangle (in the
    light's plane, axes t, b) twice the size of the light polygon's bounding box, same centre."""
    c, n, t, b = _frame(light)
    x0, y0, x1, y1 = light_polygon(light).bounds
    mx, my, hx, hy = (x0 + x1) / 2, (y0 + y1) / 2, x1 - x0, y1 - y0
    corners = [c + (mx + sx * hx) * t + (my + sy * hy) * b for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    mid = c + mx * t + my * b
    planes = []
    for i in range(4):
        m = np.cross(corners[i] - p, corners[(i + 1) % 4] - p)
        planes.append(m if m @ (mid - p) > 0 else -m)
    return planes


def occluded_region(light, triangles: np.ndarray, p: np.ndarray, normal: np.ndarray, frustum: bool = False):
    """Shapely geometry in the light plane's (t, b) coordinates: the projections from ``p`` of
    the occluding ``triangles`` (T, 3, 3) float64 united with the half-plane below ``p``'s
    tangent plane (unit ``normal`` (3,)); not yet cut to the light.

    ``frustum``: each slab-clipped triangle is also clipped (in 3D) to the four planes through
    ``p`` and the edges of a rectangle twice the light's bounding box, which changes nothing
    inside the light (every point cut away projects outside that rectangle) but keeps the
    projections' coordinates bounded. Without it, a triangle that reaches P's parallel plane
    (a box standing on the receiver beside P) projects to vertices ~1e9 away (the slab margin),
    and GEOS's union loses precision on them: measured on soft_large_close at 160x120, 2 of
    400 random points off by 3e-4 (e.g. a point where adding the box, whose shadow misses the
    light, raised V from 0.956864 to 0.957159), others by ~1e-9; with it the oracle and
    shadowlab's exact_soft agree to 1e-12 there (tests/techniques/geometric/test_exact_soft.py)."""
    c, n, t, b = _frame(light)
    p = np.asarray(p, np.float64)
    d_p = (p - c) @ n
    top = d_p * (1.0 - SLAB_MARGIN)
    sides = _frustum_planes(light, p) if frustum else []
    pieces = []
    # triangles' planes through p: zero-area projections
    e1, e2 = triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]
    tn = np.cross(e1, e2)
    tn_len = np.linalg.norm(tn, axis=1)
    through_p = np.abs(np.einsum("ij,ij->i", p - triangles[:, 0], tn)) <= 1e-12 * tn_len * max(1.0, np.abs(p).max())
    for tri in triangles[(tn_len > 0) & ~through_p]:
        d = (tri - c) @ n
        if d.max() <= 0.0 or d.min() >= top:
            continue
        poly, dd = _clip(tri, d, 0.0)
        if len(poly) < 3:
            continue
        poly, dd = _clip(poly, -dd, -top)
        dd = -dd
        if len(poly) < 3:
            continue
        for m in sides:
            side = (poly - p) @ m
            if (side >= 0).all():
                continue
            poly, _ = _clip(poly, side, 0.0)
            if len(poly) < 3:
                break
            dd = (poly - c) @ n  # heights of the new vertices (all below top: inside the frustum)
        if len(poly) < 3:
            continue
        s = d_p / (d_p - dd)  # the ray p + s (x − p) meets the light plane (d = 0)
        y = p + s[:, None] * (poly - p) - c
        g = Polygon(np.stack([y @ t, y @ b], axis=1))
        if g.area > 0:
            pieces.append(g.buffer(0) if not g.is_valid else g)
    # below the horizon: points y of the light plane with (y − p)·N ≤ 0 — in (t, b) coordinates
    # the half-plane a·x + β·z ≤ γ, drawn as a large polygon around the light
    a, beta = t @ normal, b @ normal
    gamma = (p - c) @ normal
    big = 1e3 * (np.sqrt(light_polygon(light).area) + np.linalg.norm(p - c))
    if np.hypot(a, beta) < 1e-15:  # tangent plane parallel to the light's plane
        if gamma >= 0:  # the whole light is on or below the horizon
            pieces.append(box(-big, -big, big, big))
    else:
        ax = np.array([a, beta]) / np.hypot(a, beta)
        off = gamma / np.hypot(a, beta)  # boundary: x·ax = off; hidden side: x·ax ≤ off
        perp = np.array([-ax[1], ax[0]])
        foot = off * ax
        hp = Polygon([foot + big * perp, foot - big * perp, foot - big * perp - big * ax, foot + big * perp - big * ax])
        pieces.append(hp)
    if not pieces:
        return Polygon()
    if not frustum:
        return unary_union(pieces)
    # the horizon's half-plane cut to the frustum's rectangle too (robust axis-aligned clipping):
    # no coordinate far beyond the light
    x0, y0, x1, y1 = light_polygon(light).bounds
    wx, wy = x1 - x0, y1 - y0
    pieces = [shapely.clip_by_rect(g, x0 - wx, y0 - wy, x1 + wx, y1 + wy) for g in pieces]
    pieces = [g for g in pieces if not g.is_empty]
    # bounded pieces: GEOS's snap-rounding overlay on a fixed grid (1e-13 of the light's size),
    # robust where cut edges of neighbouring triangles are collinear to within rounding
    grid = FRUSTUM_GRID * np.sqrt(light_polygon(light).area)
    return shapely.union_all([shapely.set_precision(g, grid) for g in pieces], grid_size=grid)


def exact_visibility(light, triangles: np.ndarray, p: np.ndarray, normal: np.ndarray, frustum: bool = False) -> float:
    """V(P) in [0, 1] (module docstring) for a rect or disc ``light`` (shadowlab.scene.area_lights),
    occluders ``triangles`` (T, 3, 3) float64 world coordinates, the point ``p`` (3,) and its
    unit camera-facing ``normal`` (3,); ``frustum``: see :func:`occluded_region`."""
    c, n, _, _ = _frame(light)
    if not (np.asarray(p, np.float64) - c) @ n > 0:
        return 0.0  # behind (or in the plane of) a one-sided light
    lp = light_polygon(light)
    hidden = occluded_region(light, np.asarray(triangles, np.float64).reshape(-1, 3, 3), p, normal, frustum)
    if frustum:
        return float(1.0 - shapely.intersection(hidden, lp, grid_size=FRUSTUM_GRID * np.sqrt(lp.area)).area / lp.area)
    return float(1.0 - hidden.intersection(lp).area / lp.area)


def sphere_cap_visibility(r: float, d: float, alpha: float) -> float:
    """Exact V from a point P at distance ``d`` from the centre C of a sphere light of radius
    ``r`` (d > r) when every ray within angle ``alpha`` (radians) of the axis P→C is blocked
    and nothing else is (docs/metrics.md: fraction by area of the cap P sees).

    A cap point at polar angle θ from the axis (at C, towards P) is seen from P at angle β with
    tan β = r sin θ / (d − r cos θ), i.e. r sin(θ + β) = d sin β; β rises monotonically from 0
    to asin(r/d) on the visible cap 0 ≤ θ ≤ θmax (cos θmax = r/d, where θmax + β = π/2), so the
    blocked part is θ ≤ θ* = asin((d/r) sin α) − α, and by Archimedes (area ∝ 1 − cos θ)

        V = 1 − (1 − cos θ*) / (1 − cos θmax),   V = 0 for α ≥ asin(r/d)."""
    if not d > r > 0:
        raise ValueError(f"need d > r > 0, got r={r}, d={d}")
    if alpha <= 0:
        return 1.0
    if alpha >= np.arcsin(r / d):
        return 0.0
    theta = np.arcsin(d / r * np.sin(alpha)) - alpha
    return float(1.0 - (1.0 - np.cos(theta)) / (1.0 - r / d))


def sphere_silhouette_disc_visibility(r: float, d: float, alpha: float) -> float:
    """What a WRONG sphere sampler — uniform over the silhouette disc (the flat disc bounded by the
    cap's rim: radius r sin θmax, at distance d − r²/d from P) — converges to in the setting of
    :func:`sphere_cap_visibility`: the blocked part is the central disc of radius
    (d − r²/d) tan α, so V = 1 − min(1, ((d − r²/d) tan α / (r sin θmax))²)."""
    rim = r * np.sqrt(1.0 - (r / d) ** 2)
    blocked = (d - r * r / d) * np.tan(alpha) if alpha > 0 else 0.0
    return float(1.0 - min(1.0, (blocked / rim) ** 2))


def scene_triangles(scene) -> np.ndarray:
    """World triangles (T, 3, 3) float64 of the scene's casting objects."""
    tris = [o.vertices[o.faces].astype(np.float64) for o in scene.objects if o.casts]
    return np.concatenate(tris) if tris else np.zeros((0, 3, 3))


__all__ = ["exact_visibility", "light_polygon", "occluded_region", "scene_triangles", "sphere_cap_visibility",
           "sphere_silhouette_disc_visibility", "DISC_SIDES", "SLAB_MARGIN"]
