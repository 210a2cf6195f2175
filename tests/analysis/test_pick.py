"""The cheapest pick under an error budget (shadowlab.analysis.pick) on a hand-made results table:
per scene and per scene family, still and moving light, runner-up, degenerate configurations,
nothing within the budget, soft scenes and predicted times."""
import math

import pandas as pd
import pytest

from shadowlab.analysis.pick import PICK_COLUMNS, Budget, pick_table

HARD, SOFT = "hard edges", "soft shadows"


def _row(scene, label, edge, time, family=HARD, iqr=0.2, pre=None, degenerate=False, vmae=0.0, err=None):
    tech = label.split(":")[0]
    row = {"scene": scene, "light": 0, "technique": tech, "label": label, "short_label": label,
           "reference": tech == "raytrace", "scene_family": family, "status": "ok", "error": "",
           "width": 64, "height": 48, "evaluated_pixels": 3000, "error_rate": edge / 10 if err is None else err,
           "edge_error_rate": edge, "truth_boundary_pixels": 300, "visibility_mae": vmae,
           "time_ms_median": time, "time_ms_iqr": iqr, "setup_ms": 1.0, "degenerate": degenerate}
    if pre is not None:
        row["preprocess_ms"] = pre
    return row


#: shadow_polygons' edge error and time per hard scene: the family's worst is h3's, its median time h2's.
POLY = {"h1": (0.0003, 1.05), "h2": (0.0005, 1.5), "h3": (0.0008, 1.6)}


def results():
    """Hard scenes h1-h3 (edge error; times ± 0.1 repeat intervals), one soft scene."""
    rows = []
    for s in ("h1", "h2", "h3"):
        rows += [_row(s, "raytrace", 0.0, 100.0),
                 _row(s, "shadow_volume", 0.0002, 10.0),
                 _row(s, "shadow_map", 0.005, 2.0),
                 _row(s, "shadow_map:size=512", 0.2 if s == "h3" else 0.05, 1.0),  # within 10 % on 2 of 3
                 _row(s, "planar", 0.0, 0.5, degenerate=True),                       # cheapest, exact, degenerate
                 _row(s, "shadow_polygons", POLY[s][0], POLY[s][1], pre=20.0)]
    rows += [_row("soft1", "raytrace", 0.0, 100.0, family=SOFT),
             _row("soft1", "pcss", 0.3, 3.0, family=SOFT, vmae=0.004),
             _row("soft1", "blob", 0.01, 1.0, family=SOFT, vmae=0.01)]
    return pd.DataFrame(rows)


def _one(table, level, budget, motion, scene=""):
    hit = table[(table["level"] == level) & (table["budget"] == budget) & (table["motion"] == motion)
                & (table["scene"] == scene)]
    assert len(hit) == 1, (level, budget, motion, scene)
    return hit.iloc[0]


def test_default_budgets_cover_every_scene_in_its_own_metric():
    t = pick_table(results())
    assert list(t.columns) == PICK_COLUMNS
    hard, soft = t[t["scene_family"] == HARD], t[t["scene_family"] == SOFT]
    # hard: 3 edge budgets × 2 motions × (3 scenes + the family); soft: 2 mae budgets × 2 × (1 + 1)
    assert len(hard) == 24 and len(soft) == 8 and len(t) == 32
    assert set(hard["metric"]) == {"edge_error_rate"} and sorted(set(hard["budget"])) == [0.001, 0.01, 0.1]
    assert set(soft["metric"]) == {"visibility_mae"} and sorted(set(soft["budget"])) == [0.005, 0.02]
    assert not t["predicted"].any()
    assert set(t.loc[t["level"] == "family", "scene"]) == {""}
    assert t.loc[t["level"] == "family", "scenes"].tolist() == [3] * 6 + [1] * 4


