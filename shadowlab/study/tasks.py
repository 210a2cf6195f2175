"""What a study's workers do (docs/guide.md#studies-the-whole-comparison-in-one-command): the ground truth of a scene, one configuration's
visibility and metrics, or one configuration's timing — each a picklable task dict in, a
picklable result dict out, so the same functions run in a local process pool and on a Dask
cluster.

Each worker process makes one GL context (on first use, through :func:`shadowlab.gpu.gl.context`)
and reuses it, with the frames (G-buffers) of the scenes it last worked on. GL contexts belong
to a thread, and a Dask worker may run tasks on several threads, so every task runs on one
dedicated GL thread of the process.

A task names its scene by ``scene_path`` and, on Dask, also carries it as bytes
(``scene_bundle``, :mod:`shadowlab.study.bundle`), so workers need no copy of the scene files;
each result's meta records the ``scene_file`` the worker read.

Results: ``{"ok": bool, "error": str, "seconds": float, "meta": dict, "arrays": {name: ndarray},
"files": {name: PNG bytes}}`` (the layout :class:`shadowlab.output.cache.Cache` stores).
"""
from __future__ import annotations

import os
import threading
import time
import traceback
from collections import OrderedDict
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from ..measurement.scenes import load_measured_scene
from ..gpu.timing import is_time_column

#: Frames kept per worker (each holds a G-buffer and the scene's geometry).
FRAMES_KEPT = 2
#: The study's signed difference maps V − G share this fixed scale (±, visibility units): tasks
#: run apart, so no run-wide maximum is known when each map is drawn; beyond it the colours clip.
STUDY_SIGNED_LIMIT = 0.5

_gl_thread: ThreadPoolExecutor | None = None
_gl_thread_lock = threading.Lock()
_frames: OrderedDict = OrderedDict()


def init_worker(threads: int | None) -> None:
    """Process-pool initializer: llvmpipe's rasteriser threads for this worker (``LP_NUM_THREADS``,
    read when the GL context is made), and Ctrl-C left to the main process, which stops the pool."""
    import signal

    if threads:
        os.environ["LP_NUM_THREADS"] = str(int(threads))
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _on_gl_thread(fn, *args):
    """``fn(*args)`` on this process's one GL thread (made on first use)."""
    global _gl_thread
    with _gl_thread_lock:
        if _gl_thread is None:
            _gl_thread = ThreadPoolExecutor(max_workers=1, thread_name_prefix="shadowlab-gl")
    return _gl_thread.submit(fn, *args).result()


def run_task(task: dict) -> dict:
    """Run one task on this process's GL thread; never raises: a failure is a result with
    ``ok`` False and the error (type, message and where it happened)."""
    return _on_gl_thread(_run_here, task)


def _run_here(task: dict) -> dict:
    t0 = time.perf_counter()
    try:
        result = {"truth": _truth, "config": _config, "timing": _timing, "tune": _tune}[task["kind"]](task)
        result["meta"]["scene_file"] = str(scene_file(task))  # where this worker read the scene
        result.update(ok=True, error="")
    except Exception as exc:  # noqa: BLE001 - recorded as the run's error, the study goes on
        where = traceback.extract_tb(exc.__traceback__)[-1]
        result = {"ok": False, "error": f"{type(exc).__name__}: {exc} (at {os.path.basename(where.filename)}:"
                                        f"{where.lineno})", "meta": {}, "arrays": {}, "files": {}}
        _forget_frames()  # a failure may leave GL in a bad state; start the next task afresh
    result["seconds"] = time.perf_counter() - t0
    result["pid"] = os.getpid()
    return result


def scene_file(task: dict) -> Path:
    """The scene file a task renders: its bundle's copy on this worker when the task carries one
    (``scene_bundle``, on Dask: written under :func:`shadowlab.study.bundle.bundle_root` on first
    use), else ``scene_path`` itself (local workers share the planner's disk)."""
    from .bundle import materialize

    if task.get("scene_bundle") is not None:
        return materialize(task["scene_bundle"])
    return Path(task["scene_path"])


def _frame(task: dict):
    """The worker's frame of the task's scene at its size (built on first use, kept for the next
    tasks of the same scene)."""
    from ..gpu.frame import Frame
    from ..output.cache import scene_content_hash

    key = (task["scene_hash"], tuple(task["size"]))
    if key in _frames:
        _frames.move_to_end(key)
        return _frames[key]
    while len(_frames) >= FRAMES_KEPT:
        _, old = _frames.popitem(last=False)
        old.release()
    path = scene_file(task)
    scene = load_measured_scene(path)
    # the run is cached under the hash the study planned with: the files must still be those
    if scene_content_hash(path) != task["scene_hash"]:
        raise RuntimeError(f"{task['scene_path']} (or a mesh it names) changed after the study was planned; "
                           f"run the study again")
    frame = Frame(scene, *task["size"])
    _frames[key] = frame
    return frame


def _forget_frames() -> None:
    while _frames:
        _, frame = _frames.popitem(last=False)
        try:
            frame.release()
        except Exception:  # noqa: BLE001 - releasing after a failure is best effort
            pass


