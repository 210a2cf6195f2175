"""``shadowlab animate``: the ground truth and N configurations on every frame of an animated
scene, with per-frame metrics, temporal metrics and the flicker pictures.

Per frame k (time t_k = k / (n − 1), :func:`shadowlab.scene.animation.frame_times`): the scene at t_k
(:func:`shadowlab.scene.animation.scene_at`) → a :class:`~shadowlab.gpu.frame.Frame` → the truth and each
technique on every light through :mod:`shadowlab.measurement.pipeline` (``measure``; one untimed-in-effect
render unless ``repeat`` says otherwise; before each, ``Technique.begin_frame`` tells the technique
which frame and light it is measuring, for state it keeps across frames) → the usual metrics row plus ``frame``, ``t`` and, from
frame 1 on, the temporal columns of :mod:`shadowlab.evaluation.temporal` against frame k−1.

Outputs (through the one run-directory writer, :class:`shadowlab.output.rundir.RunDirectory`:
written into a temporary sibling and moved into place at the end, so a failed run leaves earlier
results untouched — as :mod:`shadowlab.commands.compare` does): ``frames.csv`` (one row per
frame × light × configuration, the truth included), ``summary.csv`` (per configuration and
light: mean error rate, flip rate mean/p95/max, temporal error mean/max, median time per frame),
``flicker_<name>.png`` (per technique, first light: per pixel, how many frame pairs flipped where
the truth did not, coloured over the last frame's shaded truth in grey), ``strip_<name>.gif``
(per technique, first light: truth | technique | error map, one labelled GIF frame per animation
frame), ``animation.json`` (provenance, :mod:`shadowlab.output.provenance`) and ``report.html``
(template ``animate.html``). These names are a contract: users' scripts read them.

The GIFs are written, and their frames labelled, with Pillow (GIF writer, ImageDraw and its
default font): Pillow is already installed (matplotlib depends on it), whereas imageio would be a
new dependency for the same few lines; the strips are flat colour pictures that a 256-colour
palette holds without visible loss.
"""
from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..measurement.scenes import load_measured_scene
from ..output import pictures
from ..gpu import gl, timing
from ..evaluation import metrics, temporal
from ..output import provenance
from ..scene.animation import frame_times, scene_at
from ..gpu.frame import Frame
from ..measurement.pipeline import (
    Evaluator, StepCallback, build_techniques, check_lights, measure, pass_order,
)
from ..output.pages import provenance_items
from ..output.rundir import RunDirectory, error_legend, safe_name
from ..gpu.shading import ShadingPass
from ..util.validation import RunError
from ..util.validation import check_size
from ..scene import Scene

#: Display time of one GIF frame, milliseconds.
GIF_FRAME_MS = 150
#: Width of the dark separator between the panels of a strip, pixels.
STRIP_GAP = 2
#: Colour map of the flicker heat maps (matplotlib name): dark = few flips, bright = many.
FLICKER_COLORMAP = "inferno"
#: Where on :data:`FLICKER_COLORMAP` a count of 1 starts: its near-black low end would read as
#: shadow over the grey scene, so the overlay uses the map from here up.
FLICKER_COLORMAP_FLOOR = 0.3
#: Entries of that cut colour map (matplotlib's usual resolution).
FLICKER_COLORMAP_STEPS = 256
#: The grey scene under the flicker counts: luminance of the shaded truth mapped linearly onto
#: [low, high], so the scene is visible but never as bright as the brightest overlay colours.
FLICKER_UNDERLAY_GREY = (0.15, 0.75)
#: Rec. 709 luma weights (sRGB-encoded RGB → grey) of the flicker picture's underlay.
LUMA_WEIGHTS = np.array([0.2126, 0.7152, 0.0722])
#: Panel names of a strip, left to right, drawn on every GIF frame.
STRIP_PANELS = ("truth", "technique", "error")
#: Margin of a GIF label from its panel's corner, and padding of its dark box, pixels.
LABEL_MARGIN = 2
LABEL_PAD = 1
#: Opacity (0–255) of the dark box behind a GIF label.
LABEL_BOX_ALPHA = 170
#: The flicker figure: width and title height (inches), resolution, and its colour bar's width
#: and gap from the picture (matplotlib axes_grid1 sizes).
FLICKER_FIGURE_WIDTH = 5.0
FLICKER_TITLE_HEIGHT = 0.6
FLICKER_DPI = 110
COLORBAR_WIDTH = "4%"
COLORBAR_PAD = 0.08
#: Decimals of the temporal error (a visibility difference, not a rate) on the page.
TEMPORAL_ERROR_DECIMALS = 4
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