def test_the_cheapest_within_the_budget_per_scene():
    t = pick_table(results(), [Budget("edge_error_rate", 0.1), Budget("edge_error_rate", 0.01)], motions=("still",))
    h1 = _one(t, "scene", 0.1, "still", "h1")
    assert (h1["label"], h1["technique"]) == ("shadow_map:size=512", "shadow_map")
    assert (h1["error"], h1["time_ms"]) == (0.05, 1.0)
    assert (h1["time_lo_ms"], h1["time_hi_ms"]) == pytest.approx((0.9, 1.1))
    # the runner-up's 0.95-1.15 overlaps 0.9-1.1: a toss-up on time
    assert (h1["runner_up"], h1["runner_up_ms"], h1["runner_up_ties"]) == ("shadow_polygons", 1.05, True)
    h2 = _one(t, "scene", 0.1, "still", "h2")
    assert h2["label"] == "shadow_map:size=512"
    assert (h2["runner_up"], h2["runner_up_ms"], h2["runner_up_ties"]) == ("shadow_polygons", 1.5, False)
    # on h3 size=512 is at 20 %: over the budget
    h3 = _one(t, "scene", 0.1, "still", "h3")
    assert (h3["label"], h3["error"], h3["time_ms"]) == ("shadow_polygons", 0.0008, 1.6)
    assert (h3["runner_up"], h3["runner_up_ms"], h3["runner_up_ties"]) == ("shadow_map", 2.0, False)
    # the most accurate is reported whatever the budget: never the degenerate planar (0 error)
    assert (h3["most_accurate"], h3["most_accurate_error"]) == ("shadow_volume", 0.0002)
    one = _one(t, "scene", 0.01, "still", "h1")
    assert (one["label"], one["runner_up"]) == ("shadow_polygons", "shadow_map")
    assert (one["scene_family"], one["metric"], one["scenes"]) == (HARD, "edge_error_rate", 1)


def test_the_family_pick_needs_every_scene_within_and_reports_the_worst():
    t = pick_table(results(), [Budget("edge_error_rate", 0.1), Budget("edge_error_rate", 0.001)], motions=("still",))
    fam = _one(t, "family", 0.1, "still")
    # size=512 is cheaper and within 10 % on h1 and h2, but not on h3: it does not qualify
    assert fam["label"] == "shadow_polygons" and fam["scene_family"] == HARD and fam["scenes"] == 3
    assert fam["error"] == 0.0008                          # its worst scene
    assert fam["time_ms"] == 1.5                           # its median time over the scenes
    assert (fam["time_lo_ms"], fam["time_hi_ms"]) == pytest.approx((1.4, 1.6))
    assert (fam["runner_up"], fam["runner_up_ms"], fam["runner_up_ties"]) == ("shadow_map", 2.0, False)
    assert (fam["most_accurate"], fam["most_accurate_error"]) == ("shadow_volume", 0.0002)
    strict = _one(t, "family", 0.001, "still")
    assert (strict["label"], strict["runner_up"], strict["runner_up_ms"]) == ("shadow_polygons", "shadow_volume", 10.0)
    # a budget between the polygons' best and worst scene: within on h1 and h2 only -> not the family's
    mid = pick_table(results(), [Budget("edge_error_rate", 0.0006)], motions=("still",))
    assert _one(mid, "scene", 0.0006, "still", "h2")["label"] == "shadow_polygons"
    assert _one(mid, "scene", 0.0006, "still", "h3")["label"] == "shadow_volume"
    assert _one(mid, "family", 0.0006, "still")["label"] == "shadow_volume"
    # a configuration that ran on 2 of the 3 scenes (its h3 run failed) is no family's pick,
    # however cheap and accurate where it ran
    part = pd.concat([results(), pd.DataFrame([
        _row("h1", "shadow_map:size=256", 0.0001, 0.8), _row("h2", "shadow_map:size=256", 0.0001, 0.8),
        {**_row("h3", "shadow_map:size=256", math.nan, math.nan), "status": "failed", "error": "RuntimeError: x"}])])
    t = pick_table(part, [Budget("edge_error_rate", 0.001)], motions=("still",))
    assert _one(t, "scene", 0.001, "still", "h1")["label"] == "shadow_map:size=256"
    assert _one(t, "scene", 0.001, "still", "h3")["label"] == "shadow_polygons"
    fam = _one(t, "family", 0.001, "still")
    assert (fam["label"], fam["runner_up"]) == ("shadow_polygons", "shadow_volume")


