"""Projected planar shadows: with every fix on they match the truth; each fix off shows its artefact."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.techniques.geometric.planar import fit_plane, planar_projection

SIZE = (640, 480)


def visibilities(lab, scene, spec):
    """(frame, visibility, truth) of one configuration on the shared frame."""
    return lab.frame(scene, SIZE), lab.measure(scene, spec, SIZE).visibility, lab.truth(scene, SIZE)


@pytest.mark.parametrize("scene", ["box_on_plane", "pp_overlap", "pp_table_edge", "pp_light_plane", "pp_far_low"])
def test_all_fixes_on_match_ground_truth(lab, scene):
    df = lab.rows(scene, ["planar"], SIZE)
    assert df.loc["planar", "truth_shadowed_pixels"] > 1000
    assert df.loc["planar", "error_rate"] <= 0.005


def test_without_offset_the_shadow_z_fights(lab):
    df = lab.rows("pp_far_low", ["planar", "planar:offset=false"], SIZE)
    assert df.loc["planar:offset=false", "false_lit_rate"] > 0.02
    assert df.loc["planar:offset=false", "false_lit_rate"] > 20 * df.loc["planar", "false_lit_rate"]


def test_without_stencil_overlaps_darken_twice(lab):
    df = lab.rows("pp_overlap", ["planar", "planar:stencil=false"], SIZE)
    assert df.loc["planar", "umbra_visibility_std"] == 0.0  # one darkening everywhere in the umbra
    assert df.loc["planar:stencil=false", "umbra_visibility_std"] > 0.01
    assert df.loc["planar:stencil=false", "error_rate"] <= 0.005  # thresholding cannot see it


def test_without_clip_the_shadow_hangs_off_the_table(lab):
    """Out-of-receiver area: shadowed pixels off the table top that the truth has lit, over the
    true shadow area on the table."""
    ratios = {}
    for spec in ("planar", "planar:clip=false"):
        frame, vis, truth = visibilities(lab, "pp_table_edge", spec)
        ev = frame.evaluated(0)
        table = frame.object_id == [o.name for o in frame.scene.objects].index("table_top")
        off = (vis < 0.5) & (truth >= 0.5) & ev & ~table
        ratios[spec] = off.sum() / max(1, ((truth < 0.5) & ev & table).sum())
    assert ratios["planar"] < 0.01 and ratios["planar:clip=false"] > 0.1, ratios


def test_without_light_clip_geometry_behind_the_receiver_casts(lab):
    df = lab.rows("pp_light_plane", ["planar", "planar:clip_light=false"], SIZE)
    assert df.loc["planar:clip_light=false", "false_shadow_pixels"] > 100
    assert df.loc["planar", "false_shadow_pixels"] < 20


def test_non_planar_receivers_are_reported(lab):
    df = lab.rows("sun_scene", ["planar"], SIZE)
    assert "not planar" in df.loc["planar", "notes"] and "ramp" in df.loc["planar", "notes"]


def test_projection_matrix_lands_on_the_plane():
    plane = fit_plane(np.array([[0, 1, 0], [1, 1, 0], [0, 1, 1], [2, 1, 3.0]]))
    assert plane is not None and abs(abs(plane[1]) - 1) < 1e-12
    light = np.array([0.3, 4.0, -0.2, 1.0])
    m = planar_projection(plane, light)
    p = m @ np.array([0.5, 2.0, 0.5, 1.0])
    p = p[:3] / p[3]
    assert abs(p[1] - 1.0) < 1e-12
    # on the ray from the light through the point
    d1, d2 = p - light[:3], np.array([0.5, 2.0, 0.5]) - light[:3]
    assert np.linalg.norm(np.cross(d1, d2)) < 1e-12
    assert fit_plane(np.random.default_rng(0).normal(size=(10, 3))) is None
