"""Study aggregation on small hand-made tables (shadowlab.analysis.aggregate): verdicts per scene
and technique family, failures, ties, the moving-light time and the generated sentences."""
import math

import numpy as np
import pandas as pd
import pytest

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
                 _row(scene, "shadow_volume", 0.00002 if scene == "s1" else 0.00001, 3.0),
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
    # without tiles, errors tie only when equal: on s1 planar's 0 is alone best, 0.001 % and 0.002 % are not
    assert v.loc[("s1", "planar"), "best_error"]
    assert not v.loc[("s1", "shadow_polygons"), "best_error"] and not v.loc[("s1", "shadow_volume"), "best_error"]
    assert not v.loc[("s1", "shadow_map"), "best_error"]
    # on s2 polygons and volumes are equal (0.001 %): both best; planar fails there and is not
    assert v.loc[("s2", "shadow_polygons"), "best_error"] and v.loc[("s2", "shadow_volume"), "best_error"]
    assert not v.loc[("s2", "planar"), "best_error"] and not v.loc[("s2", "shadow_map"), "best_error"]
    assert not v["tested"].astype(bool).any()            # no tiles: nothing was tested on tiles
    assert v["tiles"].isna().all()
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
    # planar is the most accurate on s1 but fails s2: the median would hide it, the sentence does not.
    # shadow_volume is worse on s1 only and equal on s2: per-scene differences (1e-5, 0) whose
    # median's interval holds 0 — not told apart from the polygons, its record said
    assert ("most accurate: shadow_polygons (median error rate 0.001 %), not told apart from it at 95 %: "
            "shadow_volume (worse on 1 of 2 scenes);") in maps
    assert "planar" not in maps.split("fails:")[0]
    assert "fails: planar on 1 of 2" in maps
    assert "fastest for a static light: shadow_polygons (1.000 ms);" in maps
    assert ("for a moving light: shadow_volume (3.000 ms); shadow_polygons needs 51.000 ms with its per-light "
            "preprocessing") in maps
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


def test_times_whose_repeat_intervals_overlap_share_the_verdict():
    """Without quartile columns the repeat interval is median ± IQR/2: 3.0 ± 0.25 and 3.2 ± 0.25
    overlap, 4.0 ± 0.25 does not reach 3.25."""
    rows = [_row("t", "raytrace", 0.0, 10.0, time_ms_iqr=0.5), _row("t", "shadow_volume", 0.0, 3.0, time_ms_iqr=0.5),
            _row("t", "shadow_map", 0.0, 3.2, time_ms_iqr=0.5), _row("t", "planar", 0.0, 4.0, time_ms_iqr=0.5)]
    v = ver.verdict_table(pd.DataFrame(rows)).set_index("technique")
    assert (v.loc["shadow_volume", "time_lo_ms"], v.loc["shadow_volume", "time_hi_ms"]) == (2.75, 3.25)
    assert v.loc["shadow_volume", "best_time"] and v.loc["shadow_map", "best_time"]
    assert not v.loc["planar", "best_time"]
    assert v["best_error"].all()                           # equal errors tie without tiles
    (_, sentence), = ver.verdict_sentences(ver.verdict_table(pd.DataFrame(rows)))
    assert "fastest for a static light: shadow_volume (3.000 ms), tied with it at 95 %: shadow_map;" in sentence
    assert "the same for a moving light" in sentence
    # the same times with the table's usual IQR of 0.1: 3.05 < 3.15, no longer tied
    narrow = pd.DataFrame([{**r, "time_ms_iqr": 0.1} for r in rows])
    v = ver.verdict_table(narrow).set_index("technique")
    assert v.loc["shadow_volume", "best_time"] and not v.loc["shadow_map", "best_time"]
    (_, sentence), = ver.verdict_sentences(ver.verdict_table(narrow))
    assert "fastest for a static light: shadow_volume (3.000 ms); the same for a moving light" in sentence


