"""Resolution sweep: boundary error and time against shadow-map resolution, per variant.

On the perspective-aliasing case (a wide spot cone, the camera close to a receiver far from the
light) and the spot scene, maps from 128² to 4096²: ``boundary_error_px`` (mean distance of the
technique's shadow boundary to the truth's) and the median time of the technique's passes.
Writes results/sm_resolution_sweep.csv and .png.

    python experiments/sm_resolution_sweep.py [--size 320x240] [--repeat 3]
    (the figures in earlier notes used --size 640x480; a JSON record of provenance is written beside the CSV)
"""
from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from shadowlab import gl, provenance
from shadowlab.frame import Frame
from shadowlab.cli import parse_size
from shadowlab.pipeline import measure_configs
from shadowlab.scene import load_scene

RESOLUTIONS = [128, 256, 512, 1024, 2048, 4096]
VARIANTS = ["constant", "slope", "normal_offset", "second_depth", "midpoint"]
SCENES = ["sm_aliasing", "spot_scene"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="320x240")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", default="results/sm_resolution_sweep")
    args = ap.parse_args()
    size = parse_size(args.size)
    frames = []
    for scene in SCENES:
        frame = Frame(load_scene(scene), *size)
        specs = [f"shadow_map:variant={v},resolution={r}" for v in VARIANTS for r in RESOLUTIONS]
        print(f"{scene}: {len(specs)} configurations", flush=True)
        df = measure_configs(scene, specs, frame=frame, repeat=args.repeat, warmup=1)
        frames.append(df[~df["reference"]])
    df = pd.concat(frames)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out.with_suffix(".csv"), index=False)
    provenance.write_record(out, {"size": list(size), "timing": f"wall clock around ctx.finish(), median of {args.repeat}"})
    plot(df, out.with_suffix(".png"), size)
    cols = ["scene", "param_variant", "param_resolution", "boundary_error_px", "error_rate", "time_ms_median"]
    with pd.option_context("display.width", 200, "display.max_rows", 200):
        print(df[cols].to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    print(f"renderer: {gl.renderer()}; wrote {out.with_suffix('.csv')} and {out.with_suffix('.png')}")


def plot(df, path, size):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, len(SCENES), figsize=(12, 8), dpi=100, squeeze=False)
    for c, scene in enumerate(SCENES):
        d = df[df["scene"] == scene]
        for v in VARIANTS:
            g = d[d["param_variant"] == v].sort_values("param_resolution")
            axes[0, c].loglog(g["param_resolution"], g["boundary_error_px"], "o-", label=v)
            axes[1, c].loglog(g["param_resolution"], g["time_ms_median"], "o-", label=v)
        axes[0, c].set_title(f"{scene}: boundary error", fontsize=10)
        axes[0, c].set_ylabel("mean distance to the true shadow boundary, px")
        axes[1, c].set_title(f"{scene}: time of the technique's passes", fontsize=10)
        axes[1, c].set_ylabel("ms (median)")
        for ax in axes[:, c]:
            ax.set_xticks(RESOLUTIONS, [str(r) for r in RESOLUTIONS])
            ax.minorticks_off()
            ax.set_xlabel("shadow map resolution (texels per side)")
            ax.grid(alpha=0.3, which="both")
            ax.legend(fontsize=7)
    fig.suptitle(f"Shadow-map resolution sweep — {size[0]}x{size[1]}, {gl.renderer()} (wall clock)", fontsize=11)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


if __name__ == "__main__":
    main()
