"""Per-triangle quantities: normals and planes (the one definition the frame, the edge table
and the techniques share)."""
from __future__ import annotations

import numpy as np

from .vectors import dot


def triangle_cross(tris: np.ndarray) -> np.ndarray:
    """(v1 − v0) × (v2 − v0) of triangles (T, 3, 3) float64 → (T, 3): the normal scaled by twice
    the area, oriented by the counter-clockwise winding; zero for degenerate triangles."""
    tris = np.asarray(tris, np.float64)
    return np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])


def triangle_normals(tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals (T, 3) of triangles (T, 3, 3) and the cross products' lengths (T,) (twice
    the areas). Degenerate (zero-area) triangles get the zero vector, never NaN."""
    cross = triangle_cross(tris)
    length = np.linalg.norm(cross, axis=1, keepdims=True)
    unit = np.divide(cross, length, out=np.zeros_like(cross), where=length > 0)
    return unit, length[:, 0]


def triangle_planes(tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Planes n·x + d = 0 of triangles (T, 3, 3): unit normals (T, 3) and offsets d (T,)
    (n = 0, d = 0 for degenerate triangles)."""
    unit, _ = triangle_normals(tris)
    return unit, -dot(unit, np.asarray(tris, np.float64)[:, 0])
