"""Loud degenerate configurations (issue 35): a configuration that draws almost no shadow where
the truth has one is flagged on its metrics rows (``degenerate``), its run carries a note naming
it, the figures and the likely cause (the technique's :meth:`degenerate_causes`), the casters'
height above their shadows comes free with the occluder layers, and the pages mark it."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from shadowlab.evaluation import metrics
from shadowlab.evaluation.occluder_layers import first_occluder_distance
from shadowlab.measurement.pipeline import Measurement, measure_configs
from shadowlab.techniques import from_spec
from shadowlab.gpu.timing import Timing

from helpers import SMALL, make_scene

BIAS_ONE = "shadow_map:bias=1.0,bias_space=window"  # the broken configuration (window depth)
WORLD_ONE = "shadow_map:bias=1.0"  # the default bias_space: 1 x the scene's extent towards the light


def test_thresholds_are_the_documented_ones():
    """More than 1 % of the evaluated pixels shadowed by the truth, under a tenth of them by the
    configuration; the configuration's count comes from the row's counts."""
    assert metrics.DEGENERATE_TRUTH_SHARE == 0.01 and metrics.DEGENERATE_KEPT_SHARE == 0.1
    assert metrics.is_degenerate(101, 10, 10000)
    assert not metrics.is_degenerate(101, 11, 10000)      # a tenth of 101 is 10.1: 11 is kept
    assert not metrics.is_degenerate(100, 0, 10000)       # exactly 1 %: too small a shadow to judge
    assert not metrics.is_degenerate(0, 0, 0)
    row = {"evaluated_pixels": 10000, "truth_shadowed_pixels": 500, "false_lit_pixels": 480, "false_shadow_pixels": 9}
    assert metrics.shadowed_pixels(row) == 29 and metrics.row_is_degenerate(row)
    assert not metrics.row_is_degenerate({"evaluated_pixels": 10000})   # counts missing: not flagged


def test_a_bias_of_one_is_degenerate_and_its_note_names_the_bias(lab):
    """box_on_plane, 160x120: shadow_map:bias=1.0 passes every depth comparison — 2.66 % wrong,
    all of the truth's shadow lost — and is flagged; the default shadow map is not; the truth's
    row never is."""
    df = measure_configs(None, [BIAS_ONE, "shadow_map", WORLD_ONE], evaluator=lab.evaluator("box_on_plane", SMALL))
    truth, bad, good, world = (df.iloc[i] for i in range(4))
    assert bool(world["degenerate"]) and world["false_lit_rate"] == 1.0  # moved past the light: lit
    assert "likely cause: the bias (1 x the scene's extent, bias_space=world) amounts to" in world["notes"]
    df = df.iloc[:3]
    assert bool(truth["reference"]) and not bool(truth["degenerate"])
    assert bool(bad["degenerate"]) and not bool(good["degenerate"])
    assert bad["truth_shadowed_pixels"] / bad["evaluated_pixels"] > metrics.DEGENERATE_TRUTH_SHARE
    assert metrics.shadowed_pixels(bad) == 0 and bad["false_lit_rate"] == 1.0
    note = bad["notes"]
    share = metrics.COLUMN_BY_NAME["error_rate"].format(bad["truth_shadowed_pixels"] / bad["evaluated_pixels"])
    assert note.startswith(f"{BIAS_ONE} draws almost no shadow on light 0: the truth shadows {share} of the "
                           f"evaluated pixels, this configuration 0.000 % of them")
    assert "likely cause: the bias (1 in window depth)" in note
    assert "almost no shadow" not in good["notes"] and "cause" not in good["notes"]
    # the casters' height above their shadows: one figure per light, on every row
    heights = df["occluder_height_median"]
    assert heights.nunique() == 1 and 0.0 < heights.iloc[0] < 2.0   # a unit box on the floor


def test_compare_frame_puts_the_note_in_the_run_notes(lab):
    """The run notes (what compare prints and run.json holds) carry the note once, naming the
    configuration itself (no spec prefix)."""
    from shadowlab.measurement.pipeline import compare_frame

    result = compare_frame(lab.frame("box_on_plane", SMALL), [from_spec(BIAS_ONE)], repeat=1, warmup=0)
    notes = [n for n in result.notes if "almost no shadow" in n]
    assert len(notes) == 1 and notes[0].startswith(BIAS_ONE + " draws almost no shadow on light 0")
    assert result.rows["degenerate"].tolist() == [False, True]


def test_first_occluder_distance_is_the_casters_height():
    """A plank whose underside is 0.95 above the floor, lit straight down by a directional light:
    every shadowed floor pixel's first caster is 0.95 away along its shadow ray."""
    from shadowlab.gpu.frame import Frame
    from shadowlab.measurement.pipeline import Evaluator

    scene = make_scene([{"mesh": "plane", "size": [8.0, 8.0], "name": "floor"},
                        {"mesh": "box", "size": [2.0, 0.1, 2.0], "translate": [0.0, 1.0, 0.0], "name": "plank"}],
                       [{"type": "directional", "direction": [0.0, -1.0, 0.0]}])
    frame = Frame(scene, 80, 60)
    ev = Evaluator(frame)
    floor = (frame.object_id == 0) & frame.evaluated_image(frame.slot(0))
    shadowed = floor & (ev.truth(0).visibility < 0.5)
    assert shadowed.sum() > 50
    d = first_occluder_distance(frame, 0)
    assert np.allclose(d[shadowed], 0.95, atol=1e-3)
    assert np.isnan(d[floor & ~shadowed]).all()
    assert math.isclose(ev.occluder_height(0), 0.95, abs_tol=1e-3)


