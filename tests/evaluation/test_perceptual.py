"""Perceptual metrics beside the exact ones (shadowlab.evaluation.perceptual, issue 28): FLIP and SSIM on
known pictures, the columns absent with a note when their packages are missing, and the rank
agreement (Kendall τ) of shadowlab.study.agreement on hand-made tables with known orders."""
from __future__ import annotations

import importlib.util
import json

import numpy as np
import pandas as pd
import pytest

from shadowlab.evaluation import perceptual
from shadowlab.study import agreement

needs_packages = pytest.mark.skipif(perceptual.available() != list(perceptual.PACKAGES),
                                    reason="pip install 'shadowlab[perceptual]'")


def _picture(dark=None, size=(64, 96)):
    """A mid-grey sRGB picture with a darker square ``dark`` = (row0, row1, col0, col1)."""
    img = np.full(size + (3,), 0.6, np.float32)
    if dark is not None:
        r0, r1, c0, c1 = dark
        img[r0:r1, c0:c1] = 0.2
    return img


@needs_packages
def test_identical_pictures_score_perfectly_and_a_wrong_shadow_does_not():
    covered = np.ones((64, 96), bool)
    ref = _picture((20, 40, 30, 60))
    same = perceptual.compare_pictures(ref, ref, covered)
    assert same == {"flip_mean": 0.0, "ssim": pytest.approx(1.0, abs=1e-6)}
    missing = perceptual.compare_pictures(_picture(), ref, covered)  # the shadow missing
    shifted = perceptual.compare_pictures(_picture((20, 40, 33, 63)), ref, covered)  # moved by 3 pixels
    assert 0 < shifted["flip_mean"] < missing["flip_mean"]
    assert missing["ssim"] < shifted["ssim"] < 1.0


@needs_packages
def test_only_covered_pixels_are_averaged():
    """A difference outside the covered pixels does not count; the same difference inside does,
    and the mean is over covered pixels (a smaller covered area, a larger mean)."""
    ref, test = _picture(), _picture((0, 10, 0, 10))
    covered = np.zeros((64, 96), bool)
    covered[30:, 30:] = True  # the difference lies outside, more than FLIP's filter away
    assert perceptual.compare_pictures(test, ref, covered)["flip_mean"] == 0.0
    inside_all = perceptual.compare_pictures(test, ref, np.ones((64, 96), bool))["flip_mean"]
    inside_part = np.zeros((64, 96), bool)
    inside_part[:32, :48] = True
    assert perceptual.compare_pictures(test, ref, inside_part)["flip_mean"] > inside_all > 0


def test_without_the_packages_the_columns_are_absent_with_a_note(monkeypatch):
    real = importlib.util.find_spec
    monkeypatch.setattr(perceptual.importlib.util, "find_spec",
                        lambda name, *a: None if name in perceptual.PACKAGES.values() else real(name, *a))
    assert perceptual.available() == []
    assert perceptual.compare_pictures(_picture(), _picture((1, 5, 1, 5)), np.ones((64, 96), bool)) == {}
    note = perceptual.missing_note()
    assert "flip_mean, ssim" in note and "pip install 'shadowlab[perceptual]'" in note


@pytest.mark.slow  # inner-loop budget (issue 36): one of the slowest tests; make test runs it
def test_a_run_without_the_packages_has_no_perceptual_columns_and_says_why(tmp_path, monkeypatch):
    from shadowlab.commands.compare import compare

    real = importlib.util.find_spec
    monkeypatch.setattr(perceptual.importlib.util, "find_spec",
                        lambda name, *a: None if name in perceptual.PACKAGES.values() else real(name, *a))
    out = compare("soft_overlap", ["pcss"], size=(64, 48), repeat=1, warmup=0, out=tmp_path / "run")
    df = pd.read_csv(out / "metrics.csv")
    assert "flip_mean" not in df.columns and "ssim" not in df.columns
    notes = json.loads((out / "run.json").read_text())["notes"]
    assert any("shadowlab[perceptual]" in n for n in notes)


@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
@needs_packages
def test_a_run_has_perceptual_columns_on_every_configuration_row(tmp_path):
    from shadowlab.commands.compare import compare

    out = compare("soft_overlap", ["pcss", "shadow_map:light_samples=4"], size=(64, 48), repeat=1, warmup=0,
                      out=tmp_path / "run")
    df = pd.read_csv(out / "metrics.csv").set_index("short_label")
    assert np.isnan(df.loc["raytrace", "flip_mean"])  # the truth is not judged against itself
    for label in ("pcss", "shadow_map:light_samples=4"):
        assert 0 < df.loc[label, "flip_mean"] < 1 and 0 < df.loc[label, "ssim"] < 1


