"""The tuning phase of a study: each ``[[tuned]]`` entry tuned on each of its scenes before the
accuracy phase, which then runs every scene's optimum like any other configuration.

The tune tasks run in parallel and are cached like the study's other tasks; afterwards this
module also says what the tuning found, for results.csv and study.json.

The runner (:mod:`shadowlab.study.runner`) calls, in order: :func:`run_tuning_phase` (the tune
tasks), :func:`with_tuned` (the suite with each optimum among its scene's configurations), then,
once the results are assembled, :func:`tuned_rows_under_their_name` and :func:`tuning_summary`
(study.json's ``tuned``, with one global bias tuned leave-one-out on the exact route).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..output.cache import Cache, run_key, scene_content_hash
from ..techniques import from_spec
from .bundle import SceneBundles
from .executors import LocalExecutor, lost_result
from .suite import Suite


@dataclass
class TunedRun:
    """One ``[[tuned]]`` entry on one scene: its cache key and the tune task's result (None
    until run; ``ok`` False with ``error`` when it failed)."""

    entry: object   # TunedEntry
    scene: object   # SceneEntry
    scene_hash: str
    key: str
    result: dict | None = None


def run_tuning_phase(executor, suite: Suite, cache: Cache, revision: str, device: str, force: bool, workers: int,
                     log, bundles: SceneBundles | None = None) -> list[TunedRun]:
    """Run (or take from the cache) every ``[[tuned]]`` entry on each of its scenes, in parallel:
    before the accuracy phase, which then runs the tuned configurations like any other
    (``bundles``: on Dask, the scenes' bundles the tasks carry)."""
    from .tasks import run_task

    jobs = []
    for entry in suite.tuned:
        for scene in suite.scenes:
            if entry.applies_to(scene.name):
                h = scene_content_hash(scene.path)
                key = run_key(h, f"tune:{entry.spec}", suite.size, revision, device, params=list(entry.params),
                              objective=entry.objective, budget=entry.budget, truth=suite.truth)
                job = TunedRun(entry, scene, h, key)
                job.result = None if force else cache.load_result(key)
                jobs.append(job)
    todo = [j for j in jobs if j.result is None]
    if not todo:
        return jobs
    ex = executor or LocalExecutor(min(workers, len(todo)))
    log(f"tuning phase: {len(todo)} tune task(s) ({len(jobs) - len(todo)} cached) on {ex.description}")
    try:
        pending = {}
        for j in todo:
            task = {"kind": "tune", "scene_path": str(j.scene.path), "scene_hash": j.scene_hash,
                    "size": list(suite.size), "spec": j.entry.spec, "params": list(j.entry.params),
                    "objective": j.entry.objective, "budget": j.entry.budget, "truth_spec": suite.truth}
            if bundles is not None:
                task["scene_bundle"] = bundles.of(j.scene.path)
            pending[ex.submit(run_task, task)] = j
        while pending:
            for fut in ex.wait_first(pending.keys()):
                j = pending.pop(fut)
                try:
                    j.result = fut.result()
                except Exception as exc:  # noqa: BLE001 - run_task never raises: the worker died
                    j.result = lost_result(exc)
                if j.result["ok"]:
                    cache.store_result(j.key, j.result)
                    found = ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                                      for k, v in j.result["meta"]["params"].items())
                    log(f"  tuned {j.entry.name} on {j.scene.name}: {found}")
                else:
                    log(f"  tuning {j.entry.name} on {j.scene.name} FAILED: {j.result['error']}")
    except BaseException:
        if hasattr(ex, "kill"):
            ex.kill()
        raise
    finally:
        if ex is not executor:
            ex.close()
    return jobs


def with_tuned(suite: Suite, tuned: list[TunedRun]) -> Suite:
    """The suite with each tuned optimum added to its scene's configurations, named
    ``<spec> [tuned <params>]`` (a spec the suite already runs keeps its own name)."""
    import dataclasses

    configurations = {k: list(v) for k, v in suite.configurations.items()}
    written = dict(suite.written)
    for j in tuned:
        if j.result is None or not j.result.get("ok", True) or "best" not in j.result.get("meta", {}):
            continue
        spec = from_spec(j.result["meta"]["best"]).spec()
        written.setdefault(spec, j.entry.name)
        if spec not in configurations[j.scene.name]:
            configurations[j.scene.name].append(spec)
    return dataclasses.replace(suite, configurations=configurations, written=written)


