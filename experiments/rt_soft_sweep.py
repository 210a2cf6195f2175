"""rt_soft sweep: error and flicker of few-sample ray-traced soft shadows against samples per
pixel, with and without each stage (ratio estimator, à-trous denoiser, temporal accumulation).

Stills — every soft scene (``shadowlab/scenes/soft_*.toml``; an animated one at its frame 0) at
--size against ``raytrace:samples=1024``: ``visibility_mae``, ``penumbra_mae`` and
``time_ms_median`` (median of 3 timed renders after 1 warm-up) of ``rt_soft`` at 1 / 4 / 16
samples in four configurations — plain average, ratio estimator, each with and without the
denoiser (``ratio``, ``iterations``; ``temporal_alpha=0``: nothing to accumulate in a still) —
plus ``contact_mae``: mean |V − G| over evaluated pixels within :data:`CONTACT_RADIUS` pixels
of a contact line (:meth:`shadowlab.measurement.pipeline.Evaluator.contact_lines`: where a caster touches
its receiver), the blur across contact edges of hard case SS3, on the scenes that have contact
lines (soft_contact_hardening above all).

Animation — ``shadowlab animate`` on ``soft_moving_caster`` (a crate slides under a rect light
while the camera pans): ``flip_rate`` and ``temporal_error`` (means over the frame pairs) and the
mean ``visibility_mae`` / ``penumbra_mae`` over frames, at 1 / 4 / 16 samples, with and without
temporal accumulation (``temporal_alpha`` = 0.8 / 0; without the neighbourhood clamp too,
``temporal_clamp=0``, to show the trail a moving shadow leaves) and the denoiser.

Writes results/rt_soft_sweep.csv (stills and animation rows, ``part`` says which), .png (error
against samples per scene; flicker against samples) and .json (provenance,
:func:`shadowlab.output.provenance.write_record`); the animation's run directory under
results/rt_soft_sweep/. About 5 minutes on a 2-core machine at 320x240.

    python experiments/rt_soft_sweep.py [--size 320x240] [--out results/rt_soft_sweep] [--frames N]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from shadowlab.gpu import gl
from shadowlab.output import provenance
from shadowlab.commands.animate import animate
from shadowlab.gpu.frame import Frame
from shadowlab.measurement.pipeline import Evaluator, measure
from shadowlab.scene import load_scene
from shadowlab.scenes import __path__ as _scenes_path
from shadowlab.techniques import from_spec

TRUTH = "raytrace:samples=1024"
SAMPLES = (1, 4, 16)
#: Still configurations: stage name → parameters (temporal accumulation off in stills).
STILL_STAGES = {
    "plain": "ratio=false,iterations=0,temporal_alpha=0",
    "ratio": "ratio=true,iterations=0,temporal_alpha=0",
    "plain+denoise": "ratio=false,temporal_alpha=0",
    "ratio+denoise": "ratio=true,temporal_alpha=0",
}
#: Animated configurations: stage name → parameters.
ANIMATED_STAGES = {
    "ratio": "iterations=0,temporal_alpha=0",
    "ratio+temporal(no clamp)": "iterations=0,temporal_alpha=0.8,temporal_clamp=0",
    "ratio+temporal": "iterations=0,temporal_alpha=0.8",
    "ratio+denoise": "temporal_alpha=0",
    "ratio+denoise+temporal": "temporal_alpha=0.8",
}
ANIMATED_SCENE = "soft_moving_caster"
#: Pixels around a contact line that ``contact_mae`` averages over.
CONTACT_RADIUS = 6


def soft_scenes() -> list[str]:
    """The shipped soft scenes, by name."""
    return sorted(p.stem for p in Path(_scenes_path[0]).glob("soft_*.toml"))


def spec(stage_params: str, samples: int) -> str:
    return f"rt_soft:samples={samples},{stage_params}"


def contact_region(evaluator: Evaluator) -> np.ndarray:
    """Evaluated pixels within CONTACT_RADIUS pixels of a contact line of light 0."""
    from scipy.ndimage import binary_dilation

    lines = evaluator.contact_lines(0)
    ev = evaluator.frame.evaluated_image(evaluator.frame.as_slot(0))
    if not lines.any():
        return np.zeros_like(ev)
    return binary_dilation(lines, iterations=CONTACT_RADIUS) & ev


def stills(size) -> pd.DataFrame:
    """Metric rows of every still configuration on every soft scene (light 0)."""
    rows = []
    for name in soft_scenes():
        frame = Frame(load_scene(name), *size)
        try:
            ev = Evaluator(frame, truth=from_spec(TRUTH))
            truth = ev.truth(0)
            near = contact_region(ev)
            for stage, params in STILL_STAGES.items():
                for n in SAMPLES:
                    m = measure(from_spec(spec(params, n)), frame, 0, repeat=3, warmup=1)
                    row = ev.row(m)
                    err = np.abs(m.visibility - truth.visibility)
                    rows.append({"part": "still", "scene": name, "stage": stage, "samples": n, "spec": m.technique.spec(),
                                 "visibility_mae": row["visibility_mae"], "penumbra_mae": row["penumbra_mae"],
                                 "contact_mae": float(err[near].mean()) if near.any() else float("nan"),
                                 "contact_pixels": int(near.sum()), "time_ms_median": row["time_ms_median"],
                                 "truth_stderr_max": row.get("truth_stderr_max")})
                    print(f"{name:24s} {stage:14s} N={n:2d} vis_mae={rows[-1]['visibility_mae']:.4f} "
                          f"pen_mae={rows[-1]['penumbra_mae']:.4f} contact_mae={rows[-1]['contact_mae']:.4f} "
                          f"{rows[-1]['time_ms_median']:.1f} ms", flush=True)
        finally:
            frame.release()
    return pd.DataFrame(rows)


def animated(size, frames, out: Path) -> pd.DataFrame:
    """Temporal and per-frame metrics of every animated configuration on ANIMATED_SCENE."""
    specs = {spec(params, n): (stage, n) for stage, params in ANIMATED_STAGES.items() for n in SAMPLES}
    run = animate(ANIMATED_SCENE, list(specs), frames=frames, size=size, out=out / ANIMATED_SCENE)
    summary = pd.read_csv(run / "summary.csv")
    per_frame = pd.read_csv(run / "frames.csv")
    rows = []
    for s in specs:
        label = from_spec(s).spec()
        (stage, n) = specs[s]
        srow = summary[summary["label"] == label].iloc[0]
        f = per_frame[per_frame["label"] == label]
        rows.append({"part": "animation", "scene": ANIMATED_SCENE, "stage": stage, "samples": n, "spec": label,
                     "visibility_mae": float(f["visibility_mae"].mean()), "penumbra_mae": float(f["penumbra_mae"].mean()),
                     "flip_rate": srow["flip_rate_mean"], "temporal_error": srow["temporal_error_mean"],
                     "time_ms_median": srow["time_ms_median"]})
    return pd.DataFrame(rows)


def plot(df: pd.DataFrame, path: Path, size) -> None:
    """Per still scene: visibility_mae (top) and penumbra_mae (bottom) against samples, a curve
    per stage; last column: the animation's temporal_error (top) and flip_rate (bottom)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    still = df[df["part"] == "still"]
    anim = df[df["part"] == "animation"]
    scenes = list(dict.fromkeys(still["scene"]))
    cols = len(scenes) + (1 if len(anim) else 0)
    fig, axes = plt.subplots(2, cols, figsize=(3.4 * cols, 6.4), dpi=100, squeeze=False)
    for c, scene in enumerate(scenes):
        for r, metric in enumerate(("visibility_mae", "penumbra_mae")):
            ax = axes[r, c]
            for stage, g in still[still["scene"] == scene].groupby("stage", sort=False):
                ax.plot(g["samples"], g[metric], marker="o", label=stage)
            ax.set_xscale("log", base=2)
            ax.set_yscale("log")
            ax.set_title(f"{scene}: {metric}", fontsize=8)
            ax.set_xlabel("samples / pixel", fontsize=7)
            ax.tick_params(labelsize=7)
    if len(anim):
        for r, metric in enumerate(("temporal_error", "flip_rate")):
            ax = axes[r, -1]
            for stage, g in anim.groupby("stage", sort=False):
                ax.plot(g["samples"], g[metric], marker="s", label=stage)
            ax.set_xscale("log", base=2)
            ax.set_title(f"{ANIMATED_SCENE}: {metric}", fontsize=8)
            ax.set_xlabel("samples / pixel", fontsize=7)
            ax.tick_params(labelsize=7)
            ax.legend(fontsize=6)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=7, loc="lower center", ncol=len(labels))
    fig.suptitle(f"rt_soft: error and flicker against samples per stage ({size[0]}x{size[1]}, truth {TRUTH})",
                 fontsize=9)
    fig.tight_layout(rect=(0, 0.05, 1, 0.96))
    fig.savefig(path)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="320x240", help="WxH")
    ap.add_argument("--frames", type=int, default=None, help="animation frames (default: the scene's own)")
    ap.add_argument("--out", default="results/rt_soft_sweep", help="output stem (CSV, PNG, JSON) and run folder")
    ap.add_argument("--skip-animation", action="store_true", help="stills only")
    args = ap.parse_args(argv)
    size = tuple(int(v) for v in args.size.lower().split("x"))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    parts = [stills(size)]
    if not args.skip_animation:
        parts.append(animated(size, args.frames, out))
    df = pd.concat(parts, ignore_index=True)
    df.to_csv(out.with_suffix(".csv"), index=False)
    plot(df, out.with_suffix(".png"), size)
    provenance.write_record(out, {"size": list(size), "truth": TRUTH, "samples": list(SAMPLES),
                                  "still_stages": STILL_STAGES, "animated_stages": ANIMATED_STAGES,
                                  "animated_scene": ANIMATED_SCENE, "frames": args.frames,
                                  "contact_radius_px": CONTACT_RADIUS, "seconds": round(time.time() - t0, 1),
                                  "load_average": list(__import__("os").getloadavg())})
    with pd.option_context("display.width", 220, "display.max_rows", 500):
        print(df.drop(columns=["spec"]).to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    print(f"renderer: {gl.renderer()}; wrote {out.with_suffix('.csv')}, .png and .json")


if __name__ == "__main__":
    main()
