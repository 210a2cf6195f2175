"""Tuned studies (docs/tuning.md): a suite's ``[[tuned]]`` tables run each configuration at its
per-scene optimum beside its defaults, measured like any configuration; study.json, summary.md
and the page report the regret of the defaults and, on the exact bias route, whether one global
bias serves every scene; a second run takes the tuning from the cache; bad tables are refused
before anything runs."""
from __future__ import annotations

import json

import pytest

from shadowlab.study.runner import run_study
from shadowlab.study.suite import SuiteError, builtin_suites, load_suite
from shadowlab.techniques import from_spec

TUNED = """
name = "tuned_small"
size = [128, 96]
repeat = 1
warmup = 0
scenes = ["sm_contact", "sm_grazing"]
techniques = []

[[tuned]]
technique = "shadow_map"
params = ["bias"]

[[tuned]]
technique = "filtered_map"
params = ["min_variance"]
budget = 3
scenes = ["sm_contact"]
"""


@pytest.fixture(scope="module")
def tuned_study(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("tuned")
    path = tmp / "suite.toml"
    path.write_text(TUNED)
    outcome = run_study(path, out=tmp / "out", workers=1, log=lambda _: None)
    return path, outcome


@pytest.mark.slow  # a study: spawned worker processes
def test_tuned_configurations_run_beside_their_defaults(tuned_study):
    _, outcome = tuned_study
    assert not outcome.failed
    res = outcome.results
    exact = res[res["config"] == "shadow_map [tuned bias]"]
    assert sorted(exact["scene"]) == ["sm_contact", "sm_grazing"]
    searched = res[res["config"] == "filtered_map [tuned min_variance]"]
    assert list(searched["scene"]) == ["sm_contact"]  # limited to its own scenes
    # the defaults run too, and a tuned spec differs from its default only in the tuned values
    for scene, row in exact.set_index("scene").iterrows():
        default = res[(res["scene"] == scene) & (res["config"] == "shadow_map")].iloc[0]
        tuned, given = from_spec(row["label"]), from_spec(default["label"])
        assert {k: v for k, v in tuned.params().items() if k != "bias"} == \
            {k: v for k, v in given.params().items() if k != "bias"}
        assert row["error_rate"] <= default["error_rate"]


@pytest.mark.slow  # a study: spawned worker processes
def test_study_reports_the_regret_and_the_global_bias(tuned_study):
    _, outcome = tuned_study
    meta = json.loads((outcome.out / "study.json").read_text())
    by_name = {t["name"]: t for t in meta["tuned"]}
    assert set(by_name) == {"shadow_map [tuned bias]", "filtered_map [tuned min_variance]"}
    exact = by_name["shadow_map [tuned bias]"]
    res = outcome.results
    for sc in exact["scenes"]:
        assert sc["status"] == "ok" and sc["route"] == "exact"
        measured = res[(res["scene"] == sc["scene"]) & (res["label"] == sc["best"])]["error_rate"].iloc[0]
        assert sc["value"] == measured
        assert sc["regret"] == pytest.approx(sc["default_value"] - sc["value"]) and sc["regret"] >= 0
        assert sc["oracle"] <= sc["value"]
    # contact detaches at the default bias: the tuned bias must gain there
    contact = next(sc for sc in exact["scenes"] if sc["scene"] == "sm_contact")
    assert contact["regret"] > 0
    g = exact["global"]
    assert {h["scene"] for h in g["held_out"]} == {"sm_contact", "sm_grazing"}
    for h in g["held_out"]:  # a bias tuned on the other scene can never beat this scene's own optimum
        assert h["regret"] >= 0 and h["value"] >= h["own_optimum"]
    assert by_name["filtered_map [tuned min_variance]"]["global"] is None  # search route: no curves
    summary = (outcome.out / "summary.md").read_text()
    page = (outcome.out / "study.html").read_text()
    for text in ("shadow_map [tuned bias]", "One bias for every scene?", "regret of the default"):
        assert text in summary and text in page
    assert "(search route)" in summary  # no oracle on the search route, and the page says why
    # the configurations table groups a tuned configuration's per-scene specs under one name
    assert sum(line.startswith("| shadow_map [tuned bias] ") for line in summary.splitlines()) == 1


@pytest.mark.slow  # a study: spawned worker processes
def test_a_second_run_takes_the_tuning_from_the_cache(tuned_study, tmp_path):
    path, first = tuned_study
    logged = []
    again = run_study(path, out=first.out, workers=1, log=logged.append)
    assert again.ran == 0 and not any("tuning phase" in line for line in logged)
    assert again.results.equals(first.results)


@pytest.mark.parametrize("table,culprit", [
    ('technique = "shadow_map"\nparams = ["biass"]', "biass"),
    ('technique = "shadow_map"\nobjective = "nope"', "nope"),
    ('technique = "shadow_map"\nscenes = ["box_on_plane"]', "box_on_plane"),
    ('technique = "shadow_map"\nbudget = 0', "budget"),
    ('technique = "shadow_map"\nparam = ["bias"]', "param"),
])
def test_bad_tuned_tables_name_the_file_and_entry(tmp_path, table, culprit):
    path = tmp_path / "bad.toml"
    path.write_text(TUNED.split("[[tuned]]")[0] + "[[tuned]]\n" + table + "\n")
    with pytest.raises(SuiteError) as err:
        load_suite(path)
    message = str(err.value)
    assert "bad.toml" in message and "tuned[0]" in message and culprit in message, message


def test_the_fair_suite_tunes_every_shadow_map_hard_case():
    suite = load_suite(builtin_suites()["fair"])
    names = {t.name for t in suite.tuned}
    assert "shadow_map [tuned bias]" in names
    hard = {s.name for s in suite.scenes}
    assert {"sm_grazing", "sm_contact", "sm_far_origin", "sm_thin", "sm_nonconvex", "sm_point_cube",
            "sm_aliasing"} <= hard


@pytest.mark.slow  # a study: spawned worker processes
def test_an_optimum_equal_to_the_spec_as_given_keeps_its_tuned_name(tmp_path):
    """A one-render search keeps the start: the optimum is the spec as given, which the suite
    runs anyway; its rows still appear under the tuned name, so the entry is on every scene."""
    path = tmp_path / "suite.toml"
    path.write_text(TUNED.split("[[tuned]]")[0] + '[[tuned]]\ntechnique = "filtered_map"\n'
                    'params = ["min_variance"]\nbudget = 1\n')
    outcome = run_study(path, out=tmp_path / "out", workers=1, log=lambda _: None)
    res = outcome.results
    for scene in ("sm_contact", "sm_grazing"):
        tuned = res[(res["scene"] == scene) & (res["config"] == "filtered_map [tuned min_variance]")]
        given = res[(res["scene"] == scene) & (res["config"] == "filtered_map")]
        assert len(tuned) == len(given) == 1
        assert tuned["label"].iloc[0] == given["label"].iloc[0]
        assert tuned["error_rate"].iloc[0] == given["error_rate"].iloc[0]


def test_two_tuned_tables_of_one_name_are_refused(tmp_path):
    path = tmp_path / "dup.toml"
    path.write_text(TUNED.split("[[tuned]]")[0] + '[[tuned]]\ntechnique = "shadow_map"\n'
                    '[[tuned]]\ntechnique = "shadow_map"\nobjective = "false_lit_rate"\n')
    with pytest.raises(SuiteError, match=r"tuned\[1\].*same configuration"):
        load_suite(path)
