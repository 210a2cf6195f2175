"""The texel-footprint metric: how large, in image pixels, the shadow-map texel covering each
pixel appears — Lloyd et al.'s perspective-aliasing error *m* (D. B. Lloyd, N. K. Govindaraju,
C. Quammen, S. E. Molnar, D. Manocha, "Logarithmic perspective shadow maps", ACM TOG 27(4),
2008, §3 "Aliasing error"; first in Lloyd, Govindaraju, Molnar & Manocha, "Practical
logarithmic rasterization for low-error shadow maps", Graphics Hardware 2007 / UNC TR 2006).

For a pixel with exact surface point P (the float64 hit of its centre ray, docs/architecture.md#evaluation-evaluator-in-shadowlabmeasurementpipelinepy) and
geometric normal N, let Px, Py be where the centre rays of the pixel one to the right and one
below meet P's tangent plane {X : (X − P)·N = 0}. With T the technique's texel coordinates
(``technique.texel_coordinates``, every point projected through the face P itself looks up),
the Jacobian of the screen → map mapping, in texels per pixel, is

    J = [T(Px) − T(P) | T(Py) − T(P)]   (2 x 2, columns: one pixel right, one pixel down).

A texel's image on the screen is the unit square mapped by J⁻¹; its longest axis is the larger
singular value of J⁻¹, so

    m = σ_max(J⁻¹) = 1 / σ_min(J) = σ_max(J) / |det J|.

m <= 1: every texel is at most a pixel wide (no perspective aliasing); m > 1: a texel spans m
pixels along its worst axis (blocky shadow edges m pixels wide; m > 10 is severe). The
difference over one pixel is exact for orthographic maps on flat receivers (both mappings are
affine there) and a one-pixel finite difference otherwise.

Edge cases: where a neighbour ray does not meet the tangent plane in front of the camera (the
plane is edge-on to it, or the hit is behind the eye) the pixel on the other side (left, or
above) is used with the sign turned; where neither side meets it, or T is not finite (behind a
perspective map's centre of projection), the pixel gets NaN. A singular J (the surface edge-on
to the light) gives m = inf.
"""
from __future__ import annotations

import numpy as np

from ..techniques.base import TechniqueError

#: The percentiles (of the evaluated pixels' m) that become ``texel_footprint_p<q>`` columns.
PERCENTILES = (50, 95)


