"""Runs a study (docs/contracts.md#study-directory): every scene × configuration of a suite, in parallel, cached,
then the comparison drawn.

Two phases, so that timings stay honest:

1. **Accuracy** — in parallel (local worker processes, or a Dask cluster): per scene the ground
   truth, then every configuration's visibility, metrics, images. Nothing here is timed.
2. **Timing** — afterwards, one task at a time: each configuration (and the truth) is set up and
   rendered ``warmup`` + ``repeat`` times alone, in one worker process with every core's
   llvmpipe threads, so no other work of the study overlaps a timed section on this host.

A suite with ``[[tuned]]`` entries first has a tuning phase (:mod:`shadowlab.study.tuning_phase`):
each entry's optimum on each scene joins that scene's configurations for both phases.

Every finished task is stored in the study's cache (:mod:`shadowlab.output.cache`) as soon as it
returns, so Ctrl-C loses only the tasks in flight and the next run resumes. Then, without GL,
the results are assembled: per scene a run directory, ``results.csv``, ``study.json`` and the
study report (``pareto.png``, ``study.html``, ``summary.md``).
"""
from __future__ import annotations

import datetime as _dt
import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from ..evaluation import perceptual
from ..output import provenance
from ..gpu import timing
from ..output.rundir import GROUND_TRUTH_KEY, safe_name
from ..util.files import replacing, write_text_atomic
from ..util.validation import RunError
from ..techniques import from_spec
from . import rundir
from .bundle import SceneBundles
from ..output.cache import Cache, run_key, scene_content_hash
from .executors import DaskExecutor, LocalExecutor, cores, lost_result
from ..scene import scene_purpose
from .suite import Suite, load_suite
from .tiles import TILES_FILE, write_tiles
from .tuning_phase import run_tuning_phase, tuned_rows_under_their_name, tuning_summary, with_tuned

#: Columns a study adds to every metrics row in results.csv (docs/contracts.md#study-directory).
STUDY_COLUMNS = ("config", "scene_family", "status", "error", "run_dir", "revision", "renderer", "shaded_image",
                 "error_image", "signed_image", "footprint_image")


@dataclass
class StudyOutcome:
    """What :func:`run_study` did: the study directory, its results (results.csv as a
    DataFrame), counts of tasks run / taken from the cache / failed, and the wall time."""

    out: Path
    results: pd.DataFrame
    ran: int
    cached: int
    failed: list[str] = field(default_factory=list)
    elapsed_s: float = 0.0  # the whole study, report included
    report: dict = field(default_factory=dict)
    phases_s: dict = field(default_factory=dict)


class Progress:
    """Minimal progress interface the runner reports to (the CLI passes a tqdm bar)."""

    def start(self, total: int) -> None:
        """The number of tasks to run."""

    def step(self, what: str) -> None:
        """One task finished."""

    def close(self) -> None:
        """All done (or interrupted)."""


@dataclass
class _Run:
    scene: object          # SceneEntry
    spec: str
    reference: bool
    acc_key: str
    time_key: str
    scene_hash: str        # the scene's content when the study was planned (workers check it)


def default_out_dir(suite: Suite) -> Path:
    """results/study-<suite name> under the current directory (a fixed place, so that running the
    same suite again finds its cache)."""
    return Path("results") / f"study-{safe_name(suite.name)}"


