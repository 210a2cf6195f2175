"""``shadowlab tune``: one technique configuration at its best settings on one scene, written
as a run directory (docs/tuning.md).

The tuning itself is :func:`shadowlab.tuning.tuner.find_best` (the exact bias route or the
search route). Then the best configuration and the spec as given are run as a ``compare`` run
of the same scene and size into the same directory (``report.html``: default and best side by
side with the truth, ``metrics.csv``), so ``best.json``'s ``value`` is what ``compare`` reports
for its spec — and on the exact route the run checks that it equals the optimiser's prediction
bit for bit (``verified``).

Outputs: ``candidates.csv`` (one row per evaluated candidate: its parameters and every metric
column, ``source`` = exact or render), ``best.json`` (``spec``, ``params``, ``objective``,
``value``, then the default's value, the regret and how it was found), ``frontier.png`` (exact)
or ``search.png`` (search), ``curve.npz`` (exact: every step of every curve), ``tune.json``
(the plan and provenance), ``tune.html`` and the comparison run's files. Bad parameter names,
ranges or objectives exit 2 before any rendering; a failed tune leaves an earlier run
directory as it was.
"""
from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from ..measurement.scenes import load_measured_scene
from ..gpu import gl
from ..evaluation import metrics
from ..output import provenance
from ..gpu.frame import Frame
from ..output import tune_plots
from ..output.pages import provenance_items
from ..output.rundir import RunDirectory
from ..measurement.pipeline import Comparison, Evaluator, check_lights, compare_frame
from ..techniques import from_spec
from ..tuning import exact_bias
from ..tuning.tuner import DEFAULT_BUDGET, TuneOutcome, find_best, plan_tune
from ..util.sizes import COMPARE_SIZE
from ..util.validation import RunError
from ..util.validation import check_size
from .compare import write_run

#: Rows of the page's table of best candidates.
TOP_CANDIDATES = 15


def tune(scene_ref, spec: str, params: list[str], objective: str = "error_rate", size=COMPARE_SIZE,
         out: Path | None = None, light: int = 0, budget: int = DEFAULT_BUDGET, time_budget_ms: float | None = None,
         repeat: int = 3, warmup: int = 1, cache_dir: Path | None = None,
         on_step: Callable[[str, int], None] | None = None) -> Path:
    """Tune ``spec``'s ``params`` (``--param`` strings) on ``scene_ref`` for ``objective`` and
    write the run directory (module docstring); returns it."""
    if budget < 1:
        raise RunError(f"--budget must be >= 1, got {budget}")
    if repeat < 1 or warmup < 0:
        raise RunError(f"--repeat must be >= 1 and --warmup >= 0, got {repeat} and {warmup}")
    if time_budget_ms is not None and not time_budget_ms > 0:
        raise RunError(f"--time-budget must be > 0 ms, got {time_budget_ms}")
    size = check_size(size)
    scene = load_measured_scene(scene_ref)
    plan = plan_tune(spec, params, objective)
    if not 0 <= light < len(scene.lights):
        raise RunError(f"--light {light}: scene {scene.name} has {len(scene.lights)} light(s)")
    check_lights([from_spec(plan.spec)], scene)
    out = Path(out) if out is not None else Path("results") / f"{scene.name}_tune_{from_spec(spec).name}"
    started = time.perf_counter()
    cache = scene_hash = None
    if cache_dir is not None:
        from ..output.cache import Cache, scene_content_hash

        cache, scene_hash = Cache(Path(cache_dir)), scene_content_hash(scene.path)
    with RunDirectory(out) as rd:
        frame = Frame(scene, *size)
        try:
            evaluator = Evaluator(frame)
            outcome = find_best(evaluator, plan, light, budget, repeat, warmup, time_budget_ms, cache, scene_hash,
                                on_step)
            comparison = _side_by_side(frame, plan.spec, outcome.spec, repeat, warmup, evaluator)
            write_run(rd, comparison, repeat, warmup)
        finally:
            frame.release()
        best = _best_record(outcome, comparison.rows, scene.name, light, size, time_budget_ms,
                            time.perf_counter() - started)
        rd.record("best.json", best)
        rd.table("candidates.csv", outcome.candidates)
        if outcome.exact is not None:
            np.savez_compressed(rd.path / "curve.npz", **_curve_arrays(outcome.exact))
            figure = "frontier.png"
            tune_plots.frontier_plot(outcome.exact, rd.path / figure, default=outcome.default_point,
                                     best=outcome.best_point,
                                     objective=objective if objective in exact_bias.EXACT_OBJECTIVES else "error_rate")
        else:
            figure = "search.png"
            tune_plots.search_plot(outcome.trials, plan.dimensions, objective, rd.path / figure)
        record = {"scene": scene.describe(), "renderer": gl.renderer(), "device": gl.device(), **provenance.record()}
        rd.record("tune.json", {**record, "plan": plan.describe()})
        rd.page("tune.html", name="tune.html", title=f"shadowlab tune: {scene.name}", renderer=record["renderer"],
                provenance=provenance_items(record), best=best, plan=plan, figure=figure,
                top=top_candidates(outcome.candidates, objective), objective=objective,
                column=metrics.COLUMN_BY_NAME.get(objective))
    return out


