"""The exact bias optimiser (shadowlab.tuning.exact_bias): thresholds exact in float32, the
emulated visibility equal to the render bit for bit, the optimum equal to a compare run at
that bias, and the curve equal to every render of a brute-force sweep (issue 24's must-show)."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.measurement.pipeline import Evaluator, measure
from shadowlab.techniques import from_spec
from shadowlab.techniques.maps.toolkit import FILTERS
from shadowlab.tuning import exact_bias
from shadowlab.tuning.exact_bias import BiasCurve, exact_bias_tune, lit_at, tap_thresholds

from helpers import MEDIUM, SMALL


def test_thresholds_are_the_smallest_float32_bias_that_lights(rng):
    n = 20_000
    receiver = rng.uniform(0, 1, n).astype(np.float32)
    stored = (receiver + rng.normal(0, 1e-3, n)).astype(np.float32)
    extra = np.where(rng.uniform(size=n) < 0.5, 0, rng.uniform(0, 1e-3, n)).astype(np.float32)
    t = tap_thresholds(receiver, stored, extra, np.ones(n, bool))
    assert np.isfinite(t).all()
    assert lit_at(t, receiver, stored, extra).all()
    below = np.nextafter(t, np.float32(-np.inf))
    assert not lit_at(below, receiver, stored, extra).any()


def test_thresholds_of_uncompared_taps_are_minus_infinity():
    t = tap_thresholds(np.float32([0.5, 0.5]), np.float32([0.1, 0.1]), np.float32([0, 0]), np.array([False, True]))
    assert t[0] == -np.inf and np.isfinite(t[1])


def test_curve_by_hand():
    # three pixels, one tap each: thresholds 0.1 (truly lit), 0.2 (truly shadowed), 0.3 (truly lit)
    th = np.float32([[0.1, 0.2, 0.3]])
    truth = np.float32([1.0, 0.0, 1.0])
    c = BiasCurve.build(th, truth, 0.0, 1.0)
    # b < 0.1: pixels 0 and 2 wrongly shadowed; [0.1, 0.2): pixel 2; [0.2, 0.3): 1 and 2; >= 0.3: 1
    assert list(c.breaks) == [0.0, np.float32(0.1), np.float32(0.2), np.float32(0.3)]
    assert list(c.sums["error_rate"]) == [2, 1, 2, 1]
    assert list(c.sums["false_shadow_rate"]) == [2, 1, 1, 0]
    assert list(c.sums["false_lit_rate"]) == [0, 0, 1, 1]
    opt = c.optimum("error_rate")
    # two optimal runs: [0.1, 0.2) and [0.3, 1]; the wider is taken
    assert opt.runs == 2 and opt.lo == pytest.approx(0.3) and opt.hi == 1.0 and 0.3 <= opt.bias <= 1.0
    assert opt.value == pytest.approx(1 / 3)
    assert c.oracle["error_rate"] == 0.0  # each pixel alone can be right


def test_oracle_counts_pixels_no_bias_in_range_fixes():
    # a truly shadowed pixel lit already at b = 0 (threshold < 0): wrong for every b >= 0
    th = np.float32([[-0.5, 0.2]])
    c = BiasCurve.build(th, np.float32([0.0, 1.0]), 0.0, 1.0)
    assert c.oracle["error_rate"] == pytest.approx(0.5)
    assert c.optimum("error_rate").value == pytest.approx(0.5)


def test_signed_curve_by_hand():
    # the oriented bias: pixel 0 faces the light (lit from 0.2 on), pixel 1 faces away (lit below
    # 0.3, then dark); both truly lit
    th = np.float32([[0.2, 0.3]])
    away = np.array([[False, True]])
    c = BiasCurve.build(th, np.float32([1.0, 1.0]), 0.0, 1.0, away)
    assert list(c.breaks) == [0.0, np.float32(0.2), np.float32(0.3)]
    assert list(c.sums["error_rate"]) == [1, 0, 1]  # [0, 0.2): pixel 0; [0.2, 0.3): none; >= 0.3: pixel 1
    opt = c.optimum("error_rate")
    assert opt.value == 0.0 and opt.lo == pytest.approx(0.2) and opt.hi == pytest.approx(0.3)
    assert c.oracle["error_rate"] == 0.0


def test_away_thresholds_are_the_smallest_float32_bias_that_shadows(rng):
    n = 20_000
    receiver = rng.uniform(0, 1, n).astype(np.float32)
    stored = (receiver + rng.normal(0, 1e-3, n)).astype(np.float32)
    extra = np.zeros(n, np.float32)
    away = np.ones(n, bool)
    t = tap_thresholds(receiver, stored, extra, np.ones(n, bool), away)
    finite = np.isfinite(t)
    assert (t[~finite] == -np.inf).all()  # stored below the receiver: shadowed at every bias
    assert not lit_at(t[finite], receiver[finite], stored[finite], extra[finite], away[finite]).any()
    below = np.nextafter(t[finite], np.float32(-np.inf))
    assert lit_at(below, receiver[finite], stored[finite], extra[finite], away[finite]).all()


def test_pcf_pixel_lights_at_its_median_tap():
    # nine taps of one truly lit pixel: thresholded V >= 0.5 from the 5th smallest threshold on
    th = np.float32(np.arange(1, 10) / 100.0)[:, None]
    c = BiasCurve.build(th, np.float32([1.0]), 0.0, 1.0)
    k = c.step_of(0.05)
    assert c.sums["error_rate"][k] == 0 and c.sums["error_rate"][k - 1] == 1
    assert c.sums["visibility_mae"][k] == pytest.approx(4 / 9)


@pytest.mark.parametrize("scene", ["sm_contact", "sm_grazing"])
@pytest.mark.parametrize("spec", ["shadow_map", "shadow_map:filter=pcf3", "shadow_map:variant=slope",
                                  "shadow_map:variant=normal_offset,filter=pcf5",
                                  # per-tap comparisons: the receiver term (receiver plane) or the
                                  # extra bias (adaptive) differs from tap to tap
                                  "shadow_map:variant=receiver_plane,bias=1e-5",
                                  "shadow_map:variant=receiver_plane,filter=pcf5,bias=1e-6",
                                  "shadow_map:variant=adaptive,bias=0",
                                  "shadow_map:variant=adaptive,filter=pcf3,bias=1e-6,adaptive_epsilon=1e-6",
                                  # the oriented bias: taps facing away from the light compare
                                  # receiver + bias, lit below their threshold
                                  "shadow_map:variant=oriented",
                                  pytest.param("shadow_map:variant=oriented,filter=pcf3,bias=0.05",
                                               marks=pytest.mark.slow)])
def test_emulation_equals_the_render(lab, scene, spec):
    """The window-depth form (bias_space=window) is emulated to the bit."""
    t = from_spec(spec + ("," if ":" in spec else ":") + "bias_space=window")
    frame = lab.frame(scene, SMALL)
    m = measure(t, frame, 0, repeat=1, warmup=0, release=False)
    r = FILTERS[t.filter]
    taps = [(dx, dy) for dy in range(-r, r + 1) for dx in range(-r, r + 1)]
    try:
        terms = t.comparison_terms(taps)
    finally:
        t.release()
    flat = terms.reshape(len(taps), -1, 4)
    away = flat[..., 3] < 0
    assert away.any() == (t.variant == "oriented")  # both scenes show faces turned away from the light
    th = tap_thresholds(flat[..., 0], flat[..., 1], flat[..., 2], flat[..., 3] != 0, away)
    lit = np.where(away, th > np.float32(t.bias), th <= np.float32(t.bias))
    vis = (lit.sum(0).astype(np.float32) / np.float32(len(taps))).reshape(m.visibility.shape)
    assert int((vis != m.visibility).sum()) == 0


#: The exact route on each bias variant with a per-tap comparison term besides the constant one:
#: spec, grid (adaptive: adaptive_epsilon on a grid holding the spec's own value).
EXACT_SPECS = {"constant": ("shadow_map", None),
               "receiver_plane": ("shadow_map:variant=receiver_plane", None),
               "adaptive": ("shadow_map:variant=adaptive", {"adaptive_epsilon": [1e-7, 1e-4]}),
               "oriented": ("shadow_map:variant=oriented", None)}


@pytest.mark.parametrize("scene", ["sm_contact", "sm_grazing"])
@pytest.mark.parametrize("variant", [v if v != "oriented" else pytest.param(v, marks=pytest.mark.slow)
                                     for v in EXACT_SPECS])  # oriented: constant's twin on these scenes
def test_optimum_equals_a_render_at_that_bias_bit_for_bit(lab, scene, variant):
    base, grid = EXACT_SPECS[variant]
    ev = lab.evaluator(scene, MEDIUM)
    tune = exact_bias_tune(ev, base, grid=grid, repeat=1, warmup=0)
    assert tune.emulation_mismatch == 0
    point, opt = tune.best("error_rate")
    spec = ",".join([f"{base}:bias={opt.bias!r}" if ":" not in base else f"{base},bias={opt.bias!r}"]
                    + [f"{k}={v!r}" for k, v in point.params.items()])
    row = lab.rows(scene, [spec], MEDIUM).iloc[0]
    assert row["error_rate"] == opt.value  # bit for bit
    assert row["false_shadow_rate"] == point.curve.at(opt.bias)["false_shadow_rate"]
    assert row["false_lit_rate"] == point.curve.at(opt.bias)["false_lit_rate"]
    # the emulated candidate row is the rendered row in every metric column
    cand = exact_bias.candidate_row(ev, tune, point, from_spec(spec).spec())
    for col in ("error_rate", "false_shadow_rate", "false_lit_rate", "boundary_error_px", "visibility_mae",
                "contact_gap_px", "over_darkening_px"):
        assert cand[col] == row[col] or (np.isnan(cand[col]) and np.isnan(row[col])), col
    assert point.curve.oracle["error_rate"] <= opt.value


def test_adaptive_epsilon_is_a_grid_parameter_of_the_adaptive_variant_only():
    exact_bias.check_spec(from_spec("shadow_map:variant=adaptive"), "adaptive_epsilon")
    exact_bias.check_spec(from_spec("shadow_map:variant=receiver_plane"))
    with pytest.raises(exact_bias.ExactBiasError, match="acts with variant=adaptive"):
        exact_bias.check_spec(from_spec("shadow_map:variant=constant"), "adaptive_epsilon")


def _sweep(lab, scene, biases):
    specs = [f"shadow_map:bias={b!r}" for b in biases]
    return lab.rows(scene, specs, MEDIUM)["error_rate"].to_numpy()


@pytest.mark.slow  # inner-loop budget (issue 36): one of the slowest tests; make test runs it
@pytest.mark.parametrize("scene", ["sm_contact", "sm_grazing"])
def test_curve_predicts_a_short_sweep(lab, scene):
    """Twelve renders across the bias range: each render's error rate is the curve's, exactly."""
    tune = exact_bias_tune(lab.evaluator(scene, MEDIUM), "shadow_map", repeat=1, warmup=0)
    curve = tune.points[0].curve
    biases = [float(np.float32(b)) for b in np.geomspace(1e-6, 0.05, 12)]
    rendered = _sweep(lab, scene, biases)
    predicted = np.array([curve.at(b)["error_rate"] for b in biases])
    assert np.array_equal(rendered, predicted)
    assert curve.optimum("error_rate").value <= rendered.min()


@pytest.mark.slow
@pytest.mark.parametrize("scene", ["sm_contact", "sm_grazing"])
def test_exact_optimum_is_the_best_of_200_renders(lab, scene):
    """Issue 24's must-show: the brute-force sweep of 200 renders (log-spaced biases 1e-6..0.05,
    plus the exact optimum's interval ends and middle) never beats the exact optimum, finds it
    where its spacing reaches the optimal interval, and every render equals the curve."""
    tune = exact_bias_tune(lab.evaluator(scene, MEDIUM), "shadow_map", repeat=1, warmup=0)
    curve = tune.points[0].curve
    opt = curve.optimum("error_rate")
    biases = sorted({float(np.float32(b)) for b in np.geomspace(1e-6, 0.05, 200)})
    assert len(biases) == 200
    rendered = _sweep(lab, scene, biases)
    assert np.array_equal(rendered, [curve.at(b)["error_rate"] for b in biases])
    assert opt.value <= rendered.min()
    inside = [i for i, b in enumerate(biases) if opt.lo <= b < opt.hi]
    if inside:  # the sweep's spacing reaches the optimal interval: it finds the same value
        assert rendered[inside].min() == opt.value == rendered.min()


@pytest.mark.parametrize("scene", ["sm_contact", "sm_grazing", "spot_scene"])
@pytest.mark.parametrize("spec", ["shadow_map", "shadow_map:filter=pcf3", "shadow_map:variant=oriented"])
def test_world_bias_thresholds_reproduce_the_render(lab, scene, spec):
    """The world-distance bias (the default bias_space): window thresholds converted to world
    distances at each receiver reproduce the rendered visibility at the spec's own bias (the
    conversion is float64 against the shader's float32, so not to the bit by construction;
    measured 0 pixels on these scenes)."""
    frame = lab.frame(scene, SMALL)
    result = exact_bias_tune(Evaluator(frame), spec, 0)
    assert from_spec(spec).bias_space == "world"
    assert result.emulation_mismatch <= frame.width * frame.height // 1000, result.emulation_mismatch