def test_quartile_columns_give_the_repeat_interval_when_present():
    """time_ms_q25 / q75 are summed over the lights and used instead of median ± IQR/2: with IQR
    0.1 per light (2 lights: ± 0.1) 3.0 and 3.25 would not tie, with their quartiles (2.9-3.5 and
    3.1-3.4) they do; and quartiles can also separate what the IQR would tie."""
    def two_lights(label, time, q25, q75, **kw):
        return [_row("t", label, 0.0, time / 2, light=i, time_ms_q25=q25 / 2, time_ms_q75=q75 / 2, **kw)
                for i in range(2)]

    rows = (two_lights("raytrace", 10.0, 9.0, 11.0) + two_lights("shadow_volume", 3.0, 2.9, 3.5)
            + two_lights("shadow_map", 3.25, 3.1, 3.4) + two_lights("planar", 3.4, 3.35, 3.45, time_ms_iqr=5.0)
            + two_lights("shadow_polygons", 3.3, 3.25, 3.35, pre=1.0))
    cfg = agg.per_configuration(pd.DataFrame(rows)).set_index("label")
    assert cfg.loc["shadow_volume", "time_ms"] == 3.0
    assert cfg.loc["shadow_volume", "time_lo_ms"] == pytest.approx(2.9)
    assert cfg.loc["shadow_volume", "time_hi_ms"] == pytest.approx(3.5)
    v = ver.verdict_table(pd.DataFrame(rows)).set_index("technique")
    assert v.loc["shadow_volume", "best_time"] and v.loc["shadow_map", "best_time"]
    assert v.loc["planar", "best_time"]                   # quartiles 3.35-3.45 overlap 2.9-3.5
    # moving: the polygons' 2 × 1 ms preprocessing shifts their interval to 5.25-5.35
    assert v.loc["shadow_polygons", "moving_lo_ms"] == pytest.approx(5.25)
    assert v.loc["shadow_polygons", "moving_hi_ms"] == pytest.approx(5.35)
    assert v.loc["shadow_polygons", "best_time"] and not v.loc["shadow_polygons", "best_moving"]
    assert v.loc["shadow_volume", "best_moving"]
    late = [{**r, "time_ms_q25": 1.8, "time_ms_q75": 1.9} if r["label"] == "planar" else r for r in rows]
    v = ver.verdict_table(pd.DataFrame(late)).set_index("technique")
    assert not v.loc["planar", "best_time"]               # 3.6-3.8 misses 2.9-3.5; its IQR (± 5) would have tied it
    # without the quartile columns the IQR gives 2.9-3.1 and 3.15-3.35: shadow_map is not tied
    plain = pd.DataFrame(rows).drop(columns=["time_ms_q25", "time_ms_q75"])
    v = ver.verdict_table(plain).set_index("technique")
    assert v.loc["shadow_volume", "best_time"] and not v.loc["shadow_map", "best_time"]
    assert v.loc["planar", "best_time"]                   # 3.4 ± 5 reaches everything


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


# --------------------------------------------------------------------------- ties tested on tiles

_TILES, _PER_TILE = 20, 256     # a scene of 20 tiles of 16 × 16 evaluated pixels


def _tile_array(wrong, abs_diff=None):
    """(3, N) per-tile sums as study/tiles.py stores them: evaluated, wrong, Σ|V − G| (here 0
    unless given: a hard scene's verdict must test the wrong-pixel row)."""
    wrong = np.asarray(wrong, np.float32)
    diff = np.zeros(_TILES, np.float32) if abs_diff is None else np.asarray(abs_diff, np.float32)
    return np.stack([np.full(_TILES, _PER_TILE, np.float32), wrong, diff])


