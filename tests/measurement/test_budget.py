"""Shadow budgets on any technique (budget=K, select=POLICY, drop=...): the spec, what is rendered,
what the dropped lights get, and the radiance they cost."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.gpu.frame import Frame
from shadowlab.measurement.pipeline import compare_frame, measure
from shadowlab.measurement.scenes import load_measured_scene
from shadowlab.techniques import TechniqueError, from_spec

SIZE = (128, 96)


@pytest.fixture(scope="module")
def frame():
    f = Frame(load_measured_scene("multi_light"), *SIZE)  # a point light, a spot and the sun
    yield f
    f.release()


def test_spec_round_trip_and_errors():
    t = from_spec("shadow_map:budget=2,select=closest,drop=unlit")
    assert t.budget_settings() == {"budget": 2, "select": "closest", "drop": "unlit", "atlas": 0}
    assert from_spec(t.spec()).spec() == t.spec()
    assert t.short_label() == "shadow_map:budget=2,select=closest,drop=unlit"
    assert from_spec("shadow_map").budget_settings() == {}
    assert "budget" not in from_spec("shadow_map").spec()  # a spec without a budget keeps its label
    for bad, match in (("shadow_map:select=screen", "needs a shadow budget"),
                       ("shadow_map:budget=2,select=scren", "did you mean 'screen'"),
                       ("shadow_map:budget=2,drop=none", "drop must be one of"),
                       ("raytrace:budget=2,atlas=2048", "no resolution parameter"),
                       ("shadow_volume:budget=-1", ">= 0"),
                       ("shadow_map:budget=2,atlas=1000", "power of two >= 32"),
                       ("shadow_map:budget=2,atlas=1024", "from 32 to 1024, got 2048"),
                       ("shadow_map:resolution=500,budget=2,atlas=4096", "got 500")):
        with pytest.raises(TechniqueError, match=match):
            from_spec(bad)


def test_a_budget_of_every_light_changes_nothing(frame):
    alone = [measure(from_spec("shadow_map"), frame, li, repeat=1, warmup=0) for li in range(3)]
    budget = [measure(from_spec("shadow_map:budget=3,select=screen"), frame, li, repeat=1, warmup=0) for li in range(3)]
    for a, b in zip(alone, budget):
        assert np.array_equal(a.visibility, b.visibility)
        assert b.stats["budget_rendered"] == 1 and b.stats["budget_kept_share"] == 1.0


def test_dropped_lights_are_not_rendered_and_get_the_drop_policy(frame):
    """budget=1 of the sun, spot and point light (select=closest: the eye is nearest the spot):
    the two others are never rendered (time 0) and are lit unshadowed, or left out (weight 0)."""
    keep = int(np.argmin([np.linalg.norm(light.position - frame.camera.eye) if hasattr(light, "position") and
                          not light.at_infinity else np.inf for light in frame.scene.lights]))
    for drop, value in (("unshadowed", 1.0), ("unlit", 0.0)):
        tech = from_spec(f"shadow_map:budget=1,select=closest,drop={drop}")
        for li in range(3):
            m = measure(tech, frame, li, repeat=2, warmup=0)
            if li == 2:  # the sun: at infinity, the closest of all
                assert m.stats["budget_rendered"] == 1 and m.timing.median_ms > 0
                continue
            assert m.stats["budget_rendered"] == 0 and m.timing.median_ms == 0.0, (drop, li, keep)
            assert np.all(m.visibility[frame.covered] == value)
            assert (m.weight is None) == (drop == "unshadowed")
            if m.weight is not None:
                assert np.all(m.weight[frame.covered] == 0.0)


def test_the_face_rule_on_shadow_polygons_equals_max_lights(frame):
    """The seed's rule applied by the budget to exact shadow polygons gives the same images as
    their own max_lights (the rule the seed built into them)."""
    for li in range(3):
        own = measure(from_spec("shadow_polygons:max_lights=1"), frame, li, repeat=1, warmup=0)
        budget = measure(from_spec("shadow_polygons:budget=1,select=face"), frame, li, repeat=1, warmup=0)
        ev = frame.evaluated(li)  # off them the light does not matter (and is not drawn when kept nowhere on them)
        assert np.array_equal(own.visibility[ev], budget.visibility[ev]), li


def test_the_radiance_of_a_budget(frame):
    """Exact shadows under a budget: error only where shadows were dropped; dropping shadows
    brightens (bias > 0), dropping lights darkens (bias < 0) and costs more; every row of a
    configuration carries the same image columns; the note names the budget as the cause."""
    result = compare_frame(frame, [from_spec("raytrace:budget=3,select=face,pixel_samples=1,seed=1"),
                                   from_spec("raytrace:budget=1,select=face,seed=1"),
                                   from_spec("raytrace:budget=1,select=face,drop=unlit,seed=1")], repeat=1, warmup=0)
    df = result.rows
    full, unshadowed, unlit = (df[df.label == t.spec()] for t in (r[0].technique for r in result.results))
    assert (full.radiance_error == 0).all() and (full.error_rate == 0).all()
    assert unshadowed.radiance_error.nunique() == 1
    e, bias = unshadowed.radiance_error.iloc[0], unshadowed.radiance_bias.iloc[0]
    assert e > 0 and bias == pytest.approx(e)  # exact where kept, brighter where dropped
    assert unlit.radiance_bias.iloc[0] < 0 and unlit.radiance_error.iloc[0] > e
    dropped = unshadowed[unshadowed.budget_kept_share < 1]
    assert len(dropped) and (dropped.error_rate > 0).any()
    # the lights the budget dropped are said once, in the run notes, not as "draws almost no shadow"
    assert not [n for ms in result.results[1:] for m in ms for n in m.judgement]
    said = [n for n in result.notes if "shadows computed for" in n]
    assert len(said) == 3 and "shadows computed for 3 of 3 lights; 0 lights" in said[0]
    assert "shadows computed for 1 of 3 lights" in said[1] and "not drawn there" in said[2]


def test_drop_imperfect_shadows_the_rest_with_imperfect_maps(frame):
    """drop=imperfect: where a light is dropped its visibility is imperfect_map's, and the ISM's time
    is added; where it is kept, the technique's."""
    tech = from_spec("shadow_map:budget=1,select=closest,drop=imperfect")
    li = 0  # the point light: dropped (the sun is the closest)
    m = measure(tech, frame, li, repeat=1, warmup=0)
    ism = measure(from_spec("imperfect_map"), frame, li, repeat=1, warmup=0)
    ev = frame.evaluated(li)
    assert m.stats["budget_rendered"] == 0 and m.stats["imperfect_rendered"] == 1
    assert np.array_equal(m.visibility[ev], ism.visibility[ev])
    assert m.timing.median_ms > 0
    assert (m.visibility[ev] < 0.5).any()  # the ISM shadows something the unshadowed drop would not