def label_strip(strip: np.ndarray, k: int, n: int) -> np.ndarray:
    """One strip picture (uint8 (H, 3W + 2·gap, 3), :func:`_strip_picture`) with its labels drawn
    in: each panel's name (:data:`STRIP_PANELS`) at its top left and "frame k/n" (1-based) at the
    bottom left, white on a translucent dark box, so a GIF frame says what it shows and when
    (Pillow ImageDraw, default font). Returns a new array of the same shape."""
    from PIL import Image, ImageDraw, ImageFont

    h, total, _ = strip.shape
    panel = (total - (len(STRIP_PANELS) - 1) * STRIP_GAP) // len(STRIP_PANELS)
    image = Image.fromarray(strip, "RGB").convert("RGBA")
    overlay = Image.new("RGBA", image.size, (0, 0, 0, 0))
    draw = ImageDraw.Draw(overlay)
    font = ImageFont.load_default()

    def text(x: int, y: int, words: str, anchor: str) -> None:
        box = draw.textbbox((x, y), words, font=font, anchor=anchor)
        draw.rectangle((box[0] - LABEL_PAD, box[1] - LABEL_PAD, box[2] + LABEL_PAD, box[3] + LABEL_PAD),
                       fill=(0, 0, 0, LABEL_BOX_ALPHA))
        draw.text((x, y), words, font=font, fill=(255, 255, 255, 255), anchor=anchor)

    for i, name in enumerate(STRIP_PANELS):
        text(i * (panel + STRIP_GAP) + LABEL_MARGIN, LABEL_MARGIN, name, "la")
    text(LABEL_MARGIN, h - LABEL_MARGIN, f"frame {k + 1}/{n}", "ld")
    return np.asarray(Image.alpha_composite(image, overlay).convert("RGB")).copy()


def write_gif(path: Path, strip: list[np.ndarray]) -> None:
    """An animated, looping GIF of uint8 RGB pictures (H, W, 3), :data:`GIF_FRAME_MS` each
    (Pillow's GIF writer, see the module docstring)."""
    from PIL import Image

    images = [Image.fromarray(p, "RGB") for p in strip]
    images[0].save(path, save_all=True, append_images=images[1:], duration=GIF_FRAME_MS, loop=0)


def flicker_colormap():
    """:data:`FLICKER_COLORMAP` from :data:`FLICKER_COLORMAP_FLOOR` up (a matplotlib colour map):
    the overlay's colours, none of them dark enough to pass for shadow."""
    import matplotlib
    from matplotlib.colors import ListedColormap

    base = matplotlib.colormaps[FLICKER_COLORMAP]
    return ListedColormap(base(np.linspace(FLICKER_COLORMAP_FLOOR, 1.0, FLICKER_COLORMAP_STEPS)),
                          name=f"{FLICKER_COLORMAP}_floor")


def flicker_overlay(counts: np.ndarray, covered: np.ndarray, underlay: np.ndarray) -> np.ndarray:
    """The flicker picture's pixels, RGB float in [0, 1] (H, W, 3), row 0 = top: the scene in grey
    (``underlay``: sRGB-encoded shaded RGB (H, W, 3), its luma mapped onto
    :data:`FLICKER_UNDERLAY_GREY`), the flip ``counts`` in :func:`flicker_colormap` colours where
    a count is above 0 (1 → the floor colour, the largest count → the top), background where
    nothing is covered. Why: counts alone are black wherever nothing flickers, which hides the
    scene the flicker is on."""
    lo, hi = FLICKER_UNDERLAY_GREY
    grey = lo + (hi - lo) * np.clip(underlay @ LUMA_WEIGHTS, 0.0, 1.0)
    rgb = np.repeat(grey[..., None], 3, axis=2)
    top = max(1, int(counts.max()))
    hot = (counts > 0) & covered
    if hot.any():
        rel = (counts[hot] - 1) / max(1, top - 1)
        rgb[hot] = flicker_colormap()(rel)[:, :3]
    rgb[~covered] = pictures.BACKGROUND
    return rgb


