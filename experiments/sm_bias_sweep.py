"""Bias sweep: the acne / peter-panning trade-off of every shadow-map variant.

On the grazing case (light 3 degrees above the floor) and the contact case (casters resting on
the floor), with the classic fit over every visible receiver, 2048² maps: each biased variant
is swept over its own parameter — constant ``bias``, ``slope_scale`` (bias 0), ``normal_offset``
(bias 0), the ``dual`` offset cap — and second-depth and midpoint (no parameter) are drawn as
reference lines. Reports false-shadow rate (acne), false-lit rate (leaks) and the contact gap.
Writes results/sm_bias_sweep.csv and results/sm_bias_sweep.png.

    python experiments/sm_bias_sweep.py [--size 320x240] [--resolution 2048]
    (the figures in earlier notes used --size 640x480; a JSON record of provenance is written beside the CSV)
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from shadowlab import gl, provenance
from shadowlab.frame import Frame
from shadowlab.cli import parse_size
from shadowlab.pipeline import measure_configs
from shadowlab.scene import load_scene

SWEEPS = {  # variant: (parameter, values, fixed parameters)
    "constant": ("bias", [0.0, 0.0001, 0.0002, 0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05], ""),
    "slope": ("slope_scale", [0.0, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0], "bias=0"),
    "normal_offset": ("normal_offset", [0.0, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0], "bias=0"),
    "dual": ("bias", [0.0001, 0.0005, 0.001, 0.002, 0.005, 0.01, 0.05], ""),
}
FIXED = ["second_depth", "midpoint"]
SCENES = ["sm_grazing", "sm_contact"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="320x240")
    ap.add_argument("--resolution", type=int, default=2048)
    ap.add_argument("--out", default="results/sm_bias_sweep")
    args = ap.parse_args()
    size = parse_size(args.size)
    frames = []
    for scene in SCENES:
        frame = Frame(load_scene(scene), *size)
        specs, meta = [], []
        for variant, (param, values, fixed) in SWEEPS.items():
            for v in values:
                extra = f",{fixed}" if fixed else ""
                specs.append(f"shadow_map:variant={variant},{param}={v},fit=receivers,resolution={args.resolution}{extra}")
                meta.append((variant, param, v))
        for variant in FIXED:
            specs.append(f"shadow_map:variant={variant},fit=receivers,resolution={args.resolution}")
            meta.append((variant, "", np.nan))
        print(f"{scene}: {len(specs)} configurations", flush=True)
        df = measure_configs(scene, specs, frame=frame)
        df = df[~df["reference"]].reset_index(drop=True)
        df["variant"], df["swept"], df["value"] = zip(*meta)
        frames.append(df)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    all_rows = pd.concat(frames)
    all_rows.to_csv(out.with_suffix(".csv"), index=False)
    provenance.write_record(out, {"size": list(size), "resolution": args.resolution})
    plot(all_rows, out.with_suffix(".png"), args.resolution, size)
    cols = ["scene", "variant", "swept", "value", "false_shadow_rate", "false_lit_rate", "contact_gap_px"]
    with pd.option_context("display.width", 200, "display.max_rows", 200):
        print(all_rows[cols].to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    print(f"renderer: {gl.renderer()}; wrote {out.with_suffix('.csv')} and {out.with_suffix('.png')}")


def plot(df, path, resolution, size):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(SCENES), len(SWEEPS), figsize=(16, 7.5), dpi=100, squeeze=False)
    for r, scene in enumerate(SCENES):
        d = df[df["scene"] == scene]
        for c, (variant, (param, _, fixed)) in enumerate(SWEEPS.items()):
            ax = axes[r, c]
            g = d[d["variant"] == variant].sort_values("value")
            x = g["value"].to_numpy()
            x = np.where(x == 0, np.nan, x)
            ax.semilogx(x, 100 * g["false_shadow_rate"], "o-", color="tab:orange", label="false shadow (acne)")
            ax.semilogx(x, 100 * g["false_lit_rate"], "s-", color="tab:blue", label="false lit (leaks)")
            for v, style in zip(FIXED, (":", "--")):
                row = d[d["variant"] == v].iloc[0]
                ax.axhline(100 * row["false_lit_rate"], color="tab:blue", ls=style, lw=0.8, label=f"{v}: false lit")
                ax.axhline(100 * row["false_shadow_rate"], color="tab:orange", ls=style, lw=0.8, label=f"{v}: false shadow")
            ax.set_yscale("symlog", linthresh=0.01)
            ax.set_ylim(bottom=0)
            ax.set_xlabel(f"{param}" + (f"  ({fixed})" if fixed else "") + ("  [window depth]" if param == "bias" else "  [texels]" if param == "normal_offset" else ""))
            ax.set_ylabel("% of truly lit / truly shadowed pixels")
            ax.set_title(f"{scene}: variant={variant}", fontsize=10)
            ax.grid(alpha=0.3, which="both")
            if scene == "sm_contact":
                ax2 = ax.twinx()
                ax2.semilogx(x, g["contact_gap_px"], "^-", color="tab:green", label="contact gap (px)")
                ax2.set_ylabel("contact gap, px", color="tab:green")
            if r == 0 and c == 0:
                ax.legend(fontsize=6, loc="best")
    fig.suptitle(f"Shadow-map bias sweep: acne (false shadow) against leaks and peter-panning — "
                 f"{resolution}² maps fitted to all visible receivers, {size[0]}x{size[1]}, {gl.renderer()}", fontsize=11)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


if __name__ == "__main__":
    main()
