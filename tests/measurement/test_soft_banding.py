"""The soft-shadow hard case "a light sampled with 1 vs 5 vs 64 samples" (scene soft_banding,
docs/metrics.md): averaging N hard shadows from N fixed points of a 2 × 2 rectangle light
(shadowlab.measurement.light_sampling, Heckbert & Herf 1997) draws N overlapping hard shadows — bands — and
the error against the sampled truth falls as the bands get finer.

``shadow_polygons`` is exact for hard shadows, so each of its N hard renders is 0 or 1 per pixel
and the average takes only the levels k/N (the light is above the floor and the floor is in
front of it: the horizon and one-sided factors are all 1 there). The board is turned 20°
against the light's edges so that no two sample points project its edge onto the same line:
every level shows. Measured at 160 × 120 over the truth's penumbra (0.02 < G < 0.98, 10485 floor
pixels; truth N = 1024, bound 0.5/√N = 0.0156):

- distinct levels of V: N = 1 → {0, 1}; N = 5 → the six levels 0, 0.2, …, 1; N = 64 → 63 of
  the 65 levels k/64 (65 over all evaluated floor pixels); every value is k/N to float32
  rounding.
  Asserted: exactly 2 and 6, at least 60 for N = 64. The truth, jittered per pixel, is noise,
  not bands: 983 distinct values there (asserted > 200). With the pattern collapsed to the
  centre (light_samples ignored) N = 5 and 64 show 2 levels and the same mae as N = 1: fails.
- penumbra_mae 0.2292 → 0.0646 → 0.0051 (a staircase of N equal steps against a ramp errs by
  about 1/(4N): 0.25, 0.05, 0.004). Asserted: each ≥ 3× the next, N = 64 below 0.01, and
  N = 1 above 0.15 (a hard shadow against a 2-unit-wide penumbra).
"""
from __future__ import annotations

import numpy as np
import pytest

from helpers import SMALL

SIZE = SMALL
SCENE = "soft_banding"
COUNTS = (1, 5, 64)


def spec(n: int) -> str:
    return f"shadow_polygons:light_samples={n}"


@pytest.fixture(scope="module")
def penumbra(lab):
    """Bool (H, W): evaluated floor pixels in the truth's penumbra (0.02 < G < 0.98)."""
    frame = lab.frame(SCENE, SIZE)
    floor = frame.to_image(frame.compact_object, fill=-1, dtype=np.int64) == 0
    g = lab.truth(SCENE, SIZE)
    return frame.evaluated(0) & floor & (g > 0.02) & (g < 0.98)


def test_banding_levels(lab, penumbra):
    """N fixed light samples give N + 1 exact visibility levels k/N across the penumbra: N = 1 a
    hard edge, N = 5 six bands, N = 64 fine bands; the truth is not banded."""
    assert penumbra.sum() > 5000
    levels = {}
    for n in COUNTS:
        m = lab.measure(SCENE, spec(n), SIZE)
        assert m.stats["light_samples"] == n
        v = m.visibility[penumbra].astype(np.float64)
        k = v * n
        # float32 k/N: within a few ulps of a multiple of 1/N (the next level is 1/N away)
        assert np.abs(k - np.round(k)).max() <= 1e-5 * n, f"N={n}: values that are not multiples of 1/N"
        levels[n] = np.unique(v)
    assert levels[1].tolist() == [0.0, 1.0]
    assert levels[5].tolist() == pytest.approx([0.0, 0.2, 0.4, 0.6, 0.8, 1.0], abs=1e-7)
    assert 60 <= len(levels[64]) <= 65
    assert len(np.unique(lab.truth(SCENE, SIZE)[penumbra])) > 200


def test_banding_error_falls_with_samples(lab, penumbra):
    """penumbra_mae against the sampled truth falls 1 → 5 → 64 (≥ 3× per step), and the truth's
    own bound stays well below the N = 5 error."""
    df = lab.rows(SCENE, [spec(n) for n in COUNTS], SIZE)
    mae = [float(df.loc[spec(n), "penumbra_mae"]) for n in COUNTS]
    rmse = [float(df.loc[spec(n), "visibility_rmse"]) for n in COUNTS]
    assert (df["penumbra_pixels"] == penumbra.sum()).all()
    assert mae[0] > 0.15
    assert mae[0] > 3 * mae[1] and mae[1] > 3 * mae[2], mae
    assert mae[2] < 0.01, mae
    assert rmse[0] > rmse[1] > rmse[2], rmse
    assert float(df["truth_stderr_max"].iloc[0]) <= 0.5 / np.sqrt(1024) < mae[1]
