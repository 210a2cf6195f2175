"""The shadow map measured against the ground truth on the standard scenes (stated tolerances)."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.frame import Frame
from shadowlab.metrics import compare
from shadowlab.scene import load_scene
from shadowlab.techniques import from_spec
from shadowlab.techniques.raytrace import RayTraced


def measure(scene_name, spec, size=(640, 480), light=0):
    frame = Frame(load_scene(scene_name), *size)
    gt = RayTraced()
    gt.setup(frame, light)
    gt.render()
    tech = from_spec(spec)
    tech.setup(frame, light)
    tech.render()
    vis = tech.visibility()
    tech.release()
    assert vis.dtype == np.float32 and vis.shape == (size[1], size[0])
    return compare(vis, gt.visibility(), frame.evaluated(light)), tech


def test_box_on_plane_2048_sensible_bias_under_1_percent():
    m, _ = measure("box_on_plane", "shadow_map:resolution=2048,bias=0.002", size=(800, 600))
    assert m["evaluated_pixels"] > 100_000 and m["truth_shadowed_pixels"] > 2_000
    assert m["error_rate"] < 0.01


def test_zero_bias_on_sloped_receiver_shows_acne():
    """sun_scene has a ramp (a receiver sloped to the light): without bias, self-shadowing acne."""
    m, _ = measure("sun_scene", "shadow_map:resolution=2048,bias=0")
    assert m["false_shadow_rate"] > 0.05
    fixed, _ = measure("sun_scene", "shadow_map:resolution=2048,bias=0.002")
    assert fixed["false_shadow_rate"] < 0.01


@pytest.mark.parametrize("scene", ["spot_scene", "sun_scene", "target_direct_scene"])
def test_standard_scenes_within_tolerance(scene):
    """Every light type on its standard scene: error rate under 1 % at 2048² with the default bias."""
    m, _ = measure(scene, "shadow_map")
    assert m["truth_shadowed_pixels"] > 1_000
    assert m["error_rate"] < 0.01


def test_lower_resolution_is_worse_on_boundary():
    hi, _ = measure("box_on_plane", "shadow_map:resolution=2048")
    lo, _ = measure("box_on_plane", "shadow_map:resolution=128")
    assert lo["false_lit_rate"] + lo["false_shadow_rate"] > hi["false_lit_rate"] + hi["false_shadow_rate"]


def test_cost_figures():
    _, tech = measure("box_on_plane", "shadow_map:resolution=512,depth_bits=16", size=(160, 120))
    st = tech.stats()
    assert (st["memory_bytes"], st["faces"], st["passes"]) == (512 * 512 * 2, 1, 2) and st["depth_range"] > 0