def _accuracy_row(row: dict) -> dict:
    """A metrics row without its time columns (the timing phase supplies those)."""
    return {k: v for k, v in row.items() if not is_time_column(k)}


def _images(frame, visibilities, truth=None, footprint=None, weights=None) -> tuple[dict, dict]:
    """PNG bytes of a configuration's pictures (:func:`shadowlab.output.pictures.config_pictures`):
    the shaded image (``weights``: per light, where it is drawn — a budget's ``drop=unlit`` — or
    None), the first light's visibility and, given the truth (one visibility per light), the error map, the signed map of a soft configuration (on :data:`STUDY_SIGNED_LIMIT`)
    and the texel-footprint map; and, given the truth, the perceptual metrics of the shaded
    image against the truth's (:func:`shadowlab.evaluation.perceptual.compare_pictures`; {} without it)."""
    from ..evaluation import perceptual
    from ..output import pictures
    from ..gpu.shading import ShadingPass

    shading = ShadingPass(frame)
    try:
        shaded = pictures.to_display(shading.shade(list(visibilities), weights), frame.covered)
        judged = {}
        if truth is not None and perceptual.available():
            truth_shaded = pictures.to_display(shading.shade(list(truth)), frame.covered)
            judged = perceptual.compare_pictures(shaded, truth_shaded, frame.covered)
    finally:
        shading.release()
    truth0 = None if truth is None else truth[0]
    ev0 = frame.evaluated(0)
    signed = None
    if truth0 is not None:
        diff = pictures.signed_difference(frame.scene.lights[0], visibilities[0], truth0, ev0)
        signed = None if diff is None else (diff, STUDY_SIGNED_LIMIT)
    made = pictures.config_pictures(shaded, visibilities[0], truth0, ev0, frame.covered, signed, footprint)
    return {f"{kind}.png": data for kind, data in made.items()}, judged  # the cache's file names


def _same_perceptual(task: dict) -> None:
    """The perceptual columns this worker can compute must be those the study planned with (they
    are part of the cache key, :func:`shadowlab.study.runner._plan`): a Dask worker without the
    packages would otherwise cache rows without the columns under a key that says they are there."""
    from ..evaluation import perceptual

    planned = task.get("perceptual")
    if planned is not None and list(planned) != perceptual.available():
        raise RuntimeError(f"this worker computes the perceptual columns {perceptual.available() or 'none'}, the "
                           f"study planned {list(planned) or 'none'}: install the same packages "
                           f"(pip install '{perceptual.EXTRA}') on every worker, or on none")


def _truth(task: dict) -> dict:
    """The ground truth of every light of a scene, with what the configurations of that scene
    need to be judged: the truth's visibility per light (float32 (H, W), row 0 = top)."""
    from ..evaluation import perceptual
    from ..measurement.pipeline import Evaluator, add_radiance
    from ..techniques import from_spec

    frame = _frame(task)
    evaluator = Evaluator(frame, from_spec(task["spec"]), repeat=1, warmup=0)
    lights = range(len(frame.scene.lights))
    truths = [evaluator.truth(li) for li in lights]
    rows = [_accuracy_row(evaluator.row(m, reference=True)) for m in truths]
    add_radiance(frame, rows, truths, [m.visibility for m in truths])
    files, _ = _images(frame, [m.visibility for m in truths])
    ev0 = frame.evaluated(0)
    arrays = {f"truth_{li}": m.visibility.astype(np.float32) for li, m in zip(lights, truths)}
    arrays["mask_0"] = np.where(ev0, truths[0].visibility, np.nan).astype(np.float32)
    cam = frame.camera
    notes = list(frame.scene.notes)  # what reading the scene left out (a glTF file's skins, ...)
    notes += [f"{frame.degenerate_triangles} degenerate (zero-area) triangles in the scene"] \
        if frame.degenerate_triangles else []
    notes += [n for n in [perceptual.missing_note()] if n]
    meta = {"rows": rows, "notes": notes + list(dict.fromkeys(evaluator.truth_technique.notes)),
            "scene": frame.scene.describe(), "lights": len(lights),
            "camera": {"eye": cam.eye.tolist(), "target": cam.target.tolist(), "fov_y": cam.fov_y,
                       "near": cam.near, "far": cam.far}}
    return {"meta": meta, "arrays": arrays, "files": files}


