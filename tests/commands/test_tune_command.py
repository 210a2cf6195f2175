"""`shadowlab tune` end to end (docs/tuning.md): the contract files, best.json's spec running
as-is in `compare` with the value it reports, both routes, and bad input exiting 2 before any
rendering with earlier results kept."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from shadowlab.cli import main
from shadowlab.techniques import from_spec

SIZE = "160x120"


@pytest.fixture(scope="module")
def exact_run(tmp_path_factory):
    """The constant bias of the default shadow map tuned exactly on the contact case."""
    out = tmp_path_factory.mktemp("tune") / "exact"
    assert main(["tune", "sm_contact", "-t", "shadow_map", "--size", SIZE, "--out", str(out), "--repeat", "1"]) == 0
    return out


@pytest.mark.slow  # inner-loop budget (issue 36): one of the slowest tests; make test runs it
def test_exact_route_writes_the_contract(exact_run):
    out = exact_run
    for name in ("best.json", "candidates.csv", "curve.npz", "frontier.png", "tune.html", "tune.json",
                 "report.html", "metrics.csv"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    best = json.loads((out / "best.json").read_text())
    assert set(best) >= {"spec", "params", "objective", "value", "default", "regret_of_default", "route",
                         "oracle", "verified"}
    assert best["route"] == "exact" and best["objective"] == "error_rate" and best["verified"] is True
    assert from_spec(best["spec"]).bias == best["params"]["bias"]
    # the optimum never loses to the spec as given, and the oracle never loses to the optimum
    assert best["oracle"] <= best["value"] <= best["default"]["value"]
    assert best["regret_of_default"] == pytest.approx(best["default"]["value"] - best["value"])
    # sm_contact's default bias detaches the contact shadows: tuning must find a real gain
    assert best["regret_of_default"] > 0
    cand = pd.read_csv(out / "candidates.csv")
    assert {"param_bias", "error_rate", "false_shadow_rate", "false_lit_rate", "source"} <= set(cand.columns)
    assert set(cand["source"]) == {"exact"} and cand["error_rate"].min() == pytest.approx(best["value"])
    curve = np.load(out / "curve.npz")
    assert "0_breaks" in curve.files and "0_error_rate" in curve.files
    assert np.all(np.diff(curve["0_breaks"]) > 0)
    # the page names the optimum and says the render matched the prediction
    page = (out / "tune.html").read_text()
    assert "equal, bit for bit" in page and "frontier.png" in page


@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
def test_best_spec_runs_as_is_in_compare_with_the_same_value(exact_run, tmp_path):
    """best.json's ``value`` is what ``compare`` reports for its ``spec``, bit for bit."""
    best = json.loads((exact_run / "best.json").read_text())
    out = tmp_path / "cmp"
    assert main(["compare", "sm_contact", "--technique", best["spec"], "--size", SIZE, "--out", str(out),
                 "--repeat", "1"]) == 0
    df = pd.read_csv(out / "metrics.csv")
    row = df[~df["reference"]].iloc[0]
    assert row["error_rate"] == best["value"]


@pytest.mark.slow  # a search over renders within its budget (~1.9 s)
def test_search_route_tries_every_parameter_within_its_budget(tmp_path):
    out = tmp_path / "search"
    assert main(["tune", "sm_light_bleeding", "-t", "filtered_map", "--param", "min_variance",
                 "--param", "bleed_reduction", "--budget", "6", "--size", SIZE, "--out", str(out),
                 "--repeat", "1"]) == 0
    best = json.loads((out / "best.json").read_text())
    assert best["route"] == "search" and (out / "search.png").is_file()
    cand = pd.read_csv(out / "candidates.csv")
    rendered = cand[cand["source"] == "render"]
    assert 1 < len(rendered) <= 6
    assert rendered["param_min_variance"].nunique() > 1 and rendered["param_bleed_reduction"].nunique() > 1
    assert best["value"] == rendered["error_rate"].min() <= best["default"]["value"]


@pytest.mark.parametrize("args,culprit", [
    (["sm_contact", "-t", "shadow_map", "--param", "biass"], "biass"),
    (["sm_contact", "-t", "shadow_map", "--param", "bias=1:0"], "bias=1:0"),
    (["sm_contact", "-t", "shadow_map", "--objective", "error_rat"], "error_rat"),
    (["sm_contact", "-t", "shadow_map", "--param", "near"], "near=LO:HI"),
    (["sm_contact", "-t", "nope"], "nope"),
    (["no_such_scene", "-t", "shadow_map"], "no_such_scene"),
    (["sm_contact", "-t", "shadow_map", "--budget", "0"], "--budget"),
])
def test_bad_input_exits_2_before_rendering(tmp_path, capsys, args, culprit):
    out = tmp_path / "existing"
    out.mkdir()
    (out / "keep.txt").write_text("earlier results")
    assert main(["tune"] + args + ["--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and culprit in err, err
    assert (out / "keep.txt").read_text() == "earlier results"
    assert [p.name for p in tmp_path.iterdir()] == ["existing"]
