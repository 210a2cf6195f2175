"""A comparison run: one scene, the ground truth and N technique configurations → a run directory.

The measuring is :func:`shadowlab.pipeline.compare_frame`; this module checks the arguments
and writes what DESIGN §6 promises: ``metrics.csv``, ``masks.npz``, ``run.json``, the images and
``pictures.html``. Everything is written into a temporary sibling directory and moved into place
at the very end, so a run that fails leaves earlier results untouched.
"""
from __future__ import annotations

import datetime as _dt
import json
import os
import re
import shutil
from pathlib import Path

import numpy as np

from ..output import pictures
from .. import gl, metrics, provenance, timing
from ..frame import Frame
from ..pipeline import Comparison, StepCallback, build_techniques, check_lights, compare_frame
from ..scene import Scene, load_scene
from ..shading import ShadingPass

GROUND_TRUTH_KEY = "ground_truth"
#: The largest image a run accepts, in pixels (GL's usual maximum framebuffer side, squared).
MAX_PIXELS = 8192 * 8192
#: Re-exported for scripts that read metrics.csv (DESIGN §6 column order).
CONTRACT_COLUMNS = metrics.CONTRACT_COLUMNS


class RunError(ValueError):
    """Bad run arguments (size, repeat, duplicate configurations, output location)."""


def check_size(size: tuple[int, int]) -> tuple[int, int]:
    """``size`` = (width, height) if it is a sensible image size; RunError otherwise."""
    w, h = map(int, size)
    if w < 8 or h < 8 or w * h > MAX_PIXELS:
        raise RunError(f"--size {w}x{h} is out of range (each side >= 8, at most {MAX_PIXELS} pixels)")
    return w, h


def default_out_dir(scene: Scene) -> Path:
    """results/<scene>_<date-time> under the current directory."""
    return Path("results") / f"{scene.name}_{_dt.datetime.now().strftime('%Y%m%d-%H%M%S')}"