def _tiled_study():
    """One hard scene: shadow_volume wrong 4 pixels in tile 0; shadow_map those and 3 more in
    each of tiles 1 and 2 (differs in 2 tiles); planar those and 1 more in each of tiles 1-10
    (differs in 10 tiles). Errors 4, 10 and 14 wrong pixels of 5120."""
    base = np.zeros(_TILES)
    base[0] = 4
    maps, planar = base.copy(), base.copy()
    maps[1:3] += 3
    planar[1:11] += 1
    n = _TILES * _PER_TILE
    rows = [_row("t", "raytrace", 0.0, 10.0), _row("t", "shadow_volume", 4 / n, 3.0),
            _row("t", "shadow_map", 10 / n, 2.0), _row("t", "planar", 14 / n, 1.0)]
    for r in rows:
        r["evaluated_pixels"] = n
    tiles = {("t", "shadow_volume"): _tile_array(base), ("t", "shadow_map"): _tile_array(maps),
             ("t", "planar"): _tile_array(planar), ("t", "raytrace"): _tile_array(np.zeros(_TILES))}
    return pd.DataFrame(rows), tiles


def test_errors_tie_by_the_tile_bootstrap_when_tiles_are_given():
    results, tiles = _tiled_study()
    v = ver.verdict_table(results, tiles=tiles).set_index("technique")
    assert v.loc["shadow_volume", "best_error"]
    assert v.loc["shadow_map", "best_error"]              # 6 more wrong pixels, but in 2 tiles: not told apart
    assert not v.loc["planar", "best_error"]              # 10 more, spread over 10 tiles: told apart
    assert v["tested"].all()
    assert v.loc["shadow_map", "tiles"].tolist() == [4, 3, 3] + [0] * 17   # the verdict error's numerators
    # without tiles the three differ and only the lowest is best
    plain = ver.verdict_table(results).set_index("technique")
    assert plain["best_error"].tolist() == [True, False, False] and not plain["tested"].any()
    assert list(plain.index) == ["shadow_volume", "shadow_map", "planar"]   # volumes first, then maps
    # a family without tiles falls back to equality (and is not marked tested)
    partial = {k: a for k, a in tiles.items() if k[1] != "shadow_map"}
    v = ver.verdict_table(results, tiles=partial).set_index("technique")
    assert not v.loc["shadow_map", "best_error"] and not v.loc["shadow_map", "tested"]
    assert v.loc["shadow_volume", "tested"] and v.loc["planar", "tested"]


def test_the_sentence_names_the_ties_of_the_tile_test():
    results, tiles = _tiled_study()
    (_, sentence), = ver.verdict_sentences(ver.verdict_table(results, tiles=tiles))
    assert "most accurate: shadow_volume (median error rate " in sentence
    assert "not told apart from it at 95 %: shadow_map;" in sentence
    assert "planar" not in sentence.split("fastest")[0]
    assert "fastest for a static light: planar (1.000 ms)" in sentence
    (_, plain), = ver.verdict_sentences(ver.verdict_table(results))
    assert "not told apart" not in plain


def _edge_rows(scene, label, err, edge, time, boundary=(100, 300), **kw):
    """Two lights of a hard scene with edge figures; ``edge``: the two lights' edge error rates."""
    return [_row(scene, label, err, time / 2, light=i, edge_error_rate=edge[i], truth_boundary_pixels=boundary[i],
                 **kw) for i in range(2)]


