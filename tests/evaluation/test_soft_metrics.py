"""Soft-shadow metrics of docs/metrics.md on hand-made arrays: visibility_rmse, the truth's penumbra
(penumbra_mae, penumbra_pixels), umbra_error_rate and lit_error_rate with their counts, the
report table showing them only for soft runs, and truth_stderr_max on every row (no GL)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from shadowlab.gpu import timing
from shadowlab.output import pictures as report
from shadowlab.scene.area_lights import RectLight
from shadowlab.scene.lights import PointLight
from shadowlab.evaluation.metrics import PENUMBRA_HIGH, PENUMBRA_LOW, compare, format_table, soft_regions
from shadowlab.gpu.frame import LightSlot
from shadowlab.measurement.pipeline import Evaluator, Measurement
from shadowlab.techniques import from_spec

# Truth G and technique V, 3 x 4, row 0 = top; the last pixel (G = 0.5) is not evaluated.
G = np.array([[0.00, 0.01, 0.50, 1.00],
              [0.02, 0.30, 0.98, 0.99],
              [0.00, 1.00, 1.00, 0.50]])
V = np.array([[0.60, 0.00, 0.25, 1.00],
              [0.00, 0.30, 0.40, 1.00],
              [0.00, 1.00, 1.00, 0.90]])
EV = np.ones(G.shape, bool)
EV[2, 3] = False


def test_regions_by_hand():
    """Umbra G <= 0.02 and fully lit G >= 0.98 include their bounds; the penumbra is between."""
    assert (PENUMBRA_LOW, PENUMBRA_HIGH) == (0.02, 0.98)
    umbra, pen, lit = soft_regions(G, EV)
    assert np.argwhere(umbra).tolist() == [[0, 0], [0, 1], [1, 0], [2, 0]]
    assert np.argwhere(pen).tolist() == [[0, 2], [1, 1]]          # (2, 3) is not evaluated
    assert np.argwhere(lit).tolist() == [[0, 3], [1, 2], [1, 3], [2, 1], [2, 2]]


def test_soft_metrics_by_hand():
    m = compare(V, G, EV)
    # |V - G| on the 11 evaluated pixels: 0.6, 0.01, 0.25, 0 / 0.02, 0, 0.58, 0.01 / 0, 0, 0
    # squares sum to 0.36 + 0.0001 + 0.0625 + 0.0004 + 0.3364 + 0.0001 = 0.7595
    assert m["evaluated_pixels"] == 11
    assert m["visibility_mae"] == pytest.approx(1.47 / 11, abs=1e-12)
    assert m["visibility_rmse"] == pytest.approx(np.sqrt(0.7595 / 11), abs=1e-12)
    # penumbra: (0, 2) |0.25 - 0.5| and (1, 1) |0.3 - 0.3|
    assert m["penumbra_pixels"] == 2
    assert m["penumbra_mae"] == pytest.approx(0.125, abs=1e-12)
    # umbra: only (0, 0) is lit (0.6 >= 0.5); fully lit: only (1, 2) is shadowed (0.4 < 0.5)
    assert (m["umbra_pixels"], m["umbra_error_pixels"]) == (4, 1)
    assert m["umbra_error_rate"] == pytest.approx(0.25, abs=1e-12)
    assert (m["lit_pixels"], m["lit_error_pixels"]) == (5, 1)
    assert m["lit_error_rate"] == pytest.approx(0.2, abs=1e-12)
    # the thresholded rates stay defined (at 0.5): wrong at (0, 0) (lit), (0, 2) and (1, 2)
    # (shadowed; G = 0.5 counts as lit)
    assert m["error_rate"] == pytest.approx(3 / 11, abs=1e-12)


def test_float32_bounds_fall_on_the_same_side():
    """Visibility images are float32: 0.02 and 0.98 stored as float32 are still umbra / lit."""
    m32 = compare(V.astype(np.float32), G.astype(np.float32), EV)
    m64 = compare(V, G, EV)
    for k in ("penumbra_pixels", "umbra_pixels", "lit_pixels", "umbra_error_pixels", "lit_error_pixels"):
        assert m32[k] == m64[k], k
    assert m32["penumbra_mae"] == pytest.approx(m64["penumbra_mae"], abs=1e-7)


def test_rmse_weighs_large_errors_more_than_mae():
    """Same MAE (0.1 over 10 pixels), different RMSE: one pixel off by 1 vs ten off by 0.1."""
    g = np.full((1, 10), 0.5)
    ev = np.ones_like(g, bool)
    spread = compare(g + 0.1, g, ev)
    spike = g.copy()
    spike[0, 0] = 1.5  # V = 1.5 is impossible, but the formula does not care: |V - G| = 1
    one = compare(spike, g, ev)
    assert spread["visibility_mae"] == pytest.approx(one["visibility_mae"], abs=1e-12)
    assert spread["visibility_rmse"] == pytest.approx(0.1, abs=1e-12)
    assert one["visibility_rmse"] == pytest.approx(np.sqrt(0.1), abs=1e-12)


def test_hard_truth_has_an_empty_penumbra():
    """A hard truth (0 or 1): no penumbra → penumbra_mae 0 with the count 0; umbra and lit
    rates equal false_lit_rate and false_shadow_rate."""
    g = np.ones((6, 6))
    g[:3] = 0.0
    v = g.copy()
    v[0, :2] = 1.0    # 2 umbra pixels lit
    v[5, :3] = 0.0    # 3 lit pixels shadowed
    m = compare(v, g, np.ones_like(g, bool))
    assert m["penumbra_pixels"] == 0 and m["penumbra_mae"] == 0.0
    assert m["umbra_error_rate"] == pytest.approx(2 / 18) == m["false_lit_rate"]
    assert m["lit_error_rate"] == pytest.approx(3 / 18) == m["false_shadow_rate"]


def test_empty_regions_give_zero_with_zero_counts():
    g = np.full((4, 4), 0.5)                     # all penumbra: no umbra, nothing fully lit
    v = np.zeros_like(g)
    m = compare(v, g, np.ones_like(g, bool))
    assert (m["umbra_pixels"], m["umbra_error_rate"]) == (0, 0.0)
    assert (m["lit_pixels"], m["lit_error_rate"]) == (0, 0.0)
    assert m["penumbra_pixels"] == 16 and m["penumbra_mae"] == pytest.approx(0.5)
    none = compare(v, g, np.zeros_like(g, bool))  # nothing evaluated: every figure 0
    for k in ("visibility_rmse", "penumbra_mae", "penumbra_pixels", "umbra_error_rate", "umbra_pixels",
              "lit_error_rate", "lit_pixels"):
        assert none[k] == 0, k


def _row(penumbra: int) -> dict:
    return {"short_label": "x", "error_rate": 0.1, "penumbra_pixels": penumbra, "penumbra_mae": 0.05,
            "umbra_error_rate": 0.01, "lit_error_rate": 0.02, "visibility_rmse": 0.2}


def test_report_table_shows_soft_columns_only_for_soft_runs():
    soft_cols = {"penumbra_mae", "umbra_error_rate", "lit_error_rate", "visibility_rmse"}
    hard = format_table(pd.DataFrame([_row(0), _row(0)]), "report")
    soft = format_table(pd.DataFrame([_row(0), _row(12)]), "report")
    assert not soft_cols & set(hard.columns) and "error_rate" in hard.columns
    assert soft_cols <= set(soft.columns)
    assert soft["penumbra_mae"].tolist() == ["0.05", "0.05"] and soft["lit_error_rate"].iloc[0] == "2.000 %"


def test_every_row_carries_the_truths_stderr():
    """Evaluator.row copies the truth measurement's truth_stderr_max onto a technique's row
    (0 when the truth reports none). A stand-in frame: no GL."""
    h, w = G.shape
    lights = [SimpleNamespace(type_name="area"), SimpleNamespace(type_name="area")]
    slots = [LightSlot(i, light, EV.reshape(-1)) for i, light in enumerate(lights)]
    frame = SimpleNamespace(scene=SimpleNamespace(name="s", lights=lights), width=w, height=h,
                            slot=lambda i: slots[i], as_slot=lambda x: slots[x] if isinstance(x, int) else x,
                            evaluated_image=lambda slot: EV)
    ev = Evaluator(frame)
    # the caches key on the light object: id(light) → (light, value)
    ev._contact = {id(light): (light, np.zeros(G.shape, bool)) for light in lights}
    ev._overlap = {id(light): (light, np.zeros(G.shape, bool)) for light in lights}
    ev._height = {id(light): (light, float("nan")) for light in lights}
    no_time = timing.Timing(float("nan"), float("nan"), [])
    ev._truth[id(lights[0])] = (lights[0], Measurement(ev.truth_technique, 0, G, no_time,
                                                       {"truth_stderr_max": 0.015625}))
    ev.use_truth(1, G.astype(np.float32))  # measured elsewhere: no stats
    tech = from_spec("shadow_map")
    row0 = ev.row(Measurement(tech, 0, V, no_time, {}))
    row1 = ev.row(Measurement(tech, 1, V, no_time, {}))
    assert row0["truth_stderr_max"] == 0.015625 and row1["truth_stderr_max"] == 0.0
    assert row0["penumbra_pixels"] == 2 and row0["lit_error_rate"] == pytest.approx(0.2)


def test_signed_map_colours_and_scale():
    """V − G through the diverging map: +limit blue (too bright), 0 white, −limit red (too
    dark), beyond the limit clipped; not evaluated slate, uncovered the background."""
    diff = np.array([[0.5, 0.0, -0.5, 2.0, 0.3, 0.0]])
    ev = np.array([[True, True, True, True, False, True]])
    covered = np.array([[True, True, True, True, True, False]])
    rgb = report.signed_picture(diff, 0.5, ev, covered)
    assert rgb.shape == (1, 6, 3)
    blue, white, red, clipped = rgb[0, :4]
    assert blue[2] > 0.2 + blue[0] and red[0] > 0.2 + red[2]            # the two ends (dark blue, dark red)
    assert np.all(white > 0.95) and np.ptp(white) < 0.01                  # the centre is white
    assert np.allclose(clipped, blue)
    assert np.allclose(rgb[0, 4], report.NOT_EVALUATED) and np.allclose(rgb[0, 5], report.BACKGROUND)
    with pytest.raises(ValueError, match="limit"):
        report.signed_picture(diff, 0.0, ev, covered)


def test_signed_limit_is_shared_rounded_and_bounded():
    a = np.array([0.1, -0.31, np.nan])
    b = np.array([0.2, np.nan])
    assert report.signed_limit([a, b]) == pytest.approx(0.35)     # max |V − G| = 0.31, up to a 0.05 step
    assert report.signed_limit([np.array([0.001])]) == pytest.approx(0.05)  # noise stays pale
    assert report.signed_limit([np.array([0.0, np.nan])]) == pytest.approx(0.05)
    assert report.signed_limit([np.array([1.0, -1.0])]) == pytest.approx(1.0)
    assert report.signed_limit([np.array([0.4])]) == pytest.approx(0.4)


def test_which_configurations_are_soft():
    ev = np.ones((2, 2), bool)
    hard = np.array([[0.0, 1.0], [1.0, 0.0]])
    point = PointLight(position=np.array([0.0, 3.0, 0.0]))
    rect = RectLight(position=np.array([0.0, 3.0, 0.0]), u=np.array([1.0, 0, 0]), v=np.array([0, 0, 1.0]))
    assert report.is_soft(rect, hard, hard, ev)                      # an area light
    assert not report.is_soft(point, hard, hard, ev)                 # hard light, 0/1 visibility
    pcf = hard.copy()
    pcf[0, 0] = 0.25
    assert report.is_soft(point, pcf, hard, ev)                      # fractional visibility (PCF)
    assert report.is_soft(point, hard, pcf, ev)
    assert not report.is_soft(point, pcf, hard, ev & (pcf != 0.25))  # only on evaluated pixels
