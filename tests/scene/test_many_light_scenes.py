"""The many-light scenes (issue 40, family "many lights", prefix ``ml_``): they load with their
light counts, every light but the city's moon has a range, the ranges bite (each light's
evaluated pixels are a small share of the frame), and the generator reproduces the committed
files byte for byte."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from helpers import SMALL
from shadowlab.gpu.frame import Frame
from shadowlab.scene import builtin_scene_dir, builtin_scenes, load_scene
from shadowlab.scene.animation import scene_at

ROOT = Path(__file__).resolve().parents[2]

#: scene → (lights, of which spot lights, triangles), as experiments/make_many_light_scenes.py prints them
SCENES = {
    "ml_city_64": (64, 24, 3998),
    "ml_city_256": (256, 96, 3998),
    "ml_city_walk": (64, 24, 3998),
    "ml_interior": (40, 14, 1802),
}


@pytest.fixture(scope="module")
def scenes():
    return {name: load_scene(name) for name in SCENES}


def test_the_family_is_shipped(scenes):
    assert {n for n in builtin_scenes() if n.startswith("ml_")} == set(SCENES)
    for name, scene in scenes.items():
        assert scene.family == "many lights", name


@pytest.mark.parametrize("name", SCENES)
def test_counts_and_ranges(scenes, name):
    """Light and triangle counts; every light but the city's moon is a point or spot light
    with a range and no ambient; the moon is the only light with ambient, and a small one."""
    scene = scenes[name]
    lights, spots, triangles = SCENES[name]
    assert len(scene.lights) == lights
    assert sum(l.type_name == "spot" for l in scene.lights) == spots
    assert sum(len(o.faces) for o in scene.objects) == triangles
    unranged = [l for l in scene.lights if getattr(l, "range", 0.0) == 0.0]
    ranged = [l for l in scene.lights if getattr(l, "range", 0.0) > 0.0]
    if name.startswith("ml_city"):
        assert [l.type_name for l in unranged] == ["directional"] and 0 < unranged[0].ambient <= 0.05
    else:
        assert not unranged
    assert len(ranged) == lights - len(unranged)
    assert {l.type_name for l in ranged} == {"point", "spot"} and all(l.ambient == 0.0 for l in ranged)


def test_the_small_city_is_part_of_the_large_one_in_the_same_city(scenes):
    """ml_city_64 and ml_city_walk light the same geometry as ml_city_256 with a subset of its
    lights: only the light count (and the walk's camera) differs."""
    big, small, walk = scenes["ml_city_256"], scenes["ml_city_64"], scenes["ml_city_walk"]
    for other in (small, walk):
        assert [o.name for o in other.objects] == [o.name for o in big.objects]
        assert all(np.array_equal(a.vertices, b.vertices) for a, b in zip(other.objects, big.objects))
    keys = {(l.type_name, tuple(l.position) if hasattr(l, "position") else None) for l in big.lights}
    assert all((l.type_name, tuple(l.position) if hasattr(l, "position") else None) in keys for l in small.lights)
    assert [l.describe() for l in walk.lights] == [l.describe() for l in small.lights]
    assert walk.animation is not None and walk.animation.frames == 24 and small.animation is None
    first = scene_at(walk, 0.0).camera
    assert np.allclose(first.eye, walk.camera.eye) and np.allclose(first.target, walk.camera.target)
    assert np.linalg.norm(scene_at(walk, 1.0).camera.eye - walk.camera.eye) > 30  # it walks down the street


@pytest.mark.parametrize("name", SCENES)
def test_ranges_bite(scenes, name):
    """At 160x120 each ranged light's evaluated pixels are a small share of the frame (the
    unranged lights' would be most of it), yet most lights of a still view light some pixel."""
    frame = Frame(scenes[name], *SMALL)
    try:
        ranged = [i for i, l in enumerate(frame.scene.lights) if getattr(l, "range", 0.0) > 0]
        share = np.array([frame.compact_evaluated(i).sum() for i in ranged]) / (SMALL[0] * SMALL[1])
        assert share.mean() < 0.1 and share.max() < 0.5, (share.mean(), share.max())
        assert (share > 0).mean() > (0.25 if name == "ml_city_walk" else 0.6)
        if name.startswith("ml_city"):
            moon = frame.compact_evaluated(0).sum() / (SMALL[0] * SMALL[1])
            assert moon > 2 * share.max() and moon > 20 * share.mean()
    finally:
        frame.release()


def test_the_generator_reproduces_the_files(tmp_path):
    subprocess.run([sys.executable, str(ROOT / "experiments" / "make_many_light_scenes.py"), "--out", str(tmp_path)],
                   check=True, capture_output=True)
    written = sorted(p.name for p in tmp_path.glob("*.toml"))
    assert written == sorted(f"{n}.toml" for n in SCENES)
    for name in written:
        assert (tmp_path / name).read_bytes() == (builtin_scene_dir() / name).read_bytes(), name


@pytest.mark.parametrize("name", SCENES)
def test_each_file_says_what_it_is_and_that_it_is_generated(name):
    head = (builtin_scene_dir() / f"{name}.toml").read_text().split("\nfamily")[0]
    assert head.startswith("# Many lights (issue 40)") and "Generated by experiments/make_many_light_scenes.py" in head