def test_a_hard_scene_with_boundary_counts_is_judged_on_the_edge_error():
    # shadow_map: the default has the lower error rate, size=2048 the lower edge error — the one judged
    rows = (_edge_rows("e", "raytrace", 0.0, (0.0, 0.0), 10.0)
            + _edge_rows("e", "shadow_map", 0.001, (0.1, 0.4), 2.0)
            + _edge_rows("e", "shadow_map:size=2048", 0.002, (0.05, 0.05), 4.0)
            + _edge_rows("e", "shadow_volume", 0.003, (0.0, 0.02), 3.0))
    cfg = agg.per_configuration(pd.DataFrame(rows)).set_index("label")
    # pooled by the truth's boundary pixels: (0.1·100 + 0.4·300) / 400, not the plain mean 0.25
    assert cfg.loc["shadow_map", "edge_error_rate"] == pytest.approx(0.325)
    v = ver.verdict_table(pd.DataFrame(rows)).set_index("technique")
    assert (v["metric"] == "edge_error_rate").all()
    assert v.loc["shadow_map", "label"] == "shadow_map:size=2048"
    assert v.loc["shadow_map", "error"] == pytest.approx(0.05)
    assert v.loc["shadow_map", "error_rate"] == 0.002      # the share of all pixels is still carried
    assert v.loc["shadow_volume", "error"] == pytest.approx(0.015)
    assert v.loc["shadow_volume", "best_error"] and not v.loc["shadow_map", "best_error"]
    (_, sentence), = ver.verdict_sentences(ver.verdict_table(pd.DataFrame(rows)))
    assert "most accurate: shadow_volume (median edge error " in sentence
    # the same study without the edge columns: judged on error_rate, shadow_map's default wins
    old = pd.DataFrame(rows).drop(columns=["edge_error_rate", "truth_boundary_pixels"])
    v = ver.verdict_table(old).set_index("technique")
    assert (v["metric"] == "error_rate").all()
    assert v.loc["shadow_map", "label"] == "shadow_map" and v.loc["shadow_map", "error"] == 0.001
    assert v.loc["shadow_map", "best_error"] and not v.loc["shadow_volume", "best_error"]
    (_, sentence), = ver.verdict_sentences(ver.verdict_table(old))
    assert "most accurate: shadow_map (median error rate " in sentence


def test_a_soft_scene_tests_the_visibility_difference_row():
    """On a soft scene the tie is tested on Σ|V − G| (row 2), not on the wrong pixels (row 1):
    pcss and blob have the same wrong pixels, blob's |V − G| is larger in 12 tiles."""
    fam = "soft shadows"
    rows = [_row("soft", "raytrace", 0.0, 10.0, family=fam), _row("soft", "pcss", 0.001, 5.0, family=fam, vmae=0.004),
            _row("soft", "blob", 0.001, 1.0, family=fam, vmae=0.006)]
    wrong = np.ones(_TILES)
    diff = np.full(_TILES, 2.0)
    more = diff.copy()
    more[:12] += 1.0
    tiles = {("soft", "pcss"): _tile_array(wrong, diff), ("soft", "blob"): _tile_array(wrong, more)}
    v = ver.verdict_table(pd.DataFrame(rows), tiles=tiles).set_index("technique")
    assert (v["metric"] == "visibility_mae").all()
    assert v.loc["pcss", "best_error"] and not v.loc["blob", "best_error"] and v["tested"].all()
    assert v.loc["blob", "tiles"].tolist() == more.tolist()
    # blob's extra error in 3 tiles only: not told apart
    few = diff.copy()
    few[:3] += 1.0
    tiles[("soft", "blob")] = _tile_array(wrong, few)
    v = ver.verdict_table(pd.DataFrame(rows), tiles=tiles).set_index("technique")
    assert v.loc["pcss", "best_error"] and v.loc["blob", "best_error"]


