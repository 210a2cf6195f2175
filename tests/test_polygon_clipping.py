"""Exact shadow polygons: property tests against an independent computation (hypothesis).

The independent answer: project the caster polygon onto the receiver's plane from the light
(central projection, closed form) and intersect it with the receiver with scipy's half-space
intersection (Qhull) — no code shared with shadowlab.polygon_clipping.
"""
from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from scipy.spatial import ConvexHull

from shadowlab import polygon_clipping as pc
from shadowlab.convex_reference import ccw, overlap_area

EPS = 1e-12


def convex_polygon_2d(draw, n, radius, centre):
    """A strictly convex polygon: n distinct angles on a 10-degree grid, radii in [0.5, 1]."""
    steps = draw(st.lists(st.integers(0, 35), min_size=n, max_size=n, unique=True))
    angles = np.radians(10.0 * np.sort(steps))
    radii = np.array(draw(st.lists(st.floats(0.5, 1.0), min_size=n, max_size=n)))
    pts = np.stack([np.cos(angles) * radii, np.sin(angles) * radii], 1) * radius + centre
    hull = ConvexHull(pts)
    return pts[hull.vertices]  # counter-clockwise, strictly convex


@st.composite
def configurations(draw):
    """A convex receiver on y = 0, a convex caster between it and a point light above."""
    rec2 = convex_polygon_2d(draw, draw(st.integers(3, 7)), 2.0, np.zeros(2))
    cas2 = convex_polygon_2d(draw, draw(st.integers(3, 7)), draw(st.floats(0.2, 1.2)),
                             np.array([draw(st.floats(-1.5, 1.5)), draw(st.floats(-1.5, 1.5))]))
    height = draw(st.floats(0.2, 2.0))
    tilt = np.array([draw(st.floats(-0.2, 0.2)), draw(st.floats(-0.2, 0.2))])
    light = np.array([draw(st.floats(-2, 2)), draw(st.floats(3.5, 8.0)), draw(st.floats(-2, 2)), 1.0])
    receiver = np.stack([rec2[:, 0], np.zeros(len(rec2)), rec2[:, 1]], 1)
    caster = np.stack([cas2[:, 0], height + cas2 @ tilt, cas2[:, 1]], 1)
    return receiver, caster, light


def intersection_area(p, q):
    """Area of the intersection of two convex 2D polygons (Qhull, independent of the clipper)."""
    return overlap_area(p, q)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(configurations())
def test_fragment_is_the_projected_caster_clipped_to_the_receiver(config):
    receiver, caster, light = config
    assume(np.all(caster[:, 1] < light[1] - 0.5) and np.all(caster[:, 1] > 0.05))
    L = light[:3]
    s = L[1] / (L[1] - caster[:, 1])                 # central projection onto y = 0
    shadow2 = ccw((L + (caster - L) * s[:, None])[:, [0, 2]])
    expected = intersection_area(ccw(receiver[:, [0, 2]]), shadow2)
    frag, pieces = pc.shadow_fragment(receiver, caster, light, EPS)
    got = pc.area(frag)
    scale = pc.area(receiver)
    assert abs(got - expected) <= 1e-9 * scale, (got, expected)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(configurations())
def test_fragment_and_lit_pieces_tile_the_receiver(config):
    receiver, caster, light = config
    frag, pieces = pc.shadow_fragment(receiver, caster, light, EPS)
    parts = ([frag] if len(frag) else []) + pieces
    total = pc.area(receiver)
    assert abs(sum(pc.area(p) for p in parts) - total) <= 1e-9 * total
    flat = [ccw(p[:, [0, 2]]) for p in parts if len(p) >= 3]
    for i in range(len(flat)):
        assert np.all(np.abs(parts[i][:, 1]) < 1e-12)  # on the receiver's plane
        for j in range(i + 1, len(flat)):
            assert intersection_area(flat[i], flat[j]) <= 1e-9 * total  # no overlaps


def test_no_shadow_when_the_caster_is_behind_the_receiver_or_edge_on():
    receiver = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1.0]])
    below = receiver + [0, -0.5, 0]
    light = np.array([0.0, 3.0, 0.0, 1.0])
    frag, pieces = pc.shadow_fragment(receiver, below, light, EPS)
    assert len(frag) == 0 and pieces[0] is receiver
    edge_on = np.array([[0, 1, -0.3], [0, 1.5, 0.3], [0, 2.0, 0.0]])  # its plane holds the light
    assert len(pc.shadow_fragment(receiver, edge_on, light, EPS)[0]) == 0


def test_directional_light_fragment_is_the_parallel_projection():
    receiver = np.array([[-2, 0, -2], [2, 0, -2], [2, 0, 2], [-2, 0, 2.0]])
    caster = np.array([[-0.5, 1, -0.5], [0.5, 1, -0.5], [0.5, 1, 0.5], [-0.5, 1, 0.5]])
    d = np.array([0.3, -1.0, 0.2])
    frag, _ = pc.shadow_fragment(receiver, caster, np.append(-d, 0.0), EPS)
    assert abs(pc.area(frag) - 1.0) < 1e-12
    assert np.allclose(frag.mean(axis=0), [0.3, 0, 0.2])
