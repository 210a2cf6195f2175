"""Temporal metrics between consecutive frames of an animation: flicker and temporal error.

Players notice shadows that shimmer more than any still-frame error, so the lab measures how a
technique's visibility *changes* from frame to frame against how the truth's changes. Pixels
of frame k are matched to frame k−1 by exact reprojection (the reverse reprojection of Nehab
et al. 2007, "Accelerating real-time shading with reverse reprojection caching", §3, here
with the frames' exact float64 surface points, docs/architecture.md#evaluation-evaluator-in-shadowlabmeasurementpipelinepy):

- each evaluated pixel p of frame k has its exact point P_k; P_k is projected through frame
  k−1's camera to the *nearest* pixel q (the pixel whose area holds the projection);
- the match is **valid** when q lies inside the image, is evaluated in frame k−1, and frame
  k−1's exact point at q lies within :data:`SAME_SURFACE_FOOTPRINTS` (a quarter) pixel footprints
  of P_k (nearly the same world point: same surface, not something that hid or uncovered it);
- with a still camera (same view-projection and size) q = p.

Over the valid pixels, with V thresholded at 0.5 (:data:`shadowlab.evaluation.metrics.THRESHOLD`):

- ``flip_rate`` = #(V's class changes while G's does not) / #valid — flicker the truth does
  not have (a pixel that flips with the truth does not count);
- ``temporal_error`` = mean |ΔV − ΔG|, ΔV = V_k(p) − V_{k−1}(q) — change that is not the
  truth's, without thresholding;
- ``valid_pixels`` = #valid.

Images are (height, width) with row 0 = top (docs/architecture.md#conventions); all of this is numpy, no GL.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.reprojection import (  # noqa: F401  (part of the temporal metrics' vocabulary)
    SAME_SURFACE_FOOTPRINTS, FrameGeometry, FrameStep, Reprojection, project_to_pixels, reproject,
)
from .metrics import THRESHOLD

#: The temporal columns each frame row gets from frame 1 on (NaN on frame 0).
TEMPORAL_COLUMNS = ("flip_rate", "temporal_error", "valid_pixels")


@dataclass
class PairMetrics:
    """Temporal metrics of one configuration between frames k−1 and k: the columns and the
    per-pixel flips ``flips`` bool (H, W) in frame k's pixels (flips the truth does not make)."""

    flip_rate: float
    temporal_error: float
    valid_pixels: int
    flips: np.ndarray

    def columns(self) -> dict:
        """The frame row's temporal columns (:data:`TEMPORAL_COLUMNS`)."""
        return {"flip_rate": self.flip_rate, "temporal_error": self.temporal_error, "valid_pixels": self.valid_pixels}


def pair_metrics(vis_prev: np.ndarray, vis_curr: np.ndarray, truth_prev: np.ndarray, truth_curr: np.ndarray,
                 reproj: Reprojection) -> PairMetrics:
    """``flip_rate``, ``temporal_error`` and ``valid_pixels`` (module docstring) of visibility
    images float (H, W) in [0, 1] of frames k−1 and k, against the truth's, over the valid
    matches of ``reproj``. With no valid pixel both rates are 0 (the count says so)."""
    valid = reproj.valid
    q = reproj.source[valid]
    v1, g1 = vis_curr[valid].astype(np.float64), truth_curr[valid].astype(np.float64)
    v0, g0 = vis_prev.reshape(-1)[q].astype(np.float64), truth_prev.reshape(-1)[q].astype(np.float64)
    flip = ((v1 < THRESHOLD) != (v0 < THRESHOLD)) & ((g1 < THRESHOLD) == (g0 < THRESHOLD))
    n = int(valid.sum())
    flips = np.zeros(valid.shape, bool)
    flips[valid] = flip
    if n == 0:
        return PairMetrics(0.0, 0.0, 0, flips)
    return PairMetrics(float(flip.sum()) / n, float(np.mean(np.abs((v1 - v0) - (g1 - g0)))), n, flips)


#: The percentile of the ``p95`` summaries.
SUMMARY_PERCENTILE = 95.0


def summarise(values) -> dict:
    """``mean``, ``p95`` and ``max`` of per-frame-pair values (NaN, e.g. frame 0's, ignored);
    NaN each when there is none."""
    v = np.asarray(values, np.float64)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {"mean": float("nan"), "p95": float("nan"), "max": float("nan")}
    return {"mean": float(v.mean()), "p95": float(np.percentile(v, SUMMARY_PERCENTILE)), "max": float(v.max())}


#: The temporal columns of the shaded image (every light), from frame 1 on (NaN on frame 0).
RADIANCE_TEMPORAL_COLUMNS = ("radiance_flicker", "selection_change_rate")


def radiance_pair(lum_prev: np.ndarray, lum_curr: np.ndarray, truth_prev: np.ndarray, truth_curr: np.ndarray,
                  reproj: Reprojection, floor: float) -> float:
    """``radiance_flicker``: the mean, over the valid matches of ``reproj`` (covered pixels of
    both frames), of |ΔL − ΔL*| / max(L*_k, floor) — the change in the shaded image's luminance
    (images (H, W), NaN where uncovered) that the truth's does not have, relative to the pixel's
    brightness with the radiance metrics' dark floor (:mod:`shadowlab.evaluation.radiance`): a
    light whose shadow or whose light comes and goes as a budget's selection changes. 0 with no
    valid pixel."""
    valid = reproj.valid
    q = reproj.source[valid]
    l1, t1 = lum_curr[valid].astype(np.float64), truth_curr[valid].astype(np.float64)
    l0, t0 = lum_prev.reshape(-1)[q].astype(np.float64), truth_prev.reshape(-1)[q].astype(np.float64)
    if not valid.any():
        return 0.0
    return float(np.mean(np.abs((l1 - l0) - (t1 - t0)) / np.maximum(t1, floor)))


def selection_change(kept_prev: list, kept_curr: list, evaluated_prev: list, evaluated_curr: list,
                     reproj: Reprojection) -> float:
    """``selection_change_rate``: the share of the valid matches of ``reproj`` whose set of lights
    with shadows changed between the frames — the cause of a budget's flicker (Godot's "lights
    flickering in and out as the camera moves"). ``kept_*``: per light a bool (H, W) image of
    where a shadow budget computes its shadow; a light counts at a match only where it is
    evaluated in both frames (a pixel that leaves a light's range or cone changes its lights, not
    the budget's choice). 0 with no valid pixel."""
    valid = reproj.valid
    if not valid.any():
        return 0.0
    q = reproj.source[valid]
    changed = np.zeros(int(valid.sum()), bool)
    for k0, k1, e0, e1 in zip(kept_prev, kept_curr, evaluated_prev, evaluated_curr):
        both = e1[valid] & e0.reshape(-1)[q]
        changed |= both & (k1[valid] != k0.reshape(-1)[q])
    return float(changed.mean())