def flicker_picture(path: Path, counts: np.ndarray, covered: np.ndarray, underlay: np.ndarray, title: str,
                    caption: str) -> None:
    """The flicker heat map (PNG, matplotlib): :func:`flicker_overlay` — per pixel the number of
    frame pairs in which the technique's thresholded visibility flipped while the truth's did not,
    coloured over the grey scene ``underlay`` — with a colour bar of the counts (from 1)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.ticker import MaxNLocator
    from mpl_toolkits.axes_grid1 import make_axes_locatable

    h, w = counts.shape
    top = max(1, int(counts.max()))
    fig, ax = plt.subplots(figsize=(FLICKER_FIGURE_WIDTH, FLICKER_FIGURE_WIDTH * h / w + FLICKER_TITLE_HEIGHT),
                           dpi=FLICKER_DPI)
    ax.imshow(flicker_overlay(counts, covered, underlay), interpolation="nearest")
    ax.set_axis_off()
    ax.set_title(title, fontsize=8)
    # counts 1..top on the colour bar, as the overlay maps them (a single count still gets a bar),
    # in an axes as tall as the picture
    cax = make_axes_locatable(ax).append_axes("right", size=COLORBAR_WIDTH, pad=COLORBAR_PAD)
    cb = fig.colorbar(ScalarMappable(Normalize(1, max(top, 2)), flicker_colormap()), cax=cax)
    cb.locator = MaxNLocator(integer=True)
    cb.update_ticks()
    cb.set_label(caption, fontsize=7)
    cb.ax.tick_params(labelsize=7)
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)


def summary_table(df: pd.DataFrame) -> pd.DataFrame:
    """Per configuration and light (``label``, ``light``): frames, mean error rate, flip rate
    mean/p95/max and temporal error mean/max over the frame pairs (:func:`shadowlab.evaluation.temporal.summarise`)
    and ``time_ms_median``, the median over frames of each frame's median time (the cost beside
    the stability). Columns are only ever added: summary.csv is read by users' scripts."""
    rows = []
    for (label, light), g in df.groupby(["label", "light"], sort=False):
        flip = temporal.summarise(g["flip_rate"])
        terr = temporal.summarise(g["temporal_error"])
        rows.append({"label": label, "short_label": g["short_label"].iloc[0], "technique": g["technique"].iloc[0],
                     "reference": bool(g["reference"].iloc[0]), "light": light, "frames": len(g),
                     "error_rate_mean": float(g["error_rate"].mean()),
                     "flip_rate_mean": flip["mean"], "flip_rate_p95": flip["p95"], "flip_rate_max": flip["max"],
                     "temporal_error_mean": terr["mean"], "temporal_error_max": terr["max"],
                     "time_ms_median": float(g["time_ms_median"].median())})
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
    scene = load_measured_scene(scene_ref)
    techniques = build_techniques(specs)
    check_lights(techniques, scene, where="animate runs every technique on every light: ")
    n = frame_count(scene, frames)
    out = Path(out) if out is not None else default_out_dir(scene)
    with RunDirectory(out) as rd:
        _run(rd, scene, techniques, n, size, repeat, warmup, on_step)
    return out


def _what_moves(animation) -> str:
    """The moving parts of an animation in words ("camera, lights"; "still scene")."""
    if animation is None:
        return "still scene"
    parts = [name for name, moves in (("camera", animation.camera_moves), ("lights", bool(animation.lights)),
                                      ("objects", bool(animation.objects))) if moves]
    verb = "moves" if parts == ["camera"] else "move"
    return f"{', '.join(parts)} {verb}" + ("" if animation.camera_moves else ", camera still")


