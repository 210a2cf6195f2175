"""Per-triangle shadow volumes: exact against the ray-traced truth (the leaves test the truth's
own rays) on soups, open meshes, every light type and a point light all around; the tile-level
verdicts change no pixel; the counters add up; a full pair list is retried or fails loudly."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.techniques import TechniqueError, from_spec

from helpers import SMALL, mismatches



@pytest.mark.parametrize("scene", [
    "sv_soup",              # 3,000 single-triangle blades, crossed quads, piercing triangles, lidless boxes
    "box_on_plane",         # point light, closed box
    "sun_scene",            # directional
    "spot_scene",           # spot
    "target_direct_scene",  # rays ending on the light's plane
    "sm_point_cube",        # a point light among the casters: volumes in every direction
    "sv_open_mesh",         # open meshes
    "sv_light_close",       # the light close to a caster: wide volumes, many tiles accepted whole
    "sm_thin",              # a zero-thickness quad 1 cm above the floor
    pytest.param("city_wires", marks=pytest.mark.slow),  # tens of thousands of thin casters
])
def test_exact_against_the_truth(lab, scene):
    wrong, evaluated, m = mismatches(lab, scene, "per_triangle_volume")
    assert evaluated > 1000
    assert wrong == 0, f"{wrong} of {evaluated} pixels differ from the truth"
    assert (m.visibility < 0.5).sum() > 20  # not trivially lit: some shadow to get wrong on every scene
    assert m.stats["tiles_rejected"] > 0 and m.stats["sample_tests"] > 0


def test_the_stencil_volume_is_not_exact_on_the_soup(lab):
    """The same scene and size: the plain volume's silhouettes miscount on the soup, so the
    exactness test above can fail."""
    wrong, _, _ = mismatches(lab, "sv_soup", "shadow_volume")
    assert wrong > 0


def test_accepting_tiles_changes_no_pixel(lab):
    """A tile accepted whole (one set for all its samples) gives the mask the leaves would: equal
    bit for bit to the run where every tile not rejected goes down to the sample tests."""
    base = lab.measure("sv_light_close", "per_triangle_volume:accept=false", SMALL)
    m = lab.measure("sv_light_close", "per_triangle_volume", SMALL)
    np.testing.assert_array_equal(m.visibility, base.visibility)
    assert base.stats["tiles_accepted"] == 0 and m.stats["tiles_accepted"] > 0
    assert m.stats["sample_tests"] < base.stats["sample_tests"]  # the accepted tiles' samples are not tested


@pytest.mark.parametrize("scene", ["box_on_plane", pytest.param("sm_point_cube", marks=pytest.mark.slow)])
def test_culling_closed_meshes_changes_no_pixel(lab, scene):
    """Closed casters (the light outside): the triangles facing away from it are skipped, and the
    mask is equal bit for bit to the one from every triangle."""
    every = lab.measure(scene, "per_triangle_volume:cull=none", SMALL)
    culled = lab.measure(scene, "per_triangle_volume", SMALL)
    np.testing.assert_array_equal(culled.visibility, every.visibility)
    assert every.stats["triangles_culled"] == 0
    assert culled.stats["triangles_culled"] > culled.stats["triangles"] // 4
    assert culled.stats["pixel_ops"] < every.stats["pixel_ops"]


def test_soups_are_not_culled(lab):
    assert lab.measure("sv_soup", "per_triangle_volume", SMALL).stats["triangles_culled"] == 0


@pytest.mark.slow  # four hierarchy shapes on two scenes
@pytest.mark.parametrize("scene", ["sv_light_close", "sm_point_cube"])
def test_the_hierarchy_changes_no_pixel(lab, scene):
    """Leaf size, levels and depth clusters only change the work, never the mask."""
    base = lab.measure(scene, "per_triangle_volume:accept=false,cull=none", SMALL)
    for spec in ("per_triangle_volume", "per_triangle_volume:depth_clusters=0",
                 "per_triangle_volume:levels=1,tile=4", "per_triangle_volume:levels=4,tile=16,depth_clusters=8"):
        m = lab.measure(scene, spec, SMALL)
        np.testing.assert_array_equal(m.visibility, base.visibility, err_msg=spec)


def test_counters_add_up(lab):
    st = lab.measure("sv_light_close", "per_triangle_volume", SMALL).stats
    assert st["tile_tests"] == st["tiles_accepted"] + st["tiles_rejected"] + st["tiles_descended"]
    assert st["pixel_ops"] == st["sample_tests"] + st["tiles_accepted"]
    assert 0 < st["sample_sets"] <= st["sample_tests"]
    assert st["volume_fragments"] == 0
    assert st["triangles"] == sum(len(o.faces) for o in lab.frame("sv_light_close", SMALL).scene.objects if o.casts)
    assert st["memory_bytes"] > 0 and st["nodes"] > 0
    # counted, not estimated: a second render counts the same
    again = lab.measure("sv_light_close", "per_triangle_volume", SMALL).stats
    assert again == st


@pytest.mark.slow  # renders with and without clusters at two sizes
def test_depth_clusters_cut_the_sample_tests(lab):
    """2014's view-sample clusters: boxes split in depth are straddled by fewer volumes, so the
    soup's columns before the far ground need less than half the sample tests."""
    clustered = lab.measure("sv_soup", "per_triangle_volume", SMALL).stats
    flat = lab.measure("sv_soup", "per_triangle_volume:depth_clusters=0", SMALL).stats
    assert 2 * clustered["sample_tests"] < flat["sample_tests"]