def test_a_moving_light_pays_the_preprocessing_and_can_change_the_pick():
    t = pick_table(results(), [Budget("edge_error_rate", 0.01), Budget("edge_error_rate", 0.001)])
    assert _one(t, "scene", 0.01, "still", "h1")["label"] == "shadow_polygons"
    moving = _one(t, "scene", 0.01, "moving", "h1")
    # 1.05 + 20 ms preprocessing against shadow_map's 2 ms
    assert (moving["label"], moving["time_ms"], moving["runner_up"], moving["runner_up_ms"]) == (
        "shadow_map", 2.0, "shadow_volume", 10.0)
    strict = _one(t, "scene", 0.001, "moving", "h2")
    assert (strict["label"], strict["runner_up"], strict["runner_up_ms"]) == ("shadow_volume", "shadow_polygons", 21.5)
    fam = _one(t, "family", 0.001, "moving")
    assert (fam["label"], fam["runner_up"], fam["runner_up_ms"]) == ("shadow_volume", "shadow_polygons", 21.5)
    assert not fam["runner_up_ties"]
    # the pick's repeat interval moves with the preprocessing too
    poly = _one(pick_table(results(), [Budget("edge_error_rate", 0.001)], motions=("moving",)), "scene", 0.001,
                "moving", "h1")
    assert poly["label"] == "shadow_volume" and (poly["time_lo_ms"], poly["time_hi_ms"]) == pytest.approx((9.9, 10.1))
    # without the volumes the polygons are the only ones within 0.1 %: their interval pays 20 ms too
    rest = results()
    rest = rest[rest["technique"] != "shadow_volume"]
    poly = _one(pick_table(rest, [Budget("edge_error_rate", 0.001)], motions=("moving",)), "scene", 0.001,
                "moving", "h1")
    assert (poly["label"], poly["time_ms"], poly["runner_up"]) == ("shadow_polygons", 21.05, "")
    assert (poly["time_lo_ms"], poly["time_hi_ms"]) == pytest.approx((20.95, 21.15))
    fam = _one(pick_table(rest, [Budget("edge_error_rate", 0.001)], motions=("moving",)), "family", 0.001, "moving")
    assert (fam["label"], fam["time_ms"]) == ("shadow_polygons", 21.5)
    assert (fam["time_lo_ms"], fam["time_hi_ms"]) == pytest.approx((21.4, 21.6))
    only = pick_table(results(), [Budget("edge_error_rate", 0.01)], motions=("moving",))
    assert set(only["motion"]) == {"moving"} and len(only) == 4


def test_a_degenerate_configuration_is_never_picked():
    t = pick_table(results())
    assert "planar" not in set(t["label"]) | set(t["runner_up"]) | set(t["most_accurate"])
    # and when it is not degenerate, it wins everything on the hard scenes (0 error, 0.5 ms)
    sound = results().assign(degenerate=False)
    t = pick_table(sound, [Budget("edge_error_rate", 0.001)], motions=("still",))
    assert set(t["label"]) == {"planar"}


def test_nothing_within_the_budget_names_the_most_accurate():
    t = pick_table(results(), [Budget("edge_error_rate", 0.0001)], motions=("still",))
    assert len(t) == 4 and (t["label"] == "").all() and (t["technique"] == "").all()
    assert t["error"].isna().all() and t["time_ms"].isna().all() and (t["runner_up"] == "").all()
    assert (t["most_accurate"] == "shadow_volume").all() and (t["most_accurate_error"] == 0.0002).all()


