"""``shadowlab animate``: the ground truth and N configurations on every frame of an animated
scene, with per-frame metrics, temporal metrics and the flicker pictures.

Per frame k (time t_k = k / (n − 1), :func:`shadowlab.scene.animation.frame_times`): the scene at t_k
(:func:`shadowlab.scene.animation.scene_at`) → a :class:`~shadowlab.frame.Frame` → the truth and each
technique on every light through :mod:`shadowlab.pipeline` (``measure``; one untimed-in-effect
render unless ``repeat`` says otherwise) → the usual metrics row plus ``frame``, ``t`` and, from
frame 1 on, the temporal columns of :mod:`shadowlab.temporal` against frame k−1.

Outputs (in the run directory, written into a temporary sibling and moved into place at the
end, so a failed run leaves earlier results untouched — as :mod:`shadowlab.commands.compare` does):
``frames.csv`` (one row per frame × light × configuration, the truth included), ``summary.csv``
(per configuration and light: mean error rate, flip rate mean/p95/max, temporal error
mean/max), ``flicker_<name>.png`` (per technique, first light: per pixel, how many frame pairs
flipped where the truth did not), ``strip_<name>.gif`` (per technique, first light: truth |
technique | error map, one GIF frame per animation frame), ``pictures.html`` and
``animation.json`` (provenance, :mod:`shadowlab.provenance`).

The GIFs are written with Pillow's GIF writer: Pillow is already installed (matplotlib depends
on it), whereas imageio would be a new dependency for the same few lines; the strips are flat
colour pictures that a 256-colour palette holds without visible loss.
"""
from __future__ import annotations

import datetime as _dt
import html
import json
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..output import pictures
from .. import gl, metrics, provenance, temporal, timing
from ..scene.animation import frame_times, scene_at
from ..frame import Frame
from ..pipeline import Evaluator, StepCallback, build_techniques, check_lights, measure, pass_order
from ..output.rundir import move_into_place, safe_name, staging_dir
from ..validation import RunError
from .compare import check_size
from ..scene import Scene, load_scene

#: Display time of one GIF frame, milliseconds.
GIF_FRAME_MS = 150
#: Width of the dark separator between the panels of a strip, pixels.
STRIP_GAP = 2
#: Colour map of the flicker heat maps (matplotlib name): dark = no flips, bright = many.
FLICKER_COLORMAP = "inferno"
TRUTH_KEY = "ground_truth"


def default_out_dir(scene: Scene) -> Path:
    """results/<scene>_animate_<date-time> under the current directory."""
    return Path("results") / f"{scene.name}_animate_{_dt.datetime.now().strftime('%Y%m%d-%H%M%S')}"


def frame_count(scene: Scene, frames: int | None) -> int:
    """The number of frames to render: ``frames`` if given, else the scene's animation's; a
    scene without ``[animation]`` needs ``frames`` (then every frame is the still scene)."""
    if frames is None:
        if scene.animation is None:
            raise RunError(f"scene {scene.name} has no [animation] table: give --frames N to render N identical "
                           f"still frames, or add camera/light keyframes to the scene")
        frames = scene.animation.frames
    if frames < 2:
        raise RunError(f"--frames must be >= 2 (temporal metrics compare consecutive frames), got {frames}")
    return int(frames)


@dataclass
class _Track:
    """One configuration on one light across frames: the previous frame's visibility, the
    accumulated flip counts (int32 (H, W), each pair's flips in frame k's pixels) and the
    strip's pictures (uint8 (H, W, 3) per frame; first light only)."""

    label: str
    stem: str
    prev_vis: np.ndarray | None = None
    flip_count: np.ndarray | None = None
    strip: list = field(default_factory=list)


