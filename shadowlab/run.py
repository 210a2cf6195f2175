"""A comparison run: one scene, the ground truth and N technique configurations → a run directory.

The run directory (DESIGN §6) holds ``metrics.csv``, ``masks.npz``, ``run.json``, the images and
``report.html``. Everything is written into a temporary sibling directory and moved into place
at the very end, so a run that fails leaves earlier results untouched.
"""
from __future__ import annotations

import datetime as _dt
import json
import os
import platform
import re
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from . import __version__, gl, metrics, report, timing
from .frame import Frame
from .scene import Scene, load_scene
from .shading import Shader
from .techniques import REGISTRY, Technique, TechniqueError, from_spec
from .techniques.base import format_value
from .techniques.raytrace import RayTraced

#: Columns every metrics.csv has first, in this order (DESIGN §6).
CONTRACT_COLUMNS = ["scene", "light", "technique", "params", "width", "height", "evaluated_pixels", "error_rate",
                    "false_shadow_rate", "false_lit_rate", "boundary_error_px", "time_ms_median", "time_ms_iqr"]
GROUND_TRUTH_KEY = "ground_truth"
MAX_PIXELS = 8192 * 8192


class RunError(ValueError):
    """Bad run arguments (size, repeat, duplicate configurations, output location)."""


def parse_size(text: str) -> tuple[int, int]:
    """``'800x600'`` → (800, 600); RunError on anything else or on absurd sizes."""
    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text or "")
    if not m:
        raise RunError(f"--size must look like WIDTHxHEIGHT (e.g. 800x600), got {text!r}")
    w, h = int(m.group(1)), int(m.group(2))
    if w < 8 or h < 8 or w * h > MAX_PIXELS:
        raise RunError(f"--size {w}x{h} is out of range (each side >= 8, at most {MAX_PIXELS} pixels)")
    return w, h


@dataclass
class Progress:
    """A progress bar on a terminal (tqdm), silent when stderr is not a terminal."""

    total: int
    enabled: bool | None = None

    def __post_init__(self):
        from tqdm import tqdm

        enabled = sys.stderr.isatty() if self.enabled is None else self.enabled
        self.bar = tqdm(total=self.total, disable=not enabled, unit="pass", leave=False, file=sys.stderr)

    def step(self, what: str | None = None) -> None:
        """Advance by one; ``what`` (if given) becomes the bar's description."""
        if what:
            self.bar.set_description(what)
        self.bar.update(1)

    def close(self) -> None:
        """Remove the bar."""
        self.bar.close()


