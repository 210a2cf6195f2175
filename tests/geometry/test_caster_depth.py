"""The nearest caster inside a perspective light view (shadowlab.geometry.caster_depth): the
compiled kernel against its plain-Python reference, exact cases, and the near planes it gives
a light that stands inside a caster's bounding box."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from shadowlab.geometry import frusta
from shadowlab.geometry import transforms as tf
from shadowlab.geometry.caster_depth import nearest_depths, nearest_depths_reference

DOWN = tf.look_along(np.zeros(3), np.array([0.0, -1.0, 0.0]))


def test_kernel_equals_the_reference_on_random_triangles(rng):
    """Random triangles around a light, some inside its frustum, some straddling it, some behind:
    the compiled clipping gives the reference's depths (inf where nothing is inside)."""
    tris = rng.normal(size=(400, 3, 3)) * 2.0
    for view, tan_half, far in [(DOWN, 1.0, 3.0), (tf.look_along(np.zeros(3), np.array([0.3, 0.2, -1.0])), 0.4, 10.0)]:
        got = nearest_depths(tris, view, tan_half, far)
        want = nearest_depths_reference(tris, view, tan_half, far)
        assert np.isinf(got).sum() == np.isinf(want).sum() > 0
        assert np.isfinite(got).sum() > 50
        assert np.allclose(got, want, rtol=1e-12, atol=1e-12, equal_nan=False)


def test_a_floor_under_a_light_is_nearest_at_its_foot_and_a_wall_at_the_frustum_edge():
    """A big floor 2 below a light looking down: nearest at depth 2 (the foot of the axis). A
    wall at x = 1 reaching up past the light, seen in a 90° frustum: its nearest point inside
    is where the frustum's side plane x = d meets it, at depth 1."""
    floor = np.array([[[-50.0, -2.0, -50.0], [50.0, -2.0, -50.0], [0.0, -2.0, 80.0]]])
    wall = np.array([[[1.0, 5.0, -50.0], [1.0, 5.0, 50.0], [1.0, -60.0, 0.0]]])
    d = nearest_depths(np.concatenate([floor, wall]), DOWN, 1.0, 100.0)
    assert d == pytest.approx([2.0, 1.0], abs=1e-12)
    assert np.isinf(nearest_depths(floor, DOWN, 1.0, 1.5)).all()  # beyond far: shadows nothing covered
    behind = floor + [0.0, 4.0, 0.0]  # above the light looking down
    assert np.isinf(nearest_depths(behind, DOWN, 1.0, 100.0)).all()


def test_a_light_inside_a_rooms_box_gets_its_near_plane_from_the_triangles():
    """A lamp inside a closed room (one mesh, the light inside its bounding box): the box fit
    falls back to far x MIN_NEAR_OVER_FAR; the triangle fit puts near just in front of the
    nearest wall the view sees (the floor 2.5 below, a spot looking down)."""
    room = trimesh.creation.box(bounds=[[-3.0, 0.0, -2.5], [3.0, 3.0, 2.5]])
    room.invert()  # faces inward: an interior
    light = np.array([0.0, 2.5, 0.0])
    pts = np.array([[x, 0.0, z] for x in (-2.0, 2.0) for z in (-2.0, 2.0)])
    casters = frusta.Casters.from_triangles(room.triangles)
    view = tf.look_along(light, np.array([0.0, -1.0, 0.0]))
    near, far, notes = frusta.perspective_fit(light, pts, casters, [view], 90.0)
    box_near, box_far = frusta.perspective_range(light, pts, casters.bounds, np.array([[0.0, -1.0, 0.0]]), 90.0)
    assert box_far == pytest.approx(far)
    assert box_near == pytest.approx(far * frusta.MIN_NEAR_OVER_FAR)
    assert near == pytest.approx(min(2.5 * (1 - frusta.PAD), far * frusta.MAX_NEAR_OVER_FAR)) and not notes
    table = trimesh.creation.box(bounds=[[-0.5, 0.7, -0.5], [0.5, 0.75, 0.5]])  # a table top 1.75 below
    casters = frusta.Casters.from_triangles(np.concatenate([room.triangles, table.triangles]))
    near, _, _ = frusta.perspective_fit(light, pts, casters, [view], 90.0)
    assert near == pytest.approx(1.75 * (1 - frusta.PAD))


def test_casters_nearer_than_the_floor_are_clipped_with_a_note():
    """A shade 1e-4 below a lamp whose receivers lie 10 away: the near plane cannot follow it
    below far x MIN_NEAR_OVER_FAR; the shade is clipped, and a note says so. A forced near plane
    that clips casters says so too."""
    light = np.zeros(3)
    shade = np.array([[[-0.1, -1e-4, -0.1], [0.1, -1e-4, -0.1], [0.0, -1e-4, 0.1]]])
    floor = np.array([[[-50.0, -10.0, -50.0], [50.0, -10.0, -50.0], [0.0, -10.0, 80.0]]])
    casters = frusta.Casters.from_triangles(np.concatenate([shade, floor]))
    pts = np.array([[0.0, -10.0, 0.0], [5.0, -10.0, 5.0]])
    near, far, notes = frusta.perspective_fit(light, pts, casters, [DOWN], 90.0)
    assert near == pytest.approx(far * frusta.MIN_NEAR_OVER_FAR)
    assert len(notes) == 1 and notes[0].startswith("1 caster triangles") and "clipped" in notes[0]
    near, _, notes = frusta.perspective_fit(light, pts, casters, [DOWN], 90.0, near_override=11.0)
    assert near == 11.0 and notes[0].startswith("2 caster triangles") and "forced near plane 11" in notes[0]