def _uint8(rgb: np.ndarray) -> np.ndarray:
    return (np.clip(rgb, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def _strip_picture(vis: np.ndarray, truth: np.ndarray, evaluated: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """truth's visibility | the technique's | its error map (over the truth's visibility), uint8
    (H, 3W + 2·gap, 3), row 0 = top."""
    truth_pic = pictures.visibility_picture(truth, evaluated, covered)
    vis_pic = pictures.visibility_picture(vis, evaluated, covered)
    err_pic = pictures.error_picture(metrics.error_classes(vis, truth, evaluated), truth_pic.copy())
    gap = np.zeros((vis.shape[0], STRIP_GAP, 3))
    return _uint8(np.concatenate([truth_pic, gap, vis_pic, gap, err_pic], axis=1))


def write_gif(path: Path, pictures: list[np.ndarray]) -> None:
    """An animated, looping GIF of uint8 RGB pictures (H, W, 3), :data:`GIF_FRAME_MS` each
    (Pillow's GIF writer, see the module docstring)."""
    from PIL import Image

    images = [Image.fromarray(p, "RGB") for p in pictures]
    images[0].save(path, save_all=True, append_images=images[1:], duration=GIF_FRAME_MS, loop=0)


def flicker_picture(path: Path, counts: np.ndarray, covered: np.ndarray, title: str, caption: str) -> None:
    """The flicker heat map (PNG, matplotlib): per pixel the number of frame pairs in which the
    technique's thresholded visibility flipped while the truth's did not, on
    :data:`FLICKER_COLORMAP` with a colour bar; background where nothing is visible."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    h, w = counts.shape
    data = np.ma.masked_where(~covered, counts)
    cmap = matplotlib.colormaps[FLICKER_COLORMAP].with_extremes(bad=pictures.BACKGROUND)
    fig, ax = plt.subplots(figsize=(5.0, 5.0 * h / w + 0.6), dpi=110)
    im = ax.imshow(data, cmap=cmap, vmin=0, vmax=max(1, int(counts.max())), interpolation="nearest")
    ax.set_axis_off()
    ax.set_title(title, fontsize=8)
    cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.02)
    cb.set_label(caption, fontsize=7)
    cb.ax.tick_params(labelsize=7)
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)


def summary_table(df: pd.DataFrame) -> pd.DataFrame:
    """Per configuration and light (``label``, ``light``): frames, mean error rate, flip rate
    mean/p95/max and temporal error mean/max over the frame pairs (:func:`shadowlab.temporal.summarise`)."""
    rows = []
    for (label, light), g in df.groupby(["label", "light"], sort=False):
        flip = temporal.summarise(g["flip_rate"])
        terr = temporal.summarise(g["temporal_error"])
        rows.append({"label": label, "short_label": g["short_label"].iloc[0], "technique": g["technique"].iloc[0],
                     "reference": bool(g["reference"].iloc[0]), "light": light, "frames": len(g),
                     "error_rate_mean": float(g["error_rate"].mean()),
                     "flip_rate_mean": flip["mean"], "flip_rate_p95": flip["p95"], "flip_rate_max": flip["max"],
                     "temporal_error_mean": terr["mean"], "temporal_error_max": terr["max"]})
    return pd.DataFrame(rows)


def animate(scene_ref, specs: list[str], frames: int | None = None, size: tuple[int, int] = (320, 240),
            out: Path | None = None, repeat: int = 1, warmup: int = 0, on_step: StepCallback | None = None) -> Path:
    """Run the truth and every technique spec on every frame of an animated scene; return the
    run directory. Bad input (scene, specs, size, frames, repeat) raises SceneError /
    TechniqueError / RunError before any GL work. ``on_step(what, total)`` is called after every
    render run (progress display)."""
    if repeat < 1 or warmup < 0:
        raise RunError(f"--repeat must be >= 1 and --warmup >= 0, got {repeat} and {warmup}")
    size = check_size(size)
    scene = load_scene(scene_ref)
    techniques = build_techniques(specs)
    check_lights(techniques, scene, where="animate runs every technique on every light: ")
    n = frame_count(scene, frames)
    out = Path(out) if out is not None else default_out_dir(scene)
    tmp = staging_dir(out)
    try:
        _run(tmp, scene, techniques, n, size, repeat, warmup, on_step)
        move_into_place(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


def _run(folder: Path, scene: Scene, techniques, n: int, size, repeat: int, warmup: int,
         on_step: StepCallback | None) -> None:
    """Measure every frame and write the outputs into ``folder``."""
    lights = range(len(scene.lights))
    total = n * len(lights) * (1 + len(techniques)) * (repeat + warmup)
    times = frame_times(n)
    tracks: dict[tuple[str, int], _Track] = {}
    rows, notes = [], []
    prev_geom = prev_eval = None
    truth_spec = None
    covered_last = None
    moving = scene.animation is not None and scene.animation.camera_moves
    for k, t in enumerate(times):
        frame = Frame(scene_at(scene, t), *size)
        try:
            evaluator = Evaluator(frame, repeat=repeat, warmup=warmup)
            truth_spec = evaluator.truth_technique.spec()
            geom = temporal.FrameGeometry.of(frame)
            evals = [frame.evaluated(li) for li in lights]
            for li in lights:
                reproj = None if prev_geom is None else temporal.reproject(geom, prev_geom, evals[li], prev_eval[li])
                step = None if on_step is None else (lambda what=f"frame {k + 1}/{n} truth light {li}":
                                                     on_step(what, total))
                truth_m = evaluator.truth(li, step)
                measured = [(TRUTH_KEY, truth_m, True)]
                for tech in techniques:
                    step = None if on_step is None else (lambda what=f"frame {k + 1}/{n} {tech.short_label()} light {li}":
                                                         on_step(what, total))
                    measured.append((tech.spec(), measure(tech, frame, li, repeat, warmup, step), False))
                truth_track = tracks.get((TRUTH_KEY, li))
                truth_prev = truth_track.prev_vis if truth_track is not None else None
                for key, m, is_ref in measured:
                    track = tracks.setdefault((key, li), _Track(m.technique.spec(),
                                                                safe_name(m.technique.short_label())))
                    row = {"frame": k, "t": float(t), **evaluator.row(m, reference=is_ref),
                           "notes": "; ".join(m.notes)}
                    if reproj is not None:
                        pm = temporal.pair_metrics(track.prev_vis, m.visibility, truth_prev, truth_m.visibility, reproj)
                        row.update(pm.columns())
                        track.flip_count = (pm.flips.astype(np.int32) if track.flip_count is None
                                            else track.flip_count + pm.flips)
                    else:
                        row.update({c: float("nan") for c in temporal.TEMPORAL_COLUMNS})
                    if li == 0 and not is_ref:
                        track.strip.append(_strip_picture(m.visibility, truth_m.visibility, evals[0], frame.covered))
                    track.prev_vis = m.visibility
                    rows.append(row)
            for tech in techniques:
                notes.extend(f"frame {k}: {tech.spec()}: {x}" for x in dict.fromkeys(tech.notes))
                tech.notes.clear()
            prev_geom, prev_eval = geom, evals
            covered_last = frame.covered.copy()
        finally:
            frame.release()

    df = pd.DataFrame(rows)
    ordered = metrics.order_columns([c for c in df.columns if c not in ("frame", "t")], pass_order())
    df = df[["frame", "t"] + ordered]
    df.to_csv(folder / "frames.csv", index=False)
    summary = summary_table(df)
    summary.to_csv(folder / "summary.csv", index=False)

    where = ("accumulated in each frame's own pixels (screen space: the camera moves, so a pixel's surface "
             "changes from frame to frame)" if moving else "in the last frame's pixels (still camera)")
    caption = f"frame pairs flipping beyond the truth, {where}"
    pictures = []
    for tech in techniques:
        track = tracks[(tech.spec(), 0)]
        flicker = f"flicker_{track.stem}.png"
        strip = f"strip_{track.stem}.gif"
        flicker_picture(folder / flicker, track.flip_count, covered_last, tech.short_label(), "flips / pixel")
        write_gif(folder / strip, track.strip)
        pictures.append({"label": tech.spec(), "title": tech.short_label(), "flicker": flicker, "strip": strip,
                         "flips_total": int(track.flip_count.sum()), "flips_max": int(track.flip_count.max())})

    record = {
        "scene": scene.describe(),
        "animation": scene.animation.describe() if scene.animation is not None else None,
        "still": scene.animation is None,
        "camera_moves": moving,
        "frames": n,
        "times": times.tolist(),
        "size": list(size),
        "ground_truth": truth_spec,
        "configurations": [{"label": t.spec(), "technique": t.name, "params": t.params()} for t in techniques],
        "renderer": gl.renderer(),
        "device": gl.device(),
        "timing_method": timing.method_description(),
        "repeat": repeat,
        "warmup": warmup,
        "temporal": {"reprojection": "exact points of frame k projected into frame k-1's camera, nearest pixel; "
                                     f"valid within {temporal.SAME_SURFACE_FOOTPRINTS} pixel footprints",
                     "threshold": metrics.THRESHOLD, "flicker_caption": caption,
                     "images_light": 0},
        "images": pictures,
        "notes": list(dict.fromkeys(notes)),
        **provenance.record(),
    }
    (folder / "animation.json").write_text(json.dumps(record, indent=2, default=provenance.json_default))
    write_html(folder / "pictures.html", record, summary, pictures)


def write_html(path: Path, record: dict, summary: pd.DataFrame, pictures: list[dict]) -> None:
    """``pictures.html`` of an animate run: the run's facts, the summary table, and per technique
    its flicker heat map and its animated error strip (file names relative to the report)."""
    table = summary.copy()
    for c in table.columns:
        if c.endswith(("_mean", "_p95", "_max")):
            table[c] = table[c].map(lambda v: "" if not np.isfinite(v) else f"{v:.5f}")
    legend = "".join(f"{html.escape(name)}; " for name, _ in pictures.ERROR_COLORS.values())
    items = "".join(
        f'<h3>{html.escape(p["title"])}</h3><p class="spec">{html.escape(p["label"])} · {p["flips_total"]} flips '
        f'beyond the truth in all, at most {p["flips_max"]} on one pixel</p><div class="row">'
        f'<figure><img src="{p["flicker"]}" alt="flicker heat map"><figcaption>flicker heat map</figcaption></figure>'
        f'<figure><img class="strip" src="{p["strip"]}" alt="error strip"><figcaption>truth | technique | '
        f'error map, per frame</figcaption></figure></div>' for p in pictures)
    notes = "".join(f"<li>{html.escape(x)}</li>" for x in record["notes"])
    scene = record["scene"]["name"]
    doc = f"""<!doctype html>
<html><head><meta charset="utf-8"><title>shadowlab animate — {html.escape(scene)}</title>
<style>
body {{ font-family: system-ui, sans-serif; margin: 1.5em; color: #222; }}
table {{ border-collapse: collapse; font-size: 0.85em; }}
td, th {{ border: 1px solid #ccc; padding: 0.25em 0.5em; text-align: right; }}
.row {{ display: flex; gap: 0.8em; flex-wrap: wrap; align-items: flex-start; }}
figure {{ margin: 0; }} .row img {{ max-width: 640px; border: 1px solid #999; }}
img.strip {{ image-rendering: pixelated; min-width: 480px; }}
.spec {{ font-family: monospace; font-size: 0.75em; color: #555; word-break: break-all; }}
figcaption {{ font-size: 0.8em; color: #555; }}
</style></head><body>
<h1>shadowlab animate: {html.escape(scene)}</h1>
<p>{record['frames']} frames at {record['size'][0]}×{record['size'][1]} pixels
({'still scene' if record['still'] else 'camera moves' if record['camera_moves'] else 'lights move, camera still'})
· device: {html.escape(record['device'])} · {html.escape(record['date'])} · revision {html.escape(record['revision'])}<br>
flip_rate: share of validly reprojected pixels whose visibility (thresholded at {record['temporal']['threshold']})
changes between consecutive frames while the truth's does not; temporal_error: mean |ΔV − ΔG|.
Heat maps and strips are for light 0; the heat map counts {html.escape(record['temporal']['flicker_caption'])}.
Error map colours: {legend}</p>
{f'<h2>Notes</h2><ul>{notes}</ul>' if notes else ''}
<h2>Summary</h2>
{table.to_html(index=False, escape=True)}
<p>Per-frame rows: frames.csv.</p>
<h2>Flicker</h2>
{items}
</body></html>
"""
    path.write_text(doc)