def _run(rd: RunDirectory, scene: Scene, techniques, n: int, size, repeat: int, warmup: int,
         on_step: StepCallback | None) -> None:
    """Measure every frame and write the outputs into the run directory ``rd``."""
    lights = range(len(scene.lights))
    total = n * len(lights) * (1 + len(techniques)) * (repeat + warmup)
    times = frame_times(n)
    tracks: dict[tuple[str, int], _Track] = {}
    rows, notes = [], []
    prev_geom = prev_eval = None
    truth_spec = None
    covered_last = underlay = None
    moving = scene.animation is not None and scene.animation.camera_moves
    for tech in techniques:  # caches a technique keeps (Technique.keep) last from frame to frame
        tech.keep_across_frames = True
    try:
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
                        tech.begin_frame(temporal.FrameStep(k, li))  # state across frames, if it keeps any
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
                            track.strip.append(label_strip(_strip_picture(m.visibility, truth_m.visibility, evals[0],
                                                                          frame.covered), k, n))
                        track.prev_vis = m.visibility
                        rows.append(row)
                for tech in techniques:
                    notes.extend(f"frame {k}: {tech.spec()}: {x}" for x in dict.fromkeys(tech.notes))
                    tech.notes.clear()
                prev_geom, prev_eval = geom, evals
                covered_last = frame.covered.copy()
                if k == n - 1:
                    underlay = _shaded_truth(frame, [evaluator.truth(li).visibility for li in lights])
            finally:
                frame.release()
    finally:
        for tech in techniques:
            tech.keep_across_frames = False
            tech.begin_frame(None)  # the animation is over: no state carries into another run
            tech.forget()

    df = pd.DataFrame(rows)
    ordered = metrics.order_columns([c for c in df.columns if c not in ("frame", "t")], pass_order())
    df = df[["frame", "t"] + ordered]
    rd.table("frames.csv", df)
    summary = summary_table(df)
    rd.table("summary.csv", summary)

    where = ("accumulated in each frame's own pixels (screen space: the camera moves, so a pixel's surface "
             "changes from frame to frame)" if moving else "in the last frame's pixels (still camera)")
    caption = f"frame pairs flipping beyond the truth, {where}"
    images = []
    for tech in techniques:
        track = tracks[(tech.spec(), 0)]
        flicker = f"flicker_{track.stem}.png"
        strip = f"strip_{track.stem}.gif"
        flicker_picture(rd.path / flicker, track.flip_count, covered_last, underlay, tech.short_label(),
                        "flips / pixel")
        write_gif(rd.path / strip, track.strip)
        images.append({"label": tech.spec(), "title": tech.short_label(), "flicker": flicker, "strip": strip,
                         "flips_total": int(track.flip_count.sum()), "flips_max": int(track.flip_count.max())})

    record = {
        "scene": scene.describe(),
        "animation": scene.animation.describe() if scene.animation is not None else None,
        "still": scene.animation is None,
        "camera_moves": moving,
        "what_moves": _what_moves(scene.animation),
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
        "images": images,
        "notes": list(dict.fromkeys(notes)),
        **provenance.record(),
    }
    rd.record("animation.json", record)
    rd.page("animate.html", title=f"shadowlab animate: {scene.name}", renderer=record["renderer"],
            provenance=provenance_items(record), run=record, summary=summary.to_dict("records"), images=images,
            error_colors=error_legend(), temporal_error_decimals=TEMPORAL_ERROR_DECIMALS)


def _shaded_truth(frame: Frame, visibilities: list[np.ndarray]) -> np.ndarray:
    """The frame shaded with the truth's visibility of every light, sRGB-encoded RGB float
    (H, W, 3), background where uncovered: the scene under the flicker counts."""
    shading = ShadingPass(frame)
    try:
        return pictures.to_display(shading.shade(visibilities), frame.covered)
    finally:
        shading.release()

