"""partitioned_volume: exact against the ray-traced truth on soups, contacts, open meshes, a
light close to its casters and every light type; the stack and stackless queries identical;
counters that add up; a full pool retried or failed, never silent."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.techniques import TechniqueError, from_spec
from shadowlab.techniques.volumes.partitioned_volume import NODES_PER_TRIANGLE

from helpers import SMALL, mismatches



# Known ties (scene -> wrong pixels allowed at 160x120): none. The leaves decide with the
# watertight test on the truth's own rays, and the margins send every ray that test could call
# blocked to the leaf (the module docstring), so the mask is the exact test's on every ray.
KNOWN_TIES: dict[str, int] = {}


@pytest.mark.parametrize("scene", [
    "sv_soup",                  # a triangle soup: blades, crossed quads, piercing triangles, non-manifold fans
    "box_on_plane",             # point light, a box in contact with the floor
    "sun_scene",                # directional
    pytest.param("spot_scene", marks=pytest.mark.slow),     # spot (inner-loop budget: a deep tree)
    pytest.param("sm_point_cube", marks=pytest.mark.slow),  # point light among casters on every side
    "sv_open_mesh",             # open meshes
    "sv_light_close",           # a light close to its casters: large angular margins
    "sm_thin",                  # a zero-thickness quad 1 cm above the floor
    "target_direct_scene",      # target-direct: nothing behind the disc casts
])
def test_exact_against_the_truth(lab, scene):
    wrong, evaluated, m = mismatches(lab, scene, "partitioned_volume", SMALL)
    assert evaluated > 1000
    assert wrong <= KNOWN_TIES.get(scene, 0), f"{wrong} of {evaluated} pixels differ from the truth"
    assert (m.visibility < 0.5).sum() > 20  # not trivially lit (the fewest: target_direct_scene, 63)


@pytest.mark.slow  # two renders of spot_scene's deep trees
def test_another_insertion_order_builds_another_tree_with_the_same_mask(lab):
    scene_order = lab.measure("spot_scene", "partitioned_volume", SMALL)
    light_order = lab.measure("spot_scene", "partitioned_volume:order=light", SMALL)
    np.testing.assert_array_equal(light_order.visibility, scene_order.visibility)
    assert light_order.stats["nodes_visited"] != scene_order.stats["nodes_visited"]


def test_the_plain_volume_is_not_exact_on_the_soup(lab):
    """The same scene and size: the stencil volume's counts go wrong on the soup (so the test
    above can fail)."""
    wrong, _, _ = mismatches(lab, "sv_soup", "shadow_volume", SMALL)
    assert wrong > 0


@pytest.mark.parametrize("scene", ["sm_thin",  # three more renders each: the others with the slow tests
                                   pytest.param("sv_soup", marks=pytest.mark.slow),
                                   pytest.param("spot_scene", marks=pytest.mark.slow)])
def test_stack_and_stackless_enter_the_same_nodes(lab, scene):
    """Same mask, same nodes entered, same exact tests; a two-node stack overflows on most rays
    and the hybrid's stackless remainder still enters the same nodes."""
    runs = {spec: lab.measure(scene, spec, SMALL) for spec in
            ("partitioned_volume:query=stack", "partitioned_volume:query=stackless",
             "partitioned_volume:query=stack,stack_size=2")}
    (_, first), *rest = runs.items()
    for spec, m in rest:
        np.testing.assert_array_equal(m.visibility, first.visibility, err_msg=spec)
        for key in ("nodes_visited", "nodes_visited_max", "leaf_tests", "tree_nodes", "tree_depth"):
            assert m.stats[key] == first.stats[key], (spec, key)
    assert runs["partitioned_volume:query=stackless"].stats["stack_overflows"] == 0
    assert runs["partitioned_volume:query=stack,stack_size=2"].stats["stack_overflows"] > 1000


