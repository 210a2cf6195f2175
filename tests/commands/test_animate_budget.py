"""shadowlab animate with shadow budgets: the shaded image's radiance columns on every frame row,
its flicker and the selection's changes between frames (issue 40)."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from shadowlab.commands.animate import animate


@pytest.mark.slow  # eight frames of three lights, three configurations
def test_radiance_flicker_and_selection_change(tmp_path):
    specs = ["shadow_map:budget=1,select=screen", "shadow_map:budget=1,select=restir", "shadow_map:budget=3,select=restir"]
    out = animate("multi_light", specs, frames=8, size=(64, 48), out=tmp_path / "a")
    df = pd.read_csv(out / "frames.csv")
    for col in ("radiance_error", "radiance_flicker", "selection_change_rate", "radiance_error_light", "light_share"):
        assert col in df.columns, col
    later = df[df["frame"] > 0]
    truth = later[later["reference"]]
    assert (truth["radiance_flicker"] == 0).all() and (truth["radiance_error"] == 0).all()
    by = {s: later[later["short_label"] == s] for s in later["short_label"].unique()}
    # a still camera: the screen policy keeps its light; every light kept never changes either
    assert (by["shadow_map:budget=1,select=screen"]["selection_change_rate"] == 0).all()
    assert (by["shadow_map:budget=3,select=restir"]["selection_change_rate"] == 0).all()
    # the reservoirs draw at random: with a still camera their single light still moves now and then,
    # and the shaded image flickers exactly when it does
    restir = by["shadow_map:budget=1,select=restir"].drop_duplicates("frame")
    changed = restir["selection_change_rate"] > 0
    assert changed.any() and not changed.all()
    assert np.array_equal(changed.to_numpy(), (restir["radiance_flicker"] > 0).to_numpy())
    summary = pd.read_csv(out / "summary.csv")
    assert {"radiance_error_mean", "radiance_flicker_mean", "selection_change_mean"} <= set(summary.columns)


@pytest.mark.slow  # six frames of the 64-light walk
def test_radiance_flicker_with_a_moving_camera(tmp_path):
    """A moving camera: exact shadows for every light flicker exactly as the truth (0) and change no
    selection; a budget's selection changes as the camera walks, and its image flickers."""
    specs = ["raytrace:budget=64,select=screen,seed=1", "shadow_map:resolution=256,budget=4,select=screen"]
    out = animate("ml_city_walk", specs, frames=6, size=(64, 48), out=tmp_path / "w")
    df = pd.read_csv(out / "frames.csv").drop_duplicates(["frame", "label"])
    later = df[df["frame"] > 0]
    assert np.isfinite(later["radiance_flicker"]).all()
    exact = later[later["short_label"].str.startswith("raytrace:")]
    assert (exact["radiance_flicker"] == 0).all() and (exact["selection_change_rate"] == 0).all()
    budget = later[later["short_label"].str.startswith("shadow_map")]
    assert (budget["selection_change_rate"] > 0).any() and (budget["radiance_flicker"] > 0).any()