def test_a_full_pair_list_is_retried_to_the_same_answer(lab):
    full = lab.measure("box_on_plane", "per_triangle_volume", SMALL)
    small = lab.measure("box_on_plane", "per_triangle_volume:capacity=1", SMALL)
    np.testing.assert_array_equal(small.visibility, full.visibility)
    assert full.stats["list_retries"] == 0 and small.stats["list_retries"] > 0
    # every level retried, the top one (level 3: depth clusters and three levels of tiles) too,
    # where the culled triangles are counted; the box is closed, so some are culled
    assert any("level-3 list" in n and "overflowed" in n for n in small.notes), small.notes
    assert full.stats["triangles_culled"] > 0
    # the retried levels' counters were zeroed first: the work counted is the same
    for key in ("triangles_culled", "tile_tests", "tiles_accepted", "tiles_rejected", "tiles_descended",
                "sample_tests", "sample_sets"):
        assert small.stats[key] == full.stats[key], key


def test_a_full_pair_list_fails_loudly_when_asked(lab):
    with pytest.raises(TechniqueError, match="overflowed"):
        lab.measure("box_on_plane", "per_triangle_volume:capacity=16,on_overflow=fail", SMALL)


def test_parameters():
    t = from_spec("per_triangle_volume:tile=4,levels=2,depth_clusters=0,accept=false,cull=none,capacity=100,"
                  "on_overflow=fail")
    assert from_spec(t.spec()).params() == t.params()
    for bad in ("tile=5", "levels=0", "levels=5", "depth_clusters=9", "cull=back", "on_overflow=drop"):
        with pytest.raises(TechniqueError):
            from_spec(f"per_triangle_volume:{bad}")


def test_a_count_that_could_wrap_fails_loudly(lab, monkeypatch):
    """The counters are 32-bit: a level whose appends could reach their range is refused before
    it runs (the range lowered here so that a small scene reaches it), never a wrapped count."""
    from shadowlab.techniques.volumes import per_triangle_volume
    monkeypatch.setattr(per_triangle_volume, "COUNTER_RANGE", 1000)
    with pytest.raises(TechniqueError, match="32-bit counter"):
        lab.measure("box_on_plane", "per_triangle_volume", SMALL)
