"""Filtered shadow maps (VSM, ESM, EVSM 2/4, MSM): accuracy against the truth on three scenes,
VSM's light bleeding and its reduction and the bleeding of EVSM and MSM (sm_light_bleeding),
ESM's error at contacts and fp16 EVSM's (sm_contact), the cube atlas of a point light, MSM's
16-bit storage transform, the cost figures, and parameter checks."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from shadowlab.gpu import targets
from shadowlab.techniques import TechniqueError, from_spec
from shadowlab.techniques.maps.filtered_map import (
    MAX_EXPONENT, MSM_DEQUANTIZE, MSM_QUANTIZE, max_esm_exponent, max_evsm_exponent,
    max_evsm_negative_exponent, msm_dequantize, msm_quantize,
)

from helpers import MEDIUM, SMALL

#: SMALL (was 320x240): every bound holds unchanged; the values measured at 320x240 are kept in
#: [brackets]. The two contact tests stay at MEDIUM (a band of pixels; a ratio that narrows at
#: SMALL: fp16's error rate 1.71x float32's against the bound 1.5x).
SIZE = SMALL

#: (scene, variant) → (error_rate bound, visibility_mae bound) against raytrace at 160x120, defaults
#: (resolution 1024, kernel 5). Measured error_rate / visibility_mae [at 320x240, where the bounds
#: were set]: box_on_plane vsm 0.034 % / 0.00041 [0.017 % / 0.00030], esm 0 % / 0.00040 [0 % /
#: 0.00031]; spot_scene vsm 0.033 % / 0.0014 [0.048 % / 0.0016], esm 0.017 % / 0.0014 [0.006 % /
#: 0.0015]; sm_contact vsm 0.18 % / 0.0035 [0.10 % / 0.0034], esm 1.03 % / 0.021 [1.06 % / 0.020]
#: (light leaks at the thin card's and post's contacts, test_esm_at_contacts). Bounds: 2 to 6
#: times the measured at 320x240 (at 160x120: error rates 1.7 to 12 times, maes 1.9 to 2.9 times).
#: EVSM (c+ 40, c- 5, float32) and MSM (moment bias 3e-5; 32: float32, 16: quantised 16-bit):
#: box_on_plane evsm2 0.017 % / 0.00037 [0.013 % / 0.00028], evsm4 0.034 % / 0.00041 [0.021 % /
#: 0.00030], msm 0 % / 0.00045 [0 % / 0.00038], msm16 0.008 % / 0.00053 [0.004 % / 0.00040];
#: spot_scene evsm2 0.075 % / 0.0013 [0.042 % / 0.0014], evsm4 0.067 % / 0.0015 [0.056 % /
#: 0.0017], msm 0.008 % / 0.0029 [0.013 % / 0.0032], msm16 0.008 % / 0.0029 [0.013 % / 0.0032];
#: sm_contact evsm2 0.17 % / 0.0035 [0.096 % / 0.0034], evsm4 0.18 % / 0.0035 [0.098 % /
#: 0.0034], msm 0.075 % / 0.0042 [0.059 % / 0.0042], msm16 0.092 % / 0.0043 [0.065 % / 0.0044].
#: Bounds: 2 to 8 times the measured error rates, 2 to 3.5 times the maes at 320x240 (at 160x120:
#: at least 1.7 and 1.9 times).
BOUNDS = {
    ("box_on_plane", "vsm"): (0.001, 0.001), ("box_on_plane", "esm"): (0.001, 0.001),
    ("spot_scene", "vsm"): (0.002, 0.004), ("spot_scene", "esm"): (0.002, 0.004),
    ("sm_contact", "vsm"): (0.003, 0.008), ("sm_contact", "esm"): (0.02, 0.04),
    ("box_on_plane", "evsm2"): (0.001, 0.001), ("box_on_plane", "evsm4"): (0.001, 0.001),
    ("box_on_plane", "msm"): (0.001, 0.001), ("box_on_plane", "msm,precision=16"): (0.001, 0.001),
    ("spot_scene", "evsm2"): (0.002, 0.004), ("spot_scene", "evsm4"): (0.002, 0.004),
    ("spot_scene", "msm"): (0.001, 0.008), ("spot_scene", "msm,precision=16"): (0.001, 0.008),
    ("sm_contact", "evsm2"): (0.003, 0.008), ("sm_contact", "evsm4"): (0.003, 0.008),
    ("sm_contact", "msm"): (0.003, 0.01), ("sm_contact", "msm,precision=16"): (0.003, 0.01),
}


@pytest.mark.parametrize("scene,variant", list(BOUNDS))
def test_accuracy_against_truth(lab, scene, variant):
    """Each variant's error_rate and visibility_mae on its scene stay within BOUNDS."""
    row = lab.rows(scene, [f"filtered_map:variant={variant}"], SIZE).iloc[0]
    err, mae = BOUNDS[(scene, variant)]
    assert row["error_rate"] < err, row["error_rate"]
    assert row["visibility_mae"] < mae, row["visibility_mae"]
    # the visibility is filtered (fractional somewhere) and within [0, 1]
    vis = lab.measure(scene, f"filtered_map:variant={variant}", SIZE).visibility
    assert vis.min() >= 0.0 and vis.max() <= 1.0
    assert np.any((vis > 0.02) & (vis < 0.98))