# --------------------------------------------------------------------- rank agreement
def _row(scene, label, err, vmae, flip, ssim, family="shadow maps"):
    tech = label.split(":")[0]
    return {"scene": scene, "light": 0, "technique": tech, "label": label, "short_label": label,
            "reference": tech == "raytrace", "scene_family": family, "status": "ok", "error": "",
            "evaluated_pixels": 10000, "error_rate": err, "false_shadow_rate": err, "false_lit_rate": 0.0,
            "boundary_error_px": 0.0, "time_ms_median": 1.0, "time_ms_iqr": 0.1, "setup_ms": 1.0,
            "visibility_mae": vmae, "flip_mean": flip, "ssim": ssim}


def _agreeing_and_reversed():
    rows = []
    for scene in ("h1", "h2"):  # hard: FLIP orders as error_rate does; SSIM reverses it
        rows.append(_row(scene, "raytrace", 0.0, 0.0, np.nan, np.nan))
        for k, label in enumerate(["a", "b", "c", "d"]):
            rows.append(_row(scene, label, 0.01 * (k + 1), 0.01 * (k + 1), 0.1 * (k + 1), 0.9 + 0.02 * k))
    rows.append(_row("s1", "raytrace", 0.0, 0.0, np.nan, np.nan, family="soft shadows"))
    # soft: x and y swapped by FLIP (one discordant pair of three)
    for label, vmae, flip in (("x", 0.01, 0.2), ("y", 0.02, 0.1), ("z", 0.03, 0.3)):
        rows.append(_row("s1", label, 0.0, vmae, flip, 0.9, family="soft shadows"))
    return pd.DataFrame(rows)


def test_kendall_tau_per_family_with_its_most_discordant_pair():
    t = agreement.rank_agreement(_agreeing_and_reversed()).set_index(["scene_family", "perceptual", "exact"])
    hard = t.loc[("shadow maps", "flip_mean", "error_rate")]
    assert hard["tau"] == pytest.approx(1.0) and hard["scenes"] == 2 and hard["pairs"] == 12
    assert hard["discordant_pair"] == ""
    assert t.loc[("shadow maps", "ssim", "error_rate"), "tau"] == pytest.approx(-1.0)  # SSIM rising = better
    soft = t.loc[("soft shadows", "flip_mean", "visibility_mae")]
    assert soft["tau"] == pytest.approx(1 / 3)  # 2 concordant, 1 discordant pair of 3
    assert soft["discordant_pair"] == "y worse than x by pixels, better by eye"
    # SSIM constant on the soft scene: no τ (undefined), so no row
    assert ("soft shadows", "ssim", "visibility_mae") not in t.index


def test_scenes_with_two_configurations_do_not_count():
    df = _agreeing_and_reversed()
    df = df[~df["label"].isin(["c", "d"])]
    t = agreement.rank_agreement(df)
    assert not (t["scene_family"] == "shadow maps").any()


def test_the_sentences_name_the_judged_metric_and_the_discordant_pair():
    lines = agreement.agreement_sentences(agreement.rank_agreement(_agreeing_and_reversed()))
    soft = next(s for s in lines if s.startswith("soft shadows"))
    assert "visibility_mae" in soft and "τ = 0.33 (partly agree)" in soft and "y worse than x" in soft
    hard = next(s for s in lines if s.startswith("shadow maps"))
    assert "flip_mean τ = 1.00 (agree)" in hard and "ssim τ = -1.00 (reverse)" in hard


def test_a_worker_without_the_planned_perceptual_columns_refuses_the_task(monkeypatch):
    """The accuracy cache key records the perceptual columns the study planned with; a worker
    (Dask, another machine) that cannot compute the same ones fails the task instead of caching
    rows without them under that key."""
    from shadowlab.study import runner, tasks

    if perceptual.available():  # the key names the columns only where some are computed
        assert runner.run_key("h", "s", (1, 1), "r", "d") != runner.run_key("h", "s", (1, 1), "r", "d",
                                                                             perceptual=perceptual.available())
    tasks._same_perceptual({"perceptual": perceptual.available()})  # the same: fine
    real = importlib.util.find_spec
    monkeypatch.setattr(perceptual.importlib.util, "find_spec",
                        lambda name, *a: None if name in perceptual.PACKAGES.values() else real(name, *a))
    with pytest.raises(RuntimeError, match="install the same packages"):
        tasks._same_perceptual({"perceptual": ["flip_mean", "ssim"]})
    tasks._same_perceptual({"perceptual": []})
