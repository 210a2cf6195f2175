"""The selection policies of a shadow budget (shadowlab.lighting.selection) on scenes whose
answers are known by construction."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.gpu.frame import Frame
from shadowlab.lighting import selection

from helpers import make_scene

#: Four point lights in a row along x above a floor of 8 x 2 strips; light i is brightest over strip i.
LIGHTS = [{"type": "point", "position": [float(x), 1.0, 0.0], "color": [c, c, c], "ambient": 0.0}
          for x, c in ((-3.0, 1.0), (-1.0, 0.9), (1.0, 0.8), (3.0, 0.7))]
STRIPS = [{"name": f"strip{i}", "mesh": "plane", "size": [1.0, 2.0], "translate": [float(x), 0.0, 0.0]}
          for i, x in enumerate(np.arange(-3.5, 4.0, 1.0))]


@pytest.fixture(scope="module")
def scene():
    return make_scene(STRIPS, LIGHTS, eye=(-9.0, 3.0, 0.0), target=(0.0, 0.0, 0.0), fov_y=60.0)


@pytest.fixture(scope="module")
def frame(scene):
    f = Frame(scene, 96, 48)
    yield f
    f.release()


def test_face_rule_keeps_each_face_its_k_strongest_lights(scene, frame):
    sel = selection.select("face", 1, scene.lights, scene.objects, frame)
    ranges = selection.face_ranges(scene.objects)
    for j, (a, b) in enumerate(ranges):  # strip j at x = -3.5 + j: nearest light is (j // 2)
        kept = np.flatnonzero(sel.kept[:, a:b].all(axis=1))
        assert list(kept) == [j // 2], (j, kept)
    assert sel.kept.sum(axis=0).max() == 1
    two = selection.select("face", 2, scene.lights, scene.objects, frame)
    assert np.all(two.kept.sum(axis=0) == 2) and np.all(two.kept >= sel.kept)


def test_face_rule_matches_shadow_polygons_max_lights(scene, frame):
    """The seed's rule as the budget knows it equals shadow_polygons' own max_lights selection."""
    from shadowlab.techniques import from_spec

    sel = selection.select("face", 2, scene.lights, scene.objects, frame)
    tech = from_spec("shadow_polygons:max_lights=2")
    starts = np.cumsum([0] + [len(o.faces) for o in scene.objects])
    for li in range(len(scene.lights)):
        slot = frame.slot(li)
        for j, obj in enumerate(scene.objects):
            assert np.array_equal(tech._kept_faces(obj, slot), sel.kept[li, starts[j]:starts[j + 1]])


def test_closest_screen_and_object_policies(scene, frame):
    n = len(scene.lights)
    closest = selection.select("closest", 2, scene.lights, scene.objects, frame)  # the eye is at x = -9
    assert list(np.flatnonzero(closest.lights())) == [0, 1] and closest.kept.all(axis=1).sum() == 2
    screen = selection.select("screen", 1, scene.lights, scene.objects, frame)
    importance = selection.screen_importance(scene.lights, frame)
    assert importance.shape == (n,) and np.all(importance > 0)
    assert np.flatnonzero(screen.lights())[0] == int(np.argmax(importance))
    per_object = selection.select("object", 1, scene.lights, scene.objects, frame)
    ranges = selection.face_ranges(scene.objects)
    strength = selection.object_importance(scene.lights, scene.objects)
    for j, (a, b) in enumerate(ranges):  # one light per strip, the same over its faces
        col = per_object.kept[:, a:b]
        assert np.all(col == col[:, :1]) and col[:, 0].sum() == 1
        assert np.flatnonzero(col[:, 0])[0] == int(np.argmax(strength[:, j]))
    # without a range a point light does not fall off: the brightest light leads every object's list
    assert np.all(np.argmax(strength, axis=0) == 0)


def test_budget_of_all_lights_keeps_everything(scene, frame):
    for policy in selection.POLICIES:
        sel = selection.select(policy, len(scene.lights), scene.lights, scene.objects, frame)
        assert sel.kept.all(), policy


def test_reservoirs_are_deterministic_and_stable_on_a_still_frame():
    """Equal importance: the draw is random but reproducible; temporal reuse keeps a selection far
    more often than a fresh draw each frame would (a fresh K=1 of 4 keeps it 1/4 of the time)."""
    imp = np.ones(4)
    runs = []
    for _ in range(2):
        state = selection.ReservoirState()
        runs.append([tuple(np.flatnonzero(state.select(imp, 1))) for _ in range(40)])
    assert runs[0] == runs[1]
    kept = sum(a == b for a, b in zip(runs[0], runs[0][1:])) / 39
    assert kept > 0.7
    assert len(set(runs[0])) > 1  # and it does move: a stochastic choice
    # weight 0 is never chosen while K lights have weight
    state = selection.ReservoirState()
    for _ in range(20):
        assert not state.select(np.array([0.0, 1.0, 2.0, 0.0]), 2)[[0, 3]].any()
    # importance follows: a light 100x stronger is chosen almost always
    state = selection.ReservoirState()
    picks = [np.flatnonzero(state.select(np.array([1.0, 100.0, 1.0]), 1))[0] for _ in range(50)]
    assert picks.count(1) >= 45


def test_unknown_policy():
    with pytest.raises(ValueError, match="unknown selection policy"):
        selection.select("nearest", 1, [], [], None)