def test_edge_errors_pool_wrong_pixels_over_the_truths_boundary_from_the_counts():
    """From the counts, a light whose truth has no boundary keeps its wrong pixels in the pooled
    edge error (its own rate is 0 by convention); a family with a scene whose truth has no boundary
    at all is judged on the share of all pixels instead (no edge to count errors against)."""
    def counted(scene, label, wrong, boundary):
        return [_row(scene, label, w / 10000, 1.0, light=i, truth_boundary_pixels=b, false_shadow_pixels=w,
                     false_lit_pixels=0, edge_error_rate=w / b if b else 0.0)
                for i, (w, b) in enumerate(zip(wrong, boundary))]

    rows = counted("s", "raytrace", (0, 0), (200, 0)) + counted("s", "shadow_map", (10, 30), (200, 0))
    cfg = agg.per_configuration(pd.DataFrame(rows)).set_index("label")
    assert cfg.loc["shadow_map", "edge_error_rate"] == pytest.approx(40 / 200)   # not 10 / 200
    assert cfg.loc["shadow_map", "truth_boundary_pixels"] == 200
    assert ver.verdict_table(pd.DataFrame(rows))["metric"].eq("edge_error_rate").all()
    # a second scene of the family without any boundary: the whole family on error_rate
    rows += counted("u", "raytrace", (0, 0), (0, 0)) + counted("u", "shadow_map", (5, 0), (0, 0))
    v = ver.verdict_table(pd.DataFrame(rows))
    assert v["metric"].eq("error_rate").all()
    cfg = agg.per_configuration(pd.DataFrame(rows)).set_index(["scene", "label"])
    assert math.isnan(cfg.loc[("u", "shadow_map"), "edge_error_rate"])   # wrong pixels, no boundary: no rate


def test_the_family_test_pools_every_scenes_tiles():
    """Three scenes on which shadow_map is worse than shadow_volume in 2 tiles each: no scene's
    own test separates them (two tiles always tie), the family's test over all six tiles does; its
    record says worse on none of the 3 scenes significantly."""
    rows, tiles = [], {}
    n = _TILES * _PER_TILE
    for s in ("a", "b", "c"):
        worse = np.zeros(_TILES)
        worse[:2] = 5
        rows += [_row(s, "raytrace", 0.0, 10.0), _row(s, "shadow_volume", 0.0, 3.0),
                 _row(s, "shadow_map", 10 / n, 2.0)]
        for r in rows[-3:]:
            r["evaluated_pixels"] = n
        tiles[(s, "shadow_volume")] = _tile_array(np.zeros(_TILES))
        tiles[(s, "shadow_map")] = _tile_array(worse)
    v = ver.verdict_table(pd.DataFrame(rows), tiles=tiles)
    assert v["best_error"].all()                                   # tied scene by scene
    (_, sentence), = ver.verdict_sentences(v)
    assert "most accurate: shadow_volume (median error rate 0.000 %); fastest" in sentence   # not told apart: none
    # with two bad tiles on one scene only, the family's test ties too
    for s in ("b", "c"):
        tiles[(s, "shadow_map")] = _tile_array(np.zeros(_TILES))
    (_, sentence), = ver.verdict_sentences(ver.verdict_table(pd.DataFrame(rows), tiles=tiles))
    assert "not told apart from it at 95 %: shadow_map;" in sentence


def test_the_legend_says_when_no_tiles_were_tested():
    from shadowlab.study.verdict_views import thresholds_text, verdict_legend

    results, tiles = _tiled_study()
    tested = verdict_legend(ver.verdict_table(results, tiles=tiles), thresholds_text())
    untested = verdict_legend(ver.verdict_table(results), thresholds_text(), page=False)
    assert "paired tile bootstrap cannot tell from it at 95 %" in tested and "hover" in tested
    assert "no tiles.npz: no significance test" in untested and "hover" not in untested


def test_equal_medians_lead_by_the_mean():
    """Two techniques exact on two scenes of three: the one exact on all three leads the sentence
    (the median alone would pick the first in the tables' order, shadow_volume, which is worse)."""
    rows = []
    for s, sv in (("a", 0.0), ("b", 0.0), ("c", 0.002)):
        rows += [_row(s, "raytrace", 0.0, 10.0), _row(s, "shadow_volume", sv, 3.0),
                 _row(s, "irregular_zbuffer", 0.0, 30.0)]
    (_, sentence), = ver.verdict_sentences(ver.verdict_table(pd.DataFrame(rows)))
    assert "most accurate: irregular_zbuffer (median error rate 0.000 %)" in sentence
    # shadow_volume differs on one scene of three: not consistent, not told apart
    assert "not told apart from it at 95 %: shadow_volume (worse on 1 of 3 scenes)" in sentence
