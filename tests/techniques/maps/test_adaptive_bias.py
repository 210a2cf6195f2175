"""Per-tap depth bias for the shadow-map family: receiver-plane depth bias (Isidoro 2006) and
adaptive depth bias (Dou et al. 2014), against the constant bias, on the hard cases.

Measured at 160x120 (default resolution 2048, fit=shadowable, bias=1e-5):
sm_contact false_shadow / false_lit — constant 0.2070 / 0.00070, receiver_plane 0 / 0.00083,
adaptive 0 / 0.00083 (contact gap 0 px for all three); sm_grazing — constant 0.0447 / 0,
receiver_plane 0 / 0, adaptive 0 / 0. Other light types (false_shadow, constant → receiver_plane,
adaptive): sm_point_cube cube 0.2168 → 0.00012, 0.00012; spot_scene 0.4140 → 0.00060, 0.000085;
target_direct_scene 0.1294 → 0, 0 (pcf3 alike). adaptive_epsilon=1e-2 (100× the default) on
sm_contact: false_lit 0.045, contact gap 2.9 px — the leak bound below catches an epsilon too large.
"""
from __future__ import annotations

import pytest

from shadowlab.techniques import TechniqueError, from_spec
from shadowlab.techniques.maps.lispsm import LiSPSM
from shadowlab.techniques.maps.shadow_map import COMPARISON_PARAMS, PER_TAP_VARIANTS, VARIANTS, ShadowMap

from helpers import SMALL

#: The tiny constant bias at which the plain comparison shows acne everywhere the light grazes.
TINY = 1e-5
PER_TAP = ("receiver_plane", "adaptive")


def _rows(lab, scene, variants, extra=""):
    specs = {v: f"shadow_map:variant={v},bias={TINY},bias_space=window{extra}" for v in variants}
    df = lab.rows(scene, list(specs.values()), SMALL)
    return {v: df.loc[s] for v, s in specs.items()}


@pytest.mark.parametrize("filt", ["nearest", "pcf3"])
def test_per_tap_bias_removes_the_acne_of_a_tiny_constant_bias_on_the_contact_case(lab, filt):
    rows = _rows(lab, "sm_contact", ("constant",) + PER_TAP, f",filter={filt}")
    acne = rows["constant"]["false_shadow_rate"]
    assert acne > 0.1, acne  # measured 0.207 (pcf3 0.207)
    for v in PER_TAP:
        assert rows[v]["false_shadow_rate"] < 0.005, (v, rows[v]["false_shadow_rate"])  # measured 0
        assert rows[v]["false_shadow_rate"] < acne / 20


def test_per_tap_bias_removes_grazing_acne(lab):
    rows = _rows(lab, "sm_grazing", ("constant",) + PER_TAP)
    assert rows["constant"]["false_shadow_rate"] > 0.02  # measured 0.045
    for v in PER_TAP:
        assert rows[v]["false_shadow_rate"] < 0.002, v  # measured 0


def test_per_tap_bias_keeps_the_contact_shadow(lab):
    """No leak: the per-tap comparisons light no more of the truly shadowed pixels than the
    constant bias does, and open no gap at the casters' contacts."""
    rows = _rows(lab, "sm_contact", ("constant",) + PER_TAP)
    for v in PER_TAP:
        assert rows[v]["false_lit_rate"] < 0.003, v  # measured 0.00083 (constant 0.00070)
        assert rows[v]["contact_gap_px"] < 0.1, v    # measured 0


def test_a_large_adaptive_epsilon_opens_a_leak(lab):
    """The leak bound above can fail: 100× the default epsilon lifts receivers off the contacts."""
    df = lab.rows("sm_contact", [f"shadow_map:variant=adaptive,bias=0,adaptive_epsilon={e}" for e in (1e-4, 1e-2)],
                  SMALL)
    small, large = df.iloc[0], df.iloc[1]
    assert small["false_lit_rate"] < 0.003 and small["false_shadow_rate"] < 0.005  # the paper's form (bias 0)
    assert large["false_lit_rate"] > 0.02 and large["contact_gap_px"] > 1.0  # measured 0.045, 2.9 px


@pytest.mark.parametrize("scene,extra", [("sm_point_cube", ",projection=cube,resolution=1024"),
                                         ("spot_scene", ""), ("target_direct_scene", ",filter=pcf3")])
def test_per_tap_bias_on_every_kind_of_face(lab, scene, extra):
    """Perspective faces (spot, a point light's cube atlas) and orthographic (target-direct)."""
    rows = _rows(lab, scene, ("constant",) + PER_TAP, extra)
    acne = rows["constant"]["false_shadow_rate"]
    assert acne > 0.1, acne  # measured 0.217, 0.414, 0.129
    for v in PER_TAP:
        assert rows[v]["false_shadow_rate"] < 0.005, (v, rows[v]["false_shadow_rate"])  # at most 0.0006


def test_lispsm_takes_the_per_tap_variants(lab):
    df = lab.rows("sun_scene", [f"lispsm:variant={v},bias={TINY}" for v in ("constant",) + PER_TAP], SMALL)
    assert df["false_shadow_rate"].iloc[0] > 0.1  # measured 0.187
    assert (df["false_shadow_rate"].iloc[1:] < 0.005).all()  # measured 0


# --------------------------------------------------------------------------- parameters

def test_variants_and_defaults():
    assert set(PER_TAP) <= set(VARIANTS) and set(PER_TAP_VARIANTS) == set(PER_TAP)
    assert ShadowMap().variant == "constant" and LiSPSM().variant == "slope"
    assert LiSPSM().adaptive_epsilon == COMPARISON_PARAMS["adaptive_epsilon"].default


@pytest.mark.parametrize("spec", ["shadow_map:variant=adaptive,adaptive_epsilon=1e-06,filter=pcf5",
                                  "shadow_map:variant=receiver_plane,bias=0",
                                  "lispsm:variant=adaptive,adaptive_epsilon=0.001"])
def test_parameters_round_trip(spec):
    t = from_spec(spec)
    again = from_spec(t.spec())
    assert again.params() == t.params() and again.spec() == t.spec()


@pytest.mark.parametrize("spec,match", [
    ("shadow_map:variant=receiver_plane,filter=hw2x2", "variant=receiver_plane compares each texel"),
    ("lispsm:variant=adaptive,filter=hw2x2", "filter=hw2x2 compares one depth"),
])
def test_bad_specs(spec, match):
    with pytest.raises(TechniqueError, match=match):
        from_spec(spec)
