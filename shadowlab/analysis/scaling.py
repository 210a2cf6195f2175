"""Scaling laws (issue 27): the cost law t = t0 + a·P^α + b·T^β of a technique (P pixels,
T triangles), fitted to measured render times with confidence intervals, and where two fitted
laws cross. What ``experiments/scaling_laws.py`` fits to the ``scaling`` suite's sweeps
(docs/scaling.md); kept here, in the package, so that the tests can hold the fit to a known law.
"""
from __future__ import annotations

import itertools
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import optimize, stats

#: Units of the fit: P in Mpx, T in millions of triangles (so a, b are ms at 1 Mpx, 1M triangles).
P_UNIT, T_UNIT = 1e6, 1e6
#: Names of the law's parameters, in order.
PARAMS = ("t0", "a", "alpha", "b", "beta")
#: Upper bounds of the exponents (the lower bounds are 0, as for t0, a and b).
MAX_EXPONENT = 3.0
#: Confidence level of the intervals.
LEVEL = 0.95


def scaling_law(x, t0, a, alpha, b, beta):
    """t = t0 + a·P^α + b·T^β, with ``x`` = (P, T) in the fit's units (Mpx, millions of triangles):
    a fixed cost, a cost that grows with the pixels and one that grows with the triangles."""
    p, t = x
    return t0 + a * np.power(p, alpha) + b * np.power(t, beta)


@dataclass
class LawFit:
    """One family's fitted law: the parameters (:data:`PARAMS` order), their standard errors and
    ``LEVEL`` intervals (NaN with fewer than 6 points), R² of the time (linear), the rms relative
    residual, the number of points, and the parameters that ended on a bound (their interval is
    not trustworthy)."""

    params: np.ndarray
    stderr: np.ndarray
    low: np.ndarray
    high: np.ndarray
    r2: float
    rel_rms: float
    n: int
    at_bound: tuple[str, ...]

    def value(self, name: str) -> float:
        """The fitted value of parameter ``name``."""
        return float(self.params[PARAMS.index(name)])

    def interval(self, name: str) -> tuple[float, float]:
        """The ``LEVEL`` confidence interval of parameter ``name``."""
        i = PARAMS.index(name)
        return float(self.low[i]), float(self.high[i])

    def predict(self, pixels, triangles) -> np.ndarray:
        """The law's time (ms) at ``pixels`` and ``triangles`` (raw counts, not the fit's units)."""
        return scaling_law((np.asarray(pixels, float) / P_UNIT, np.asarray(triangles, float) / T_UNIT), *self.params)


