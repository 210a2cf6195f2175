"""Checks every area-light map technique (pcss, moment_soft) must pass, shared by their test
files so each states only its own specs: a lone floor stays fully lit under rect, disc and
sphere lights, and points behind a one-sided light see none of it."""
from __future__ import annotations

import numpy as np

from helpers import SMALL, make_scene

#: One light of each area shape over the floor of :func:`assert_fully_lit`.
LIGHTS = {
    "rect": {"type": "area", "shape": "rect", "position": [0.3, 4.0, -0.5], "u": [1.5, 0.0, 0.0],
             "v": [0.0, 0.0, 1.0]},
    "disc": {"type": "area", "shape": "disc", "position": [0.3, 4.0, -0.5], "direction": [0.2, -1.0, 0.1],
             "radius": 0.8},
    "sphere": {"type": "area", "shape": "sphere", "position": [0.3, 4.0, -0.5], "radius": 0.7},
}


def assert_fully_lit(lab, shape: str, spec: str) -> None:
    """A floor alone under the ``shape`` light of :data:`LIGHTS`: ``spec`` gives V = 1 on every
    evaluated pixel."""
    scene = make_scene([{"mesh": "plane", "size": [8.0, 8.0]}], [LIGHTS[shape]], eye=(3.0, 5.0, 6.0))
    vis = lab.measure(scene, spec, SMALL).visibility
    evaluated = lab.frame(scene, SMALL).evaluated(0)
    assert evaluated.sum() > 1000
    assert np.all(vis[evaluated] == 1.0), f"{np.sum(vis[evaluated] < 1.0)} pixels below 1"


def assert_behind_one_sided_sees_none(lab, spec: str) -> None:
    """A disc tilted 60° from straight down over a floor: ``spec`` gives V = 0 behind its
    emitting plane (docs/metrics.md) and V = 1 on the rest of the (unblocked) floor."""
    tilt = np.radians(60.0)
    light = {"type": "area", "shape": "disc", "position": [0.0, 2.0, 0.0],
             "direction": [float(np.sin(tilt)), float(-np.cos(tilt)), 0.0], "radius": 0.3}
    scene = make_scene([{"mesh": "plane", "size": [8.0, 8.0]}], [light], eye=(0.0, 6.0, 6.0))
    frame = lab.frame(scene, SMALL)
    vis = lab.measure(scene, spec, SMALL).visibility
    evaluated = frame.evaluated(0)
    behind = ((frame.position - light["position"]) @ np.array(light["direction"])) <= 0
    assert np.sum(evaluated & behind) > 100 and np.sum(evaluated & ~behind) > 100
    assert np.all(vis[evaluated & behind] == 0.0)
    assert np.all(vis[evaluated & ~behind] == 1.0)
