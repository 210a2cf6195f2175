"""Depth-precision table: 16-, 24- and 32-bit (float) shadow maps against the near plane.

Spot-light scenes at the origin (spot_scene) and 10^4 units away (sm_far_origin), the near
plane fitted to the casters or forced to 10^-2 and 10^-3; slope-scaled bias only (bias 0) so the
depth format itself is what is measured. Writes results/sm_depth_precision.csv (the rows in the
table) and a markdown table results/sm_depth_precision.md.

The grid is the shipped suite ``shadowlab/suites/sm_depth_precision.toml`` (320x240, 2048² maps);
this script runs it as a study into ``<folder of --out>/study-sm_depth_precision`` — the
directory ``shadowlab study sm_depth_precision`` uses by default, so the two share one cache and
whichever runs second only reads it — and writes this table from the study's results.
``shadowlab study sm_depth_precision`` gives the full study report.

    python experiments/sm_depth_precision.py [--out results/sm_depth_precision] [--workers N] [--force]
    (the suite fixes the size: the former --size flag is gone; the 640x480 figures in earlier
    notes need a copy of the suite with size = [640, 480], run with ``shadowlab study COPY.toml``.
    A JSON record of provenance is written beside the CSV)
"""
from __future__ import annotations

import pandas as pd

from shadowlab.study.experiment import run_experiment_suite

SUITE = "sm_depth_precision"
SCENES = ["spot_scene", "sm_far_origin"]


def table_rows(results: pd.DataFrame) -> pd.DataFrame:
    """The study's shadow-map rows (light 0), in scene, near (fitted first), depth-bits order."""
    df = results[~results["reference"].astype(bool) & (results["technique"] == "shadow_map")
                 & (results["light"] == 0)].copy()
    df["param_near"] = df["param_near"].astype(float)
    df["param_depth_bits"] = df["param_depth_bits"].astype(int)
    # fitted (near = 0) first, then the forced planes from the farthest to the closest
    df = df.sort_values(["scene", "param_near", "param_depth_bits"], ascending=[True, False, True], kind="stable",
                        key=lambda s: s.map(SCENES.index) if s.name == "scene"
                        else s.where(s != 0, float("inf")) if s.name == "param_near" else s)
    return df.reset_index(drop=True)


def main():
    run = run_experiment_suite(SUITE, __doc__.splitlines()[0], "results/sm_depth_precision")
    df = table_rows(run.outcome.results)
    size = run.save_table(df)
    resolutions = sorted(df["param_resolution"].astype(int).unique())
    renderer, out = run.renderer, run.out
    nears = list(dict.fromkeys(df["param_near"]))
    bits = sorted(df["param_depth_bits"].unique())
    res = "/".join(f"{r}²" for r in resolutions)
    lines = [f"# Shadow-map depth precision ({size[0]}x{size[1]}, {res}, slope-scaled bias only; {renderer})", "",
             "false-shadow rate (acne) / false-lit rate, % — near = 'fitted': in front of every caster point the map sees (axial depth)", ""]
    for scene in SCENES:
        d = df[df["scene"] == scene]
        lines += [f"## {scene}", "", "| near | " + " | ".join(f"{b}-bit" for b in bits) + " |",
                  "|---|" + "---|" * len(bits)]
        for n in nears:
            cells = []
            for b in bits:
                r = d[(d["param_near"] == n) & (d["param_depth_bits"] == b)].iloc[0]
                cells.append(f"{100 * r['false_shadow_rate']:.3g} / {100 * r['false_lit_rate']:.3g}")
            lines.append(f"| {'fitted' if n == 0 else f'{n:g}'} | " + " | ".join(cells) + " |")
        lines.append("")
    out.with_suffix(".md").write_text("\n".join(lines))
    print("\n".join(lines))
    print(run.summary_line(out.with_suffix(".csv"), out.with_suffix(".md")))


if __name__ == "__main__":
    main()