def _measurement(spec: str, stats: dict) -> Measurement:
    return Measurement(from_spec(spec), 0, np.ones((2, 2), np.float32), Timing(math.nan, math.nan, []), stats)


def _row(truth_shadowed=500, shadowed=0, evaluated=10000, height=0.75):
    return {"evaluated_pixels": evaluated, "truth_shadowed_pixels": truth_shadowed,
            "false_lit_pixels": truth_shadowed - shadowed, "false_shadow_pixels": 0,
            "degenerate": metrics.is_degenerate(truth_shadowed, shadowed, evaluated), "occluder_height_median": height}


def test_the_depth_map_names_its_causes_from_its_stats(lab):
    """The near plane when far/near exceeds 1000, the bias when its world size at the receivers
    exceeds the casters' height (even on a result that is not degenerate), else depth precision;
    a technique that names none gives 'cause unknown'."""
    ev = lab.evaluator("box_on_plane", SMALL)
    near = ev.judge(_measurement("shadow_map", {"near_plane": 0.001, "far_plane": 20.0, "depth_range": 20.0}), _row())
    assert len(near) == 1 and "likely cause: the near plane at 0.001, far/near = 2e+04" in near[0]
    biased = ev.judge(_measurement("shadow_map:bias=0.01,bias_space=window", {"bias_world_median": 0.9, "bias_world_max": 1.5,
                                                                             "depth_range": 20.0}), _row(shadowed=300))
    assert len(biased) == 1 and biased[0].startswith("shadow_map:bias=0.01,bias_space=window has a bias above its "
                                                     "casters' heights")
    assert ("the bias (0.01 in window depth) amounts to 0.9 world units at the receivers (median; max 1.5), more "
            "than the casters' median height 0.75 above their shadows") in biased[0]
    assert ev.judge(_measurement("shadow_map", {"bias_world_median": 0.1}), _row(shadowed=300)) == []
    precision = ev.judge(_measurement("shadow_map", {"depth_range": 3.0}), _row())
    assert "likely cause: depth precision: 24-bit depth over a depth range of 3" in precision[0]
    unknown = ev.judge(_measurement("planar", {}), _row())
    assert unknown[0].startswith("planar draws almost no shadow on light 0: the truth shadows 5.000 % of the "
                                 "evaluated pixels, this configuration 0.000 % of them")
    assert unknown[0].endswith("; cause unknown")


def test_the_compare_page_marks_a_degenerate_row():
    """The run page's metrics table and the configuration's caption carry the mark."""
    from shadowlab.output.rundir import captions_of, compare_table
    from shadowlab.analysis.aggregate import DEGENERATE_MARK

    rows = pd.DataFrame([
        {"light": 0, "label": "raytrace", "short_label": "raytrace", "reference": True, "degenerate": False,
         "error_rate": 0.0, "time_ms_median": 1.0},
        {"light": 0, "label": BIAS_ONE, "short_label": BIAS_ONE, "reference": False, "degenerate": True,
         "error_rate": 0.027, "false_shadow_rate": 0.0, "false_lit_rate": 1.0, "time_ms_median": 1.0},
        {"light": 0, "label": "shadow_map", "short_label": "shadow_map", "reference": False, "degenerate": False,
         "error_rate": 0.0001, "false_shadow_rate": 0.0, "false_lit_rate": 0.0, "time_ms_median": 1.0}])
    names = [r[0] for r in compare_table(rows)["rows"]]
    assert names == ["raytrace", f"{BIAS_ONE} {DEGENERATE_MARK}", "shadow_map"]
    captions = captions_of(rows)
    assert any(DEGENERATE_MARK in line for line in captions[BIAS_ONE])
    assert not any(DEGENERATE_MARK in line for line in captions["shadow_map"])
