"""`shadowlab pick` end to end on a hand-written study directory: the printed pick, --csv, --scene,
--model (predicted times, labelled as such), and bad input exiting 2 with one line naming it."""
from __future__ import annotations

import pandas as pd
import pytest

from shadowlab.analysis.cost import CostModel
from shadowlab.analysis.pick import PICK_COLUMNS, Budget
from shadowlab.cli import EXIT_BAD_INPUT, main
from shadowlab.commands.pick import parse_budget

HARD, SOFT = "hard edges", "soft shadows"


def _row(scene, label, edge, time, draws, family=HARD, pre=None, vmae=0.0, rays=0):
    tech = label.split(":")[0]
    row = {"scene": scene, "light": 0, "technique": tech, "label": label, "short_label": label,
           "reference": tech == "raytrace", "scene_family": family, "status": "ok", "error": "", "width": 64,
           "height": 48, "evaluated_pixels": 3000, "error_rate": edge / 10, "edge_error_rate": edge,
           "truth_boundary_pixels": 300, "visibility_mae": vmae, "time_ms_median": time, "time_ms_iqr": 0.2,
           "setup_ms": 1.0, "degenerate": False, "work_draws": draws, "work_rays": rays}
    if pre is not None:
        row["preprocess_ms"] = pre
    return row


def _results() -> pd.DataFrame:
    """Hard scenes h1, h2 (edge error) and a soft scene. Measured, the polygons are the cheapest
    within 1 % and blob within mae 0.02; by work_draws (the model below: 0.05 ms + 0.01 ms per
    draw) the volumes and pcss are. shadow_map does ray work the model cannot price."""
    rows = []
    for s in ("h1", "h2"):
        rows += [_row(s, "raytrace", 0.0, 100.0, 0, rays=10**6),
                 _row(s, "shadow_volume", 0.0002, 10.0, 10),
                 _row(s, "shadow_map", 0.005, 2.0, 50, rays=5),
                 _row(s, "shadow_polygons", 0.0005, 1.5, 100, pre=20.0)]
    rows += [_row("soft1", "raytrace", 0.0, 100.0, 0, family=SOFT, rays=10**6),
             _row("soft1", "pcss", 0.3, 3.0, 50, family=SOFT, vmae=0.004),
             _row("soft1", "blob", 0.01, 1.0, 300, family=SOFT, vmae=0.01)]
    return pd.DataFrame(rows)


@pytest.fixture
def study(tmp_path):
    d = tmp_path / "study"
    d.mkdir()
    _results().to_csv(d / "results.csv", index=False)
    return d


def _bad(capsys, argv) -> str:
    """Run ``argv``: exit 2, nothing on stdout, one line on stderr (returned)."""
    assert main(argv) == EXIT_BAD_INPUT
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert out == "" and len(lines) == 1 and lines[0].startswith("shadowlab: error: "), err
    return lines[0]


def test_parse_budget():
    assert parse_budget("edge=1%") == Budget("edge_error_rate", 0.01)
    assert parse_budget("mae=0.005") == Budget("visibility_mae", 0.005)
    assert parse_budget("error_rate=0.0001") == Budget("error_rate", 0.0001)
    assert parse_budget(" Edge = 10 % ") == Budget("edge_error_rate", 0.1)
    assert parse_budget("edge_error_rate=0.02") == Budget("edge_error_rate", 0.02)