def neighbour_rays(camera, width: int, height: int, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Unnormalised world directions (M, 3) float64 through the centres of pixels (row, col),
    row 0 = top — the same terms as :meth:`shadowlab.scene.Camera.pixel_rays`, for any integer
    row and column (also one past the image's edge)."""
    view = camera.view()
    right, up, back = view[0, :3], view[1, :3], view[2, :3]
    t = np.tan(np.radians(camera.fov_y) / 2.0)
    x = (2.0 * (np.asarray(cols, np.float64) + 0.5) / width - 1.0) * t * width / height
    y = (1.0 - 2.0 * (np.asarray(rows, np.float64) + 0.5) / height) * t
    return -back[None, :] + x[:, None] * right[None, :] + y[:, None] * up[None, :]


def tangent_hits(eye: np.ndarray, dirs: np.ndarray, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Float64 (M, 3): where rays eye + s·dirs (M, 3) meet the planes through ``points`` with
    ``normals`` (M, 3); NaN where a ray is parallel to its plane or meets it behind the eye."""
    denom = np.einsum("ij,ij->i", dirs, normals)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.einsum("ij,ij->i", points - eye, normals) / denom
    hit = np.isfinite(s) & (s > 0)
    hits = eye + np.where(hit, s, np.nan)[:, None] * dirs
    return hits


def screen_neighbours(frame, points: np.ndarray, normals: np.ndarray, rows: np.ndarray, cols: np.ndarray,
                      axis: int) -> tuple[np.ndarray, np.ndarray]:
    """For pixels (rows, cols) with exact points and normals (M, 3): the tangent-plane hit of the
    neighbour one pixel along ``axis`` (0: right, 1: down) and the step's sign (+1.0), or of the
    neighbour on the other side with sign −1.0 where the first misses the plane. Rows of the
    hits are NaN where both miss."""
    eye = np.asarray(frame.camera.eye, np.float64)
    step = (np.zeros_like(rows), np.ones_like(cols)) if axis == 0 else (np.ones_like(rows), np.zeros_like(cols))
    sign = np.ones(len(points))
    ahead = tangent_hits(eye, neighbour_rays(frame.camera, frame.width, frame.height, rows + step[0],
                                             cols + step[1]), points, normals)
    missed = np.isnan(ahead[:, 0])
    if missed.any():
        m = np.flatnonzero(missed)
        behind = tangent_hits(eye, neighbour_rays(frame.camera, frame.width, frame.height, rows[m] - step[0][m],
                                                  cols[m] - step[1][m]), points[m], normals[m])
        ahead[m] = behind
        sign[m] = -1.0
    return ahead, sign


def footprint_from_jacobian(j: np.ndarray) -> np.ndarray:
    """m = 1 / σ_min(J) for Jacobians (M, 2, 2) (texels per pixel), float64 (M,): σ_max(J) /
    |det J| (no cancellation when the texel is very elongated); inf where det J = 0, NaN where J
    is not finite."""
    a, b, c, d = j[:, 0, 0], j[:, 0, 1], j[:, 1, 0], j[:, 1, 1]
    # the singular values of a 2x2 matrix are (q ± r) / 2 (closed form of its SVD)
    q, r = np.hypot(a + d, c - b), np.hypot(a - d, b + c)
    sigma_max = 0.5 * (q + r)
    det = a * d - b * c
    with np.errstate(divide="ignore", invalid="ignore"):
        return sigma_max / np.abs(det)


#: The metrics columns :func:`footprint_columns` makes.
COLUMNS = tuple(f"texel_footprint_p{q}" for q in PERCENTILES) + ("texel_footprint_max",)


def has_texel_mapping(technique) -> bool:
    """True for a technique that renders a map per face and can say where a point's texels lie:
    one that declares the ``texel_mapping`` capability (``PROVIDES``,
    :data:`shadowlab.techniques.base.CAPABILITIES`). Asked of the declaration, not of the
    technique's class, so the metric knows no technique family."""
    return "texel_mapping" in technique.PROVIDES


def footprint_image(frame, slot, technique) -> np.ndarray:
    """Lloyd et al.'s m per pixel (see the module's docstring): float32 (height, width), row 0 =
    top, in image pixels per texel (the texel's longest axis); NaN where the pixel is not
    evaluated for ``slot`` (a :class:`~shadowlab.gpu.frame.LightSlot` or a scene light's index;
    docs/metrics.md) or m is undefined there. ``technique`` is set up for that slot and has a texel
    mapping (:func:`has_texel_mapping`): a shadow-map technique between ``setup`` and
    ``release``; TechniqueError for one without."""
    if not has_texel_mapping(technique):
        from ..techniques import REGISTRY  # late: the registry loads every technique

        having = [name for name, cls in REGISTRY.items() if "texel_mapping" in cls.PROVIDES]
        raise TechniqueError(f"{technique.name} has no shadow map, so no texel footprint (texel_coordinates): "
                             f"the techniques that provide texel_mapping have one ({', '.join(having)})")
    evaluated = frame.as_slot(slot).evaluated
    idx = frame.pixel_index[evaluated]
    rows, cols = np.divmod(idx, frame.width)
    p = frame.compact_position[evaluated]
    n = frame.compact_normal[evaluated]
    px, sx = screen_neighbours(frame, p, n, rows, cols, axis=0)
    py, sy = screen_neighbours(frame, p, n, rows, cols, axis=1)
    count = len(p)
    reference = np.concatenate([p, p, p])
    t = technique.texel_coordinates(np.concatenate([p, px, py]), reference)
    t0, tx, ty = t[:count], t[count:2 * count], t[2 * count:]
    j = np.stack([(tx - t0) * sx[:, None], (ty - t0) * sy[:, None]], axis=2)  # (M, 2 texel axes, 2 pixel axes)
    m = footprint_from_jacobian(j)
    out = np.full(frame.height * frame.width, np.nan, np.float32)
    out[idx] = m
    return out.reshape(frame.height, frame.width)


def footprint_columns(image: np.ndarray) -> dict:
    """The metrics columns of a footprint image (float (H, W), NaN where not evaluated):
    ``texel_footprint_p50``, ``texel_footprint_p95`` and ``texel_footprint_max`` over the pixels
    where m is defined (inf included: a texel edge-on to the light); NaN when there are none."""
    values = image[~np.isnan(image)].astype(np.float64)
    if len(values) == 0:
        cols = {f"texel_footprint_p{q}": float("nan") for q in PERCENTILES}
        cols["texel_footprint_max"] = float("nan")
        return cols
    # np.percentile interpolates a + (b − a)·t, which is NaN when b = inf even at t = 0 (numpy
    # gives NaN for the median of [1, 2, inf]): inf stands in as the largest float, and a
    # percentile beyond the largest finite m (it interpolates towards an inf) is inf
    finite = values[np.isfinite(values)]
    top = float(finite.max()) if len(finite) else -np.inf
    stand_in = np.where(np.isposinf(values), np.finfo(np.float64).max, values)
    cols = {f"texel_footprint_p{q}": float(np.percentile(stand_in, q)) for q in PERCENTILES}
    cols = {k: float("inf") if v > top else v for k, v in cols.items()}
    cols["texel_footprint_max"] = float(values.max())
    return cols