def test_vsm_light_bleeding_and_its_reduction(lab):
    """sm_light_bleeding: wrongly lit pixels inside the truth's umbra (umbra_error_rate), at
    resolution 512, kernel 15. Measured: bleed_reduction=0 1.57 %, 0.3 0.40 % [1.70 %, 0.45 %].
    Without reduction above 1 % and above 3x the reduced rate."""
    specs = [f"filtered_map:resolution=512,kernel=15,bleed_reduction={b}" for b in (0.0, 0.3)]
    rows = lab.rows("sm_light_bleeding", specs, SIZE)
    bleeding, reduced = rows["umbra_error_rate"]
    assert bleeding > 0.01, bleeding
    assert bleeding > 3.0 * reduced, (bleeding, reduced)
    # ESM (no variance) on the same map and filter bleeds far less: measured 0.05 % [0.32 %]
    esm = lab.rows("sm_light_bleeding", ["filtered_map:variant=esm,resolution=512,kernel=15"], SIZE).iloc[0]
    assert esm["umbra_error_rate"] < 0.5 * bleeding


@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
def test_evsm_and_msm_bleed_less_than_vsm(lab):
    """sm_light_bleeding, resolution 512, kernel 15, no bleeding reduction anywhere: umbra_error_rate
    measured VSM 1.57 %, evsm4 (c+ 40, c- 5) 0.025 %, msm 0.025 %, msm 16-bit 0.025 %; evsm2 (c+ 40)
    0.13 % [320x240: 1.70 %, 0.21 %, 0.22 %, 0.22 %; evsm2 0.53 %] (for the record, not asserted:
    evsm2 at c+ 5.5 in float16 measured 0.25 % at 320x240, less than at c+ 40). EVSM4 and MSM each
    below a quarter of VSM's (measured ratios 0.016 [0.13])."""
    base = "resolution=512,kernel=15"
    specs = [f"filtered_map:{base},bleed_reduction=0.0", f"filtered_map:variant=evsm4,{base},bleed_reduction=0.0",
             f"filtered_map:variant=msm,{base}", f"filtered_map:variant=msm,precision=16,{base}"]
    vsm, evsm4, msm, msm16 = lab.rows("sm_light_bleeding", specs, SIZE)["umbra_error_rate"]
    assert vsm > 0.01, vsm
    for other in (evsm4, msm, msm16):
        assert other < 0.25 * vsm, (vsm, evsm4, msm, msm16)


