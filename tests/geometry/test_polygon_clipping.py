"""Exact shadow polygons: property tests against an independent computation (hypothesis).

The independent answer: project the caster polygon onto the receiver's plane from the light
(central projection for point lights, parallel for directional ones, closed form) and
intersect it with the receiver with GEOS's polygon intersection (shapely) — no code shared
with shadowlab.geometry.clipping.scalar. Configurations are built with the receiver on y = 0
and then turned to any orientation and moved, so receivers and casters are tilted every way.
"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from scipy.spatial import ConvexHull

from shadowlab.geometry.clipping import scalar as pc
from convex_reference import ccw, overlap_area

EPS = 1e-12


def convex_polygon_2d(draw, n, radius, centre):
    """A strictly convex polygon: n distinct angles on a 10-degree grid, radii in [0.5, 1]."""
    steps = draw(st.lists(st.integers(0, 35), min_size=n, max_size=n, unique=True))
    angles = np.radians(10.0 * np.sort(steps))
    radii = np.array(draw(st.lists(st.floats(0.5, 1.0), min_size=n, max_size=n)))
    pts = np.stack([np.cos(angles) * radii, np.sin(angles) * radii], 1) * radius + centre
    hull = ConvexHull(pts)
    return pts[hull.vertices]  # counter-clockwise, strictly convex


def rotation(draw):
    """A rotation matrix from three Euler angles (any orientation: receivers are tilted too)."""
    ax, ay, az = (np.radians(draw(st.floats(-180, 180))) for _ in range(3))
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    return (np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]]) @ np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
            @ np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]]))


@st.composite
def configurations(draw):
    """A convex receiver, a convex tilted caster between it and a point or directional light,
    built with the receiver on y = 0 and then rotated and moved as a whole.

    Returns (receiver, caster, light_h) in world space, the expected shadow area (computed in
    the unrotated frame by projecting the caster onto y = 0 from the light: central or
    parallel projection, then shapely), and the world rotation/offset (to find the plane)."""
    rec2 = convex_polygon_2d(draw, draw(st.integers(3, 7)), 2.0, np.zeros(2))
    cas2 = convex_polygon_2d(draw, draw(st.integers(3, 7)), draw(st.floats(0.2, 1.2)),
                             np.array([draw(st.floats(-1.5, 1.5)), draw(st.floats(-1.5, 1.5))]))
    height = draw(st.floats(0.2, 2.0))
    tilt = np.array([draw(st.floats(-0.2, 0.2)), draw(st.floats(-0.2, 0.2))])
    receiver = np.stack([rec2[:, 0], np.zeros(len(rec2)), rec2[:, 1]], 1)
    caster = np.stack([cas2[:, 0], height + cas2 @ tilt, cas2[:, 1]], 1)
    if draw(st.booleans()):  # point light above
        L = np.array([draw(st.floats(-2, 2)), draw(st.floats(3.5, 8.0)), draw(st.floats(-2, 2))])
        assume(np.all(caster[:, 1] < L[1] - 0.5) and np.all(caster[:, 1] > 0.05))
        s = L[1] / (L[1] - caster[:, 1])
        shadow = L + (caster - L) * s[:, None]
        light = np.append(L, 1.0)
    else:  # directional, travelling downwards
        d = np.array([draw(st.floats(-1, 1)), -1.0, draw(st.floats(-1, 1))])
        d /= np.linalg.norm(d)
        assume(np.all(caster[:, 1] > 0.05))
        shadow = caster - d * (caster[:, 1] / d[1])[:, None]
        light = np.append(-d, 0.0)
    expected = overlap_area(ccw(receiver[:, [0, 2]]), ccw(shadow[:, [0, 2]]))
    rot, shift = rotation(draw), np.array([draw(st.floats(-3, 3)) for _ in range(3)])
    world_light = np.append(rot @ light[:3] + (shift * light[3]), light[3])
    return receiver @ rot.T + shift, caster @ rot.T + shift, world_light, expected, rot, shift


def in_plane(points, rot, shift):
    """World points → the receiver's own (x, z) coordinates and height above its plane."""
    local = (points - shift) @ rot
    return local[:, [0, 2]], local[:, 1]


@pytest.mark.slow  # a long property test: 200 hypothesis examples
@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(configurations())
def test_fragment_is_the_projected_caster_clipped_to_the_receiver(config):
    receiver, caster, light, expected, _, _ = config
    frag, pieces = pc.shadow_fragment(receiver, caster, light, EPS)
    assert abs(pc.area(frag) - expected) <= 1e-9 * pc.area(receiver), (pc.area(frag), expected)


@pytest.mark.slow  # a long property test: 200 hypothesis examples
@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(configurations())
def test_fragment_and_lit_pieces_tile_the_receiver(config):
    receiver, caster, light, _, rot, shift = config
    frag, pieces = pc.shadow_fragment(receiver, caster, light, EPS)
    parts = [p for p in ([frag] if len(frag) else []) + pieces if len(p) >= 3]
    total = pc.area(receiver)
    assert abs(sum(pc.area(p) for p in parts) - total) <= 1e-9 * total
    flat = []
    for p in parts:
        xz, height = in_plane(p, rot, shift)
        assert np.all(np.abs(height) < 1e-12 * (1 + np.abs(shift).max()))  # on the receiver's plane
        flat.append(ccw(xz))
    for i in range(len(flat)):
        for j in range(i + 1, len(flat)):
            assert overlap_area(flat[i], flat[j]) <= 1e-9 * total  # no overlaps


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
