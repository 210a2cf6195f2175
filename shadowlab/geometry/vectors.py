"""Row-wise vector products with one rounding behaviour everywhere.

numpy's ``a @ b`` on two 3-vectors and ``np.einsum`` over rows round differently in the last
bit (different summation kernels). Code that must give bit-identical planes whether it handles
one polygon or a batch (the exact shadow polygons and their bulk culling) uses :func:`dot`,
whose batched ``matmul`` rounds exactly like the 1-D ``@``.
"""
from __future__ import annotations

import numpy as np


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot products over the last axis of broadcastable float64 arrays (..., 3) → (...),
    rounded like ``a[i] @ b[i]``."""
    a, b = np.broadcast_arrays(np.asarray(a, np.float64), np.asarray(b, np.float64))
    return (a[..., None, :] @ b[..., :, None])[..., 0, 0]


def dot3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot products over the last axis (3) of broadcastable float64 arrays, as
    ``(a₀b₀ + a₁b₁) + a₂b₂`` elementwise: the same bits for one row or a million (nothing
    depends on the batch's shape), and several times cheaper than :func:`dot` on small rows;
    for code whose one-row and batched forms both use it (the exact shadow polygons)."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def dot4(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot products over the last axis (4) of broadcastable float64 arrays, as
    ``((a₀b₀ + a₁b₁) + a₂b₂) + a₃b₃`` elementwise (a plane against a homogeneous point): like
    :func:`dot3`, the same bits for one row or many, and in compiled code."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2] + a[..., 3] * b[..., 3]