def test_counters_add_up(lab):
    wrong, evaluated, m = mismatches(lab, "sv_soup", "partitioned_volume", SMALL)
    st = m.stats
    assert st["triangles"] == 3278
    inserted = st["triangles"] - st["triangles_culled"] - st["triangles_skipped"]
    assert st["tree_nodes"] == NODES_PER_TRIANGLE * inserted
    assert st["pixel_ops"] == st["nodes_visited"]
    assert st["nodes_visited_mean"] == pytest.approx(st["nodes_visited"] / evaluated)
    assert st["nodes_visited_mean"] <= st["nodes_visited_max"] <= st["tree_nodes"]
    assert NODES_PER_TRIANGLE < st["tree_depth"] <= st["tree_nodes"]
    # every shadowed pixel ended at a leaf whose exact test hit
    shadowed = int((m.visibility[lab.frame("sv_soup", SMALL).evaluated(0)] < 0.5).sum())
    assert shadowed <= st["leaf_tests"] <= st["nodes_visited"]
    assert st["memory_bytes"] > 48 * st["tree_nodes"]
    assert st["pool_retries"] == 0


def test_a_full_pool_is_retried_to_the_same_answer(lab):
    full = lab.measure("box_on_plane", "partitioned_volume", SMALL)
    small = lab.measure("box_on_plane", "partitioned_volume:pool=12", SMALL)
    np.testing.assert_array_equal(small.visibility, full.visibility)
    assert small.stats["pool_retries"] == 1 and full.stats["pool_retries"] == 0
    assert any("overflowed" in n for n in small.notes)
    assert small.stats["nodes_visited"] == full.stats["nodes_visited"]


def test_a_full_pool_fails_loudly_when_asked(lab):
    with pytest.raises(TechniqueError, match="overflowed"):
        lab.measure("box_on_plane", "partitioned_volume:pool=12,on_overflow=fail", SMALL)


def test_light_sampled_area_light(lab):
    """Area lights through the pipeline's light sampling, like the other hard techniques."""
    m = lab.measure("soft_overlap", "partitioned_volume:light_samples=2", SMALL)
    v = m.visibility[np.isfinite(m.visibility)]
    assert ((v > 0) & (v < 1)).any()  # a penumbra of two hard shadows


def test_parameters():
    t = from_spec("partitioned_volume:query=stackless,stack_size=8,pool=100,on_overflow=fail,order=scene")
    assert from_spec(t.spec()).params() == t.params()
    with pytest.raises(TechniqueError, match="query"):
        from_spec("partitioned_volume:query=bvh")
    with pytest.raises(TechniqueError, match="did you mean 'pool'"):
        from_spec("partitioned_volume:pol=10")


def test_resumed_queries_give_the_same_answer(lab, monkeypatch):
    """Queries cut off after a few steps per dispatch and resumed where they stopped (the walk
    saved per ray) enter the same nodes and give the same mask as queries that finish at once."""
    from shadowlab.techniques.volumes import partitioned_volume
    whole = lab.measure("box_on_plane", "partitioned_volume", SMALL)
    assert not any("resumed" in n for n in whole.notes)
    monkeypatch.setattr(partitioned_volume, "STEP_BUDGET", 8)
    for spec in ("partitioned_volume", "partitioned_volume:query=stackless"):
        cut = lab.measure("box_on_plane", spec, SMALL)
        np.testing.assert_array_equal(cut.visibility, whole.visibility, err_msg=spec)
        assert cut.stats["nodes_visited"] == whole.stats["nodes_visited"], spec
        assert cut.stats["nodes_visited_max"] > 8, spec  # some query needed more than one dispatch
        assert any("resumed" in n for n in cut.notes), spec


def test_a_tree_too_deep_to_walk_up_fails_loudly(lab, monkeypatch):
    """The build's walk up the ancestors loops as deep as the tree: past half llvmpipe's loop
    limit the run fails instead of leaving ancestors' depths silently stale (the limit lowered
    here so that a small scene reaches it)."""
    from shadowlab.gpu import programs
    monkeypatch.setattr(programs, "LLVMPIPE_LOOP_LIMIT", 8)
    with pytest.raises(TechniqueError, match="nodes deep"):
        lab.measure("box_on_plane", "partitioned_volume", SMALL)