def fit_law(pixels, triangles, time_ms, starts: int = 3) -> LawFit:
    """Fit :func:`scaling_law` to measured times by non-linear least squares on relative residuals
    (curve_fit with sigma = the time: a 10 % miss counts alike at 5 ms and at 5 s, since the times
    span three decades), every parameter >= 0 and the exponents <= :data:`MAX_EXPONENT`. The
    intervals come from the covariance (linearised at the optimum, scaled by the residual variance)
    and Student's t with n − 5 degrees of freedom. Several starting exponents are tried
    (``starts``² starts) and the lowest cost kept, since the exponents and the fixed cost trade off."""
    p = np.asarray(pixels, float) / P_UNIT
    t = np.asarray(triangles, float) / T_UNIT
    y = np.asarray(time_ms, float)
    ok = np.isfinite(y) & (y > 0)
    p, t, y = p[ok], t[ok], y[ok]
    n = len(y)
    if n < len(PARAMS):
        raise ValueError(f"a law of {len(PARAMS)} parameters needs at least {len(PARAMS)} points, got {n}")
    lower = np.zeros(len(PARAMS))
    upper = np.array([np.inf, np.inf, MAX_EXPONENT, np.inf, MAX_EXPONENT])
    best = None
    for alpha0, beta0 in itertools.product(np.linspace(0.3, 1.2, starts), repeat=2):
        p0 = [0.3 * y.min(), 0.3 * np.median(y), alpha0, 0.3 * np.median(y), beta0]
        try:
            popt, pcov = optimize.curve_fit(scaling_law, (p, t), y, p0=p0, sigma=y, absolute_sigma=False,
                                            bounds=(lower, upper), max_nfev=20000)
        except (RuntimeError, ValueError):
            continue
        cost = float(np.sum(((scaling_law((p, t), *popt) - y) / y) ** 2))
        if best is None or cost < best[0]:
            best = (cost, popt, pcov)
    if best is None:
        raise RuntimeError("no start of the fit converged")
    cost, popt, pcov = best
    dof = n - len(PARAMS)
    stderr = np.sqrt(np.clip(np.diag(pcov), 0, None)) if dof > 0 else np.full(len(PARAMS), np.nan)
    half = stats.t.ppf(0.5 + LEVEL / 2, dof) * stderr if dof > 0 else np.full(len(PARAMS), np.nan)
    model = scaling_law((p, t), *popt)
    ss_res, ss_tot = float(np.sum((y - model) ** 2)), float(np.sum((y - y.mean()) ** 2))
    tol = 1e-6 * np.maximum(1.0, np.abs(popt))
    at_bound = tuple(name for name, v, lo, hi, eps in zip(PARAMS, popt, lower, upper, tol)
                     if abs(v - lo) < eps or abs(v - hi) < eps)
    return LawFit(popt, stderr, popt - half, popt + half, 1 - ss_res / ss_tot if ss_tot > 0 else float("nan"),
                  float(np.sqrt(cost / n)), n, at_bound)


def crossovers(fits: dict[str, LawFit], ranges: dict[str, tuple[float, float]], axis: str, fixed: float,
               grid: int = 400) -> list[dict]:
    """Where two families' fitted costs cross along ``axis`` ("pixels" or "triangles") with the
    other count held at ``fixed``: for each pair, each sign change of log(t_a / t_b) on a log grid
    over the part of the axis both were measured on (``ranges[family]`` = (lo, hi)), refined by
    Brent's method. One row per crossing: the two families, the axis, the other count, where they
    cross, the time there, and which family is cheaper above it."""
    rows = []
    for fa, fb in itertools.combinations(sorted(fits), 2):
        lo, hi = max(ranges[fa][0], ranges[fb][0]), min(ranges[fa][1], ranges[fb][1])
        if not lo < hi:
            continue

        def gap(x, fa=fa, fb=fb):
            args = (x, fixed) if axis == "pixels" else (fixed, x)
            return float(np.log(fits[fa].predict(*args) / fits[fb].predict(*args)))

        xs = np.geomspace(lo, hi, grid)
        g = np.array([gap(x) for x in xs])
        for i in np.nonzero(np.sign(g[:-1]) * np.sign(g[1:]) < 0)[0]:
            x = optimize.brentq(gap, xs[i], xs[i + 1], xtol=1e-9 * xs[i])
            args = (x, fixed) if axis == "pixels" else (fixed, x)
            rows.append({"axis": axis, "held": "triangles" if axis == "pixels" else "pixels", "held_at": fixed,
                         "family_a": fa, "family_b": fb, "crosses_at": x, "time_ms": float(fits[fa].predict(*args)),
                         "cheaper_above": fb if g[i] < 0 else fa})
    return rows


def scene_triangles(path: Path) -> int:
    """Triangles of a scene file, every object counted (casters and receivers): from the TOML for
    the primitives whose counts are fixed by their parameters (torus: 2 × major × minor sections,
    plane: 2 × divisions²), else by loading the scene. Cheap where it matters: the 4M torus is
    counted without being built."""
    data = tomllib.loads(Path(path).read_text())
    total = 0
    for obj in data["objects"]:
        if obj["mesh"] == "torus":
            total += 2 * obj.get("major_sections", 48) * obj.get("minor_sections", 24)
        elif obj["mesh"] == "plane":
            total += 2 * obj.get("divisions", 1) ** 2
        else:
            from shadowlab.scene import load_scene

            return sum(len(o.faces) for o in load_scene(path).objects)
    return total
