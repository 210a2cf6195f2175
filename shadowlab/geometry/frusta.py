"""Light-space frusta: the side planes of a polygon's shadow frustum, and the views a shadow
map is rendered through, fitted to the points it must cover (docs/architecture.md: model only what the
scene needs). The light classes (:mod:`shadowlab.scene.lights`) choose which fit applies to them.

Every fit keeps the points it covers strictly inside the clip volume (relative padding
:data:`PAD`) and puts near planes in front of every caster point a view can see, measured along
the view's axis: a caster in front of the near plane would be clipped and lose its shadow.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import transforms as tf
from .bounds import box_corners, box_distance
from .caster_depth import nearest_depths
from .vectors import dot3

#: Relative padding of fitted ranges, so that fitted points do not sit exactly on a clip plane.
PAD = 1e-3
#: Smallest width given to a fitted range (world units): a single point still gets a valid frustum.
MIN_EXTENT = 1e-9
#: Perspective maps: near ≥ far · this. Window depth resolves Δz ≈ z² · 2⁻²⁴ / near at distance z
#: in a 24-bit map, so at the far plane the step stays below 6e-4 · far.
MIN_NEAR_OVER_FAR = 1e-4
#: Perspective maps: near ≤ far · this, so the frustum keeps a depth range when casters are far.
MAX_NEAR_OVER_FAR = 0.5
#: Widest full field of view of a perspective map (degrees): at 180 the projection is singular.
MAX_FOV = 179.0
#: Widest half-angle of a point light's single frustum (degrees): beyond it texels blow up.
MAX_POINT_HALF_ANGLE = 80.0
#: Cube faces: look direction and up vector, in the order the lookup shader's face_of() uses.
CUBE_FACES = [((1, 0, 0), (0, -1, 0)), ((-1, 0, 0), (0, -1, 0)), ((0, 1, 0), (0, 0, 1)),
              ((0, -1, 0), (0, 0, -1)), ((0, 0, 1), (0, -1, 0)), ((0, 0, -1), (0, -1, 0))]


def side_planes(polys: np.ndarray, light_h: np.ndarray) -> np.ndarray:
    """Side planes of the shadow frusta of convex polygons ``polys`` (C, K, 3) from the
    homogeneous light ``light_h`` ((L, 1) or (−direction, 0)): one plane (n, d) per edge,
    (C, K, 4), through the light (or containing its direction) and the edge, unit n, oriented
    so that the frustum's inside (the polygon's centre) is positive. A degenerate edge, or one
    pointing at the light, gives the zero plane, which classifies every point as *on* it."""
    polys = np.asarray(polys, np.float64)
    a, b = polys, np.roll(polys, -1, axis=1)
    if light_h[3] != 0:  # point light: the plane through L, a and b
        L = light_h[:3] / light_h[3]
        n = np.cross(a - L, b - L)
    else:  # directional: the plane through a and b containing the light's direction
        n = np.cross(b - a, np.broadcast_to(light_h[:3], a.shape))
    length = np.sqrt(dot3(n, n))[..., None]
    n = np.divide(n, length, out=np.zeros_like(n), where=length > 0)
    d = -dot3(n, a)
    centre = polys.mean(axis=1)
    inward = np.where(dot3(n, centre[:, None, :]) + d < 0, -1.0, 1.0)
    return np.concatenate([n * inward[..., None], (d * inward)[..., None]], axis=2)


@dataclass(frozen=True)
class Casters:
    """What casts shadows in a scene, in the two forms the light-view fits use: per caster
    object its axis-aligned bounds (K, 2, 3) — orthographic depth ranges, blocker-search slices
    — and every caster triangle (T, 3, 3), world, float64 — the near planes of perspective
    views (:func:`perspective_fit`)."""

    bounds: np.ndarray
    triangles: np.ndarray

    @classmethod
    def from_triangles(cls, triangles: np.ndarray) -> "Casters":
        """One caster made of ``triangles`` (T, 3, 3): its bounds are theirs."""
        tris = np.asarray(triangles, np.float64).reshape(-1, 3, 3)
        if not len(tris):
            return cls(np.zeros((0, 2, 3)), tris)
        pts = tris.reshape(-1, 3)
        return cls(np.stack([pts.min(0), pts.max(0)])[None], tris)


@dataclass
class LightView:
    """One view a shadow map is rendered through: view and projection (float64 4x4, row-major);
    ``texel_world`` is the world size of a texel (orthographic) and ``texel_angle`` its size per
    unit distance (perspective), at the map's resolution."""

    view: np.ndarray
    proj: np.ndarray
    texel_world: float = 0.0
    texel_angle: float = 0.0

    @property
    def view_proj(self) -> np.ndarray:
        """Projection · view."""
        return self.proj @ self.view

    def near_far(self) -> tuple[float, float]:
        """(near, far) of a perspective projection (world distances along the view's axis)."""
        p = self.proj
        return float(p[2, 3] / (p[2, 2] - 1.0)), float(p[2, 3] / (p[2, 2] + 1.0))

    @property
    def depth_range(self) -> float:
        """far − near of the projection (world units along the view axis)."""
        p = self.proj
        if p[3, 3] == 1.0:  # orthographic: depth = (z - near) / (far - near)
            return float(2.0 / abs(p[2, 2]))
        near, far = p[2, 3] / (p[2, 2] - 1.0), p[2, 3] / (p[2, 2] + 1.0)
        return float(abs(far - near))