def run_study(suite_ref, out: Path | None = None, workers: int | None = None, dask=None, force: bool = False,
              progress: Progress | None = None, log: Callable[[str], None] | None = None) -> StudyOutcome:
    """Run a suite (shipped name, path, or a :class:`Suite`) into ``out`` and draw the comparison.

    ``workers``: local worker processes (default: the machine's cores); ``dask``: a scheduler
    address (or a ``distributed.Client``) to run on instead; ``force``: ignore the cache.
    Bad suites raise :class:`shadowlab.study.suite.SuiteError` before anything runs; failed runs
    are recorded in results.csv (``status`` = failed, ``error``) and listed in the outcome.
    KeyboardInterrupt propagates after the pool is stopped; the cache stays consistent.
    """
    t_start = time.perf_counter()
    log = log or (lambda msg: print(msg, file=sys.stderr))
    progress = progress or Progress()
    suite = suite_ref if isinstance(suite_ref, Suite) else load_suite(suite_ref)
    for note in suite.notes:  # e.g. a scene's family guessed from its name: said before anything runs
        log(note)
    if workers is not None and workers < 1:
        raise RunError(f"--workers must be >= 1, got {workers}")
    out = Path(out) if out is not None else default_out_dir(suite)
    if out.exists() and not out.is_dir():
        raise RunError(f"--out {out} exists and is not a directory")
    if workers is not None and workers > cores() and dask is None:
        log(f"--workers {workers} is more than the {cores()} cores: using {cores()} (GL work does not gain from more)")
        workers = cores()
    workers = workers or cores()
    cache = Cache(out / "cache")
    revision = provenance.code_fingerprint()

    executor = DaskExecutor(dask) if dask is not None else None
    bundles = SceneBundles() if dask is not None else None  # Dask workers may share no disk
    try:
        for scene in suite.scenes if bundles is not None else []:
            bundles.of(scene.path)  # up front: a scene that cannot be bundled stops the study before it runs
        device = _probe(executor)
        renderer = device["renderer"]
        tuned = []
        if suite.tuned:  # each [[tuned]] entry's per-scene optimum joins the scene's configurations
            tuned = run_tuning_phase(executor, suite, cache, revision, device["device"], force, workers, log,
                                     bundles)
            suite = with_tuned(suite, tuned)
        runs = _plan(suite, revision, device["device"])
        todo_truth = [r for r in runs if r.reference and (force or not cache.has_result(r.acc_key))]
        todo_config = [r for r in runs if not r.reference and (force or not cache.has_result(r.acc_key))]
        todo_time = [r for r in runs if force or cache.load_timing(r.time_key) is None]
        known_truths = {}  # scene → cached truth, for scenes whose configurations must run
        for r in runs:
            if r.reference and r not in todo_truth and any(c.scene.name == r.scene.name for c in todo_config):
                cached = cache.load_result(r.acc_key)
                if cached is None:
                    todo_truth.append(r)  # an unreadable entry: recompute
                else:
                    known_truths[r.scene.name] = cached
        n_tasks = len(todo_truth) + len(todo_config) + len(todo_time)
        log(f"study {suite.name}: {len(suite.scenes)} scenes, {suite.runs()} configuration runs "
            f"+ {len(suite.scenes)} ground truths; {n_tasks} tasks to run, "
            f"{2 * len(runs) - n_tasks} cached ({out / 'cache'})")
        failed: dict[tuple[str, str], str] = {}         # accuracy: no metrics
        timing_failed: dict[tuple[str, str], str] = {}  # metrics, but no time
        phases = {}
        if n_tasks:
            progress.start(n_tasks)
            if executor is None and (todo_truth or todo_config):
                executor_acc = LocalExecutor(min(workers, len(todo_truth) + len(todo_config)))
            else:
                executor_acc = executor
            t0 = time.perf_counter()
            if todo_truth or todo_config:
                log(f"accuracy phase on {executor_acc.description}")
                _accuracy_phase(executor_acc, suite, todo_truth, todo_config, known_truths, cache, failed, progress,
                                bundles)
                if executor_acc is not executor:
                    executor_acc.close()
            phases["accuracy_s"] = time.perf_counter() - t0
            t0 = time.perf_counter()
            for r in todo_time:  # nothing to time where the accuracy run failed
                if (r.scene.name, r.spec) in failed:
                    progress.step(f"timing {r.scene.name}: skipped")
            todo_time = [r for r in todo_time if (r.scene.name, r.spec) not in failed]
            if todo_time:
                restart = None if executor is not None else (lambda: LocalExecutor(1, threads=cores()))
                executor_time = executor or restart()
                log(f"timing phase, one task at a time, on {executor_time.description}")
                executor_time = _timing_phase(executor_time, suite, todo_time, cache, timing_failed, progress,
                                              restart, bundles)
                if executor_time is not executor:
                    executor_time.close()
            phases["timing_s"] = time.perf_counter() - t0
            progress.close()
    finally:
        if executor is not None:
            executor.close()

    timing_text = _timing_sentence(suite, renderer, dask)
    record = {"renderer": renderer, "device": device["device"], "gl": device["gl"], GROUND_TRUTH_KEY: suite.truth,
              "timing_method": timing_text, "timing_phase": "separate",
              "pass_timing": timing.pass_timing_method_for(renderer) if suite.pass_timing else None,
              "repeat": suite.repeat, "warmup": suite.warmup, "study": suite.name, "size": list(suite.size),
              **provenance.record(gl_info=False)}
    tiles = {}
    results, problems = _assemble(suite, runs, cache, failed, timing_failed, out, record, tiles)
    results = tuned_rows_under_their_name(suite, tuned, results)
    elapsed = time.perf_counter() - t_start
    meta = {"name": suite.name, "description": suite.description, "size": list(suite.size), "repeat": suite.repeat,
            "warmup": suite.warmup, "device": device["device"], "renderer": renderer,
            "revision": provenance.revision(), "date": record["date"], "timing": timing_text,
            "workers": f"dask {executor.description}" if executor is not None else workers,
            "elapsed_s": elapsed, "runs": len(runs), "cached": 2 * len(runs) - n_tasks,
            "failed": len(problems), "suite_file": suite.file, "phases_s": phases,
            "scenes": {e.name: {"family": e.family, "metric": e.metric, "purpose": scene_purpose(e.path)}
                       for e in suite.scenes},
            "tuned": tuning_summary(suite, tuned, results)}
    report_files = _write_study_files(out, results, meta, record, tiles)
    failures = [f"{scene} / {spec}: {err}" for (scene, spec), err in problems.items()]
    phases["report_s"] = time.perf_counter() - t_start - elapsed
    return StudyOutcome(out, results, n_tasks, 2 * len(runs) - n_tasks, failures, time.perf_counter() - t_start,
                        report_files, phases)


