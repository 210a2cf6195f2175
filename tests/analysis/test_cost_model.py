"""Cost models (shadowlab.analysis.cost, ``shadowlab cost fit/predict``): the fit recovers a known device,
cross-validates by scene, round-trips, predicts, and bad input exits 2 with one line."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from shadowlab import cli
from shadowlab.analysis import cost

#: A made-up device: ms per unit of each kind of work, and per render.
TRUE = {"samples_passed": 2e-6, "bytes_cleared": 1e-8, "draws": 0.01, "rays": 5e-5}
TRUE_RENDER_MS = 0.05


def synthetic(n_scenes: int = 5, per_scene: int = 12, noise: float = 0.0, seed: int = 1) -> pd.DataFrame:
    """Study rows whose times are exactly (or with multiplicative noise) the TRUE device's."""
    rng = np.random.default_rng(seed)
    rows = []
    for s in range(n_scenes):
        for j in range(per_scene):
            work = {"samples_passed": rng.integers(1e4, 5e6), "bytes_cleared": rng.integers(0, 6.7e7),
                    "draws": rng.integers(1, 40), "rays": rng.integers(0, 1e6) * (j % 3 == 0)}
            t = TRUE_RENDER_MS + sum(TRUE[k] * v for k, v in work.items())
            rows.append({"scene": f"s{s}", "label": f"cfg{j}", "light": 0, "technique": f"t{j % 4}", "status": "ok",
                         "time_ms_median": t * float(np.exp(rng.normal(0, noise))) if noise else t,
                         **{f"work_{k}": v for k, v in work.items()},
                         "work_lookup_draws": 1})
    return pd.DataFrame(rows)


def test_fit_recovers_a_known_device():
    model = cost.fit(synthetic(), "made-up device")
    for k, v in TRUE.items():
        assert model.coefficients[k] == pytest.approx(v, rel=1e-6)
    assert model.intercept_ms == pytest.approx(TRUE_RENDER_MS, rel=1e-6)
    assert model.r2 == pytest.approx(1.0)
    assert model.cv_median_rel_error < 1e-6
    assert set(model.cv_per_scene) == {f"s{i}" for i in range(5)}
    # counters no row did are dropped, not fitted to zero silently
    assert "texture_taps" not in model.counters


def test_noise_shows_in_the_cross_validated_error():
    noisy = cost.fit(synthetic(noise=0.2), "noisy")
    assert 0.02 < noisy.cv_median_rel_error < 0.5
    assert noisy.cv_median_rel_error >= noisy.median_rel_error * 0.8
    assert all(v >= 0 for v in noisy.coefficients.values()) and noisy.intercept_ms >= 0


def test_one_scene_has_no_cross_validation():
    model = cost.fit(synthetic(n_scenes=1), "one")
    assert np.isnan(model.cv_median_rel_error)
    assert "n/a" in cost.summary_line(model)


def test_model_round_trips_and_predicts(tmp_path):
    rows = synthetic()
    model = cost.fit(rows, "made-up device")
    model.save(tmp_path / "m.json")
    again = cost.CostModel.load(tmp_path / "m.json")
    assert again == model
    table = cost.predict(rows, again, device="made-up device")
    assert np.allclose(table[f"{cost.PREDICTED_LABEL}_ms"], rows["time_ms_median"], rtol=1e-6)
    assert (table["rel_error"] < 1e-6).all()
    # rows from another device: predicted, but never compared with that device's times
    other = cost.predict(rows, again, device="another device")
    assert other["measured_ms"].isna().all() and other["rel_error"].isna().all()
    assert np.allclose(other["measured_here_ms"], rows["time_ms_median"])
    # failed rows are left out, and the rows stay aligned whatever the index
    shuffled = rows.iloc[::-1].copy()
    shuffled.loc[shuffled.index[0], "status"] = "failed"
    table = cost.predict(shuffled, again, device="made-up device")
    assert len(table) == len(rows) - 1 and (table["rel_error"] < 1e-6).all()