def test_pick_prints_the_cheapest_within_each_budget(study, capsys):
    assert main(["pick", str(study), "--budget", "edge=1%", "--budget", "mae=0.02"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert lines[0] == "The cheapest configuration within each budget (times measured in the study):"
    blocks = out.split("\n\n")
    assert [b.splitlines()[0] for b in blocks[1:]] == [
        "edge error ≤ 1 %, still light:", "edge error ≤ 1 %, moving light:",
        "mean |V − G| ≤ 0.02, still light:", "mean |V − G| ≤ 0.02, moving light:"]
    # the scene family first, its scenes indented under it
    still = blocks[1].splitlines()
    assert still[1].startswith("  hard edges (2 scenes)") and "shadow_polygons: 1.50 ms" in still[1]
    assert "(worst of 2 scenes, median time)" in still[1]
    assert still[2].split() == ["h1", "shadow_polygons:", "1.50", "ms,", "0.05", "%", "=", "5", "%", "of", "the",
                                "budget;", "next", "shadow_map", "2.00", "ms"]
    assert still[2].startswith("    h1") and still[3].startswith("    h2")
    # a moving light pays the polygons' 20 ms preprocessing: shadow_map
    moving = blocks[2].splitlines()
    assert "shadow_map: 2.00 ms, 0.500 % = 50 % of the budget; next shadow_volume 10.0 ms" in moving[2]
    # a family of one scene is one line, naming its scene
    soft = blocks[3].splitlines()
    assert len(soft) == 2 and soft[1].split()[:5] == ["soft", "shadows", "(soft1)", "blob:", "1.00"]
    assert "next pcss 3.00 ms" in soft[1]


def test_pick_scene_motion_and_csv(study, tmp_path, capsys):
    csv = tmp_path / "pick.csv"
    assert main(["pick", str(study / "results.csv"), "--budget", "edge=0.1%", "--scene", "h2", "--motion", "still",
                 "--csv", str(csv)]) == 0
    out = capsys.readouterr().out
    assert "h1" not in out and "hard edges" not in out
    assert "shadow_polygons: 1.50 ms, 0.05 % = 50 % of the budget; next shadow_volume 10.0 ms" in out
    assert [ln.split()[0] for ln in out.splitlines()[3:4]] == ["h2"]
    assert f"table: {csv.resolve()}" in out
    table = pd.read_csv(csv, keep_default_na=False)
    assert list(table.columns) == PICK_COLUMNS
    assert len(table) == 1
    row = table.iloc[0]
    assert (row["level"], row["scene"], row["motion"], row["label"], float(row["budget"])) == (
        "scene", "h2", "still", "shadow_polygons", 0.001)
    # a scene family: its line and its scenes
    assert main(["pick", str(study), "--budget", "edge=1%", "--scene", HARD, "--motion", "moving"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[3].startswith("  hard edges") and "shadow_map: 2.00 ms" in out[3] and len(out) == 6
    assert [ln.split()[0] for ln in out[4:]] == ["h1", "h2"]


def test_nothing_within_the_budget_names_the_closest(study, capsys):
    assert main(["pick", str(study), "--budget", "edge=0.01%", "--motion", "still"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert [ln.split()[0] for ln in lines[3:]] == ["hard", "h1", "h2"]
    assert all(ln.endswith("nothing within the budget; closest: shadow_volume at 0.02 %") for ln in lines[3:])


@pytest.mark.parametrize("budget, words", [
    ("edgy=1%", "unknown metric 'edgy'; did you mean 'edge'?"),
    ("edge=abc", "--budget must look like METRIC=VALUE"),
    ("edge=e", "'e' is not a number"),
    ("mae=1%", "mean |V − G| is not a percentage"),
    ("edge=0", "the budget must be a positive number"),
    ("edge=1", "would be 100 % of the pixels; did you mean edge=1%?"),
])
def test_a_bad_budget_exits_2(study, capsys, budget, words):
    line = _bad(capsys, ["pick", str(study), "--budget", budget])
    assert words in line and repr(budget) in line


def test_bad_studies_and_scenes_exit_2(study, tmp_path, capsys):
    line = _bad(capsys, ["pick", str(tmp_path / "nowhere")])
    assert "nowhere: no results.csv" in line
    other = tmp_path / "other"
    other.mkdir()
    pd.DataFrame({"scene": ["s"], "label": ["shadow_map"]}).to_csv(other / "results.csv", index=False)
    line = _bad(capsys, ["pick", str(other)])
    assert "not a study's results.csv (no column technique, error_rate, time_ms_median)" in line
    line = _bad(capsys, ["pick", str(study), "--scene", "nosuch"])
    assert "--scene 'nosuch': no such scene or scene family" in line and "did you mean" not in line
    line = _bad(capsys, ["pick", str(study), "--scene", "hard edge"])
    assert "did you mean 'hard edges'?" in line
    line = _bad(capsys, ["pick", str(study), "--scene", "h11"])
    assert "did you mean 'h1'?" in line
    # a soft-only budget on a study whose only scenes are hard
    hard = tmp_path / "hard"
    hard.mkdir()
    r = _results()
    r[r["scene_family"] == HARD].to_csv(hard / "results.csv", index=False)
    line = _bad(capsys, ["pick", str(hard), "--budget", "mae=0.01"])
    assert "is judged on visibility_mae" in line
    # a scene that exists but is judged on another metric than the budget's: the line says which
    line = _bad(capsys, ["pick", str(study), "--budget", "mae=0.01", "--scene", "h1"])
    assert "--scene 'h1' is judged on edge_error_rate: give a budget in it" in line


def test_a_model_prices_a_still_light_only(study, tmp_path, capsys):
    line = _bad(capsys, ["pick", str(study), "--model", str(_model(tmp_path / "m.json")), "--motion", "moving"])
    assert "--model predicts a still light's time per frame only" in line


def _model(path, unseen=("rays",)):
    CostModel(device="testgpu", target="time_ms_median", counters=["draws"], coefficients={"draws": 0.01},
              intercept_ms=0.05, per_pass=False, rows=12, scenes=["h1", "h2", "soft1"], r2=0.9,
              median_rel_error=0.05, cv_median_rel_error=0.12, cv_mean_rel_error=0.15,
              unseen=list(unseen)).save(path)
    return path


def test_pick_with_a_model_ranks_by_predicted_times(study, tmp_path, capsys):
    model = _model(tmp_path / "model.json")
    assert main(["pick", str(study), "--budget", "edge=1%", "--budget", "mae=0.02", "--model", str(model)]) == 0
    out = capsys.readouterr().out
    # 1 configuration left out: shadow_map; not the truth, which is never ranked
    assert out.splitlines()[0] == (
        f"The cheapest configuration within each budget (times PREDICTED for testgpu by {model} (not measured: the "
        "model's leave-one-scene-out median error is 12 %); 1 configuration(s) it cannot price are left out):")
    # still light only: the model prices the GPU work, not a moving light's preprocessing
    assert "moving light" not in out and "edge error ≤ 1 %, still light:" in out
    # predicted: volumes 0.05 + 10 × 0.01 = 0.15 ms, polygons 1.05 ms (measured 10 and 1.5 ms)
    assert "    h1" in out and "shadow_volume: 0.15 ms predicted, 0.02 % = 2 % of the budget; next shadow_polygons 1.05 ms" in out
    assert "shadow_polygons: 1.50 ms" not in out
    # shadow_map does ray work the model has no cost for: left out, though measured it would be runner-up
    assert "shadow_map" not in out
    # soft: pcss 0.55 ms predicted against blob's 3.05 (measured blob 1 ms is cheaper)
    assert "soft shadows (soft1)   pcss: 0.55 ms predicted" in out and "next blob 3.05 ms" in out
    # a model that can price every configuration leaves nothing out; the truth's rays unpriced do not count
    only_truth = _results()
    only_truth.loc[only_truth["label"] == "shadow_map", "work_rays"] = 0
    only_truth.to_csv(study / "results.csv", index=False)
    assert main(["pick", str(study), "--budget", "edge=1%", "--model", str(model), "--scene", "h1"]) == 0
    assert "left out" not in capsys.readouterr().out.splitlines()[0]
    full = _model(tmp_path / "full.json", unseen=())
    assert main(["pick", str(study), "--budget", "edge=1%", "--model", str(full), "--scene", "h1"]) == 0
    out = capsys.readouterr().out
    assert "left out" not in out.splitlines()[0] and "PREDICTED" in out.splitlines()[0]
    assert "shadow_volume: 0.15 ms predicted, 0.02 % = 2 % of the budget; next shadow_map 0.55 ms" in out


def test_a_bad_model_exits_2(study, tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    line = _bad(capsys, ["pick", str(study), "--model", str(bad)])
    assert f"{bad}: not a readable cost model" in line
    nowork = tmp_path / "nowork"
    nowork.mkdir()
    _results().drop(columns=["work_draws", "work_rays"]).to_csv(nowork / "results.csv", index=False)
    line = _bad(capsys, ["pick", str(nowork), "--model", str(_model(tmp_path / "m.json"))])
    assert "no work_ columns" in line
