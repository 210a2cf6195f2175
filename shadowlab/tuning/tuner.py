"""One configuration tuned on one scene and light: the plan (which route, checked before any
rendering) and the search itself, without writing anything — what ``shadowlab tune`` and a
tuned study's tasks share (docs/tuning.md).

Two routes, chosen from the spec and the parameters asked for:

- **exact** (:mod:`shadowlab.tuning.exact_bias`): the shadow-map bias family — ``bias`` of the
  constant, slope, normal_offset, receiver_plane, adaptive and oriented variants, with at most the
  variant's one grid parameter (``slope_scale``, ``normal_offset`` or ``adaptive_epsilon``) on a
  stated grid — from one render per grid value: every constant bias at once;
- **search** (:mod:`shadowlab.tuning.search`): any other parameters, by coordinate search over
  rendered candidates on a budget of renders, reusing a study cache when given one.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import pandas as pd

from ..measurement.pipeline import Evaluator
from ..techniques import from_spec
from ..util.validation import RunError, did_you_mean
from . import exact_bias
from .search import OBJECTIVES, RenderedCandidates, coordinate_search
from .space import Dimension, TuneError, parse_params, with_params

#: Renders the search route may spend by default.
DEFAULT_BUDGET = 24
#: Grid points of slope_scale / normal_offset on the exact route when no list is given.
EXACT_GRID_POINTS = 9


@dataclass
class TunePlan:
    """What a tune will do, decided before any rendering: the technique spec, the dimensions,
    the objective, the route (``exact`` or ``search``) and why, and for the exact route its bias
    range and grid."""

    spec: str
    dimensions: list[Dimension]
    objective: str
    route: str
    reason: str
    bias_range: tuple[float, float] = (0.0, 1.0)
    grid: dict = field(default_factory=dict)

    def describe(self) -> dict:
        """The plan as JSON-ready facts."""
        return {"spec": self.spec, "objective": self.objective, "route": self.route, "reason": self.reason,
                "dimensions": [d.describe() for d in self.dimensions], "grid": self.grid,
                "bias_range": list(self.bias_range)}


def plan_tune(spec: str, params: list[str], objective: str = "error_rate") -> TunePlan:
    """Check the arguments and choose the route; TuneError / TechniqueError (exit 2) on bad
    input, before any GL work. No ``params``: ``bias`` where the technique has one."""
    tech = from_spec(spec)
    if objective not in OBJECTIVES:
        raise TuneError(f"--objective {objective}: not a metric column{did_you_mean(objective, OBJECTIVES)}")
    if not params:
        if "bias" not in tech.params():
            raise TuneError(f"{tech.name}: say which parameters to tune (--param NAME); it has "
                            f"{', '.join(tech.params())}")
        params = ["bias"]
    dims = parse_params(tech, params)
    names = [d.name for d in dims]
    others = [n for n in names if n != "bias"]
    reason = "coordinate search over rendered candidates"
    if "bias" in names and len(others) <= 1 and all(n in exact_bias.GRID_UNIFORMS for n in others):
        try:
            exact_bias.check_spec(tech, others[0] if others else None)
        except exact_bias.ExactBiasError as exc:
            if others:  # a grid parameter with the wrong variant: say so rather than render blindly
                raise TuneError(str(exc)) from None
            reason = f"coordinate search over rendered candidates (not exact: {exc})"
        else:
            bias = next(d for d in dims if d.name == "bias")
            if bias.kind == "choice":
                lo, hi = float(min(bias.choices)), float(max(bias.choices))
            else:
                lo, hi = float(bias.lo), float(bias.hi)
            grid = {}
            if others:
                d = next(d for d in dims if d.name == others[0])
                values = sorted({float(v) for v in d.grid(EXACT_GRID_POINTS)})
                current = float(getattr(tech, d.name))
                if d.kind != "choice" and d.lo <= current <= d.hi and current not in values:
                    values = sorted(values + [current])  # the spec's own value: the emulation check
                grid[d.name] = values
            return TunePlan(tech.spec(), dims, objective, "exact",
                            "the bias family, every constant bias at once from one render"
                            + (f"; {others[0]} on a grid of {len(grid[others[0]])}" if others else ""),
                            (lo, hi), grid)
    return TunePlan(tech.spec(), dims, objective, "search", reason)


@dataclass
class TuneOutcome:
    """What :func:`find_best` found: the best ``spec`` and its tuned ``params``, the objective's
    ``value`` as the tuner measured it (exact route: the optimiser's exact value; search: the
    rendered row's), every candidate row (``candidates``: parameters and every metric column,
    ``source`` = exact or render), facts for best.json, and the route's own result (``exact``:
    the :class:`~shadowlab.tuning.exact_bias.ExactBiasTune` with the default's and the best's
    (grid point, bias); ``trials``: the search history)."""

    plan: TunePlan
    spec: str
    params: dict
    value: float
    candidates: pd.DataFrame
    facts: dict
    exact: exact_bias.ExactBiasTune | None = None
    default_point: tuple | None = None
    best_point: tuple | None = None
    trials: list | None = None


def find_best(evaluator: Evaluator, plan: TunePlan, light: int = 0, budget: int = DEFAULT_BUDGET,
              repeat: int = 3, warmup: int = 1, time_budget_ms: float | None = None, cache=None,
              scene_hash: str | None = None, on_step: Callable[[str, int], None] | None = None) -> TuneOutcome:
    """Run the plan on the evaluator's frame and light (see the module docstring)."""
    if plan.route == "exact":
        return _exact(evaluator, plan, light, repeat, warmup, time_budget_ms, on_step)
    return _search(evaluator, plan, light, budget, repeat, warmup, time_budget_ms, cache, scene_hash, on_step)