def _probe(executor) -> dict:
    """The GL device the runs will use: this process's (local workers share its driver), or a
    Dask worker's."""
    from .tasks import probe, probe_here

    if executor is None:
        return probe_here()
    return executor.submit(probe, None).result()


def _plan(suite: Suite, revision: str, device: str) -> list[_Run]:
    """Every run of the suite with its cache keys (``device``: the GL device line — renderer,
    vendor, driver): per scene the truth, then its configurations."""
    runs = []
    timing_settings = {"repeat": suite.repeat, "warmup": suite.warmup, "pass_timing": suite.pass_timing}
    # the perceptual columns this process can compute, part of the accuracy key when there are
    # any: installing their packages redoes the runs (and every task checks that its worker
    # computes the same ones: shadowlab.study.tasks)
    judged = {"perceptual": perceptual.available()} if perceptual.available() else {}
    for scene in suite.scenes:
        h = scene_content_hash(scene.path)
        for spec, ref in [(suite.truth, True)] + [(s, False) for s in suite.configurations[scene.name]]:
            acc = run_key(h, spec, suite.size, revision, device, **judged)
            runs.append(_Run(scene, spec, ref, acc, run_key(h, spec, suite.size, revision, device, **timing_settings),
                             h))
    return runs


def _task(run: _Run, suite: Suite, kind: str, bundles: SceneBundles | None = None, **extra) -> dict:
    """A run's task dict; with ``bundles`` (on Dask) it also carries its scene's bundle."""
    task = {"kind": kind, "scene_path": str(run.scene.path), "scene_hash": run.scene_hash,
            "size": list(suite.size), "spec": run.spec, **extra}
    if bundles is not None:
        task["scene_bundle"] = bundles.of(run.scene.path)
    return task


def _truth_arrays(result: dict) -> list[np.ndarray]:
    n = result["meta"]["lights"]
    return [result["arrays"][f"truth_{li}"] for li in range(n)]


