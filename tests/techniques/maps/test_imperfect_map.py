"""Imperfect shadow maps: the point set (uniform by area, deterministic, a subset per light), the
splat's holes and the pull-push that fills them (holes left lit are light leaks), the error
approaching a same-resolution shadow map's with many points, the counters, and bad input."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.measurement.pipeline import measure
from shadowlab.techniques import TechniqueError, from_spec
from shadowlab.techniques.maps.imperfect_map import caster_points, pyramid_levels, radical_inverse

from helpers import SMALL


def _measure(lab, scene, spec, light=0, size=SMALL):
    """One measurement and, for the tests that read the maps, the technique before release."""
    return lab.measure(scene, spec, size, light)


def _rates(lab, scene, spec, light=0, size=SMALL) -> tuple[float, float]:
    """(error_rate, false_lit_rate) of ``spec`` against the truth, thresholded at 0.5."""
    m = lab.measure(scene, spec, size, light)
    truth = lab.truth(scene, size, light)[lab.frame(scene, size).evaluated(light)] < 0.5
    vis = m.visibility[lab.frame(scene, size).evaluated(light)] < 0.5
    return float(np.mean(vis != truth)), float(np.mean(~vis & truth) / max(truth.mean(), 1e-12))


# --------------------------------------------------------------------------- the point set

def test_radical_inverse_mirrors_the_digits():
    np.testing.assert_array_equal(radical_inverse(np.arange(1, 8), 2), [0.5, 0.25, 0.75, 0.125, 0.625, 0.375, 0.875])
    np.testing.assert_allclose(radical_inverse(np.array([1, 2, 3, 4]), 3), [1 / 3, 2 / 3, 1 / 9, 4 / 9])


def test_points_are_uniform_by_area_stratified_and_on_their_triangles():
    """Two triangles of areas 1 and 3: 4096 points split 1024 / 3072 to within one (any 2^m
    consecutive Halton points put one in each 2^-m slice of the cumulative area), every point
    inside its triangle, the same points on every call, another light's subset different."""
    tris = np.array([[[0, 0, 0], [1, 0, 0], [0, 2, 0]],            # area 1, plane z = 0
                     [[0, 0, 5], [3, 0, 5], [0, 2, 5]]], float)    # area 3, plane z = 5
    pts = caster_points(tris, 0, 4096)
    assert pts.shape == (4096, 3)
    first = pts[:, 2] == 0.0
    assert abs(int(first.sum()) - 1024) <= 1 and int((pts[:, 2] == 5.0).sum()) == 4096 - int(first.sum())
    # inside: x / a + y / b <= 1 with the legs a, b of each right triangle
    assert np.all(pts[first, 0] / 1 + pts[first, 1] / 2 <= 1 + 1e-12) and np.all(pts[~first, 0] / 3 + pts[~first, 1] / 2 <= 1 + 1e-12)
    assert np.all(pts[:, :2] >= -1e-12)
    # uniform inside the big triangle: its four corner-similar quarters (midpoint split) get a quarter each
    big = pts[~first]
    mid = (big[:, 0] / 3 + big[:, 1] / 2 <= 0.5)                 # the corner quarter at the right angle
    assert abs(mid.mean() - 0.25) < 0.01
    np.testing.assert_array_equal(caster_points(tris, 0, 4096), pts)
    assert not np.array_equal(caster_points(tris, 4096, 4096), pts)
    assert caster_points(tris[:, :, :] * 0.0, 0, 10).shape == (0, 3)  # no area: no points


def test_pyramid_levels_default_to_one_texel_per_face():
    assert pyramid_levels(64, 0) == 6 and pyramid_levels(32, 0) == 5 and pyramid_levels(64, 2) == 2


# --------------------------------------------------------------------------- holes and pull-push

def test_pull_push_fills_every_hole_and_keeps_every_splatted_depth(lab):
    """spot_scene's spot light, 64² (one face): the splat leaves holes, pull-push fills them all,
    a texel a point reached keeps its depth, and a filled depth lies between the face's
    splatted extremes (averages and interpolations of them)."""
    tech = from_spec("imperfect_map:points=4096")
    frame = lab.frame("spot_scene", SMALL)
    tech.prepare(frame, frame.slot(0))
    try:
        tech.render()
        splat, filled = tech.splat_depths(), tech.map_depths()
        stats = tech.stats()
    finally:
        tech.release()
    valid = splat < 1.0
    assert stats["points_splatted"] == 4096 and stats["map_texels"] == 64 * 64
    assert stats["hole_texels"] == int((~valid).sum()) > 500      # measured 2,560 of 4,096
    assert stats["hole_texels_after"] == 0 and np.all(filled < 1.0)
    np.testing.assert_array_equal(filled[valid], splat[valid])
    assert filled[~valid].min() >= splat[valid].min() and filled[~valid].max() <= splat[valid].max()
    assert stats["pyramid_levels"] == 6 and stats["passes"] == 1 + 2 * 6 + 1