@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
def test_fp16_evsm_leaks_at_contacts(lab):
    """sm_contact, evsm4: half floats cap the exponents at ln(65504)/2 = 5.545, and their 11-bit
    mantissa loses the variance E[p²] − E[p]² near contacts. Measured umbra_error_rate (false lit
    inside the truth's umbra) / error_rate: float32 c = 40/5 0.014 % / 0.098 %, float32 c = 5.5/5.5
    0.014 % / 0.098 % (the small exponent alone costs nothing here), float16 c = 5.5/5.5 0.18 % /
    0.21 %. The float16 map's umbra rate is over 5x and its error rate over 1.5x the float32 ones
    (measured 12.7x, 2.1x); float32 at c = 5.5 within 1.5x of c = 40 (measured equal)."""
    small = "positive_exponent=5.5,negative_exponent=5.5"
    specs = ["filtered_map:variant=evsm4", f"filtered_map:variant=evsm4,{small}",
             f"filtered_map:variant=evsm4,precision=16,{small}"]
    rows = lab.rows("sm_contact", specs, MEDIUM)
    (full, small32, half) = rows["umbra_error_rate"]
    assert half > 5.0 * full and half > 0.001, (full, small32, half)
    assert small32 < 1.5 * full + 1e-5, (full, small32)
    err = list(rows["error_rate"])
    assert err[2] > 1.5 * err[0], err


def _near_contact(lab, scene, band):
    """Evaluated pixels within ``band`` pixels of the scene's contact lines."""
    ev = lab.evaluator(scene, MEDIUM)
    return ndimage.binary_dilation(ev.contact_lines(0), iterations=band) & ev.frame.evaluated(0)


def test_esm_at_contacts(lab):
    """ESM near sm_contact's contact lines (within 4 pixels): where the receiver lies just behind
    its occluder, exp(-c (t - z)) stays near 1. Measured (c = 80): false shadow 0 pixels (no
    over-darkening at these contacts), false lit 450 pixels; VSM 2 false shadow, 5 false lit.
    The leak is what ESM gets wrong there: ESM false lit > 10x VSM's; over-darkening (false
    shadow) stays below 5 pixels."""
    truth = lab.truth("sm_contact", MEDIUM) < 0.5
    near = _near_contact(lab, "sm_contact", 4)
    counts = {}
    for variant in ("esm", "vsm"):
        shadowed = lab.measure("sm_contact", f"filtered_map:variant={variant}", MEDIUM).visibility < 0.5
        counts[variant] = (int((shadowed & ~truth & near).sum()), int((~shadowed & truth & near).sum()))
    assert counts["esm"][0] < 5, counts
    assert counts["esm"][1] > 10 * max(counts["vsm"][1], 1), counts


@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
def test_point_light_cube_atlas(lab):
    """A point light on a cube atlas of six faces: as accurate as the single frustum on
    box_on_plane (measured error_rate: cube 0.051 %, frustum 0.034 % [0.029 %, 0.017 %]; bound
    0.1 %), with 6 moments passes, 12 blur passes and one lookup."""
    row = lab.rows("box_on_plane", ["filtered_map:projection=cube"], SIZE).iloc[0]
    assert row["error_rate"] < 0.001
    assert row["faces"] == 6 and row["passes"] == 6 + 12 + 1