def test_soft_scenes_use_the_visibility_budgets():
    budgets = [Budget("visibility_mae", 0.005), Budget("visibility_mae", 0.02), Budget("edge_error_rate", 0.1)]
    t = pick_table(results(), budgets, motions=("still",))
    soft = t[t["scene_family"] == SOFT]
    assert set(soft["metric"]) == {"visibility_mae"} and set(soft["budget"]) == {0.005, 0.02}
    tight = _one(t, "scene", 0.005, "still", "soft1")
    assert (tight["label"], tight["error"], tight["runner_up"]) == ("pcss", 0.004, "")   # blob's 0.01 is over
    loose = _one(t, "scene", 0.02, "still", "soft1")
    assert (loose["label"], loose["error"], loose["runner_up"], loose["runner_up_ms"]) == ("blob", 0.01, "pcss", 3.0)
    fam = t[(t["level"] == "family") & (t["budget"] == 0.02)].iloc[0]
    assert (fam["scene_family"], fam["label"]) == (SOFT, "blob")
    # the hard scenes get only their edge budget
    assert set(t.loc[t["scene_family"] == HARD, "budget"]) == {0.1}


def test_a_study_without_edge_figures_is_picked_on_error_rate():
    old = results().drop(columns=["edge_error_rate", "truth_boundary_pixels"])
    t = pick_table(old, [Budget("edge_error_rate", 0.1), Budget("error_rate", 0.0001)], motions=("still",))
    hard = t[t["scene_family"] == HARD]
    assert set(hard["metric"]) == {"error_rate"} and set(hard["budget"]) == {0.0001}
    # error_rate = edge / 10: polygons at 0.00003-0.00008 are within 0.01 %, shadow_map's 0.0005 is not
    h1 = _one(t, "scene", 0.0001, "still", "h1")
    assert (h1["label"], h1["error"], h1["runner_up"]) == ("shadow_polygons", pytest.approx(0.00003), "shadow_volume")


def test_predicted_times_override_the_measured_ones():
    times = pd.DataFrame([(s, label, t) for s in ("h1", "h2", "h3")
                          for label, t in (("shadow_volume", 0.5), ("shadow_polygons", 0.7), ("planar", 0.1),
                                           ("shadow_map:size=512", math.nan if s == "h1" else 0.2))],
                         columns=["scene", "spec_label", "time_ms"])
    times = times.assign(time_lo_ms=times["time_ms"], time_hi_ms=times["time_ms"])  # no band: ties only if equal
    t = pick_table(results(), [Budget("edge_error_rate", 0.1), Budget("edge_error_rate", 0.01),
                               Budget("visibility_mae", 0.02)], times=times)
    assert t["predicted"].all()
    # the soft scene's configurations have no predicted time: nothing to rank, nothing closest either
    soft = t[t["scene_family"] == SOFT]
    assert len(soft) == 4 and (soft["label"] == "").all() and (soft["most_accurate"] == "").all()
    h1 = _one(t, "scene", 0.01, "still", "h1")
    # measured, the polygons (1.05 ms) win; predicted, the volumes (0.5 ms) do
    assert (h1["label"], h1["time_ms"], h1["time_lo_ms"], h1["time_hi_ms"]) == ("shadow_volume", 0.5, 0.5, 0.5)
    assert (h1["runner_up"], h1["runner_up_ms"], h1["runner_up_ties"]) == ("shadow_polygons", 0.7, False)
    # shadow_map has no prediction: left out everywhere
    assert "shadow_map" not in set(t["label"]) | set(t["runner_up"]) | set(t["most_accurate"])
    # size=512 has no prediction on h1: left out there, picked on h2 (0.2 ms, within 10 %)
    assert _one(t, "scene", 0.1, "still", "h1")["label"] == "shadow_volume"
    assert _one(t, "scene", 0.1, "still", "h2")["label"] == "shadow_map:size=512"
    # moving: the predicted time plus the measured preprocessing
    mv = _one(t, "scene", 0.01, "moving", "h2")
    assert (mv["label"], mv["runner_up"], mv["runner_up_ms"]) == ("shadow_volume", "shadow_polygons", 20.7)
    assert _one(t, "family", 0.01, "still")["label"] == "shadow_volume"