def orthographic_fit(view: np.ndarray, points: np.ndarray, caster_bounds: np.ndarray, resolution: int,
                     radius: float | None = None, near_min: float | None = None) -> LightView:
    """An orthographic view along ``view``'s −z covering ``points`` (N, 3) sideways (clipped to
    ``radius`` of the axis if given) and in depth from the nearest caster box (but not in front
    of ``near_min``) to the farthest point."""
    rv = tf.transform_points(view, points)
    lo, hi = rv[:, :2].min(0), rv[:, :2].max(0)
    if radius is not None:
        lo, hi = np.maximum(lo, -radius), np.minimum(hi, radius)
    pad = PAD * max(float(np.max(hi - lo)), MIN_EXTENT)
    lo, hi = lo - pad, hi + pad
    depth = -rv[:, 2]
    far = float(depth.max())
    caster_depth = -tf.transform_points(view, box_corners(caster_bounds))[:, 2]
    near = float(min(depth.min(), caster_depth.min() if len(caster_bounds) else depth.min()))
    if near_min is not None:
        near = max(near, near_min)
    span = max(far - near, MIN_EXTENT)
    near, far = near - PAD * span, far + PAD * span
    proj = tf.orthographic(lo[0], hi[0], lo[1], hi[1], near, far)
    return LightView(view, proj, texel_world=float(max(hi - lo)) / resolution)


def perspective_range(position: np.ndarray, points: np.ndarray, caster_bounds: np.ndarray, axes: np.ndarray,
                      fov: float, near_override: float = 0.0) -> tuple[float, float]:
    """(near, far) of square perspective views from ``position`` along each of ``axes`` (A, 3)
    with full angle ``fov``, from caster *bounding boxes*: far just past the farthest point; near
    in front of every caster box a view can see, within [far · MIN_NEAR_OVER_FAR, far ·
    MAX_NEAR_OVER_FAR], unless ``near_override`` > 0 forces it. The shadow maps fit from the
    triangles instead (:func:`perspective_fit`): a light inside a caster's box gets the floor
    here. Kept for projective's per-caster images (a light inside the box gets no image there)
    and as the "before" of ``experiments/light_frusta.py``.

    The near plane bounds *axial* depth: a caster point at Euclidean distance d can lie at depth
    d · cos γ only (γ: its angle from the axis). Per caster box two lower bounds of the depth
    of its points inside a view hold — the smallest depth of its corners, and its distance
    times the cosine of the view's corner angle, cos γc = 1 / √(1 + 2 tan²(fov/2)) — and the
    larger of the two is used."""
    dist = np.linalg.norm(points - position, axis=1)
    far = float(dist.max()) * (1 + PAD)
    if len(caster_bounds):
        cos_corner = 1.0 / np.sqrt(1.0 + 2.0 * np.tan(np.radians(fov) / 2) ** 2)
        corners = box_corners(caster_bounds).reshape(-1, 8, 3) - position           # (K, 8, 3)
        corner_depth = (corners @ np.asarray(axes, np.float64).T).min(axis=1)       # (K, A)
        bound = np.maximum(corner_depth, box_distance(position, caster_bounds)[:, None] * cos_corner)
        nearest = float(bound.min())
    else:
        nearest = far * MAX_NEAR_OVER_FAR
    near = min(max(nearest * (1 - PAD), far * MIN_NEAR_OVER_FAR), far * MAX_NEAR_OVER_FAR)
    return (near_override if near_override > 0 else near), far


