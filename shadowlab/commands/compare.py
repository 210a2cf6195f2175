"""A comparison run: one scene, the ground truth and N technique configurations → a run directory.

The measuring is :func:`shadowlab.measurement.pipeline.compare_frame`; this module checks the arguments
and writes what docs/contracts.md#run-directory promises: ``metrics.csv``, ``masks.npz``, ``run.json``, the images and
``pictures.html``. Everything is written into a temporary sibling directory and moved into place
at the very end, so a run that fails leaves earlier results untouched.
"""
from __future__ import annotations

import datetime as _dt
from pathlib import Path

import numpy as np
import pandas as pd

from ..measurement.scenes import load_measured_scene
from ..gpu import gl, timing
from ..evaluation import metrics, perceptual
from ..output import provenance
from ..output import pictures
from ..output.rundir import GROUND_TRUTH_KEY, ConfigImages, RunDirectory, write_comparison
from ..util.sizes import COMPARE_SIZE
from ..util.validation import RunError, check_size  # noqa: F401  (check_size: the commands' size check)
from ..gpu.frame import Frame
from ..measurement.pipeline import (
    Comparison, StepCallback, build_techniques, check_lights, compare_frame, pass_order,
)
from ..scene import Scene
from ..gpu.shading import ShadingPass
#: Re-exported for scripts that read metrics.csv (docs/contracts.md#run-directory column order).
CONTRACT_COLUMNS = metrics.CONTRACT_COLUMNS


def default_out_dir(scene: Scene) -> Path:
    """results/<scene>_<date-time> under the current directory."""
    return Path("results") / f"{scene.name}_{_dt.datetime.now().strftime('%Y%m%d-%H%M%S')}"


def compare(scene_ref, specs: list[str], size: tuple[int, int] = COMPARE_SIZE, out: Path | None = None,
            repeat: int = 5, warmup: int = 1, on_step: StepCallback | None = None, pass_timing: bool = False) -> Path:
    """Run the ground truth and every technique spec on a scene; return the run directory.

    Bad input (scene, specs, size, repeat) raises SceneError / TechniqueError / RunError before
    any GL work. ``on_step(what, total)`` is called after every render run (progress display).
    ``pass_timing`` adds per-pass times (``pass_<name>_ms``) and the report's pass chart.
    """
    if repeat < 1 or warmup < 0:
        raise RunError(f"--repeat must be >= 1 and --warmup >= 0, got {repeat} and {warmup}")
    size = check_size(size)
    scene = load_measured_scene(scene_ref)
    techniques = build_techniques(specs)
    check_lights(techniques, scene)
    out = Path(out) if out is not None else default_out_dir(scene)
    with RunDirectory(out) as rd:
        frame = Frame(scene, *size)
        try:
            result = compare_frame(frame, techniques, repeat, warmup, on_step, pass_timing=pass_timing)
            write_run(rd, result, repeat, warmup, pass_timing)
        finally:
            frame.release()
    return out


def write_run(rd: RunDirectory, result: Comparison, repeat: int, warmup: int, pass_timing: bool = False) -> None:
    """Write a comparison's run directory (docs/contracts.md#run-directory) through the one writer
    (:func:`shadowlab.output.rundir.write_comparison`)."""
    frame, df = result.frame, result.rows
    ev0 = frame.evaluated(0)
    gt_vis = [m.visibility for m in result.truth]
    # signed difference maps V - G (first light) of the soft configurations, on one shared scale
    light0 = frame.scene.lights[0]
    diffs = {ms[0].technique.spec(): d for ms in result.results
             if (d := pictures.signed_difference(light0, ms[0].visibility, gt_vis[0], ev0)) is not None}
    limit = pictures.signed_limit(diffs.values()) if diffs else None
    shading = ShadingPass(frame)
    try:
        def shaded(vis_all, weights=None):
            return pictures.to_display(shading.shade(vis_all, weights), frame.covered)

        truth = result.truth[0].technique
        truth_shaded = shaded(gt_vis)
        configs = [ConfigImages(truth.spec(), truth.short_label(), truth.name, truth.params(), True,
                                _masked(gt_vis[0], ev0),
                                pictures.config_pictures(truth_shaded, gt_vis[0], None, ev0, frame.covered))]
        judged = {}  # spec → perceptual metrics of its shaded image against the truth's
        for ms in result.results:
            tech = ms[0].technique
            signed = (diffs[tech.spec()], limit) if tech.spec() in diffs else None
            picture = shaded([m.visibility for m in ms], [m.weight for m in ms])
            judged[tech.spec()] = perceptual.compare_pictures(picture, truth_shaded, frame.covered)
            configs.append(ConfigImages(
                tech.spec(), tech.short_label(), tech.name, tech.params(), False, _masked(ms[0].visibility, ev0),
                pictures.config_pictures(picture, ms[0].visibility, gt_vis[0], ev0,
                                         frame.covered, signed, ms[0].footprint)))
    finally:
        shading.release()
    df = with_perceptual(df, judged)
    cam = frame.camera
    record = {
        "scene": frame.scene.describe(),
        "camera": {"eye": cam.eye.tolist(), "target": cam.target.tolist(), "fov_y": cam.fov_y, "near": cam.near,
                   "far": cam.far},
        GROUND_TRUTH_KEY: result.truth[0].technique.spec(),
        "configurations": [{"label": ms[0].technique.spec(), "technique": ms[0].technique.name,
                            "params": ms[0].technique.params()} for ms in result.results],
        "renderer": gl.renderer(),
        "device": gl.device(),
        "timing_method": timing.method_description(),
        "pass_timing": timing.pass_timing_method() if pass_timing else None,
        "repeat": repeat,
        "warmup": warmup,
        # per light: the sampled truth's per-pixel standard error bound (docs/architecture.md#evaluation-evaluator-in-shadowlabmeasurementpipelinepy; 0 for a point-like light)
        "truth_stderr_max": [float(m.stats.get("truth_stderr_max", 0.0)) for m in result.truth],
        "notes": result.notes + [n for n in [perceptual.missing_note()] if n],
        # the notes on degenerate results (also in notes): the page shows them at the top
        "judgement": [n for ms in result.results for m in ms for n in m.judgement],
        **provenance.record(),
    }
    write_comparison(rd, df, configs, record, signed_limit=limit, pass_timing=pass_timing)


def with_perceptual(df: pd.DataFrame, judged: dict) -> pd.DataFrame:
    """``df`` with each configuration's perceptual metrics (``judged``: spec → {column: value})
    on every one of its rows (one shaded picture covers every light), columns in CSV order."""
    df = df.copy()
    for spec, values in judged.items():
        for col, value in values.items():
            df.loc[df["label"] == spec, col] = value
    return df[metrics.order_columns(df.columns, pass_order())]


def _masked(vis: np.ndarray, evaluated: np.ndarray) -> np.ndarray:
    """A visibility image as masks.npz stores it: float32, NaN off the evaluated pixels."""
    return np.where(evaluated, vis, np.nan).astype(np.float32)
