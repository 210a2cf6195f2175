"""The camera's pixel rays and the exact surface points behind them, in float64, with no GL:
the terms that form each pixel's ray (:func:`_pixel_ray_terms`), the ray met with a triangle's
plane (:func:`plane_hits`, :func:`plane_numerators`), and the one rule that says which points a
light is evaluated at (:func:`evaluated_rule`). The frame (:mod:`shadowlab.gpu.frame`) forms its
pixel-centre points with them and the sub-pixel samples (:mod:`.subpixel`) their other samples,
so the two agree bit for bit at the centre."""
from __future__ import annotations

import numpy as np


#: Where the frame's camera rays cross a pixel: its centre, as a fraction of the pixel (x, y).
PIXEL_CENTRE = (0.5, 0.5)


def _pixel_ray_terms(camera, width: int, height: int, offset: tuple[float, float] = PIXEL_CENTRE
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The two terms :meth:`Camera.pixel_rays` sums for pixel (row, col), as tables: per column
    ``−back + x·right`` (width, 3) and per row ``y·up`` (height, 3), each computed with the same
    operations, so ``col_term[col] + row_term[row]`` is bitwise ``pixel_rays(...)[row, col]``.

    ``offset`` (ox, oy) in [0, 1)²: the ray through (col + ox, row + oy) in pixel units, x right
    and y down from the pixel's top-left corner (sub-pixel samples, :mod:`shadowlab.truth.subpixel`);
    the default, the centre, gives the pixel-centre rays bit for bit."""
    ox, oy = offset
    view = camera.view()
    right, up, back = view[0, :3], view[1, :3], view[2, :3]
    t = np.tan(np.radians(camera.fov_y) / 2.0)
    x = (2.0 * (np.arange(width) + ox) / width - 1.0) * t * width / height
    y = (1.0 - 2.0 * (np.arange(height) + oy) / height) * t
    return -back[None, :] + x[:, None] * right[None, :], y[:, None] * up[None, :]


def plane_hits(eye: np.ndarray, dirs: np.ndarray, tri: np.ndarray, unit: np.ndarray, numerator: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact float64 hits of camera rays ``eye + t · dirs`` (M, 3) with the planes of triangles
    ``tri`` (M,): ``unit`` the (T, 3) unit triangle normals (zero if degenerate), ``numerator``
    the (T,) per-triangle (v0 − eye)·n (:func:`plane_numerators`). Returns (points (M, 3) — written
    into ``dirs`` —, normals (M, 3) turned towards the camera, valid (M,): a point in front of
    the eye on a non-degenerate triangle).

    The same operations as :func:`shadowlab.geometry.rays.ray_plane_hits`, bit for bit (pinned
    by tests/truth/test_ground_truth.py), with fewer temporaries: N·d with the same ``einsum``, the
    numerator gathered per triangle, eye + t·d a column at a time (1-D loops, no (M, 3)
    broadcast)."""
    normals = np.take(unit, tri, axis=0)  # (M, 3)
    denom = np.einsum("ij,ij->i", dirs, normals)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.take(numerator, tri)
        t /= denom
    points = dirs
    flip = denom > 0  # turn the normal towards the camera
    for k in range(3):
        np.multiply(points[:, k], t, out=points[:, k])
        np.add(points[:, k], eye[k], out=points[:, k])
        np.negative(normals[:, k], out=normals[:, k], where=flip)
    valid = np.take(np.any(unit != 0, axis=1), tri)  # per triangle: negation keeps zero-ness
    valid &= t > 0
    valid &= t < np.inf  # with t > 0: isfinite(t)
    return points, normals, valid


def plane_numerators(triangles: np.ndarray, unit: np.ndarray, eye: np.ndarray) -> np.ndarray:
    """Per triangle (T,): (v0 − eye)·n, the numerator of the ray parameter of :func:`plane_hits`
    — the same ``einsum``, row by row, as on gathered (M, 3) arrays."""
    return np.einsum("ij,ij->i", triangles[:, 0] - eye, unit)


def evaluated_rule(light, points: np.ndarray, normals: np.ndarray, valid: np.ndarray,
                   receives: np.ndarray) -> np.ndarray:
    """The evaluated points of docs/metrics.md for ``light``: bool (K,) for float64 ``points`` (K, 3)
    with camera-facing unit ``normals`` (K, 3), ``valid`` (K,) (an exact point exists) and
    ``receives`` (K,) (its object receives shadows) — receiving, valid, facing the light
    (N·L > 0), inside its footprint (λ > 0) and not at the light (distance > 0). The one rule
    behind :meth:`Frame.evaluated_mask` (pixel centres) and
    :meth:`shadowlab.truth.subpixel.SubpixelSamples.evaluated` (sub-pixel samples)."""
    dirs, dist = light.to_light(points)
    facing = np.einsum("ij,ij->i", dirs, normals) > 0
    lam = light.footprint(points)
    return receives & valid & facing & (lam > 0) & (dist > 0)