def _accuracy_phase(executor, suite, todo_truth, todo_config, known_truths: dict, cache: Cache, failed: dict,
                    progress, bundles: SceneBundles | None = None) -> None:
    """Truths first; each scene's configurations as soon as its truth is known (``known_truths``:
    scene → a cached truth result; ``bundles``: on Dask, the scenes' bundles the tasks carry)."""
    from .tasks import run_task

    waiting: dict[str, list[_Run]] = {}
    for r in todo_config:
        waiting.setdefault(r.scene.name, []).append(r)
    pending: dict = {}

    def submit(r: _Run, task: dict) -> None:
        try:
            pending[executor.submit(run_task, task)] = r
        except Exception as exc:  # noqa: BLE001 - a pool broken by a lost worker takes no more tasks
            failed[(r.scene.name, r.spec)] = lost_result(exc)["error"]
            progress.step(f"{r.scene.name}: lost")

    def submit_configs(scene_name: str, truth_result: dict) -> None:
        arrays = _truth_arrays(truth_result)
        stderr = [float(row.get("truth_stderr_max", 0.0)) for row in truth_result["meta"]["rows"]]
        for r in waiting.pop(scene_name, []):
            submit(r, _task(r, suite, "config", bundles, truth=arrays, truth_stderr=stderr,
                            perceptual=perceptual.available()))  # what the accuracy key says it computes

    try:
        for r in todo_truth:
            submit(r, _task(r, suite, "truth", bundles))
        for scene_name, truth_result in known_truths.items():
            submit_configs(scene_name, truth_result)
        while pending:
            for fut in executor.wait_first(pending.keys()):
                r = pending.pop(fut)
                try:
                    result = fut.result()
                except Exception as exc:  # noqa: BLE001 - run_task never raises: the worker died
                    result = lost_result(exc)
                progress.step(f"{r.scene.name}: {'truth' if r.reference else from_spec(r.spec).short_label()}")
                if not result["ok"]:
                    failed[(r.scene.name, r.spec)] = result["error"]
                    if r.reference:
                        for c in waiting.pop(r.scene.name, []):
                            failed[(c.scene.name, c.spec)] = f"not run: the ground truth failed ({result['error']})"
                            progress.step(f"{c.scene.name}: skipped")
                    continue
                cache.store_result(r.acc_key, result)
                if r.reference:
                    submit_configs(r.scene.name, result)
    except BaseException:
        if hasattr(executor, "kill"):
            executor.kill()
        raise


def _timing_phase(executor, suite, todo_time, cache: Cache, timing_failed: dict, progress, restart=None,
                  bundles: SceneBundles | None = None):
    """Each timing task alone: submitted only when the previous one has returned. ``restart``:
    makes a fresh local executor after a worker was lost (None on Dask, which replaces its own);
    ``bundles``: on Dask, the scenes' bundles the tasks carry; returns the executor in use at the end."""
    from .tasks import run_task

    try:
        for r in sorted(todo_time, key=lambda r: (r.scene.name, not r.reference)):
            try:
                result = executor.submit(run_task, _task(r, suite, "timing", bundles, repeat=suite.repeat, warmup=suite.warmup,
                                                         pass_timing=suite.pass_timing)).result()
            except Exception as exc:  # noqa: BLE001 - run_task never raises: the worker died
                result = lost_result(exc)
                if restart is not None:
                    executor.kill()
                    executor = restart()
            progress.step(f"timing {r.scene.name}: {'truth' if r.reference else from_spec(r.spec).short_label()}")
            if not result["ok"]:
                timing_failed[(r.scene.name, r.spec)] = f"timing failed: {result['error']}"
                continue
            cache.store_timing(r.time_key, result["meta"])
    except BaseException:
        if hasattr(executor, "kill"):
            executor.kill()
        raise
    return executor


def _timing_sentence(suite: Suite, renderer: str, dask) -> str:
    where = ("one task at a time on the Dask cluster (no other task of this study running)" if dask is not None
             else f"one task at a time in one worker process with LP_NUM_THREADS={cores()}")
    return (f"separate timing phase after all accuracy work: each configuration set up and rendered alone, {where}; "
            f"{timing.method_for(renderer)}; {suite.repeat} repeats after {suite.warmup} warm-up")


def _failed_row(scene, spec: str, error: str, light: int, suite: Suite, renderer: str) -> dict:
    tech = from_spec(spec)
    return {"scene": scene.name, "light": light, "technique": tech.name, "params": tech.params_string(),
            "label": tech.spec(), "short_label": tech.short_label(), "reference": spec == suite.truth,
            "config": suite.config_name(spec),
            "width": suite.size[0], "height": suite.size[1], "scene_family": scene.family, "status": "failed",
            "error": error, "run_dir": "", "revision": provenance.revision(), "renderer": renderer}


