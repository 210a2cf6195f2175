"""Reprojection between two frames of an animation with exact points: where pixel p of frame k
was in frame k−1, and whether it is the same surface point (within a fraction of a pixel
footprint) — shared by the temporal metrics (:mod:`shadowlab.evaluation.temporal`) and the
techniques that accumulate over frames (``rt_soft``). :class:`FrameStep` names the frame and
the light a technique renders for during an animation."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: A reprojected match is judged only when the two exact points are at most this many pixel
#: footprints (frame k's, at p) apart: the two frames' visibilities are then compared at nearly
#: the same world point. A looser match (up to the one-pixel rounding to the nearest pixel)
#: compares V at points up to a pixel apart, and a shadow map's staircase — fixed in the world
#: under a stabilised map — then reads as flicker merely because a different point of it was
#: sampled: on tm_camera_dolly, matched within 2 footprints, stabilised cascades "flipped" more
#: than unstabilised ones although their texel grids do not move. A point on another surface is rejected all the more. Pixels that find no match this
#: close are not judged (``valid_pixels`` says how many were).
SAME_SURFACE_FOOTPRINTS = 0.25

@dataclass
class FrameGeometry:
    """What reprojection needs of one frame: exact points float64 (H, W, 3) (NaN where nothing
    is visible), the pixel footprint float64 (H, W) (world size of a pixel there), the camera's
    view-projection matrix float64 (4, 4) (OpenGL clip space)."""

    position: np.ndarray
    footprint: np.ndarray
    view_projection: np.ndarray

    @property
    def shape(self) -> tuple[int, int]:
        """(height, width)."""
        return self.position.shape[:2]

    @classmethod
    def of(cls, frame) -> "FrameGeometry":
        """The geometry of a :class:`shadowlab.gpu.frame.Frame` (copies: the frame may be released)."""
        return cls(frame.position, frame.pixel_footprint(), np.array(frame.view_projection, np.float64))


@dataclass
class Reprojection:
    """Frame k's pixels matched to frame k−1's: ``source`` int64 (H, W), the flat index
    (row·W + col) of q in frame k−1 (−1 where there is none) and ``valid`` bool (H, W)."""

    source: np.ndarray
    valid: np.ndarray

    @property
    def valid_pixels(self) -> int:
        """Number of valid matches."""
        return int(self.valid.sum())


def project_to_pixels(points: np.ndarray, view_projection: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """Continuous image coordinates of world ``points`` (M, 3) float64 through a camera:
    (M, 2) float64 (x = column, y = row, both in pixels, pixel (i, j)'s centre at (i + 0.5,
    j + 0.5), row 0 = top) and a bool (M,) that is True where the point is in front of the
    camera (clip w > 0)."""
    hom = np.concatenate([points, np.ones((len(points), 1))], axis=1) @ view_projection.T
    w = hom[:, 3]
    front = w > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        x_ndc, y_ndc = hom[:, 0] / w, hom[:, 1] / w
    xy = np.stack([(x_ndc + 1.0) * 0.5 * width, (1.0 - y_ndc) * 0.5 * height], axis=1)
    return xy, front


def reproject(curr: FrameGeometry, prev: FrameGeometry, curr_evaluated: np.ndarray,
              prev_evaluated: np.ndarray, footprints: float = SAME_SURFACE_FOOTPRINTS) -> Reprojection:
    """Match the evaluated pixels of frame k (``curr``, bool mask (H, W)) to frame k−1
    (``prev``) by exact reprojection (module docstring); same image size required. A match is
    valid within ``footprints`` pixel footprints (the metrics' :data:`SAME_SURFACE_FOOTPRINTS`
    by default; temporal accumulation, which must find the nearest pixel of the same surface,
    passes a looser one)."""
    if curr.shape != prev.shape:
        raise ValueError(f"frames of different sizes: {curr.shape} and {prev.shape}")
    h, w = curr.shape
    ev = curr_evaluated.astype(bool) & np.isfinite(curr.position).all(axis=2)
    idx = np.flatnonzero(ev)
    pts = curr.position.reshape(-1, 3)[idx]
    if np.array_equal(curr.view_projection, prev.view_projection):
        q = idx.copy()  # a still camera: every point projects to its own pixel
        ok = np.ones(len(idx), bool)
    else:
        xy, ok = project_to_pixels(pts, prev.view_projection, w, h)
        with np.errstate(invalid="ignore"):
            col, row = np.floor(xy[:, 0]), np.floor(xy[:, 1])
            ok &= (col >= 0) & (col < w) & (row >= 0) & (row < h)
        q = np.where(ok, np.nan_to_num(row) * w + np.nan_to_num(col), -1).astype(np.int64)
    ok &= np.take(prev_evaluated.reshape(-1), np.where(ok, q, 0))
    prev_pts = prev.position.reshape(-1, 3)[np.where(ok, q, 0)]
    dist = np.linalg.norm(prev_pts - pts, axis=1)
    with np.errstate(invalid="ignore"):
        ok &= dist <= footprints * curr.footprint.reshape(-1)[idx]
    source = np.full(h * w, -1, np.int64)
    source[idx[ok]] = q[ok]
    valid = np.zeros(h * w, bool)
    valid[idx[ok]] = True
    return Reprojection(source.reshape(h, w), valid.reshape(h, w))


@dataclass(frozen=True)
class FrameStep:
    """What ``shadowlab animate`` tells a technique before it measures light ``light`` of frame
    ``index`` (:meth:`shadowlab.techniques.base.Technique.begin_frame`): which frame of the
    animation this is, so that a technique can keep state across frames (a history) and draw a
    fresh random stream per frame. The frames themselves reach it as always, through ``setup``;
    a technique that reprojects keeps its own previous frame's geometry
    (:meth:`FrameGeometry.of`) and calls :func:`reproject` with the tolerance it needs."""

    index: int
    light: int