def _safe(label: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", label).strip("_")


def build_techniques(specs: list[str]) -> list[Technique]:
    """Techniques from spec strings; duplicates and the ground truth itself are rejected."""
    techs = [from_spec(s) for s in specs]
    seen: set[str] = set()
    reference = RayTraced().spec()
    for t in techs:
        if t.spec() == reference:
            raise TechniqueError(f"'{t.spec()}' is the ground truth itself, which every run computes; "
                                 f"give raytrace other parameters to compare against it")
        if t.spec() in seen:
            raise TechniqueError(f"configuration given twice: {t.spec()}")
        seen.add(t.spec())
    return techs


def default_out_dir(scene: Scene) -> Path:
    """results/<scene>_<date-time> under the current directory."""
    return Path("results") / f"{scene.name}_{_dt.datetime.now().strftime('%Y%m%d-%H%M%S')}"


def _versions() -> dict:
    import embreex
    import moderngl
    import scipy
    import trimesh

    return {"shadowlab": __version__, "python": platform.python_version(), "numpy": np.__version__,
            "moderngl": moderngl.__version__, "trimesh": trimesh.__version__, "scipy": scipy.__version__,
            "pandas": pd.__version__, "embreex": getattr(embreex, "__version__", "unknown"),
            "platform": platform.platform()}


def _measure(tech: Technique, frame: Frame, light_index: int, repeat: int, warmup: int, progress: Progress):
    """setup → timed renders → visibility, for one technique and light."""
    tech.setup(frame, light_index)
    t = timing.time_passes(tech.render, repeat=repeat, warmup=warmup, gpu=not tech.cpu,
                           on_step=lambda: progress.step(f"{tech.name} light {light_index}"))
    vis = tech.visibility()
    gl.check_errors(f"{tech.name}")
    return vis, t


def compare(scene_ref, specs: list[str], size: tuple[int, int] = (800, 600), out: Path | None = None,
            repeat: int = 5, warmup: int = 1, progress: bool | None = None) -> Path:
    """Run the ground truth and every technique spec on a scene; return the run directory.

    Bad input (scene, specs, size, repeat) raises SceneError / TechniqueError / RunError before
    any GL work. ``progress``: None = show a bar only on a terminal.
    """
    if repeat < 1 or warmup < 0:
        raise RunError(f"--repeat must be >= 1 and --warmup >= 0, got {repeat} and {warmup}")
    scene = load_scene(scene_ref)
    techniques = build_techniques(specs)
    out = Path(out) if out is not None else default_out_dir(scene)
    if out.exists() and not out.is_dir():
        raise RunError(f"--out {out} exists and is not a directory")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f".{out.name}.tmp-{os.getpid()}"
    if tmp.exists():
        shutil.rmtree(tmp)
    (tmp / "images").mkdir(parents=True)
    try:
        _run(scene, techniques, size, tmp, repeat, warmup, progress)
        _move_into_place(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


def _move_into_place(tmp: Path, out: Path) -> None:
    old = None
    if out.exists():
        old = out.parent / f".{out.name}.old-{os.getpid()}"
        out.rename(old)
    tmp.rename(out)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def _run(scene: Scene, techniques: list[Technique], size, tmp: Path, repeat: int, warmup: int, progress) -> None:
    width, height = size
    n_lights = len(scene.lights)
    bar = Progress(total=n_lights * (1 + len(techniques)) * (repeat + warmup), enabled=progress)
    try:
        frame = Frame(scene, width, height)
        shader = Shader(frame)
        truth = RayTraced()
        gt_vis, rows, notes = [], [], []
        if frame.degenerate_triangles:
            notes.append(f"{frame.degenerate_triangles} degenerate (zero-area) triangles in the scene")
        for li in range(n_lights):
            vis, t = _measure(truth, frame, li, repeat, warmup, bar)
            gt_vis.append(vis)
            rows.append(_row(scene, li, truth, frame, vis, vis, t, reference=True))
        per_tech_vis = []
        for tech in techniques:
            vis_all = []
            for li in range(n_lights):
                vis, t = _measure(tech, frame, li, repeat, warmup, bar)
                vis_all.append(vis)
                rows.append(_row(scene, li, tech, frame, vis, gt_vis[li], t))
                tech.release()
            notes.extend(f"{tech.spec()}: {n}" for n in dict.fromkeys(tech.notes))
            per_tech_vis.append(vis_all)
    finally:
        bar.close()

    df = pd.DataFrame(rows)
    df = df[CONTRACT_COLUMNS + [c for c in df.columns if c not in CONTRACT_COLUMNS]]
    df.to_csv(tmp / "metrics.csv", index=False)

    ev0 = frame.evaluated(0)
    masks = {GROUND_TRUTH_KEY: np.where(ev0, gt_vis[0], np.nan).astype(np.float32)}
    for tech, vis_all in zip(techniques, per_tech_vis):
        masks[tech.spec()] = np.where(ev0, vis_all[0], np.nan).astype(np.float32)
    np.savez_compressed(tmp / "masks.npz", **masks)

    images = [_write_images(tmp, "ground_truth", truth.spec(), "ground truth", shader, frame, gt_vis, None)]
    for tech, vis_all in zip(techniques, per_tech_vis):
        images.append(_write_images(tmp, _safe(tech.short_label()), tech.spec(), tech.short_label(), shader, frame,
                                    vis_all, gt_vis[0]))
    report.speed_error_plot(df, tmp / "speed_vs_error.png")

    run = {
        "scene": scene.describe(),
        "size": [width, height],
        "camera": {"eye": frame.camera.eye.tolist(), "target": frame.camera.target.tolist(),
                   "fov_y": frame.camera.fov_y, "near": frame.camera.near, "far": frame.camera.far},
        "ground_truth": truth.spec(),
        "configurations": [{"label": t.spec(), "technique": t.name, "params": t.params()} for t in techniques],
        "renderer": gl.renderer(),
        "gl": gl.gl_info(),
        "versions": _versions(),
        "timing_method": timing.method_description(),
        "repeat": repeat,
        "warmup": warmup,
        "date": _dt.datetime.now().astimezone().isoformat(timespec="seconds"),
        "command": sys.argv,
        "masks_light": 0,
        "notes": notes,
        "images": images,
    }
    (tmp / "run.json").write_text(json.dumps(run, indent=2, default=_json_default))
    report.write_html(tmp / "report.html", run, df, images)
    shader.release()
    frame.release()


def measure_configs(scene_ref, specs: list[str], size: tuple[int, int] = (640, 480), repeat: int = 1,
                    warmup: int = 0, light_index: int = 0, frame: Frame | None = None) -> pd.DataFrame:
    """Metrics and cost rows (the metrics.csv columns) for several configurations on one scene
    and light, sharing one frame and one ground truth; writes nothing. For sweeps and tests.
    Pass ``frame`` to reuse a frame across calls."""
    scene = frame.scene if frame is not None else load_scene(scene_ref)
    techniques = [from_spec(s) for s in specs]
    frame = frame or Frame(scene, *size)
    bar = Progress(total=(1 + len(techniques)) * (repeat + warmup))
    try:
        truth = RayTraced()
        gt_vis, t = _measure(truth, frame, light_index, repeat, warmup, bar)
        rows = [_row(scene, light_index, truth, frame, gt_vis, gt_vis, t, reference=True)]
        for tech in techniques:
            vis, t = _measure(tech, frame, light_index, repeat, warmup, bar)
            row = _row(scene, light_index, tech, frame, vis, gt_vis, t)
            row["notes"] = "; ".join(dict.fromkeys(tech.notes))
            rows.append(row)
            tech.release()
    finally:
        bar.close()
    return pd.DataFrame(rows)


def _json_default(obj):
    if isinstance(obj, (np.integer, np.floating)):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(type(obj).__name__)


def _row(scene, li, tech, frame, vis, truth, t, reference=False) -> dict:
    row = {"scene": scene.name, "light": li, "light_type": scene.lights[li].type_name, "technique": tech.name,
           "params": tech.params_string(), "label": tech.spec(), "short_label": tech.short_label(),
           "reference": reference,
           "width": frame.width, "height": frame.height}
    row.update(metrics.compare(vis, truth, frame.evaluated(li)))
    row["contact_gap_px"] = metrics.contact_gap(vis, truth, frame.evaluated(li), frame.contact_lines(li))
    row.update(t.columns())
    row.update({f"param_{k}": v for k, v in tech.params().items()})
    row.update(tech.stats())
    return row


def _write_images(tmp: Path, stem: str, label: str, title: str, shader: Shader, frame: Frame, vis_all,
                  truth0) -> dict:
    covered = frame.covered
    ev0 = frame.evaluated(0)
    shaded = report.to_display(shader.shade(vis_all), covered)
    files = {"label": label, "title": title, "shaded": f"images/{stem}_shaded.png", "visibility": f"images/{stem}_visibility.png"}
    report.save_png(tmp / files["shaded"], shaded)
    report.save_png(tmp / files["visibility"], report.visibility_picture(vis_all[0], ev0, covered))
    if truth0 is not None:
        files["error"] = f"images/{stem}_error.png"
        classes = metrics.error_classes(vis_all[0], truth0, ev0)
        report.save_png(tmp / files["error"], report.error_picture(classes, shaded))
    return files


def technique_listing() -> str:
    """Registered techniques with their parameters and defaults, for ``shadowlab techniques``."""
    lines = []
    for name, cls in REGISTRY.items():
        lines.append(f"{name}: {cls.summary}")
        for key, p in cls.PARAMS.items():
            extra = f" (one of {', '.join(map(str, p.choices))})" if p.choices else ""
            lines.append(f"    {key}={format_value(p.default)}  {p.doc}{extra}")
    return "\n".join(lines)
