"""Exact camera-ray hits in float64 (docs/architecture.md#evaluation-evaluator-in-shadowlabmeasurementpipelinepy): where a pixel-centre ray meets a known plane."""
from __future__ import annotations

import numpy as np


def ray_plane_hits(origin: np.ndarray, dirs: np.ndarray, plane_points: np.ndarray, normals: np.ndarray):
    """Intersect rays ``origin + t · dirs[i]`` (dirs (M, 3), unnormalised) with the planes
    through ``plane_points[i]`` with unit ``normals[i]`` (both (M, 3)).

    Returns ``(points, facing, valid)``: hit points (M, 3) float64; the normals turned towards
    the ray's origin (surfaces are two-sided, docs/metrics.md); and a bool (M,) that is False where
    there is no hit in front of the origin (ray parallel to the plane, degenerate normal, t ≤ 0).
    """
    denom = np.einsum("ij,ij->i", dirs, normals)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.einsum("ij,ij->i", plane_points - origin, normals) / denom
    points = origin + t[:, None] * dirs
    facing = np.where((denom > 0)[:, None], -normals, normals)
    valid = np.isfinite(t) & (t > 0) & np.any(facing != 0, axis=1)
    return points, facing, valid
