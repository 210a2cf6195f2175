"""The significance tests behind the verdicts (shadowlab.analysis.significance): the paired
Poisson bootstrap over tiles, the bootstrap of a median over scenes and interval overlap."""
import math

import numpy as np
import pytest

from shadowlab.analysis import significance as sig


def _tiles(n=40, base=3.0):
    return np.full(n, base)


def test_identical_tiles_tie_with_a_zero_interval():
    a = _tiles()
    assert sig.paired_interval(a - a) == (0.0, 0.0)
    assert sig.errors_tie(a, a.copy())
    assert sig.errors_tie(np.zeros(0), np.zeros(0))


@pytest.mark.parametrize("k", [1, 2, 3])
def test_a_difference_in_three_tiles_or_fewer_always_ties(k):
    """A resample draws none of k tiles with chance e^-k >= e^-3 ≈ 5 % > 2.5 %: the interval's low
    end is 0, however large the difference."""
    a = _tiles()
    b = a.copy()
    b[:k] += 50.0
    lo, hi = sig.paired_interval(b - a)
    assert lo == 0.0 and hi > 0.0
    assert sig.errors_tie(a, b) and sig.errors_tie(b, a)


def test_a_difference_in_eight_tiles_of_one_sign_does_not_tie():
    a = _tiles()
    b = a.copy()
    b[5:13] += 1.0                    # 8 tiles one wrong pixel more: Poisson(8) is 0..2 with < 2.5 %
    lo, hi = sig.paired_interval(b - a)
    assert lo > 0.0 and hi > lo
    assert not sig.errors_tie(a, b) and not sig.errors_tie(b, a)
    lo_neg, hi_neg = sig.paired_interval(a - b)
    assert hi_neg < 0.0
    assert (lo_neg, hi_neg) == (-hi, -lo)   # the same resamples, mirrored


def test_tiles_where_the_two_agree_change_nothing():
    d = np.zeros(100)
    d[[3, 50, 70, 80, 90, 91, 92, 99]] = 2.0
    assert sig.paired_interval(d) == sig.paired_interval(np.full(8, 2.0))


def test_mixed_sign_differences_of_equal_size_tie():
    d = np.array([4.0, -4.0] * 10)    # 20 tiles, half better, half worse
    lo, hi = sig.paired_interval(d)
    assert lo < 0.0 < hi
    a = _tiles(20, 10.0)
    assert sig.errors_tie(a + d, a)


def test_the_interval_is_deterministic():
    rng = np.random.default_rng(1)
    d = rng.normal(0.5, 2.0, 60)
    first = sig.paired_interval(d)
    assert sig.paired_interval(d.copy()) == first
    assert sig.median_interval(d) == sig.median_interval(d.copy())


def test_tiles_of_different_shapes_are_refused():
    with pytest.raises(ValueError, match="different tiles"):
        sig.errors_tie(np.zeros(3), np.zeros(4))


def test_median_interval():
    """The order-statistic interval: the range (with its coverage 1 − 2^(1−n)) for five values or
    fewer, where no pair of order statistics covers the median with 95 %; inner order statistics
    from nine values on."""
    assert sig.median_interval([0.25]) == (0.25, 0.25, 0.25, 0.0)
    assert sig.median_interval([0.25, math.nan]) == (0.25, 0.25, 0.25, 0.0)   # NaNs left out
    assert all(math.isnan(x) for x in sig.median_interval([math.nan, math.nan]))
    assert all(math.isnan(x) for x in sig.median_interval([]))
    med, lo, hi, cover = sig.median_interval([5.0, 1.0, 4.0, 2.0, 3.0])
    assert (med, lo, hi) == (3.0, 1.0, 5.0) and cover == pytest.approx(1 - 2 ** -4)   # the range: 93.75 %
    assert sig.median_interval([2.0, 3.0, 1.0])[3] == pytest.approx(0.75)
    med, lo, hi, cover = sig.median_interval(list(range(1, 10)))                      # 9 values: 2nd and 8th
    assert (med, lo, hi) == (5.0, 2.0, 8.0) and cover == pytest.approx(1 - 2 * 10 / 512)
    assert sig.median_interval([2.0, 2.0, 2.0])[:3] == (2.0, 2.0, 2.0)


def test_separated():
    assert not sig.separated([0.0, 0.0, 0.0])          # every scene's own test tied
    assert sig.separated([1.0, 2.0, 3.0, 4.0, 5.0])   # consistently worse
    assert sig.separated([-1.0, -2.0, -3.0])          # consistently better
    assert not sig.separated([1.0, -1.0, 2.0, -2.0, 0.0])
    assert not sig.separated([])
    assert not sig.separated([math.nan, math.nan])
    assert sig.separated([0.5]) and not sig.separated([0.0])   # one scene: its own test decides
    assert sig.separated([math.nan, 1.0, 2.0, 3.0, 4.0, 5.0])  # a scene one did not run is left out


def test_intervals_overlap():
    assert sig.intervals_overlap((1.0, 2.0), (1.5, 3.0))
    assert sig.intervals_overlap((1.0, 2.0), (2.0, 3.0))           # touching ends share a point
    assert sig.intervals_overlap((0.0, 10.0), (4.0, 5.0))          # one inside the other
    assert sig.intervals_overlap((4.0, 5.0), (0.0, 10.0))
    assert not sig.intervals_overlap((1.0, 2.0), (2.1, 3.0))
    assert not sig.intervals_overlap((2.1, 3.0), (1.0, 2.0))
    assert sig.intervals_overlap((3.0, 3.0), (3.0, 3.0))           # unknown spreads: equal medians
    assert not sig.intervals_overlap((3.0, 3.0), (3.1, 3.1))
    assert not sig.intervals_overlap((math.nan, math.nan), (1.0, 2.0))
