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
  resampled difference contains 0. A difference carried by three tiles or fewer always ties at 95 %
  (the chance that a resample draws none of them is at least e⁻³ ≈ 5 %).
- **Time on one scene** — two configurations tie when their repeat intervals (first to third
  quartile of the timed renders, summed over the scene's lights) overlap.
- **Across a family of scenes** — the median over the scenes with a percentile bootstrap
  interval over the scenes (:func:`median_interval`); one technique is *separated* from another
  when the per-scene differences (0 where that scene's test ties) have a bootstrap interval of
  their median that excludes 0 (:func:`separated`): consistently better, not once by luck.

Every resampling uses the fixed seed :data:`SEED`: a verdict is a function of the study's results.
"""
from __future__ import annotations

import functools

import numpy as np

#: The confidence level of every interval and test (two-sided).
LEVEL = 0.95
#: Bootstrap resamples per test.
RESAMPLES = 2000
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
    sums = rng.poisson(1.0, size=(RESAMPLES, d.size)).astype(np.float64) @ d
    return _quantiles(sums)


def errors_tie(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two configurations' per-tile error numerators on the same tiles (equal-length 1-D
    arrays) cannot be told apart at :data:`LEVEL` (:func:`paired_interval` contains 0)."""
    a, b = np.asarray(a, dtype=np.float64).ravel(), np.asarray(b, dtype=np.float64).ravel()
    if a.shape != b.shape:
        raise ValueError(f"the two configurations have different tiles: {a.shape} vs {b.shape}")
    lo, hi = paired_interval(a - b)
    return lo <= 0.0 <= hi


def intervals_overlap(a: tuple[float, float], b: tuple[float, float]) -> bool:
    """Whether two (low, high) intervals share a point; an interval with a NaN end overlaps only
    when the medians are equal — the caller passes (median, median) for an unknown spread."""
    return bool(a[0] <= b[1] and b[0] <= a[1])


def _resampled_medians(values: np.ndarray) -> np.ndarray:
    rng = np.random.default_rng(SEED)
    picks = rng.integers(0, values.size, size=(RESAMPLES, values.size))
    return np.median(values[picks], axis=1)


def median_interval(values) -> tuple[float, float, float]:
    """(median, low, high): the median of ``values`` (one per scene) and its :data:`LEVEL`
    percentile bootstrap interval over them; NaNs are left out, all three NaN when none is left.
    With one value the interval is that value: one scene says nothing about the others."""
    v = np.asarray(values, dtype=np.float64).ravel()
    v = v[~np.isnan(v)]
    if not v.size:
        return float("nan"), float("nan"), float("nan")
    med = float(np.median(v))
    if v.size == 1:
        return med, med, med
    lo, hi = _quantiles(_resampled_medians(v))
    return med, lo, hi


def separated(diffs) -> bool:
    """Whether per-scene differences (other − best, 0 where that scene's own test ties) say the
    two differ across the scenes: the bootstrap interval of their median excludes 0. NaNs (a scene
    one of them did not run) are left out; False when none is left."""
    v = np.asarray(diffs, dtype=np.float64).ravel()
    v = v[~np.isnan(v)]
    if not v.size:
        return False
    if v.size == 1:
        return bool(v[0] != 0)
    lo, hi = _quantiles(_resampled_medians(v))
    return not (lo <= 0.0 <= hi)
