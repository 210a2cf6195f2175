"""Reference areas for checking the exact shadow polygons: the intersection of 2D polygons
computed by GEOS (through shapely), whose predicates are robust to the slivers that clipping
produces. It shares no code with :mod:`shadowlab.geometry.clipping.scalar`, so tests and
experiments can judge that module by it.

(An earlier version intersected half-spaces with Qhull after finding an interior point by linear
programming; the solver's 1e-7 feasibility tolerance made it report overlaps of 1e-8-thin slivers
that do not exist, and Qhull then refused them: CI failed on such a case.)
"""
from __future__ import annotations

import numpy as np
from shapely.geometry import Polygon


def ccw(poly2: np.ndarray) -> np.ndarray:
    """The polygon (K, 2) in counter-clockwise order (positive signed area)."""
    x, y = poly2[:, 0], poly2[:, 1]
    return poly2 if np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0 else poly2[::-1]


def overlap_area(p2: np.ndarray, q2: np.ndarray) -> float:
    """Area of the intersection of two simple 2D polygons (K, 2) and (M, 2), in any vertex order;
    0 when they only touch or are disjoint."""
    p, q = Polygon(p2), Polygon(q2)
    if not (p.is_valid and q.is_valid):
        raise ValueError("overlap_area needs simple polygons")
    return float(p.intersection(q).area)