def test_cost_figures_per_variant_and_precision(lab):
    """Bits per texel = components x precision: vsm 64/32, esm 32/16, evsm2 64/32, evsm4 128/64,
    msm 128/64 (precision 32/16); memory = two maps (ping-pong) + a 4-byte depth buffer per texel;
    4 passes (moments, two blur directions, lookup) for each."""
    configs = {"vsm,precision=16": 32, "esm,precision=16,exponent=11": 16, "evsm2": 64,
               "evsm2,precision=16,positive_exponent=5.5": 32, "evsm4": 128,
               "evsm4,precision=16,positive_exponent=5.5": 64, "msm": 128, "msm,precision=16": 64}
    specs = [f"filtered_map:resolution=256,variant={c}" for c in configs]
    rows = lab.rows("box_on_plane", specs, SIZE)
    texels = 256 * 256
    assert list(rows["bits_per_texel"]) == list(configs.values())
    assert list(rows["memory_bytes"]) == [texels * (2 * bits // 8 + 4) for bits in configs.values()]
    assert list(rows["passes"]) == [4] * len(configs)


def test_msm_quantization_round_trip():
    """Peters & Klein 2015 §4: the published 16-bit transform and its published inverse. Stored
    then restored moments of depths in [0, 1] come back to 1e-6 (measured 9e-11 in float64: the
    inverse is printed to 10 digits), the two matrices multiply to the identity within 1e-7
    (measured 6.5e-9), and every stored channel lies in [0, 1] within 1e-6 (measured
    [-6.5e-8, 0.99999999]; the UNORM store clamps the tiny undershoot): a mistyped constant
    breaks one of these."""
    z = np.linspace(0.0, 1.0, 2001)
    b = np.stack([z, z ** 2, z ** 3, z ** 4], axis=-1)
    stored = msm_quantize(b)
    assert np.abs(msm_dequantize(stored) - b).max() < 1e-6
    assert np.abs(MSM_DEQUANTIZE @ MSM_QUANTIZE - np.eye(4)).max() < 1e-7
    assert stored.min() >= -1e-6 and stored.max() <= 1.0 + 1e-6, (stored.min(), stored.max())
    # the transform is affine: averaging (the blur) commutes with it
    assert np.allclose(msm_quantize(b.mean(axis=0)), stored.mean(axis=0), atol=1e-12)


@pytest.mark.parametrize("precision", [32, 16])
def test_msm_stored_moments_read_back(lab, precision):
    """The moments pass on box_on_plane (kernel 1, no blur), read back (16-bit: UNORM / 65535,
    then :func:`msm_dequantize`): every texel holds (z, z², z³, z⁴) of one depth. Measured max
    |b_k − z^k|: float32 7.7e-8, 16-bit 2.5e-5 (quantisation); bounds 1e-6 and 1e-4. A shader
    applying the transform transposed would write values outside [0, 1] that the UNORM clamps."""
    t = from_spec(f"filtered_map:variant=msm,precision={precision},kernel=1,resolution=256")
    t.prepare(lab.frame("box_on_plane", SIZE), 0)
    try:
        t.render()
        raw = targets.read_texture(t.moments[0], 4, "f4" if precision == 32 else "u2").astype(np.float64)
    finally:
        t.release()
    b = raw.reshape(-1, 4) if precision == 32 else msm_dequantize(raw.reshape(-1, 4) / np.iinfo(np.uint16).max)
    z = b[:, 0]
    assert z.min() >= -1e-4 and z.max() <= 1.0 + 1e-4 and np.ptp(z) > 0.01, (z.min(), z.max())
    tol = 1e-6 if precision == 32 else 1e-4
    for k in (2, 3, 4):
        assert np.abs(b[:, k - 1] - z ** k).max() < tol, k


def test_cost_figures(lab):
    """Bits per texel 64 (VSM) and 32 (ESM); memory = two maps (the blur's ping-pong) plus a 4-byte
    depth buffer; passes 1 + 2 + 1 with a blur, 1 + 1 without."""
    rows = lab.rows("box_on_plane", ["filtered_map:resolution=256", "filtered_map:variant=esm,resolution=256",
                                     "filtered_map:resolution=256,kernel=1"], SIZE)
    texels = 256 * 256
    assert list(rows["bits_per_texel"]) == [64, 32, 64]
    assert list(rows["memory_bytes"]) == [texels * (2 * 8 + 4), texels * (2 * 4 + 4), texels * (2 * 8 + 4)]
    assert list(rows["passes"]) == [4, 4, 2]


def test_params_round_trip():
    """from_spec(t.spec()) rebuilds the same parameters."""
    t = from_spec("filtered_map:variant=esm,exponent=40,kernel=7,resolution=512")
    assert from_spec(t.spec()).params() == t.params()
    assert t.params()["exponent"] == 40.0 and t.params()["kernel"] == 7
    for spec in ("filtered_map:variant=evsm4,positive_exponent=3.5,negative_exponent=2.25,precision=16",
                 "filtered_map:variant=msm,moment_bias=0.0001,precision=16"):
        t = from_spec(spec)
        assert from_spec(t.spec()).params() == t.params()
    assert t.params()["moment_bias"] == 1e-4 and t.params()["precision"] == 16
    assert from_spec("filtered_map").params()["precision"] == 32


def test_exponent_bounds_per_precision():
    """EVSM: c <= ln(max)/2 of the format (float32 44.36, float16 5.545); ESM at float16:
    c <= ln(65504) = 11.09. The bounds themselves are accepted, just above them is an error
    naming the bound; the default c+ = 40 needs float32; precision must be 32 or 16."""
    assert max_evsm_exponent(32) == pytest.approx(np.log(np.finfo(np.float32).max) / 2) == pytest.approx(44.3614, abs=1e-4)
    assert max_evsm_exponent(16) == pytest.approx(5.5449, abs=1e-4)
    assert max_esm_exponent(16) == pytest.approx(11.0899, abs=1e-4) and max_esm_exponent(32) == MAX_EXPONENT
    # the positive warp to float32's overflow bound; the negative one to the subnormal bound 35.69
    assert max_evsm_negative_exponent() == pytest.approx(35.6971, abs=1e-4)
    from_spec("filtered_map:variant=evsm4,positive_exponent=44.36,negative_exponent=35.69")
    from_spec("filtered_map:variant=evsm2,positive_exponent=44.36,negative_exponent=40")  # evsm2 has no negative warp
    with pytest.raises(TechniqueError, match=r"negative_exponent=40 makes the lookup's arithmetic subnormal.*35\.69"):
        from_spec("filtered_map:variant=evsm4,negative_exponent=40")
    from_spec("filtered_map:variant=evsm4,precision=16,positive_exponent=5.54,negative_exponent=5.54")
    from_spec("filtered_map:variant=esm,precision=16,exponent=11.08")
    with pytest.raises(TechniqueError, match=r"positive_exponent=44.37 overflows float32.*44\.361"):
        from_spec("filtered_map:variant=evsm2,positive_exponent=44.37")
    with pytest.raises(TechniqueError, match=r"positive_exponent=40 overflows float16.*5\.545.*5\.5 for precision=16"):
        from_spec("filtered_map:variant=evsm2,precision=16")
    with pytest.raises(TechniqueError, match=r"negative_exponent=5\.55 overflows float16"):
        from_spec("filtered_map:variant=evsm4,precision=16,positive_exponent=5,negative_exponent=5.55")
    with pytest.raises(TechniqueError, match=r"exponent c=80 overflows float16.*11\.09"):
        from_spec("filtered_map:variant=esm,precision=16")
    with pytest.raises(TechniqueError, match="precision must be one of 32, 16"):
        from_spec("filtered_map:precision=8")
    # alpha = 1 replaces the moments by the bias target's, whose Hankel matrix is singular (NaN)
    with pytest.raises(TechniqueError, match="moment_bias must be <= 0.99"):
        from_spec("filtered_map:variant=msm,moment_bias=1")


def test_exponent_above_the_float32_bound_is_an_error():
    """c = 88 is accepted; c = 89 (exp(89) > FLT_MAX) and c = 0 are clear errors."""
    assert from_spec(f"filtered_map:variant=esm,exponent={MAX_EXPONENT}").exponent == MAX_EXPONENT
    with pytest.raises(TechniqueError, match="overflows float32"):
        from_spec("filtered_map:variant=esm,exponent=89")
    with pytest.raises(TechniqueError, match="exponent must be > 0"):
        from_spec("filtered_map:exponent=0")


def test_even_kernel_is_an_error():
    """A box of an even width has no centre texel: rejected."""
    with pytest.raises(TechniqueError, match="kernel must be odd"):
        from_spec("filtered_map:kernel=4")


@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
def test_evsm_at_its_bounds_does_not_depend_on_the_process_state(lab):
    """At its bounds (c⁺ = 44.36, float32 overflow; c⁻ = 35.69, float32 subnormals) evsm4 gives
    the same bits before and after a float16 EVSM has run in the process. Past the negative
    bound it did not (c⁻ = 40: 722 pixels changed by up to 0.028 on box_on_plane; c⁻ = 43.6:
    false_shadow_rate 1.6 % → 0.019 %; at 320x240): subnormal arithmetic, flushed to zero or not.
    At the bounds: false_shadow_rate 0.035 % [0.022 %], as at the defaults (40, 5)."""
    spec = "filtered_map:variant=evsm4,positive_exponent=44.36,negative_exponent=35.69"
    first = lab.measure("box_on_plane", spec, SIZE).visibility
    lab.measure("box_on_plane", "filtered_map:variant=evsm4,precision=16,positive_exponent=5.5", SIZE)
    again = lab.measure("box_on_plane", spec, SIZE).visibility
    assert np.isfinite(first).all() and np.array_equal(first, again)
    rate = lab.rows("box_on_plane", [spec], SIZE)["false_shadow_rate"].iloc[0]
    assert rate < 0.001, rate
