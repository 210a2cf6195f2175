"""Study aggregation on small hand-made tables (shadowlab.analysis.aggregate): verdicts per scene
and technique family, failures, ties, the moving-light time and the generated sentences."""
import math

import pandas as pd

from shadowlab.analysis import aggregate as agg
from shadowlab.analysis import verdicts as ver


def _row(scene, label, err, time, family="shadow maps", setup=5.0, pre=None, vmae=None, status="ok", **extra):
    tech = label.split(":")[0]
    row = {"scene": scene, "light": 0, "technique": tech, "label": label, "short_label": label,
           "reference": tech == "raytrace", "scene_family": family, "status": status, "error": "",
           "evaluated_pixels": 10000, "error_rate": err, "false_shadow_rate": err, "false_lit_rate": 0.0,
           "boundary_error_px": 0.0, "time_ms_median": time, "time_ms_iqr": 0.1, "setup_ms": setup,
           "visibility_mae": err if vmae is None else vmae, **extra}
    if pre is not None:
        row["preprocess_ms"] = pre
    return row


def _table():
    rows = []
    for scene in ("s1", "s2"):
        rows += [_row(scene, "raytrace", 0.0, 10.0),
                 _row(scene, "shadow_map", 0.002, 20.0), _row(scene, "shadow_map:variant=slope", 0.0005, 25.0),
                 _row(scene, "shadow_polygons", 0.00001, 1.0, pre=50.0),
                 _row(scene, "shadow_volume", 0.00002, 3.0),
                 _row(scene, "planar", 0.02 if scene == "s2" else 0.0, 0.5)]
    rows.append(_row("soft", "raytrace", 0.0, 10.0, family="soft shadows"))
    rows.append(_row("soft", "pcss", 0.3, 5.0, family="soft shadows", vmae=0.01))        # hard error high, soft fine
    rows.append(_row("soft", "blob", 0.001, 1.0, family="soft shadows", vmae=0.05))      # soft error above 0.02
    rows.append({**_row("soft", "shadow_map", math.nan, math.nan, family="soft shadows", status="failed"),
                 "error": "RuntimeError: boom"})
    return pd.DataFrame(rows)


def test_verdict_best_configuration_per_family_and_failures():
    v = ver.verdict_table(_table()).set_index(["scene", "technique"])
    # the family's best configuration is its lowest error, not its first
    assert v.loc[("s1", "shadow_map"), "label"] == "shadow_map:variant=slope"
    assert v.loc[("s1", "shadow_map"), "error"] == 0.0005
    assert v.loc[("s1", "shadow_map"), "configurations"] == 2
    # planar fails s2 (2 % > 1 %) but not s1
    assert bool(v.loc[("s2", "planar"), "failed"]) and not bool(v.loc[("s1", "planar"), "failed"])
    assert "error_rate above 1 %" in v.loc[("s2", "planar"), "why"]
    # errors within the tie tolerance are all best; shadow_map's 0.05 % is not
    assert v.loc[("s1", "shadow_polygons"), "best_error"] and v.loc[("s1", "shadow_volume"), "best_error"]
    assert v.loc[("s1", "planar"), "best_error"] and not v.loc[("s1", "shadow_map"), "best_error"]
    # static light: the polygons win on s2; a moving light pays their 50 ms preprocessing
    assert v.loc[("s2", "shadow_polygons"), "best_time"]
    assert v.loc[("s2", "shadow_polygons"), "moving_ms"] == 51.0
    assert v.loc[("s2", "shadow_volume"), "best_moving"] and not v.loc[("s2", "shadow_polygons"), "best_moving"]
    # planar is fastest on s1 and does not fail there
    assert v.loc[("s1", "planar"), "best_time"]


def test_soft_scenes_are_judged_on_visibility_error():
    v = ver.verdict_table(_table()).set_index(["scene", "technique"])
    assert v.loc[("soft", "pcss"), "metric"] == "visibility_mae"
    assert not bool(v.loc[("soft", "pcss"), "failed"])          # 30 % thresholded error, but mean |V-G| 0.01
    assert bool(v.loc[("soft", "blob"), "failed"])              # mean |V-G| 0.05 > 0.02
    assert v.loc[("soft", "pcss"), "best_error"] and v.loc[("soft", "pcss"), "best_time"]
    # a family whose every run failed is a failed cell with the run's error
    assert bool(v.loc[("soft", "shadow_map"), "failed"])
    assert "RuntimeError: boom" in v.loc[("soft", "shadow_map"), "why"]


def test_verdict_sentences_name_winners_and_failures():
    sentences = dict(ver.verdict_sentences(ver.verdict_table(_table())))
    maps = sentences["shadow maps"]
    # planar is as accurate on s1 but fails s2: the median would hide it, the sentence does not
    assert "most accurate: shadow_polygons, shadow_volume" in maps
    assert "fails: planar on 1 of 2" in maps
    assert "fastest per frame for a static light: shadow_polygons" in maps
    assert "for a moving light: shadow_volume" in maps
    assert "no technique passes every scene" not in maps
    soft = sentences["soft shadows"]
    assert "most accurate: pcss" in soft and "blob on 1 of 1" in soft and "shadow_map on 1 of 1" in soft


