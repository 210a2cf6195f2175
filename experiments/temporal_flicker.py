"""Temporal stability: flicker of shadow-map configurations on the animated hard cases.

Runs ``shadowlab animate`` (:func:`shadowlab.commands.animate.animate`) on

- ``tm_rotating_sun`` (the sun turns 4.1° over 24 frames, still camera): one 2048² map, cascades
  with and without stabilisation (bounding-sphere fit + texel snapping), SDSM, LiSPSM and shadow
  volumes (exact: the floor of the flip rate);
- ``tm_camera_dolly`` (the camera dollies 20 units, fixed sun): the same, cascades also with
  blending;

and writes, per scene and configuration, the mean / p95 / max of ``flip_rate`` (share of validly
reprojected pixels whose thresholded visibility changes between consecutive frames while the
truth's does not) and the mean ``temporal_error`` (mean |ΔV − ΔG|) to
results/temporal_flicker.csv, a bar chart to results/temporal_flicker.png, and each run's
directory (frames.csv, heat maps, GIF strips, report.html) under results/temporal_flicker/.

    python experiments/temporal_flicker.py [--size 320x240] [--frames N] [--out results/temporal_flicker]
"""
from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from shadowlab.gpu import gl
from shadowlab.output import provenance
from shadowlab.commands.animate import animate

CASES = {
    "tm_rotating_sun": ["shadow_map", "cascaded_map", "cascaded_map:stabilize=false", "cascaded_map:fit=sdsm",
                        "lispsm", "shadow_volume"],
    "tm_camera_dolly": ["shadow_map", "cascaded_map", "cascaded_map:stabilize=false",
                        "cascaded_map:blend=true", "cascaded_map:fit=sdsm", "lispsm", "shadow_volume"],
}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="320x240", help="WxH")
    ap.add_argument("--frames", type=int, default=None, help="frames (default: each scene's own)")
    ap.add_argument("--out", default="results/temporal_flicker", help="output stem (CSV, PNG) and run folder")
    args = ap.parse_args(argv)
    size = tuple(int(v) for v in args.size.lower().split("x"))
    out = Path(args.out)
    rows = []
    for scene, specs in CASES.items():
        run = animate(scene, specs, frames=args.frames, size=size, out=out / scene)
        summary = pd.read_csv(run / "summary.csv")
        summary.insert(0, "scene", scene)
        rows.append(summary)
        print(f"{scene}: {run}")
    df = pd.concat(rows, ignore_index=True)
    df.to_csv(out.with_suffix(".csv"), index=False)
    plot(df, out.with_suffix(".png"), size)
    provenance.write_record(out, {"size": list(size), "frames": args.frames, "cases": CASES})
    cols = [c for c in ["scene", "label", "light", "flip_rate_mean", "flip_rate_p95", "flip_rate_max",
                        "temporal_error_mean", "error_rate_mean"] if c in df.columns]
    with pd.option_context("display.width", 220, "display.max_colwidth", 60):
        print(df[cols].to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    print(f"renderer: {gl.renderer()}; wrote {out.with_suffix('.csv')} and {out.with_suffix('.png')}")


def plot(df, path, size):
    """One panel per scene: mean flip rate per configuration (p95 as a tick)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(dict.fromkeys(df["scene"]))
    fig, axes = plt.subplots(1, len(scenes), figsize=(7 * len(scenes), 4.5), dpi=100, squeeze=False)
    label = "label" if "label" in df.columns else df.columns[1]
    for ax, scene in zip(axes[0], scenes):
        d = df[df["scene"] == scene]
        y = range(len(d))
        ax.barh(list(y), d["flip_rate_mean"], color="tab:blue", label="mean")
        if "flip_rate_p95" in d.columns:
            ax.plot(d["flip_rate_p95"], list(y), "k|", markersize=12, label="p95 over frame pairs")
        ax.set_yticks(list(y))
        ax.set_yticklabels(d[label], fontsize=7)
        ax.invert_yaxis()
        ax.set_xlabel("flip_rate (share of pixels flipping while the truth does not)")
        ax.set_title(scene, fontsize=10)
        ax.grid(True, axis="x", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"temporal flicker ({size[0]}x{size[1]}, {gl.renderer()})", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


if __name__ == "__main__":
    main()