def perspective_fit(position: np.ndarray, points: np.ndarray, casters: Casters, views: list[np.ndarray],
                    fov: float, near_override: float = 0.0) -> tuple[float, float, list[str]]:
    """(near, far) shared by the square perspective views ``views`` (world → view matrices)
    from ``position`` with full angle ``fov`` that cover ``points`` (N, 3), and notes for the run.

    far lies just past the farthest point. near lies just in front of the nearest caster the
    views can see — every caster triangle clipped to each view's frustum, cut at far
    (:func:`shadowlab.geometry.caster_depth.nearest_depths`) — within [far · MIN_NEAR_OVER_FAR,
    far · MAX_NEAR_OVER_FAR]. Casters nearer than the floor far · MIN_NEAR_OVER_FAR (a lamp
    touching its shade) cannot all be kept without giving up the depth precision of the rest:
    they are clipped, and a note says how many and how near. ``near_override`` > 0 forces the
    near plane; casters in front of a forced one are clipped too, with a note."""
    far = float(np.linalg.norm(points - position, axis=1).max()) * (1 + PAD)
    tan_half = float(np.tan(np.radians(fov) / 2))
    depths = np.concatenate([nearest_depths(casters.triangles, v, tan_half, far) for v in views]) \
        if len(casters.triangles) else np.full(1, np.inf)
    nearest = float(depths.min())
    floor, ceiling = far * MIN_NEAR_OVER_FAR, far * MAX_NEAR_OVER_FAR
    near = min(max(nearest * (1 - PAD), floor), ceiling) if np.isfinite(nearest) else ceiling
    notes = []
    if near_override > 0:
        near = near_override
    clipped = int(np.sum(depths < near))
    if clipped:
        why = (f"the forced near plane {near:.4g}" if near_override > 0 else
               f"the near plane's floor far x {MIN_NEAR_OVER_FAR:g} = {near:.4g} (far {far:.4g})")
        notes.append(f"{clipped} caster triangles come nearer to the light than {why}, the nearest at "
                     f"{nearest:.4g}: their parts in front of it are clipped and cast no shadow in this map")
    return near, far, notes


def cube_view_matrices(position: np.ndarray) -> list[np.ndarray]:
    """World → view matrices of a cube map's six 90° faces around ``position``, in
    :data:`CUBE_FACES` order."""
    return [tf.look_at(position, position + np.array(d, float), np.array(u, float)) for d, u in CUBE_FACES]


def perspective_view(position: np.ndarray, direction: np.ndarray, fov: float, near: float, far: float,
                     resolution: int) -> LightView:
    """A square perspective view from ``position`` along ``direction`` with full angle ``fov``."""
    return LightView(tf.look_along(position, direction), tf.perspective(fov, 1.0, near, far),
                     texel_angle=2 * np.tan(np.radians(fov) / 2) / resolution)


def cube_views(position: np.ndarray, near: float, far: float, resolution: int) -> list[LightView]:
    """The six 90° faces of a cube map around ``position``, in :data:`CUBE_FACES` order."""
    proj = tf.perspective(90.0, 1.0, near, far)
    return [LightView(view, proj, texel_angle=2.0 / resolution) for view in cube_view_matrices(position)]