def _best_record(outcome: TuneOutcome, rows: pd.DataFrame, scene: str, light: int, size, time_budget_ms,
                 seconds: float) -> dict:
    """best.json: the contract keys (spec, params, objective, value — the compare run's value of
    the best spec) first, then the default's value, the regret and the route's facts."""
    plan, objective = outcome.plan, outcome.plan.objective

    def row_of(spec: str) -> pd.Series:
        return rows[(rows["label"] == from_spec(spec).spec()) & (rows["light"] == light)].iloc[0]

    value, default_value = float(row_of(outcome.spec)[objective]), float(row_of(plan.spec)[objective])
    default = {"spec": plan.spec, "value": default_value, "time_ms": float(row_of(plan.spec)["time_ms_median"])}
    regret = default_value - value
    if time_budget_ms is not None:
        # A default slower than the budget is no candidate: its value is shown, but no regret.
        # The tuner's own verdict decides (its timing of the spec as given, the first trial; the
        # exact route stops when the spec is over budget), not the side-by-side run's timing,
        # which may fall on the other side of the budget by noise.
        feasible = math.isfinite(outcome.trials[0].value) if outcome.trials else True
        default["within_time_budget"] = bool(feasible)
        if not feasible:
            regret = None
    best = {"spec": from_spec(outcome.spec).spec(), "params": outcome.params, "objective": objective, "value": value,
            "scene": scene, "light": light, "size": list(size), "route": plan.route, "route_reason": plan.reason,
            "time_ms": float(row_of(outcome.spec)["time_ms_median"]),
            "default": default, "regret_of_default": regret,
            "time_budget_ms": time_budget_ms, "seconds": seconds, **outcome.facts}
    if plan.route == "exact":
        # the optimiser's prediction against the compare run of the best spec, bit for bit
        best["verified"] = bool(value == outcome.value)
    return best


def _curve_arrays(result: exact_bias.ExactBiasTune) -> dict:
    """curve.npz: per grid point k, ``k_breaks`` (the steps' left ends) and ``k_<objective>``
    (the objective on each step), and ``k_params`` (the grid value, ``name=value``)."""
    out = {}
    for k, p in enumerate(result.points):
        out[f"{k}_breaks"] = p.curve.breaks
        for name in exact_bias.EXACT_OBJECTIVES:
            out[f"{k}_{name}"] = p.curve.values(name)
        out[f"{k}_params"] = np.array([f"{a}={b}" for a, b in p.params.items()] or [""])
    return out


def _side_by_side(frame: Frame, default_spec: str, best_spec: str, repeat: int, warmup: int,
                  evaluator: Evaluator) -> Comparison:
    """The spec as given and the best one, measured as ``compare`` measures them (every light,
    the same truth technique)."""
    specs = [default_spec]
    if from_spec(best_spec).spec() != from_spec(default_spec).spec():
        specs.append(best_spec)
    return compare_frame(frame, [from_spec(s) for s in specs], repeat, warmup, truth=evaluator.truth_technique)


def top_candidates(candidates: pd.DataFrame, objective: str, n: int = TOP_CANDIDATES) -> list[dict]:
    """The ``n`` best candidate rows for the page (objective ascending), each with the tuned
    parameters that vary among the candidates."""
    if candidates.empty or objective not in candidates:
        return []
    cols = [c for c in candidates.columns if c.startswith("param_")]
    varying = [c for c in cols if candidates[c].nunique() > 1] or cols[:1]
    # the search's own value: infinite for a candidate over the time budget, which ranks last
    rank = "objective_value" if "objective_value" in candidates else objective
    top = candidates.sort_values(rank, kind="stable").head(n)

    def shown(value):
        # CSV round trips turn ints (a resolution) into floats: show them as ints again
        return int(value) if isinstance(value, float) and value.is_integer() else value

    return [{"params": {c[len("param_"):]: shown(r[c]) for c in varying}, "value": r[objective],
             "error_rate": r.get("error_rate"), "false_shadow_rate": r.get("false_shadow_rate"),
             "false_lit_rate": r.get("false_lit_rate"), "time_ms_median": r.get("time_ms_median"),
             "source": r.get("source"), "note": r.get("note") if isinstance(r.get("note"), str) else ""}
            for _, r in top.iterrows()]
