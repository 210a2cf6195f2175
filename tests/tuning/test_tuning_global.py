"""One global bias from per-scene exact curves (shadowlab.tuning.global_setting): the mean curve
is exact, and the held-out regret is the difference it says it is."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.tuning.global_setting import SceneCurve, held_out, leave_one_out, mean_curve


def curve(name, breaks, values, hi=1.0):
    return SceneCurve(name, np.asarray(breaks, np.float64), np.asarray(values, np.float64), hi)


def test_mean_curve_on_the_union_of_steps():
    a = curve("a", [0.0, 0.25], [1.0, 0.0])   # wants b >= 0.25
    b = curve("b", [0.0, 0.5], [0.0, 1.0])    # wants b < 0.5
    m = mean_curve([a, b])
    assert list(m.breaks) == [0.0, 0.25, 0.5]
    assert list(m.values) == [0.5, 0.0, 0.5]
    opt = m.optimum()
    assert opt.lo == 0.25 and opt.hi == 0.5 and 0.25 <= opt.bias < 0.5 and opt.value == 0.0


def test_held_out_regret_against_each_scenes_own_optimum():
    curves = {"a": curve("a", [0.0, 0.25], [1.0, 0.0]),
              "b": curve("b", [0.0, 0.5], [0.0, 1.0]),
              "c": curve("c", [0.0, 0.75], [0.4, 0.1])}  # wants b >= 0.75, which a+b's optimum misses
    h = held_out(curves, ["a", "b"], ["c"], default=0.1)
    assert 0.25 <= h.bias < 0.5
    assert h.test_values == {"c": 0.4} and h.test_optima == {"c": 0.1}
    assert h.regret == {"c": pytest.approx(0.3)}
    assert h.default_regret == {"c": pytest.approx(0.3)}
    loo = leave_one_out(curves, default=0.1)
    assert [x.test for x in loo] == [("a",), ("b",), ("c",)]


def test_curves_over_different_ranges_are_refused():
    with pytest.raises(ValueError, match="ranges"):
        mean_curve([curve("a", [0.0], [1.0], hi=1.0), curve("b", [0.0], [1.0], hi=0.5)])