def test_work_the_model_never_saw_gets_no_prediction():
    rows = synthetic()
    model = cost.fit(rows, "d", counters=["samples_passed", "bytes_cleared", "draws", "rays", "texture_taps"])
    assert model.unseen == ["texture_taps"]
    rows.loc[3, "work_texture_taps"] = 10.0
    table = cost.predict(rows, model)
    assert np.isnan(table.loc[3, f"{cost.PREDICTED_LABEL}_ms"]) and table.loc[3, "unmodelled"] == "texture_taps"
    assert table[f"{cost.PREDICTED_LABEL}_ms"].notna().sum() == len(rows) - 1
    rows["technique"] = "never_seen"
    assert cost.predict(rows, model)["extrapolated"].all()


def test_a_gpu_time_model_leaves_the_cpu_work_out():
    rows = synthetic()
    rows["gpu_time_ms_median"] = rows["time_ms_median"]
    model = cost.fit(rows, "gpu", target="gpu_time_ms_median")
    assert "rays" not in model.counters and "rays" not in model.unseen
    # a row that drew nothing (a CPU technique) has no GPU time to predict
    rows.loc[0, ["work_draws", "work_lookup_draws"]] = 0
    table = cost.predict(rows, model)
    assert np.isnan(table.loc[0, f"{cost.PREDICTED_LABEL}_ms"]) and "CPU" in table.loc[0, "unmodelled"]
    assert table[f"{cost.PREDICTED_LABEL}_ms"].notna().sum() == len(rows) - 1


def test_rows_without_counters_are_refused():
    rows = synthetic()
    rows.loc[2, [c for c in rows.columns if c.startswith("work_")]] = np.nan
    with pytest.raises(cost.CostModelError, match="1 row"):
        cost.fit(rows, "d")


def test_bad_input_is_refused(tmp_path):
    rows = synthetic()
    with pytest.raises(cost.CostModelError, match="did you mean 'draws'"):
        cost.fit(rows, "d", counters=["drawz"])
    with pytest.raises(cost.CostModelError, match="no work_ columns"):
        cost.fit(rows[["scene", "label", "time_ms_median"]], "d")
    with pytest.raises(cost.CostModelError, match="pass_timing"):
        cost.fit(rows, "d", per_pass=True)
    (tmp_path / "bad.json").write_text("{}")
    with pytest.raises(cost.CostModelError, match="bad.json"):
        cost.CostModel.load(tmp_path / "bad.json")


def two_pass_rows() -> pd.DataFrame:
    """synthetic() rows with two passes, each timed by the TRUE device: the lookup does the
    samples, the depth pass the clears and draws."""
    rows = synthetic().drop(columns="work_lookup_draws")
    rows["work_lookup_samples_passed"] = rows["work_samples_passed"]
    rows["work_depth_bytes_cleared"] = rows["work_bytes_cleared"]
    rows["work_depth_draws"] = rows["work_draws"]
    rows["pass_lookup_ms"] = TRUE_RENDER_MS + TRUE["samples_passed"] * rows["work_samples_passed"]
    rows["pass_depth_ms"] = TRUE_RENDER_MS + TRUE["bytes_cleared"] * rows["work_bytes_cleared"] + \
        TRUE["draws"] * rows["work_draws"]
    return rows


def test_per_pass_fit_shares_coefficients():
    rows = two_pass_rows()
    model = cost.fit(rows, "d", counters=["samples_passed", "bytes_cleared", "draws"], per_pass=True)
    assert model.per_pass and model.rows == 2 * len(rows)
    assert model.coefficients["samples_passed"] == pytest.approx(TRUE["samples_passed"], rel=1e-6)