def _assemble(suite: Suite, runs: list[_Run], cache: Cache, failed: dict, timing_failed: dict, out: Path,
              record: dict, tiles: dict) -> tuple[pd.DataFrame, dict]:
    """Per scene: rows with timings, the run directory; all rows as results.csv's DataFrame, and
    every run that did not finish — failed, untimed, or whose cache entry could not be read —
    with its error ((scene, spec) → error). Fills ``tiles`` ({(scene, label): per-tile error
    sums of every light}, :mod:`shadowlab.study.tiles`) for the configurations that have them."""
    all_rows = []
    problems = dict(failed)
    by_scene: dict[str, list[_Run]] = {}
    for r in runs:
        by_scene.setdefault(r.scene.name, []).append(r)
    for name, scene_runs in by_scene.items():
        scene = scene_runs[0].scene
        run_dir = f"runs/{safe_name(name)}"
        truth_run = scene_runs[0]
        truth = None if (name, truth_run.spec) in failed else cache.load_result(truth_run.acc_key)
        lights = truth["meta"]["lights"] if truth else 1
        sr = rundir.SceneRuns(name, truth, {})
        rows, bad_rows = [], []
        for r in scene_runs:
            key = (name, r.spec)
            res = truth if r.reference else (None if key in failed or truth is None else cache.load_result(r.acc_key))
            if res is None:
                if key not in problems:
                    problems[key] = ("not run: the ground truth has no result" if truth is None and not r.reference
                                     else "its cache entry is missing or unreadable; run the study again")
                bad_rows.extend(_failed_row(scene, r.spec, problems[key], li, suite, record["renderer"])
                                for li in range(lights))
                continue
            tim = cache.load_timing(r.time_key)
            if tim is None:
                problems[key] = timing_failed.get(key, "no timing: its cache entry is missing or unreadable; "
                                                       "run the study again")
            if not r.reference:
                sr.configs[r.spec] = res
                light_tiles = [res["arrays"].get(f"tiles_{li}") for li in range(len(res["meta"]["rows"]))]
                if all(t is not None for t in light_tiles):
                    tiles[(name, res["meta"]["rows"][0]["label"])] = np.concatenate(light_tiles, axis=1)
            sr.keys += [r.acc_key, r.time_key if tim is not None else "untimed"]
            stem = GROUND_TRUTH_KEY if r.reference else rundir.image_stem(res["meta"]["rows"][0]["short_label"])
            columns = tim["columns"] if tim is not None else [{}] * len(res["meta"]["rows"])
            for li, (row, cols) in enumerate(zip(res["meta"]["rows"], columns)):
                row = {**row, **cols}
                extra = {"config": suite.config_name(r.spec), "scene_family": scene.family,
                         "status": "ok" if tim is not None else "untimed",
                         "error": "" if tim is not None else problems[key], "run_dir": run_dir,
                         "revision": provenance.revision(), "renderer": record["renderer"]}
                if li == 0:
                    extra["shaded_image"] = f"{run_dir}/images/{stem}_shaded.png"
                    if not r.reference:
                        extra["error_image"] = f"{run_dir}/images/{stem}_error.png"
                        for kind in ("signed", "footprint"):
                            if f"{kind}.png" in res.get("files", {}):
                                extra[f"{kind}_image"] = f"{run_dir}/images/{stem}_{kind}.png"
                rows.append({**row, **extra})
        if truth is not None and rows:
            df = rundir.ordered(pd.DataFrame(rows))
            metric_cols = [c for c in df.columns if c not in STUDY_COLUMNS]
            rundir.write_run_dir(out / run_dir, sr, df[metric_cols], record)
        all_rows.extend(rows + bad_rows)
    results = pd.DataFrame(all_rows)
    if len(results):
        results = rundir.ordered(results)
        front = [c for c in results.columns if c not in STUDY_COLUMNS]
        results = results[front + [c for c in STUDY_COLUMNS if c in results.columns]]
    return results, problems


def _write_study_files(out: Path, results: pd.DataFrame, meta: dict, record: dict, tiles: dict) -> dict:
    """results.csv, tiles.npz, study.json and the report, each written to a temporary name and renamed."""
    out.mkdir(parents=True, exist_ok=True)
    write_tiles(out / TILES_FILE, tiles)
    with replacing(out / "results.csv") as (tmp,):
        results.to_csv(tmp, index=False)
    study = {**meta, "record": record, "date_finished": _dt.datetime.now().astimezone().isoformat(timespec="seconds")}
    write_text_atomic(out / "study.json", json.dumps(study, indent=2, default=str))
    from . import report as study_report

    return study_report.write_study_report(out, results, meta)
