"""The maths of light space perspective shadow maps (no GL): the body B, light space, n_opt and
the warp (Wimmer, Scherzer & Purgathofer 2004, "Light Space Perspective Shadow Maps", EGSR).

Frames used here (all float64, 4x4 row-major matrices acting on column vectors, OpenGL
conventions as in :mod:`shadowlab.geometry.transforms`):

- *light space*: a rotation of world space with z = −(the light's travel direction), i.e. towards
  the light (so a GL "camera" in light space looks along the light, down −z), y = the camera's
  view direction projected onto the plane perpendicular to the light (the paper's light-space
  frame: the perspective's axis lies in the shadow map's plane), x = y × z;
- *the warp*: a perspective P whose axis is light-space +y, centre of projection C at distance n
  in front of B's near face, followed by the orthographic fit of P(B) into [−1, 1]³ (the
  paper's post-perspective fit). P keeps every light ray (fixed x, y)
  a line of fixed x', y', so the light stays directional after the warp and one orthographic
  look along z' renders the map.

Hexahedra (a camera frustum, a box) are 8 corners indexed by three bits: corner 4i + 2j + k
has bit i on x (left/right), j on y (bottom/top), k on z (box: min/max z; frustum: near/far),
the order of :func:`shadowlab.geometry.bounds.box_corners`.
"""
from __future__ import annotations

import numpy as np

from . import transforms as tf
from .frusta import MIN_EXTENT, PAD

#: The 12 edges of a hexahedron in the corner order above: corner pairs differing in one bit.
HEX_EDGES = np.array([(a, a | bit) for bit in (1, 2, 4) for a in range(8) if not a & bit])
#: The 6 faces: corners sharing one bit's value (bit, value) → 4 corner indices.
HEX_FACES = np.array([[c for c in range(8) if bool(c & bit) == value] for bit in (1, 2, 4) for value in (False, True)])
#: γ (the angle between the view and light directions) below which the warp is replaced by the
#: uniform (orthographic) map: sin γ < this. n_opt grows as 1 / sin γ (:func:`n_optimal`); at
#: sin γ = 0.01 (γ = 0.57°) it is about 100 × (z_n + √(z_n z_f)), which for a frustum with far /
#: near = 100 is 11 × far: the warp then changes texel sizes across B by under 10 %, and light
#: space's y axis (the view direction projected perpendicular to the light) loses its direction.
MIN_SIN_GAMMA = 0.01
#: Relative tolerance (× the body's extent) for "inside" when intersecting convex hexahedra.
INSIDE_TOLERANCE = 1e-9


def frustum_corners(view: np.ndarray, fov_y: float, aspect: float, near: float, far: float) -> np.ndarray:
    """The 8 world corners (8, 3) of a camera's view frustum (``view``: world → view matrix,
    vertical ``fov_y`` in degrees, aspect = width / height), in the hexahedron corner order."""
    ty = np.tan(np.radians(fov_y) / 2.0)
    tx = ty * aspect
    pts = np.array([[(1 if i else -1) * tx * d, (1 if j else -1) * ty * d, -d]
                    for i in (0, 1) for j in (0, 1) for d in (near, far)])
    return tf.transform_points(np.linalg.inv(view), pts)


def hexahedron_planes(corners: np.ndarray) -> np.ndarray:
    """The 6 face planes (6, 4) of a convex hexahedron ``corners`` (8, 3): unit normal n and d
    with n·p + d ≥ 0 inside."""
    centre = corners.mean(axis=0)
    planes = []
    for face in HEX_FACES:
        a, b, c, d = corners[face]
        n = np.cross(b - a, c - a)
        if np.linalg.norm(n) < np.linalg.norm(np.cross(d - a, c - a)):  # a degenerate triple
            n = np.cross(d - a, c - a)
        n = n / np.linalg.norm(n)
        off = -n @ a
        if n @ centre + off < 0:
            n, off = -n, -off
        planes.append(np.append(n, off))
    return np.array(planes)


def _inside(points: np.ndarray, planes: np.ndarray, tol: float) -> np.ndarray:
    """Bool (M,): points on the inner side of every plane, within ``tol``."""
    return np.all(points @ planes[:, :3].T + planes[:, 3] >= -tol, axis=1)


def _edge_plane_points(corners: np.ndarray, planes: np.ndarray) -> np.ndarray:
    """Where the edges of hexahedron ``corners`` cross each of ``planes`` (K, 3)."""
    p, q = corners[HEX_EDGES[:, 0]], corners[HEX_EDGES[:, 1]]
    dp = p @ planes[:, :3].T + planes[:, 3]   # (12, 6)
    dq = q @ planes[:, :3].T + planes[:, 3]
    cross = (dp * dq) < 0
    t = np.divide(dp, dp - dq, out=np.zeros_like(dp), where=cross)
    pts = p[:, None, :] + t[..., None] * (q - p)[:, None, :]
    return pts[cross]