def compare(scene_ref, specs: list[str], size: tuple[int, int] = (800, 600), out: Path | None = None,
            repeat: int = 5, warmup: int = 1, on_step: StepCallback | None = None, pass_timing: bool = False) -> Path:
    """Run the ground truth and every technique spec on a scene; return the run directory.

    Bad input (scene, specs, size, repeat) raises SceneError / TechniqueError / RunError before
    any GL work. ``on_step(what, total)`` is called after every render run (progress display).
    ``pass_timing`` adds per-pass times (``pass_<name>_ms``) and the report's pass chart.
    """
    if repeat < 1 or warmup < 0:
        raise RunError(f"--repeat must be >= 1 and --warmup >= 0, got {repeat} and {warmup}")
    size = check_size(size)
    scene = load_scene(scene_ref)
    techniques = build_techniques(specs)
    check_lights(techniques, scene)
    out = Path(out) if out is not None else default_out_dir(scene)
    tmp = staging_dir(out)
    (tmp / "images").mkdir()
    try:
        frame = Frame(scene, *size)
        try:
            result = compare_frame(frame, techniques, repeat, warmup, on_step, pass_timing=pass_timing)
            write_run(tmp, result, repeat, warmup, pass_timing)
        finally:
            frame.release()
        move_into_place(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


def staging_dir(out: Path) -> Path:
    """A fresh, empty folder beside ``out`` to write a run into before :func:`move_into_place`
    puts it there — so a failed run leaves earlier results intact (RunError when ``out`` exists
    and is not a folder)."""
    if out.exists() and not out.is_dir():
        raise RunError(f"--out {out} exists and is not a directory")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f".{out.name}.tmp-{os.getpid()}"
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir(parents=True)
    return tmp


def move_into_place(tmp: Path, out: Path) -> None:
    """Replace ``out`` (if any) by the finished directory ``tmp``, removing the old one last."""
    old = None
    if out.exists():
        old = out.parent / f".{out.name}.old-{os.getpid()}"
        out.rename(old)
    tmp.rename(out)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def safe_name(label: str) -> str:
    """A label (technique spec, scene name) as a file-name stem: letters, digits, ``._-``."""
    return re.sub(r"[^A-Za-z0-9._-]+", "_", label).strip("_")


def write_run(folder: Path, result: Comparison, repeat: int, warmup: int, pass_timing: bool = False) -> None:
    """Write a comparison's run directory (DESIGN §6) into ``folder`` (which has ``images/``)."""
    frame, df = result.frame, result.rows
    df.to_csv(folder / "metrics.csv", index=False)
    ev0 = frame.evaluated(0)
    gt_vis = [m.visibility for m in result.truth]
    masks = {GROUND_TRUTH_KEY: np.where(ev0, gt_vis[0], np.nan).astype(np.float32)}
    for ms in result.results:
        masks[ms[0].technique.spec()] = np.where(ev0, ms[0].visibility, np.nan).astype(np.float32)
    np.savez_compressed(folder / "masks.npz", **masks)

    # signed difference maps V - G (first light) of the soft configurations, on one shared scale
    light0 = frame.scene.lights[0]
    diffs = {ms[0].technique.spec(): d for ms in result.results
             if (d := pictures.signed_difference(light0, ms[0].visibility, gt_vis[0], ev0)) is not None}
    signed_map = None
    if diffs:
        limit = pictures.signed_limit(diffs.values())
        signed_map = {"limit": limit, "colormap": pictures.SIGNED_COLORMAP, "legend": "images/signed_legend.png",
                      "caption": pictures.SIGNED_CAPTION}
        pictures.signed_legend(folder / signed_map["legend"], limit)
    footprint_legend = None
    if any(ms[0].footprint is not None for ms in result.results):
        footprint_legend = "images/footprint_legend.png"
        pictures.footprint_legend(folder / footprint_legend)
    shading = ShadingPass(frame)
    try:
        truth = result.truth[0].technique
        images = [_write_images(folder, "ground_truth", truth.spec(), "ground truth", shading, frame, gt_vis, None)]
        for ms in result.results:
            tech = ms[0].technique
            signed = (diffs[tech.spec()], signed_map["limit"]) if tech.spec() in diffs else None
            images.append(_write_images(folder, safe_name(tech.short_label()), tech.spec(), tech.short_label(), shading,
                                        frame, [m.visibility for m in ms], gt_vis[0], signed, ms[0].footprint))
    finally:
        shading.release()
    pictures.speed_error_plot(df, folder / "speed_vs_error.png")
    passes_png = pictures.pass_time_plot(df, folder / "pass_times.png") if pass_timing else None
    cam = frame.camera
    run = {
        "scene": frame.scene.describe(),
        "size": [frame.width, frame.height],
        "camera": {"eye": cam.eye.tolist(), "target": cam.target.tolist(), "fov_y": cam.fov_y, "near": cam.near,
                   "far": cam.far},
        "ground_truth": result.truth[0].technique.spec(),
        "configurations": [{"label": ms[0].technique.spec(), "technique": ms[0].technique.name,
                            "params": ms[0].technique.params()} for ms in result.results],
        "renderer": gl.renderer(),
        "device": gl.device(),
        "timing_method": timing.method_description(),
        "pass_timing": timing.pass_timing_method() if pass_timing else None,
        "pass_times_image": passes_png,
        "repeat": repeat,
        "warmup": warmup,
        "masks_light": 0,
        # per light: the sampled truth's per-pixel standard error bound (DESIGN §9; 0 for a point-like light)
        "truth_stderr_max": [float(m.stats.get("truth_stderr_max", 0.0)) for m in result.truth],
        "signed_map": signed_map,
        "footprint_legend": footprint_legend,
        # peak resident memory of the run's measurements (each config's is in metrics.csv)
        "peak_rss_mib": peak_mib(df),
        "notes": result.notes,
        "images": images,
        **provenance.record(),
    }
    (folder / "run.json").write_text(json.dumps(run, indent=2, default=provenance.json_default))
    pictures.write_html(folder / "pictures.html", run, df, images)



def _write_images(folder: Path, stem: str, label: str, title: str, shading: ShadingPass, frame: Frame, vis_all,
                  truth0, signed: tuple[np.ndarray, float] | None = None, footprint: np.ndarray | None = None) -> dict:
    """Write one configuration's images (shaded, visibility; against ``truth0``: the error map;
    with ``signed`` = (V − G float (H, W), limit): the signed difference map; with ``footprint``
    (texel footprint m, float (H, W), first light): ``<stem>_footprint.png``) and return their
    file names for the report."""
    covered = frame.covered
    ev0 = frame.evaluated(0)
    shaded = pictures.to_display(shading.shade(vis_all), covered)
    files = {"label": label, "title": title, "shaded": f"images/{stem}_shaded.png",
             "visibility": f"images/{stem}_visibility.png"}
    pictures.save_png(folder / files["shaded"], shaded)
    pictures.save_png(folder / files["visibility"], pictures.visibility_picture(vis_all[0], ev0, covered))
    if truth0 is not None:
        files["error"] = f"images/{stem}_error.png"
        classes = metrics.error_classes(vis_all[0], truth0, ev0)
        pictures.save_png(folder / files["error"], pictures.error_picture(classes, shaded))
    if signed is not None:
        files["signed"] = f"images/{stem}_signed.png"
        pictures.save_png(folder / files["signed"], pictures.signed_picture(signed[0], signed[1], ev0, covered))
    if footprint is not None:
        files["footprint"] = f"images/{stem}_footprint.png"
        pictures.save_png(folder / files["footprint"], pictures.footprint_picture(footprint, ev0, covered))
    return files


def peak_mib(df) -> float | None:
    """The largest ``peak_rss_mib`` of a run's rows (None when not measured)."""
    if "peak_rss_mib" not in df.columns or df["peak_rss_mib"].isna().all():
        return None
    return float(df["peak_rss_mib"].max())