def tuned_rows_under_their_name(suite: Suite, tuned: list, results: pd.DataFrame) -> pd.DataFrame:
    """``results`` with, for each scene whose tuned optimum is a spec the suite runs anyway (no
    gain over the spec as given, say), a copy of that spec's rows under the tuned entry's name:
    a tuned entry then has rows on every scene it ran on, whatever spec each scene got."""
    extra = []
    for j in tuned or []:
        r = j.result
        if r is None or not r.get("ok", True) or "best" not in r.get("meta", {}):
            continue
        best = from_spec(r["meta"]["best"]).spec()
        rows = results[(results["scene"] == j.scene.name) & (results["label"] == best)
                       & (results["config"] != j.entry.name)]
        if len(rows) and not ((results["scene"] == j.scene.name) & (results["config"] == j.entry.name)).any():
            extra.append(rows.assign(config=j.entry.name))
    return pd.concat([results, *extra], ignore_index=True) if extra else results


def tuning_summary(suite: Suite, tuned: list, results: pd.DataFrame) -> list[dict]:
    """study.json's ``tuned``: per ``[[tuned]]`` entry and scene, the spec as given and its
    optimum, each with its objective as the study measured it (light 0), the regret of the
    default, the per-pixel oracle (exact route); per entry, on the exact route, one global bias
    tuned leave-one-out (:func:`shadowlab.tuning.global_setting.leave_one_out`)."""
    from ..tuning.global_setting import SceneCurve, leave_one_out

    def measured(scene: str, spec: str, objective: str):
        rows = results[(results["scene"] == scene) & (results["label"] == spec) & (results["light"] == 0)]
        if not len(rows) or objective not in rows or rows.iloc[0].get("status") != "ok":
            return None
        return float(rows.iloc[0][objective])

    out = []
    for entry in suite.tuned:
        scenes, curves, held = [], {}, {}
        for j in (j for j in tuned if j.entry is entry):
            r = j.result or {"ok": False, "error": "not run"}
            item = {"scene": j.scene.name, "status": "ok" if r.get("ok", True) and "best" in r.get("meta", {})
                    else "failed", "error": r.get("error", "")}
            if item["status"] == "ok":
                m = r["meta"]
                best = from_spec(m["best"]).spec()
                default_value, value = measured(j.scene.name, entry.spec, entry.objective), \
                    measured(j.scene.name, best, entry.objective)
                item.update(best=best, best_name=suite.config_name(best), params=m["params"], route=m["route"],
                            oracle=m.get("oracle"), default_value=default_value, value=value,
                            regret=(default_value - value) if None not in (default_value, value) else None,
                            renders=m.get("renders"))
                own = _own_grid_point(m, entry.spec)
                if own is not None and np.isfinite(r["arrays"][f"{own}_values"]).all():
                    held = (m.get("grid") or [{}])[own]
                    curves[j.scene.name] = SceneCurve(j.scene.name, r["arrays"][f"{own}_breaks"],
                                                      r["arrays"][f"{own}_values"], float(m["bias_range"][1]))
            scenes.append(item)
        summary = {"name": entry.name, "spec": entry.spec, "written": entry.written, "params": list(entry.params),
                   "objective": entry.objective, "scenes": scenes, "global": None}
        if len(curves) >= 2 and len(curves) == len(scenes):
            default_bias = float(from_spec(entry.spec).bias)
            loo = leave_one_out(curves, default_bias)
            summary["global"] = {
                "held_out": [{"scene": h.test[0], "bias": h.bias, "value": h.test_values[h.test[0]],
                              "own_optimum": h.test_optima[h.test[0]], "regret": h.regret[h.test[0]],
                              "default_value": h.default_values[h.test[0]],
                              "default_regret": h.default_regret[h.test[0]]} for h in loo],
                "optima": {s: [c.optimum().lo, c.optimum().hi] for s, c in curves.items()},
                "default_bias": default_bias,
                # the grid parameters the global bias is chosen at: the spec's own values
                "held": {k: v for k, v in held.items()}}
        out.append(summary)
    return out


def _own_grid_point(meta: dict, spec: str) -> int | None:
    """Index of the grid point holding the spec's own value of the grid parameter (0 without a grid)."""
    grid = meta.get("grid") or []
    if not grid:
        return None
    tech = from_spec(spec)
    for k, params in enumerate(grid):
        if all(getattr(tech, name) == value for name, value in params.items()):
            return k
    return None