def _exact(evaluator: Evaluator, plan: TunePlan, light: int, repeat: int, warmup: int, time_budget_ms,
           on_step) -> TuneOutcome:
    """The exact route: one render, every bias; candidate rows from the emulated visibility."""
    lo, hi = plan.bias_range
    total = max(1, len(next(iter(plan.grid.values()), [None])))
    result = exact_bias.exact_bias_tune(evaluator, plan.spec, light, lo, hi, plan.grid, repeat, warmup,
                                        on_step=(lambda what: on_step(what, total)) if on_step else None)
    if result.emulation_mismatch > 0:
        raise RunError(f"{plan.spec}: the exact optimiser's emulation differs from the render on "
                       f"{result.emulation_mismatch} pixels (a driver that rounds the comparison differently?); "
                       f"tune by rendering instead (give a list: --param bias=a,b,c)")
    if time_budget_ms is not None and result.base.timing.median_ms > time_budget_ms:
        raise RunError(f"{plan.spec} takes {result.base.timing.median_ms:.3f} ms, over --time-budget "
                       f"{time_budget_ms} ms at every bias (the bias does not change the cost)")
    objective = plan.objective
    exact = objective in exact_bias.EXACT_OBJECTIVES
    tech = from_spec(plan.spec)
    rows = []
    for point in result.points:
        for b in exact_bias.candidate_biases(result, point, objective, lo, hi, float(tech.bias)):
            spec = with_params(tech, {"bias": b, **point.params})
            rows.append({"source": "exact", **exact_bias.candidate_row(evaluator, result, point, spec)})
    candidates = pd.DataFrame(rows)
    opt = None
    if exact:
        point, opt = result.best(objective)
        bias, value = opt.bias, opt.value
    else:  # any other column: the best candidate row, each evaluated exactly without a render
        i = int(np.nanargmin(candidates[objective].to_numpy(float)))
        best_row = candidates.iloc[i]
        bias, value = float(best_row["param_bias"]), float(best_row[objective])
        point = next(p for p in result.points if all(best_row[f"param_{k}"] == v for k, v in p.params.items()))
    default_point = next((p for p in result.points if all(getattr(tech, k) == v for k, v in p.params.items())),
                         result.points[0])
    per_point = []
    for p in result.points:
        o = p.curve.optimum(objective) if exact else None
        per_point.append({"params": p.params, "bias": o.bias if o else None, "value": o.value if o else None,
                          "interval": [o.lo, o.hi] if o else None, "optimal_runs": o.runs if o else None,
                          "oracle": p.curve.oracle.get(objective), "steps": int(len(p.curve.breaks))})
    facts = {
        "exact_value": value,
        "optimum_interval": [opt.lo, opt.hi] if opt else None,
        "optimal_runs": opt.runs if opt else None,
        "oracle": point.curve.oracle.get(objective) if exact else None,
        "default_exact": default_point.curve.at(float(tech.bias)).get(objective) if exact else None,
        "grid": per_point,
        "taps": result.taps,
        "emulation_mismatch": result.emulation_mismatch,
        "renders": 1,
        "exact_seconds": result.seconds,
        "candidates": len(candidates),
    }
    return TuneOutcome(plan, with_params(tech, {"bias": bias, **point.params}), {"bias": bias, **point.params},
                       value, candidates, facts, exact=result, default_point=(default_point, float(tech.bias)),
                       best_point=(point, bias))


def _search(evaluator: Evaluator, plan: TunePlan, light: int, budget: int, repeat: int, warmup: int,
            time_budget_ms, cache, scene_hash, on_step) -> TuneOutcome:
    """The search route: coordinate search over rendered candidates."""
    tech = from_spec(plan.spec)
    evaluate = RenderedCandidates(evaluator, plan.spec, light=light, objective=plan.objective,
                                  time_budget_ms=time_budget_ms, repeat=repeat, warmup=warmup, cache=cache,
                                  scene_hash=scene_hash,
                                  on_step=(lambda what: on_step(what, budget)) if on_step else None)
    start = {d.name: getattr(tech, d.name) for d in plan.dimensions}
    trials = coordinate_search(plan.dimensions, start, evaluate, budget)
    candidates = pd.DataFrame([{"source": "render", "round": t.round, "objective_value": t.value, "note": t.note,
                                **(t.row or {})} for t in trials])
    feasible = [t for t in trials if math.isfinite(t.value)]
    if not feasible:
        raise RunError(f"{plan.spec}: no candidate met --time-budget {time_budget_ms} ms in {len(trials)} renders")
    best = min(feasible, key=lambda t: t.value)  # the earliest on ties: the start wins
    facts = {"renders": getattr(evaluate, "renders", None), "cache_hits": getattr(evaluate, "hits", None),
             "budget": budget, "candidates": len(trials), "search_value": best.value}
    return TuneOutcome(plan, with_params(tech, best.params), dict(best.params), best.value, candidates, facts,
                       trials=trials)
