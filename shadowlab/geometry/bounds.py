"""Axis-aligned boxes: distances, corners and segment tests (bounds are (K, 2, 3): min, max)."""
from __future__ import annotations

import numpy as np


def box_distance(p: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Distance from point ``p`` (3,) to each box in ``bounds`` (K, 2, 3); 0 inside."""
    gap = np.maximum(0.0, np.maximum(bounds[:, 0] - p, p - bounds[:, 1]))
    return np.linalg.norm(gap, axis=1)


def box_corners(bounds: np.ndarray) -> np.ndarray:
    """The 8 corners of each box in ``bounds`` (K, 2, 3) → (8K, 3)."""
    idx = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    return np.concatenate([np.stack([b[idx[:, 0], 0], b[idx[:, 1], 1], b[idx[:, 2], 2]], 1) for b in bounds]) \
        if len(bounds) else np.zeros((0, 3))


def segments_hit_boxes(origins: np.ndarray, dirs: np.ndarray, lengths: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Bool (M,): segments ``origins + t · dirs``, 0 ≤ t ≤ ``lengths`` (unit dirs, (M, 3)), that
    cross at least one box of ``bounds`` (slab test, Kay & Kajiya 1986; one box at a time over
    all segments)."""
    hit = np.zeros(len(origins), bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / dirs
        for lo, hi in bounds:
            t1, t2 = (lo - origins) * inv, (hi - origins) * inv
            t_near = np.nanmax(np.minimum(t1, t2), axis=1)
            t_far = np.nanmin(np.maximum(t1, t2), axis=1)
            hit |= (t_near <= t_far) & (t_far >= 0) & (t_near <= lengths)
    return hit