def test_scene_metric_is_pooled_and_carried():
    t = _table()
    t["contact_gap_px"] = 0.5
    cfg = agg.per_configuration(t, {"s1": "contact_gap_px"})
    s1 = cfg[cfg["scene"] == "s1"]
    assert (s1["scene_metric"] == "contact_gap_px").all() and (s1["scene_metric_value"] == 0.5).all()
    assert (cfg[cfg["scene"] == "s2"]["scene_metric"] == "").all()
    v = ver.verdict_table(t, {"s1": "contact_gap_px"}).set_index(["scene", "technique"])
    assert v.loc[("s1", "planar"), "scene_metric_value"] == 0.5


def test_summary_table_reports_the_worst_case_beside_the_median():
    s = agg.summary_table(_table()).set_index("label")
    assert s.loc["planar", "median_error_rate"] == 0.01 and s.loc["planar", "worst_error_rate"] == 0.02


def test_times_within_the_time_tie_share_the_verdict():
    rows = [_row("t", "raytrace", 0.0, 10.0), _row("t", "shadow_volume", 0.0, 3.0),
            _row("t", "shadow_map", 0.0, 3.2), _row("t", "planar", 0.0, 4.0)]
    v = ver.verdict_table(pd.DataFrame(rows)).set_index("technique")
    assert v.loc["shadow_volume", "best_time"] and v.loc["shadow_map", "best_time"]   # 3.2 <= 3.0 * 1.1
    assert not v.loc["planar", "best_time"]
    (_, sentence), = ver.verdict_sentences(ver.verdict_table(pd.DataFrame(rows)))
    assert "shadow_volume (3.000 ms), shadow_map (3.200 ms), tied within 10 %" in sentence


def _degenerate_table():
    """s1: shadow_map's bias=1 draws no shadow (2.7 %, degenerate) beside a sound 0.5 %; planar has
    only a degenerate configuration. s2: shadow_map's degenerate configuration has the lowest
    error of the row (a scene with a small shadow)."""
    return pd.DataFrame([
        _row("s1", "raytrace", 0.0, 10.0, degenerate=False),
        _row("s1", "shadow_map:bias=1", 0.027, 5.0, degenerate=True),
        _row("s1", "shadow_map", 0.005, 6.0, degenerate=False),
        _row("s1", "planar", 0.009, 1.0, degenerate=True),
        _row("s1", "shadow_volume", 0.001, 3.0, degenerate=False),
        _row("s2", "raytrace", 0.0, 10.0, degenerate=False),
        _row("s2", "shadow_map:bias=1", 0.0005, 5.0, degenerate=True),
        _row("s2", "shadow_map", 0.003, 6.0, degenerate=False),
        _row("s2", "shadow_volume", 0.001, 3.0, degenerate=False)])


def test_a_degenerate_configuration_is_never_a_silent_best():
    v = ver.verdict_table(_degenerate_table()).set_index(["scene", "technique"])
    # a sound configuration is chosen over a degenerate one, whatever their errors
    assert v.loc[("s1", "shadow_map"), "label"] == "shadow_map"
    assert v.loc[("s2", "shadow_map"), "label"] == "shadow_map" and v.loc[("s2", "shadow_map"), "error"] == 0.003
    assert not v.loc[("s2", "shadow_map"), "degenerate"]
    # a family with only degenerate configurations shows one, marked, and fails though under 1 %
    assert v.loc[("s1", "planar"), "degenerate"] and bool(v.loc[("s1", "planar"), "failed"])
    assert v.loc[("s1", "planar"), "why"] == agg.DEGENERATE_WHY
    assert not v.loc[("s1", "planar"), "best_time"] and not v.loc[("s1", "planar"), "best_error"]
    assert v.loc[("s1", "shadow_volume"), "best_error"]
    # the configurations table: a degenerate configuration wins nothing and fails where it is degenerate
    table = agg.summary_table(_degenerate_table()).set_index("label")
    assert table.loc["shadow_map:bias=1", "wins"] == []
    assert [s for s, _ in table.loc["shadow_map:bias=1", "fails"]] == ["s1", "s2"]
    assert agg.DEGENERATE_MARK in table.loc["shadow_map:bias=1", "fails"][1][1]
    # results.csv of a study before issue 35 (no column): nothing is degenerate
    old = ver.verdict_table(_table())
    assert not old["degenerate"].astype(bool).any()


def test_the_study_pages_mark_a_degenerate_cell(tmp_path):
    from shadowlab.study import report

    lines = "\n".join(report.verdict_markdown(_degenerate_table()))
    assert f"0.900 % {agg.DEGENERATE_MARK}" in lines
    html = report.write_study_html(tmp_path, _degenerate_table(), {"name": "t"}).read_text()
    assert html.count(agg.DEGENERATE_MARK) >= 3   # the planar cell, the legend, the scene table's row
