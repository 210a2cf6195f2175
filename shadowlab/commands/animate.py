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
frame), ``animation.json`` (provenance, :mod:`shadowlab.output.provenance`; its ``notes`` hold
each distinct note once, with the frames it occurred on: "frames 0–23: <spec>: <note>",
:func:`shadowlab.util.format.group_notes`) and ``report.html`` (template ``animate.html``). These
names are a contract: users' scripts read them. The strips, GIFs and flicker maps are drawn by
:mod:`shadowlab.output.animation_pictures`.
"""
from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..measurement import budget
from ..measurement.scenes import load_measured_scene
from ..output import animation_pictures, pictures
from ..gpu import gl, timing
from ..evaluation import metrics, radiance, temporal
from ..output import provenance
from ..scene.animation import frame_times, scene_at
from ..gpu.frame import Frame
from ..measurement.pipeline import (
    Evaluator, StepCallback, build_techniques, check_lights, measure, pass_order, radiance_terms,
)
from ..output.pages import provenance_items
from ..output.rundir import GROUND_TRUTH_KEY, RunDirectory, error_legend, safe_name
from ..gpu.shading import ShadingPass
from ..util.format import group_notes
from ..util.sizes import ANIMATE_SIZE
from ..util.validation import RunError
from ..util.validation import check_size
from ..scene import Scene

#: Decimals of the temporal error (a visibility difference, not a rate) on the page and in the
#: CLI's table; a smaller nonzero value keeps two significant digits (:func:`shadowlab.util.format.fmt_fixed`).
TEMPORAL_ERROR_DECIMALS = 4


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
                     **_radiance_summary(g),
                     "time_ms_median": float(g["time_ms_median"].median())})
    return pd.DataFrame(rows)


def _radiance_summary(g: pd.DataFrame) -> dict:
    """The shaded image's columns of one configuration's frame rows (any light's: they are the
    configuration's): mean radiance error over frames and radiance flicker / selection change
    mean and max over frame pairs; {} for rows from before the radiance columns."""
    if "radiance_error" not in g.columns:
        return {}
    flicker = temporal.summarise(g["radiance_flicker"])
    change = temporal.summarise(g["selection_change_rate"])
    return {"radiance_error_mean": float(g["radiance_error"].mean()), "radiance_flicker_mean": flicker["mean"],
            "radiance_flicker_max": flicker["max"], "selection_change_mean": change["mean"],
            "selection_change_max": change["max"]}


def animate(scene_ref, specs: list[str], frames: int | None = None, size: tuple[int, int] = ANIMATE_SIZE,
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
    prev_geom = prev_eval = covered_prev = None
    radiance_prev: dict = {}  # per configuration: the previous frame's luminance image and kept masks
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
                frame_ms: dict[str, list] = {}    # this frame's measurements, per configuration, light by light
                frame_rows: dict[str, list] = {}  # and their rows
                for li in lights:
                    reproj = None if prev_geom is None else temporal.reproject(geom, prev_geom, evals[li], prev_eval[li])
                    step = None if on_step is None else (lambda what=f"frame {k + 1}/{n} truth light {li}":
                                                         on_step(what, total))
                    truth_m = evaluator.truth(li, step)
                    measured = [(GROUND_TRUTH_KEY, truth_m, True)]
                    for tech in techniques:
                        step = None if on_step is None else (lambda what=f"frame {k + 1}/{n} {tech.short_label()} light {li}":
                                                             on_step(what, total))
                        tech.begin_frame(temporal.FrameStep(k, li))  # state across frames, if it keeps any
                        measured.append((tech.spec(), measure(tech, frame, li, repeat, warmup, step), False))
                    truth_track = tracks.get((GROUND_TRUTH_KEY, li))
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
                            track.strip.append(animation_pictures.label_strip(animation_pictures.strip_picture(
                                m.visibility, truth_m.visibility, evals[0], frame.covered), k, n))
                        track.prev_vis = m.visibility
                        rows.append(row)
                        frame_ms.setdefault(key, []).append(m)
                        frame_rows.setdefault(key, []).append(row)
                covered_prev = _add_radiance(frame, frame_ms, frame_rows, evals, geom, prev_geom, covered_prev,
                                             radiance_prev)
                for tech in techniques:
                    notes.extend((k, f"{tech.spec()}: {x}") for x in dict.fromkeys(tech.notes))
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
            budget.forget_state(tech)  # nor a budget's reservoirs

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
        animation_pictures.flicker_picture(rd.path / flicker, track.flip_count, covered_last, underlay,
                                           tech.short_label(), "flips / pixel")
        animation_pictures.write_gif(rd.path / strip, track.strip)
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
        GROUND_TRUTH_KEY: truth_spec,
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
        # the scene's own notes (what reading it left out), then a note every frame repeats once:
        # "frames 0–23: spec: note"
        "notes": list(scene.notes) + group_notes(notes),
        **provenance.record(),
    }
    rd.record("animation.json", record)
    rd.page("animate.html", title=f"shadowlab animate: {scene.name}", renderer=record["renderer"],
            provenance=provenance_items(record), run=record, summary=summary.to_dict("records"), images=images,
            error_colors=error_legend(), temporal_error_decimals=TEMPORAL_ERROR_DECIMALS)


def _add_radiance(frame: Frame, frame_ms: dict, frame_rows: dict, evals: list, geom, prev_geom, covered_prev,
                  previous: dict):
    """Put the radiance columns (:mod:`shadowlab.evaluation.radiance`) on this frame's rows, per
    configuration (``frame_ms``/``frame_rows``: key → one measurement / row per light, the truth's
    under :data:`GROUND_TRUTH_KEY`), and from the second frame on the shaded image's temporal
    columns (:data:`shadowlab.evaluation.temporal.RADIANCE_TEMPORAL_COLUMNS`) against the previous
    frame's, kept in ``previous`` (updated). Returns this frame's covered mask (the next frame's
    ``covered_prev``)."""
    terms = radiance_terms(frame)
    truth = [m.visibility for m in frame_ms[GROUND_TRUTH_KEY]]
    truth_lum = radiance.luminance_image(frame, truth, None, terms)
    floor = radiance.DARK_FLOOR * max(float(np.nanmean(truth_lum)) if frame.covered.any() else 0.0, 1e-12)
    reproj = None if prev_geom is None else temporal.reproject(geom, prev_geom, frame.covered, covered_prev)
    truth_prev = previous.get(GROUND_TRUTH_KEY)  # read before the loop below replaces it with this frame's
    for key, ms in frame_ms.items():
        vis, weights = [m.visibility for m in ms], [m.weight for m in ms]
        image, per_light = radiance.radiance_columns(frame, vis, truth, weights, terms)
        lum = radiance.luminance_image(frame, vis, weights, terms)
        budgeted = any(m.budget_kept is not None for m in ms)
        kept = [m.budget_kept if m.budget_kept is not None else evals[li] for li, m in enumerate(ms)]
        if reproj is not None and key in previous and truth_prev is not None:
            prev_lum, prev_kept = previous[key]
            changes = {"radiance_flicker": temporal.radiance_pair(prev_lum, lum, truth_prev[0], truth_lum, reproj,
                                                                  floor),
                       # without a budget every light's shadow is computed everywhere: nothing to change
                       "selection_change_rate": (temporal.selection_change(prev_kept, kept, previous["_evals"], evals,
                                                                           reproj) if budgeted else 0.0)}
        else:
            changes = {c: float("nan") for c in temporal.RADIANCE_TEMPORAL_COLUMNS}
        for row, light in zip(frame_rows[key], per_light):
            row.update(image)
            row.update(light)
            row.update(changes)
        previous[key] = (lum, kept)
    previous["_evals"] = evals
    return frame.covered.copy()


def _shaded_truth(frame: Frame, visibilities: list[np.ndarray]) -> np.ndarray:
    """The frame shaded with the truth's visibility of every light, sRGB-encoded RGB float
    (H, W, 3), background where uncovered: the scene under the flicker counts."""
    shading = ShadingPass(frame)
    try:
        return pictures.to_display(shading.shade(visibilities), frame.covered)
    finally:
        shading.release()