def hexahedra_intersection(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Vertices (M, 3) of the intersection of two convex hexahedra given by their corners (8, 3)
    each — a's corners inside b, b's inside a, and the crossings of each one's edges with the
    other's faces that lie inside both (a superset of the vertices, whose convex hull is the
    intersection); (0, 3) when they do not meet."""
    pa, pb = hexahedron_planes(a), hexahedron_planes(b)
    scale = max(float(np.ptp(np.concatenate([a, b]), axis=0).max()), MIN_EXTENT)
    tol = INSIDE_TOLERANCE * scale
    cand = np.concatenate([a[_inside(a, pb, tol)], b[_inside(b, pa, tol)],
                           _edge_plane_points(a, pb), _edge_plane_points(b, pa)])
    keep = _inside(cand, pa, tol) & _inside(cand, pb, tol)
    return cand[keep]


def light_space(light_direction: np.ndarray, view_direction: np.ndarray) -> tuple[np.ndarray, float]:
    """(R, sin γ): the world → light-space rotation R (4x4; z towards the light, y the view
    direction projected perpendicular to the light) and sin γ, γ the angle between
    the view direction and the light's direction. When sin γ < :data:`MIN_SIN_GAMMA` the
    projected view direction is ill-defined and y is any axis perpendicular to the light."""
    z = -tf.normalize(light_direction)
    v = tf.normalize(view_direction)
    sin_gamma = float(np.linalg.norm(np.cross(v, z)))
    y = v - (v @ z) * z
    if sin_gamma < MIN_SIN_GAMMA:
        helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        y = helper - (helper @ z) * z
    y = y / np.linalg.norm(y)
    x = np.cross(y, z)
    r = np.eye(4)
    r[0, :3], r[1, :3], r[2, :3] = x, y, z
    return r, sin_gamma


def n_optimal(z_near: float, z_far: float, sin_gamma: float) -> float:
    """n_opt = (z_n + √(z_n · z_f)) / sin γ (the paper's optimal n for a view perpendicular
    to the light, z_n + √(z_n z_f), and its generalisation to any γ): the distance from the centre of projection to B's near face that spreads the
    perspective aliasing error evenly between B's near and far ends. z_n, z_f: the camera's
    near and far view depths of B (world units)."""
    return (z_near + np.sqrt(z_near * z_far)) / sin_gamma


def _fit_unit_cube(points: np.ndarray) -> np.ndarray:
    """The orthographic matrix that maps the bounding box of ``points`` (N, 3) (padded by
    :data:`PAD` of each side) into [−1, 1]³, larger z (nearer the light) to −1, the
    window depth 0 end; it keeps the orientation of a GL projection (z flipped), so face
    culling in the depth pass still holds."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    pad = PAD * np.maximum(hi - lo, MIN_EXTENT)  # per axis: the warp makes the sides very unequal
    lo, hi = lo - pad, hi + pad
    return tf.orthographic(lo[0], hi[0], lo[1], hi[1], -hi[2], -lo[2])


def perspective_along_y(near: float) -> np.ndarray:
    """The LiSPSM perspective P (the paper's warp) in its own frame (centre of projection at the
    origin, axis +y): x' = x / y, y' = (y − near) / y (0 on the near face, rising towards 1 far
    away), z' = z / y; w = y. The far face needs no parameter: the orthographic fit that follows
    scales P(B) into the unit cube. This y row (rather than the textbook (a·y + b) / y, which
    maps near/far to ±1) keeps the matrix free of cancelling terms of size n² / (far − near),
    so float32 keeps its precision when n is large (the near-uniform end). Orientation-
    preserving for y > 0 (Jacobian determinant near / y⁴ > 0)."""
    return np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, -near], [0.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0, 0.0]])


def warp_projection(body_ls: np.ndarray, eye_ls: np.ndarray, n: float) -> np.ndarray:
    """The whole LiSPSM projection (4x4, light space → clip space) for the body's light-space
    points ``body_ls`` (N, 3) and the camera's eye in light space ``eye_ls`` (3,): the
    perspective P with near distance ``n`` (world units) from its centre C to B's near face
    (smallest y; the fit takes in B's far end), C on the line through the eye parallel to y
    (as in the paper); then the orthographic fit of P(B) into the unit cube."""
    y_min = float(body_ls[:, 1].min())
    centre = np.array([eye_ls[0], y_min - n, eye_ls[2]])
    shift = np.eye(4)
    shift[:3, 3] = -centre
    p = perspective_along_y(n) @ shift
    warped = tf.transform_points(p, body_ls)
    return _fit_unit_cube(warped) @ p


def uniform_projection(body_ls: np.ndarray) -> np.ndarray:
    """The uniform map's projection (4x4, light space → clip space): the orthographic fit of the
    body's light-space points (N, 3) into the unit cube (the limit of the warp as n → ∞)."""
    return _fit_unit_cube(body_ls)


def texel_world_sizes(view_proj: np.ndarray, rotation: np.ndarray, points: np.ndarray, resolution: int,
                      step: float) -> np.ndarray:
    """The world size (M,) of one texel of a ``resolution``² map seen through ``view_proj`` at
    ``points`` (M, 3): 1 / √|det J| with J the Jacobian of texel coordinates over the plane
    perpendicular to the light (light-space x, y: the rows of ``rotation``), by central
    differences of ``step`` world units."""
    half = 0.5 * resolution  # clip [-1, 1] → texels [0, resolution]
    cols = []
    for axis in rotation[:2, :3]:
        plus = tf.transform_points(view_proj, points + step * axis)[:, :2]
        minus = tf.transform_points(view_proj, points - step * axis)[:, :2]
        cols.append((plus - minus) * half / (2.0 * step))
    det = cols[0][:, 0] * cols[1][:, 1] - cols[0][:, 1] * cols[1][:, 0]
    return 1.0 / np.sqrt(np.abs(det))
