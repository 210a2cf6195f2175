"""When two configurations' figures differ for real (docs/metrics.md#verdicts-and-significance): the tests
behind the study's verdicts, instead of fixed tolerances.

- **Error on one scene** — a paired bootstrap over tiles. Both configurations are judged on the
  same pixels, so the difference of their error numerators (wrong pixels, or Σ|V − G| on a soft
  scene) is a sum over pixels, and its per-tile sums (:mod:`shadowlab.evaluation.tiles`) are the
  blocks of a block bootstrap: errors are correlated within a tile (an edge is wrong along its
  length), so resampling pixels one by one would call a one-edge difference certain. The resampling
  is the Poisson bootstrap (each tile drawn Poisson(1) times: Hanley & MacGibbon 2006; Chamandy et
  al. 2012), which for many tiles behaves as the ordinary bootstrap and needs only the tiles
  where the two differ. The two **tie** when the :data:`LEVEL` percentile interval of the
  resampled difference contains 0. A difference carried by three tiles or fewer, all of one sign,
  always ties at 95 %: a resample draws none of them with probability e⁻ᵏ, above the 2.5 % tail
  for k ≤ 3.
- **Error across a family of scenes** — the same bootstrap over every tile of the family's scenes
  at once, each tile's difference divided by its scene's denominator (the truth's boundary
  pixels, or the evaluated pixels), so that the resampled sum is the sum of the per-scene
  differences of the metric (:func:`stratified_interval`). The scenes are taken as given: the
  test says whether one technique is worse *on these scenes*, not on scenes not run.
- **Time on one scene** — two configurations tie when their repeat intervals (first to third
  quartile of the timed renders, summed over the scene's lights) overlap.
- **Time across a family of scenes** — the per-scene differences (0 where that scene's repeat
  intervals overlap) separate two techniques when the distribution-free interval of their median
  excludes 0 (:func:`separated`). Repeats are not pixels: a scene's timing is one observation.
- **A median over the scenes** — with the distribution-free order-statistic interval
  (:func:`median_interval`; Conover 1999, §3.2): with five scenes or fewer no pair of order
  statistics covers the median with 95 %, so the interval given is the range, with its own
  coverage 1 − 2¹⁻ⁿ (a bootstrap of so few values would also return the range, and call it 95 %).

Every resampling uses the fixed seed :data:`SEED`: a verdict is a function of the study's results.
"""
from __future__ import annotations

import functools
import math

import numpy as np
from scipy import stats

#: The confidence level of every interval and test (two-sided).
LEVEL = 0.95
#: Bootstrap resamples per test.
RESAMPLES = 2000
#: Resamples drawn at once: bounds the weight matrix (resamples × differing tiles) in memory.
CHUNK = 250
#: The seed of every resampling, so that the same results give the same verdicts.
SEED = 38


def _quantiles(samples: np.ndarray) -> tuple[float, float]:
    alpha = (1.0 - LEVEL) / 2.0
    lo, hi = np.quantile(samples, [alpha, 1.0 - alpha])
    return float(lo), float(hi)


def paired_interval(diff_per_tile: np.ndarray) -> tuple[float, float]:
    """The :data:`LEVEL` percentile interval of Σ_t w_t d_t, the tiles' differences ``d_t`` of two
    configurations' error numerators resampled with Poisson(1) weights w_t (module docstring).
    (0, 0) when the two agree on every tile."""
    d = np.asarray(diff_per_tile, dtype=np.float64).ravel()
    d = d[d != 0]
    if not d.size:
        return 0.0, 0.0
    return _interval_of(d.tobytes())


@functools.lru_cache(maxsize=4096)
def _interval_of(nonzero: bytes) -> tuple[float, float]:
    # a study's page, summary.md and the README each ask for the same pairs: computed once
    d = np.frombuffer(nonzero, dtype=np.float64)
    rng = np.random.default_rng(SEED)
    sums = np.concatenate([rng.poisson(1.0, size=(min(CHUNK, RESAMPLES - k), d.size)).astype(np.float64) @ d
                           for k in range(0, RESAMPLES, CHUNK)])
    return _quantiles(sums)


def errors_tie(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two configurations' per-tile error numerators on the same tiles (equal-length 1-D
    arrays) cannot be told apart at :data:`LEVEL` (:func:`paired_interval` contains 0)."""
    a, b = np.asarray(a, dtype=np.float64).ravel(), np.asarray(b, dtype=np.float64).ravel()
    if a.shape != b.shape:
        raise ValueError(f"the two configurations have different tiles: {a.shape} vs {b.shape}")
    lo, hi = paired_interval(a - b)
    return lo <= 0.0 <= hi


def stratified_interval(pairs: list[tuple[np.ndarray, np.ndarray, float]]) -> tuple[float, float]:
    """The :data:`LEVEL` interval of Σ_s (metric_a,s − metric_b,s) over a family's scenes by the
    tile bootstrap of every scene at once: ``pairs`` holds per scene the two configurations'
    per-tile numerators and the scene's denominator (module docstring). (0, 0) when they agree."""
    scaled = [(np.asarray(a, np.float64).ravel() - np.asarray(b, np.float64).ravel()) / den
              for a, b, den in pairs if den > 0]
    return paired_interval(np.concatenate(scaled)) if scaled else (0.0, 0.0)


def intervals_overlap(a: tuple[float, float], b: tuple[float, float]) -> bool:
    """Whether two (low, high) intervals share a point; False when an end is NaN (an unknown
    time ties with nothing)."""
    return bool(a[0] <= b[1] and b[0] <= a[1])


def _order_statistic_ranks(n: int) -> tuple[int, int, float]:
    """(k, n + 1 − k, coverage): the widest-tailed pair of order statistics (1-based) whose interval
    covers the median of n values with at least :data:`LEVEL`, or (1, n, its coverage) when none
    does (n ≤ 5 at 95 %)."""
    best = 1
    for k in range(1, n // 2 + 1):
        if 2 * stats.binom.cdf(k - 1, n, 0.5) <= 1 - LEVEL:
            best = k
    return best, n + 1 - best, 1 - 2 * float(stats.binom.cdf(best - 1, n, 0.5))


def median_interval(values) -> tuple[float, float, float, float]:
    """(median, low, high, coverage): the median of ``values`` (one per scene) and its
    distribution-free order-statistic interval with that interval's coverage (at least
    :data:`LEVEL` when there are six values or more; the range otherwise, module docstring); NaNs
    are left out, all NaN when none is left. One value: that value, coverage 0."""
    v = np.sort(np.asarray(values, dtype=np.float64).ravel())
    v = v[~np.isnan(v)]
    if not v.size:
        return math.nan, math.nan, math.nan, math.nan
    med = float(np.median(v))
    if v.size == 1:
        return med, med, med, 0.0
    lo, hi, coverage = _order_statistic_ranks(v.size)
    return med, float(v[lo - 1]), float(v[hi - 1]), coverage


def separated(diffs) -> bool:
    """Whether per-scene differences (other − best, 0 where that scene's own test ties) say the
    two differ across the scenes: the order-statistic interval of their median
    (:func:`median_interval`) excludes 0 — with five scenes or fewer, every scene's difference is
    significant and of one sign. NaNs (a scene one of them did not run) are left out; False when
    none is left."""
    v = np.asarray(diffs, dtype=np.float64).ravel()
    v = v[~np.isnan(v)]
    if not v.size:
        return False
    _, lo, hi, _ = median_interval(v)
    return not (lo <= 0.0 <= hi)
