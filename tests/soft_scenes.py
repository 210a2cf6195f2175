"""The small area-light scenes the soft-shadow truth is checked on (tests/truth/test_soft_truth.py)
and the exact soft shadows are held to (tests/techniques/geometric/test_exact_soft.py)."""
from __future__ import annotations

import numpy as np

from helpers import make_scene

FLOOR = {"name": "floor", "mesh": "plane", "size": [10.0, 10.0]}
UP = np.array([0.0, 1.0, 0.0])


def box(name, size, translate, rotate=(0.0, 0.0, 0.0)):
    return {"name": name, "mesh": "box", "size": list(size), "translate": list(translate), "rotate": list(rotate)}


TILTED_BOX = box("box", (1.0, 0.6, 0.8), (0.2, 1.2, -0.1), (0.0, 30.0, 0.0))
SCENES = {
    # a rectangle, tilted, over a box that floats above the floor
    "rect": ([FLOOR, TILTED_BOX],
             {"type": "area", "shape": "rect", "position": [-0.5, 3.5, 0.3], "u": [1.6, 0.0, 0.0], "v": [0.0, 0.3, 1.0]}),
    "disc": ([FLOOR, TILTED_BOX],
             {"type": "area", "shape": "disc", "position": [-0.5, 3.5, 0.3], "direction": [0.2, -1.0, 0.1], "radius": 0.7}),
    # a near-vertical rectangle reaching below the floor (y from -0.4 to 1.0), emitting towards +x:
    # the floor sees only its upper part, and the floor behind it (x < -2.2) sees none of it; the
    # floor does not cast, so only the horizon rule hides the part below it (a casting floor
    # would block those rays itself)
    "below_horizon": ([{**FLOOR, "casts": False}, box("box", (0.4, 0.5, 1.2), (-1.0, 0.55, 0.2), (0.0, 10.0, 0.0))],
                      {"type": "area", "shape": "rect", "position": [-2.2, 0.3, 0.0], "u": [0.0, 1.4, 0.2],
                       "v": [0.2, 0.0, 1.6]}),
    # two casters whose shadows overlap
    "overlap": ([FLOOR, box("a", (1.0, 0.3, 1.0), (0.0, 1.0, 0.0), (0.0, 20.0, 0.0)),
                 box("b", (0.8, 0.3, 0.8), (0.4, 1.8, 0.3), (0.0, -15.0, 0.0))],
                {"type": "area", "shape": "rect", "position": [0.0, 4.0, 0.0], "u": [1.5, 0.0, 0.0], "v": [0.0, 0.0, 1.5]}),
}


def build(key):
    objects, light = SCENES[key]
    return make_scene(objects, [light], eye=(3.0, 5.0, 6.0), target=(-0.3, 0.0, 0.0), fov_y=55.0, name=key)
