"""Depth-precision table: 16-, 24- and 32-bit (float) shadow maps against the near plane.

Spot-light scenes at the origin (spot_scene) and 10^4 units away (sm_far_origin), the near
plane fitted to the casters or forced to 10^-2 and 10^-3; slope-scaled bias only (bias 0) so the
depth format itself is what is measured. Writes results/sm_depth_precision.csv and a markdown
table results/sm_depth_precision.md.

    python experiments/sm_depth_precision.py [--size 320x240]
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

NEARS = [0.0, 0.01, 0.001]
BITS = [16, 24, 32]
SCENES = ["spot_scene", "sm_far_origin"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="320x240")
    ap.add_argument("--out", default="results/sm_depth_precision")
    args = ap.parse_args()
    size = parse_size(args.size)
    rows = []
    for scene in SCENES:
        frame = Frame(load_scene(scene), *size)
        specs = [f"shadow_map:variant=slope,bias=0,near={n},depth_bits={b}" for n in NEARS for b in BITS]
        df = measure_configs(scene, specs, frame=frame)
        rows.append(df[~df["reference"]])
    df = pd.concat(rows)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out.with_suffix(".csv"), index=False)
    provenance.write_record(out, {"size": list(size)})
    lines = [f"# Shadow-map depth precision ({size[0]}x{size[1]}, 2048², slope-scaled bias only; {gl.renderer()})", "",
             "false-shadow rate (acne) / false-lit rate, % — near = 'fitted': in front of every caster point the map sees (axial depth)", ""]
    for scene in SCENES:
        d = df[df["scene"] == scene]
        lines += [f"## {scene}", "", "| near | " + " | ".join(f"{b}-bit" for b in BITS) + " |",
                  "|---|" + "---|" * len(BITS)]
        for n in NEARS:
            cells = []
            for b in BITS:
                r = d[(d["param_near"] == n) & (d["param_depth_bits"] == b)].iloc[0]
                cells.append(f"{100 * r['false_shadow_rate']:.3g} / {100 * r['false_lit_rate']:.3g}")
            lines.append(f"| {'fitted' if n == 0 else n} | " + " | ".join(cells) + " |")
        lines.append("")
    out.with_suffix(".md").write_text("\n".join(lines))
    print("\n".join(lines))
    print(f"wrote {out.with_suffix('.csv')} and {out.with_suffix('.md')}")


if __name__ == "__main__":
    main()
