"""Reference areas for checking the exact shadow polygons: intersection of convex 2D polygons
computed with Qhull (scipy's half-space intersection). It shares no code with
:mod:`shadowlab.geometry.polygon_clipping`, so tests and experiments can judge that module by it.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, HalfspaceIntersection


def ccw(poly2: np.ndarray) -> np.ndarray:
    """The polygon (K, 2) in counter-clockwise order (positive signed area)."""
    x, y = poly2[:, 0], poly2[:, 1]
    return poly2 if np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0 else poly2[::-1]


def halfspaces(poly2: np.ndarray) -> np.ndarray:
    """Half-spaces A x + b <= 0 (rows [A, b]) of a convex polygon (K, 2)."""
    poly2 = ccw(poly2)
    e = np.roll(poly2, -1, axis=0) - poly2
    normal = np.stack([e[:, 1], -e[:, 0]], 1)  # outward for counter-clockwise order
    return np.concatenate([normal, -(normal * poly2).sum(1, keepdims=True)], 1)


def overlap_area(p2: np.ndarray, q2: np.ndarray, thinnest: float = 1e-10) -> float:
    """Area of the intersection of two convex 2D polygons; 0 when it is empty or a sliver
    thinner than ``thinnest`` (its largest inscribed circle, found by linear programming)."""
    hs = np.concatenate([halfspaces(p2), halfspaces(q2)])
    norm = np.linalg.norm(hs[:, :2], axis=1)
    res = linprog([0, 0, -1], A_ub=np.concatenate([hs[:, :2], norm[:, None]], 1), b_ub=-hs[:, 2],
                  bounds=[(None, None), (None, None), (0, None)])
    if not res.success or res.x[2] < thinnest:
        return 0.0
    return float(ConvexHull(HalfspaceIntersection(hs, res.x[:2]).intersections).volume)
