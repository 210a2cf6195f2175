"""Oriented depth bias (shadow_map variant=oriented; Fatnassi 2023, "Shadow Techniques from Final
Fantasy XVI", Square Enix, §4): the constant bias with the sign of the visible side's orientation
to the light.

What the measurements show (320x240, shadow_map's defaults: resolution 2048, fit=shadowable,
bias 0.002 with bias_space=world): the metrics evaluate only points whose visible side faces the
light (docs/metrics.md), where the oriented bias moves the receiver towards the light exactly as
``constant`` does, so every metric equals constant's, at the default bias and tuned. Error rates
(error / false-shadow / false-lit), default → exact optimum of ``bias`` (error_rate):

- sm_contact: constant and oriented 0.1823 % / 0.0527 % / 0.2677 % → 0.0377 % at bias 5.15e-4;
  slope 0.2179 % → 0.0377 %; normal_offset 0.1906 % → 0.0461 %; receiver_plane 0.1885 % → 0.0419 %;
- sm_grazing: all five 0.0042 % / 0.0043 % / 0 → 0.0042 % (what remains is undersampling: the
  oracle is 0 for all, no single bias reaches it);
- sm_thin: all five 0 at the default and tuned.

Where it differs is on the surfaces the metrics leave out, those whose visible side faces away
from the light: on sm_contact the 5 mm card's far side (14 291 pixels) reads lit through the
card under the constant bias (the bias exceeds the card's thickness in depth) and shadowed
under the oriented bias (2 pixels lit, at its silhouette).
"""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.measurement.pipeline import Evaluator
from shadowlab.techniques import from_spec
from shadowlab.tuning.exact_bias import exact_bias_tune

from helpers import MEDIUM

SCENES = ("sm_contact", "sm_grazing", "sm_thin")
METRICS = ("error_rate", "false_shadow_rate", "false_lit_rate", "boundary_error_px", "contact_gap_px")
#: The bias family at its defaults (shadow_map's resolution, fit and bias), by variant.
SPECS = {v: f"shadow_map:variant={v}" for v in ("constant", "slope", "normal_offset", "receiver_plane", "oriented")}


def test_oriented_is_in_the_bias_family():
    t = from_spec("shadow_map:variant=oriented")
    assert t.variant == "oriented" and "depth_bias" in t.PROVIDES
    assert from_spec(t.spec()).spec() == t.spec()


@pytest.mark.slow
@pytest.mark.parametrize("scene", SCENES)
def test_on_the_evaluated_pixels_oriented_equals_constant(lab, scene):
    """Every evaluated point faces the light, so the oriented bias moves it as the constant one."""
    rows = lab.rows(scene, [SPECS["constant"], SPECS["oriented"]], MEDIUM)
    constant, oriented = rows.loc[SPECS["constant"]], rows.loc[SPECS["oriented"]]
    for col in METRICS:
        assert oriented[col] == constant[col], col  # bit for bit
    # llvmpipe at 320x240; the NVIDIA H200 rasterises a few grazing pixels differently (sm_grazing
    # 2.3e-05 there): the verdict above is bit for bit on both, the level within 1e-4
    measured = {"sm_contact": 0.0018225, "sm_grazing": 0.0000419, "sm_thin": 0.0}[scene]
    assert oriented["error_rate"] == pytest.approx(measured, abs=1e-4)


@pytest.mark.slow
def test_faces_turned_from_the_light_stay_in_their_own_shadow(lab):
    """The card's far side, seen by the camera: lit through a 5 mm card by the constant bias,
    shadowed by the oriented bias (the rule's purpose). Not in any metric: those points are not
    evaluated."""
    frame = lab.frame("sm_contact", MEDIUM)
    names = [o.name for o in frame.scene.objects]
    card = frame.covered & (frame.object_id == names.index("card")) & ~frame.evaluated_image(frame.slot(0))
    constant = lab.measure("sm_contact", SPECS["constant"], MEDIUM).visibility
    oriented = lab.measure("sm_contact", SPECS["oriented"], MEDIUM).visibility
    assert int(card.sum()) == 14291
    assert int((constant[card] >= 0.5).sum()) == 14291  # every pixel of the far side leaks
    assert int((oriented[card] >= 0.5).sum()) <= 10     # measured 2, at the card's silhouette


@pytest.mark.slow
def test_exact_tune_of_oriented_matches_constant(lab):
    """The exact optimiser sweeps the oriented bias (its faces turned away compare receiver +
    bias, lit below their threshold); the emulation equals the render and the optimum is the
    constant bias's."""
    ev = lab.evaluator("sm_contact", MEDIUM)
    results = {}
    for v in ("constant", "oriented"):
        tune = exact_bias_tune(ev, SPECS[v], repeat=1, warmup=0)
        assert tune.emulation_mismatch == 0
        point, opt = tune.best("error_rate")
        results[v] = (opt.bias, opt.value, point.curve.oracle["error_rate"])
        if v == "oriented":
            assert point.away is not None and point.away.any()  # faces turned away were seen
    assert results["oriented"] == results["constant"]
    bias, value, oracle = results["oriented"]
    assert bias == pytest.approx(5.155e-4, rel=1e-3) and value == pytest.approx(3.7707e-4, rel=1e-4)
    assert oracle == pytest.approx(6.28e-5, rel=1e-2)


@pytest.mark.slow
@pytest.mark.parametrize("scene", SCENES)
def test_the_bias_family_default_and_tuned(lab, scene):
    """The brief's comparison: each variant's error at its defaults and at the exact optimum of
    its constant bias (the grid parameters at their defaults), as measured."""
    measured = {  # variant: (default error_rate, tuned error_rate)
        "sm_contact": {"constant": (1.8225e-3, 3.7707e-4), "slope": (2.1786e-3, 3.7707e-4),
                       "normal_offset": (1.9063e-3, 4.6087e-4), "receiver_plane": (1.8854e-3, 4.1897e-4),
                       "oriented": (1.8225e-3, 3.7707e-4)},
        "sm_grazing": {v: (4.1912e-5, 4.1912e-5) for v in SPECS},
        "sm_thin": {v: (0.0, 0.0) for v in SPECS},
    }[scene]
    rows = lab.rows(scene, list(SPECS.values()), MEDIUM)
    ev = lab.evaluator(scene, MEDIUM)
    for v, spec in SPECS.items():
        default, tuned = measured[v]
        # measured on llvmpipe; another rasteriser moves a few pixels (the NVIDIA H200: sm_grazing
        # 2.3e-05 at the defaults), hence 1e-4 of the pixels beside the relative margin
        assert rows.loc[spec]["error_rate"] == pytest.approx(default, rel=1e-3, abs=1e-4), v
        _, opt = exact_bias_tune(ev, spec, repeat=1, warmup=0).best("error_rate")
        assert opt.value == pytest.approx(tuned, rel=1e-3, abs=1e-4), v
        assert opt.value <= rows.loc[spec]["error_rate"] + 1e-12, v  # the optimum is never worse