def _config(task: dict) -> dict:
    """One configuration on every light of a scene: visibility, metrics rows against the given
    truth (``task["truth"]``: one float32 (H, W) image per light), cost figures, notes, images,
    and per light its per-tile error sums (``tiles_<light>``,
    :func:`shadowlab.evaluation.tiles.tile_sums`)."""
    from ..evaluation.tiles import tile_sums
    from ..measurement.budget import budget_note
    from ..measurement.pipeline import Evaluator, add_radiance, measure
    from ..techniques import from_spec

    frame = _frame(task)
    evaluator = Evaluator(frame)
    stderr = task.get("truth_stderr") or [0.0] * len(task["truth"])
    for li, vis in enumerate(task["truth"]):
        evaluator.use_truth(li, vis, {"truth_stderr_max": stderr[li]})
    tech = from_spec(task["spec"])
    ms = [measure(tech, frame, li, repeat=1, warmup=0) for li in range(len(frame.scene.lights))]
    rows = [_accuracy_row(evaluator.row(m)) for m in ms]
    add_radiance(frame, rows, ms, task["truth"])
    for row, m in zip(rows, ms):
        row["notes"] = "; ".join(m.notes)
    _same_perceptual(task)
    files, judged = _images(frame, [m.visibility for m in ms], task["truth"], ms[0].footprint, [m.weight for m in ms])
    for row in rows:  # one shaded picture per configuration: its perceptual figures on every light's row
        row.update(judged)
    ev0 = frame.evaluated(0)
    arrays = {"mask_0": np.where(ev0, ms[0].visibility, np.nan).astype(np.float32)}
    # per light, the per-tile error sums the study's significance tests resample
    for li, m in enumerate(ms):
        arrays[f"tiles_{li}"] = tile_sums(m.visibility, task["truth"][li], frame.evaluated_image(frame.slot(li)))
    # the evaluator's notes on the result (degenerate, bias beyond the casters) name the
    # configuration themselves: the run notes take them without the spec prefix
    meta = {"rows": rows, "notes": list(dict.fromkeys(tech.notes)) + budget_note(tech, ms),
            "judgement": [n for m in ms for n in m.judgement]}
    return {"meta": meta, "arrays": arrays, "files": files}


def _timing(task: dict) -> dict:
    """Times one configuration (or the truth) on every light of a scene: ``repeat`` timed renders
    after ``warmup`` untimed ones (:func:`shadowlab.measurement.pipeline.measure`), per light."""
    from ..measurement.pipeline import measure
    from ..techniques import from_spec

    frame = _frame(task)
    tech = from_spec(task["spec"])
    columns = []
    for li in range(len(frame.scene.lights)):
        m = measure(tech, frame, li, repeat=task["repeat"], warmup=task["warmup"],
                    pass_timing=task.get("pass_timing", False))
        columns.append({**m.timing.columns(), "setup_ms": m.setup_ms, **m.pass_times,
                        **{k: v for k, v in m.stats.items() if is_time_column(k)}})
    return {"meta": {"columns": columns, "lp_num_threads": os.environ.get("LP_NUM_THREADS")},
            "arrays": {}, "files": {}}


def _tune(task: dict) -> dict:
    """One ``[[tuned]]`` entry on one scene, light 0 (:func:`shadowlab.tuning.tuner.find_best`):
    the best spec and its value, the spec's own value, and — on the exact bias route — each grid
    point's exact curve of the objective (``k_breaks``, ``k_values``), for the global-setting
    analysis (:mod:`shadowlab.tuning.global_setting`). Renders untimed (repeat 1, no warm-up):
    the timing phase times the tuned configuration like any other."""
    from ..measurement.pipeline import Evaluator
    from ..techniques import from_spec
    from ..tuning.tuner import find_best, plan_tune

    frame = _frame(task)
    evaluator = Evaluator(frame, from_spec(task["truth_spec"]), repeat=1, warmup=0)
    plan = plan_tune(task["spec"], task["params"], task["objective"])
    outcome = find_best(evaluator, plan, light=0, budget=task["budget"], repeat=1, warmup=0)
    meta = {"best": outcome.spec, "params": outcome.params, "value": outcome.value, "route": plan.route,
            "objective": plan.objective, "oracle": outcome.facts.get("oracle"),
            "default_value": (outcome.facts.get("default_exact") if plan.route == "exact"
                              else (outcome.trials[0].value if outcome.trials else None)),
            "renders": outcome.facts.get("renders"), "grid": [], "default_bias": None}
    arrays = {}
    if outcome.exact is not None:
        meta["default_bias"] = float(from_spec(plan.spec).bias)
        for k, point in enumerate(outcome.exact.points):
            meta["grid"].append(point.params)
            arrays[f"{k}_breaks"] = point.curve.breaks
            arrays[f"{k}_values"] = point.curve.values(plan.objective) if plan.objective in point.curve.sums \
                else np.full(len(point.curve.breaks), np.nan)
        meta["bias_range"] = list(plan.bias_range)
    return {"meta": meta, "arrays": arrays, "files": {}}


def probe_here() -> dict:
    """The GL device of this process's lab context, on the calling thread (the thread that made
    the context, or will: a GL context is current on one thread only)."""
    from ..gpu import gl

    return {"renderer": gl.renderer(), "device": gl.device(), "gl": gl.gl_info(),
            "lp_num_threads": os.environ.get("LP_NUM_THREADS"), "pid": os.getpid()}


def probe(_: object = None) -> dict:
    """The GL device of the worker that runs it (cache keys name the renderer), on the worker's
    GL thread, where its tasks run."""
    return _on_gl_thread(probe_here)
