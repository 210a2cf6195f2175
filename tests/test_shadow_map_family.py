"""The shadow-map family on its hard cases (issue: shadow maps in full). Numbers, not timings."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.frame import Frame
from shadowlab.run import measure_configs
from shadowlab.scene import load_scene

SIZE = (480, 360)
_FRAMES: dict = {}


def rows(scene, specs, size=SIZE):
    """measure_configs on a frame shared by every test of this module; indexed by the specs given."""
    if (scene, size) not in _FRAMES:
        _FRAMES[(scene, size)] = Frame(load_scene(scene), *size)
    df = measure_configs(scene, specs, frame=_FRAMES[(scene, size)])
    df = df[~df["reference"]].copy()
    df.index = list(specs)
    return df


def test_grazing_acne_and_slope_scaled_bias():
    """SM1: light 3 degrees above the floor, the classic fit over every visible receiver."""
    df = rows("sm_grazing", ["shadow_map:variant=none,fit=receivers", "shadow_map:variant=slope,fit=receivers",
                             "shadow_map:variant=slope,hardware_offset=true,fit=receivers"])
    assert df.loc["shadow_map:variant=none,fit=receivers", "false_shadow_rate"] > 0.20
    assert df.loc["shadow_map:variant=slope,fit=receivers", "false_shadow_rate"] < 0.02
    assert df.loc["shadow_map:variant=slope,hardware_offset=true,fit=receivers", "false_shadow_rate"] < 0.02


def test_bias_that_removes_grazing_acne_opens_a_contact_gap():
    """SM2: the smallest constant bias that removes the grazing acne, carried to the contact
    scene as the same world-space offset, opens a lit gap at the cube's contact; second-depth
    and midpoint keep the contact."""
    biases = [0.0002, 0.0005, 0.001, 0.002]
    graze = rows("sm_grazing", [f"shadow_map:bias={b},fit=receivers" for b in biases])
    ok = [b for b in biases if graze.loc[f"shadow_map:bias={b},fit=receivers", "false_shadow_rate"] < 0.005]
    assert ok and ok[0] > biases[0], "the sweep must bracket the acne threshold"
    world = ok[0] * graze["depth_range"].iloc[0]
    contact_specs = ["shadow_map:variant=second_depth,fit=receivers", "shadow_map:variant=midpoint,fit=receivers"]
    contact = rows("sm_contact", contact_specs)
    b_contact = float(world / contact["depth_range"].iloc[0])
    contact = rows("sm_contact", [f"shadow_map:bias={b_contact!r},fit=receivers",
                                  f"shadow_map:bias={4 * b_contact!r},fit=receivers"] + contact_specs)
    gap = contact.loc[f"shadow_map:bias={b_contact!r},fit=receivers", "contact_gap_px"]
    gap4 = contact.loc[f"shadow_map:bias={4 * b_contact!r},fit=receivers", "contact_gap_px"]
    assert gap > 0.2 and gap4 > 2 * gap, (gap, gap4)  # a lit band along the card's base, in pixels
    for spec in contact_specs:
        assert contact.loc[spec, "contact_gap_px"] < gap / 10


def test_second_depth_no_acne_on_convex_but_fails_on_thin_casters():
    """Wang & Molnar: no bias needed on closed convex casters; a single-sided quad vanishes."""
    for scene in ("box_on_plane", "sm_contact"):
        df = rows(scene, ["shadow_map:variant=second_depth"])
        assert df["false_shadow_rate"].iloc[0] < 0.005
    thin = rows("sm_thin", ["shadow_map:variant=second_depth", "shadow_map:variant=midpoint", "shadow_map"])
    assert thin.loc["shadow_map:variant=second_depth", "false_lit_rate"] > 0.03
    assert thin.loc["shadow_map:variant=second_depth", "false_lit_rate"] > 5 * thin.loc["shadow_map", "false_lit_rate"]


def test_boundary_error_falls_with_resolution_on_the_aliasing_case():
    res = [128, 256, 512, 1024, 2048]
    df = rows("sm_aliasing", [f"shadow_map:resolution={r},variant=slope" for r in res], size=(640, 480))
    errors = df["boundary_error_px"].to_numpy()
    assert np.all(np.diff(errors) < 0), errors


def test_cube_map_point_light_with_casters_all_around():
    df = rows("sm_point_cube", ["shadow_map:projection=cube,resolution=1024,variant=slope",
                                "shadow_map:projection=frustum,resolution=1024,variant=slope"])
    cube = df.loc["shadow_map:projection=cube,resolution=1024,variant=slope"]
    assert cube["faces"] == 6 and cube["error_rate"] < 0.01
    frustum = df.loc["shadow_map:projection=frustum,resolution=1024,variant=slope"]
    assert frustum["error_rate"] > cube["error_rate"] and "projection=cube" in frustum["notes"]


@pytest.mark.parametrize("filt", ["pcf3", "pcf5", "hw2x2"])
def test_filters_give_fractional_visibility(filt):
    from shadowlab.techniques import from_spec
    from shadowlab.techniques.raytrace import RayTraced
    from shadowlab.metrics import compare

    frame = _FRAMES.setdefault(("sm_contact", SIZE), Frame(load_scene("sm_contact"), *SIZE))
    tech = from_spec(f"shadow_map:filter={filt},resolution=512")
    tech.setup(frame, 0)
    tech.render()
    vis = tech.visibility()
    tech.release()
    gt = RayTraced()
    gt.setup(frame, 0)
    gt.render()
    ev = frame.evaluated(0)
    partial = (vis[ev] > 0.01) & (vis[ev] < 0.99)
    assert partial.sum() > 50, "filtered edges must be fractional"
    m = compare(vis, gt.visibility(), ev)
    assert m["error_rate"] < 0.01 and 0 < m["visibility_mae"] < 0.01


def test_two_layer_variants_keep_contact_and_cost_more():
    df = rows("sm_nonconvex", ["shadow_map:variant=midpoint", "shadow_map:variant=dual", "shadow_map"])
    for spec in ("shadow_map:variant=midpoint", "shadow_map:variant=dual"):
        assert df.loc[spec, "error_rate"] < 0.005
        assert df.loc[spec, "memory_bytes"] == 3 * df.loc["shadow_map", "memory_bytes"]
        assert df.loc[spec, "passes"] == 4


def test_depth_precision_near_plane_too_close():
    """A near plane at 1e-3 squeezes depth towards 1: 16-bit depth shows acne, 24-bit far less;
    with the fitted near plane both are clean."""
    specs = [f"shadow_map:variant=slope,bias=0,near={n},depth_bits={b}" for n in (0.001, 0.0) for b in (16, 24)]
    df = rows("spot_scene", specs)
    acne = df["false_shadow_rate"].to_numpy()
    assert acne[0] > 0.1 and acne[1] < acne[0] / 5
    assert acne[2] < 0.005 and acne[3] < 0.005