def test_a_face_without_points_stays_empty_and_the_others_fill(lab):
    """sm_room_lamp's point lamp gets a cube; the room has no ceiling, so the face looking up
    (+y) receives no point: exactly its 64² texels stay holes (lit), no other face's depths
    reach it, and every other face is filled."""
    m = _measure(lab, "sm_room_lamp", "imperfect_map:projection=cube", light=1)
    assert m.stats["faces"] == 6 and m.stats["map_texels"] == 6 * 64 * 64
    assert m.stats["hole_texels"] > 64 * 64
    assert m.stats["hole_texels_after"] == 64 * 64


def test_fewer_levels_leave_the_widest_holes(lab):
    """The pyramid's depth bounds the holes filled: one level fills some, not all; every level
    fills all."""
    auto, one, six = (
        _measure(lab, "multi_light", f"imperfect_map:points=1024,levels={n}", light=2).stats for n in (0, 1, 6))
    assert auto["hole_texels"] == one["hole_texels"] == six["hole_texels"]
    assert 0 < one["hole_texels_after"] < one["hole_texels"]
    assert auto["hole_texels_after"] == six["hole_texels_after"] == 0


def test_without_pull_push_holes_stay_and_light_leaks(lab):
    """The sun of multi_light (orthographic map, 64²): without pull-push the splat's holes stay
    (lit) and many truly shadowed pixels come out lit; pull-push removes most of those leaks.
    Measured at 160x120: 3,204 of 4,096 texels are holes; false-lit 74 % without, 6.1 % with
    (error rate 1.1 % and 1.0 %: the leaks are in a small shadowed share of the pixels)."""
    off = _measure(lab, "multi_light", "imperfect_map:pull_push=false", light=2)
    assert off.stats["hole_texels"] == off.stats["hole_texels_after"] > 1000 and off.stats["pyramid_levels"] == 0
    _, lit_on = _rates(lab, "multi_light", "imperfect_map", light=2)
    _, lit_off = _rates(lab, "multi_light", "imperfect_map:pull_push=false", light=2)
    assert lit_off > 0.4 and lit_on < 0.15 and lit_off > 4 * lit_on


def test_many_points_approach_a_same_resolution_shadow_map(lab):
    """box_on_plane, 64² maps: with 256k points the imperfect map's error comes within a
    third of a percentage point of a 64² shadow map's (slope-scaled bias, as the imperfect
    map's), and is far below the error of 1k points. Measured at 160x120: error rate 0.22 %
    (256k points), 2.7 % (1k points), shadow map 0.076 %."""
    sparse, _ = _rates(lab, "box_on_plane", "imperfect_map:points=1024")
    dense, _ = _rates(lab, "box_on_plane", "imperfect_map:points=262144")
    full, _ = _rates(lab, "box_on_plane", "shadow_map:resolution=64,variant=slope")
    assert dense < full + 0.003
    assert sparse > 5 * dense


def test_the_splat_submits_every_point_to_every_face(lab):
    """The counting render: the splat pass draws the light's points once per face (clipping
    keeps each in its own), the pull and push passes one invocation per texel of each level."""
    frame = lab.frame("multi_light", SMALL)
    m = measure(from_spec("imperfect_map:points=3000"), frame, 2, repeat=1, warmup=0)
    assert m.stats["points_splatted"] == 3000 and m.stats["faces"] == 1
    assert m.work["splat"]["vertices"] == 3000 and m.work["splat"]["draws"] == 1
    texels = sum((64 >> k) ** 2 for k in range(1, 7))            # levels 1 .. 6 of one 64² face
    assert m.work["pull"]["compute_invocations"] >= texels
    assert m.work["push"]["texture_taps"] > 0


# --------------------------------------------------------------------------- parameters

def test_spec_round_trips():
    t = from_spec("imperfect_map:points=4096,resolution=32,pull_push=false,levels=3,bias=0.01,slope_scale=1,"
                  "filter=pcf3,projection=cube")
    again = from_spec(t.spec())
    assert again.params() == t.params() and again.spec() == t.spec()
    assert t.points == 4096 and t.resolution == 32 and t.pull_push is False and t.filter == "pcf3"


@pytest.mark.parametrize("spec,match", [
    ("imperfect_map:resolution=48", "resolution must be a power of two"),
    ("imperfect_map:resolution=32,levels=6", "levels"),
    ("imperfect_map:points=0", "points"),
    ("imperfect_map:filter=hw2x2", "filter"),
    ("imperfect_map:bias=-1", "bias"),
    ("imperfect_map:pull_push=maybe", "pull_push"),
])
def test_bad_parameters_are_named(spec, match):
    with pytest.raises(TechniqueError, match=match):
        from_spec(spec)