@pytest.mark.slow  # 64 lights
def test_ranged_lights_the_face_rule_keeps_at_most_k_and_unreached_lights_are_neither():
    """With ranged lights most faces are reached by fewer than K lights: the seed's rule keeps only
    the lights that contribute (at most K per face, no ties at zero), so it renders fewer lights
    than there are; a light that reaches no pixel has no kept share (NaN) and is not "dropped"."""
    from shadowlab.lighting import selection

    frame = Frame(load_measured_scene("ml_city_64"), 96, 72)
    try:
        scene = frame.scene
        sel = selection.select("face", 4, scene.lights, scene.objects, frame)
        assert sel.kept.sum(axis=0).max() <= 4 and (sel.kept.sum(axis=0) < 4).mean() > 0.5
        reaching = [li for li in range(len(scene.lights)) if frame.slot(li).evaluated.any()]
        result = compare_frame(frame, [from_spec("raytrace:budget=64,select=screen"),
                                       from_spec("raytrace:budget=1,select=face")], repeat=1, warmup=0)
        one = result.rows[result.rows["label"] == result.results[1][0].technique.spec()]
        assert one["radiance_error"].iloc[0] > 0.001  # one light per face: shadows are lost
        rows = result.rows[result.rows["label"] == result.results[0][0].technique.spec()]
        unreached = rows[rows["evaluated_pixels"] == 0]
        assert len(unreached) and unreached["budget_kept_share"].isna().all()
        assert (rows["radiance_error"] == 0).all()
        note = next(n for n in result.notes if "shadows computed for" in n)
        assert f"shadows computed for {len(reaching)} of 64 lights; 0 lights" in note
    finally:
        frame.release()


def test_the_atlas_counts_the_faces_the_technique_renders(frame):
    """A point light fitted with one frustum takes one face of the atlas, not a cube's six."""
    from shadowlab.measurement.budget import faces_of

    point = 0  # multi_light's point light
    assert faces_of(from_spec("shadow_map:projection=frustum"), frame, point) == 1
    assert faces_of(from_spec("shadow_map:projection=cube"), frame, point) == 6
    assert faces_of(from_spec("raytrace"), frame, point) == 6  # no fit of its own: a point light's cube