@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
def test_cli_fit_and_predict_write_their_files(tmp_path, capsys):
    study = tmp_path / "study"
    study.mkdir()
    synthetic().to_csv(study / "results.csv", index=False)
    (study / "study.json").write_text(json.dumps({"device": "made-up device"}))
    (study / "cost_model.json").write_text("earlier")
    assert cli.main(["cost", "fit", str(study), "--counters", "draws,bogus"]) == cli.EXIT_BAD_INPUT
    assert (study / "cost_model.json").read_text() == "earlier"  # a failed fit leaves it as it was
    capsys.readouterr()
    assert cli.main(["cost", "fit", str(study)]) == 0
    out = capsys.readouterr().out
    assert "made-up device" in out and "R² 1.000" in out
    assert (study / "cost_model.json").is_file() and (study / "cost_fit.png").is_file()
    other = tmp_path / "other"
    other.mkdir()
    synthetic(seed=7).to_csv(other / "results.csv", index=False)
    assert cli.main(["cost", "predict", str(other), str(study / "cost_model.json")]) == 0
    out = capsys.readouterr().out
    assert out.startswith(cost.PREDICTED_LABEL)
    table = pd.read_csv(other / "cost" / "made_up_device.csv")
    assert table["rel_error"].isna().all()  # no study.json: not known to have run on the device
    (other / "study.json").write_text("{not json")
    assert cli.main(["cost", "predict", str(other), str(study / "cost_model.json")]) == cli.EXIT_BAD_INPUT
    assert "not valid JSON" in capsys.readouterr().err


def test_cli_bad_input_exits_2_with_one_line(tmp_path, capsys):
    assert cli.main(["cost", "fit", str(tmp_path / "missing")]) == cli.EXIT_BAD_INPUT
    err = capsys.readouterr().err.strip()
    assert "no results.csv" in err and len(err.splitlines()) == 1
    (tmp_path / "empty.csv").write_text("")
    assert cli.main(["cost", "fit", str(tmp_path / "empty.csv")]) == cli.EXIT_BAD_INPUT
    assert "not a readable results CSV" in capsys.readouterr().err
    good = tmp_path / "good.csv"
    synthetic().to_csv(good, index=False)
    for model in (tmp_path / "nothing.json", tmp_path / "empty.csv"):
        assert cli.main(["cost", "predict", str(good), str(model)]) == cli.EXIT_BAD_INPUT
        err = capsys.readouterr().err.strip()
        assert "not a readable cost model" in err and len(err.splitlines()) == 1
    study = tmp_path / "s"
    study.mkdir()
    synthetic().to_csv(study / "results.csv", index=False)
    assert cli.main(["cost", "fit", str(study), "--counters", "samples,draws"]) == cli.EXIT_BAD_INPUT
    assert "unknown counter 'samples'" in capsys.readouterr().err
    assert not (study / "cost_model.json").exists()  # nothing written by a failed fit


def test_the_study_page_labels_predictions():
    """study.json's cost_predictions become tables headed as predictions, with the model's
    cross-validated error; rows without a cost or outside the fitted techniques say so."""
    from shadowlab.study.report import prediction_tables

    meta = {"renderer": "llvmpipe", "cost_predictions": [{
        "device": "GPU X", "target": "gpu_time_ms_median", "r2": 0.5, "cv_median_rel_error": 0.25,
        "model_rows": 10, "model_scenes": 3, "csv": "cost/GPU_X.csv",
        "rows": [{"technique": "shadow_map", "label": "shadow_map", "measured_here_ms": 30.0, "predicted_ms": 0.5},
                 {"technique": "raytrace", "label": "raytrace", "measured_here_ms": 9.0, "predicted_ms": None,
                  "unmodelled": "rays"},
                 {"technique": "pcss", "label": "pcss", "measured_here_ms": 9.0, "predicted_ms": 1.0,
                  "extrapolated": True}]}]}
    (table,) = prediction_tables(meta)
    assert table["device"] == "GPU X" and table["here"] == "llvmpipe"
    assert "leave-one-scene-out median error 25 %" in table["what"]
    assert table["rows"][0] == ["shadow_map", "shadow_map", "30.0", "0.50"]
    assert "no cost for rays" in table["rows"][1][3]
    assert "extrapolated" in table["rows"][2][3]


def test_per_pass_model_predicts_without_pass_times():
    """A per-pass model predicts a study without pass_<name>_ms columns: per row, the passes it ran."""
    rows = two_pass_rows()
    model = cost.fit(rows, "d", counters=["samples_passed", "bytes_cleared", "draws"], per_pass=True)
    table = cost.predict(rows.drop(columns=["pass_lookup_ms", "pass_depth_ms"]), model)
    assert np.allclose(table[f"{cost.PREDICTED_LABEL}_ms"], rows["pass_lookup_ms"] + rows["pass_depth_ms"])
