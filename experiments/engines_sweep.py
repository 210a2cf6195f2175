"""What engines ship (issue 39): shadow-map ray tracing's leaks against its extrapolation slope and
step count, and the hybrid's rays per pixel against its classifier's settings.

1. ``smrt`` on soft_overlap and soft_two_heights over ``slope`` (0 to UE's directional 5.0) x
   ``samples`` (2-16), beside pcss and exact_soft: visibility_mae, penumbra_mae and the umbra
   leak (``umbra_leak``: the light passed into the truth's umbra) — does UE's cvar warning ("higher
   values ... can introduce light leaks behind second occluders") hold, and Blender's "fewer
   steps leak less"?
2. ``hybrid_rt`` on the map hard cases over ``spread`` (0-2) x ``resolution`` (512, 2048) x
   ``cutoff`` (0, 8): error_rate, rays_per_pixel, classifier_error_pixels; the smallest budget that
   is exact per scene, against the truth's one ray per evaluated pixel.

Writes results/engines/smrt_sweep.csv, results/engines/hybrid_sweep.csv and
results/engines/hybrid_exact.csv. About ten minutes at 320x240 on a 2-core machine.

    python experiments/engines_sweep.py [--out results/engines] [--size 320x240] [--only smrt|hybrid]
"""
from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd
from tqdm import tqdm

from shadowlab.measurement.pipeline import measure_configs

SOFT = ["soft_overlap", "soft_two_heights"]
SLOPES = [0.0, 0.05, 0.5, 5.0]
SAMPLES = [2, 4, 8, 16]
HARD = ["box_on_plane", "sm_contact", "sm_thin", "sm_wires", "sm_aliasing", "sm_far_origin", "sv_soup"]
SMRT_COLUMNS = ["scene", "short_label", "param_slope", "param_samples", "visibility_mae", "penumbra_mae",
                "umbra_error_rate", "umbra_leak", "false_lit_rate", "light_bleeding", "time_ms_median"]
HYBRID_COLUMNS = ["scene", "light", "short_label", "param_resolution", "param_spread", "param_cutoff", "error_rate",
                  "false_lit_pixels", "false_shadow_pixels", "rays_per_pixel", "classifier_sure_pixels",
                  "classifier_error_pixels", "time_ms_median"]


def smrt_rows(size) -> pd.DataFrame:
    """SMRT over slope x samples, with pcss and exact_soft, on the soft scenes."""
    specs = [f"smrt:slope={s},samples={n}" for s in SLOPES for n in SAMPLES] + ["pcss", "exact_soft"]
    rows = [measure_configs(scene, specs, size=size) for scene in tqdm(SOFT, desc="smrt")]
    df = pd.concat(rows, ignore_index=True)
    return df[~df["reference"].astype(bool)][[c for c in SMRT_COLUMNS if c in df.columns]]


def hybrid_rows(size) -> pd.DataFrame:
    """hybrid_rt over its classifier's settings on the map hard cases."""
    specs = [f"hybrid_rt:resolution={r},spread={s},cutoff={c}" for r in (512, 2048) for s in (0, 1, 2) for c in (0, 8)]
    rows = [measure_configs(scene, specs, size=size) for scene in tqdm(HARD, desc="hybrid")]
    df = pd.concat(rows, ignore_index=True)
    return df[~df["reference"].astype(bool)][[c for c in HYBRID_COLUMNS if c in df.columns]]


def cheapest_exact(df: pd.DataFrame) -> pd.DataFrame:
    """Per scene and light, the configuration with the fewest rays per pixel whose error is 0."""
    exact = df[df["error_rate"] == 0].sort_values("rays_per_pixel")
    best = exact.groupby(["scene", "light"], as_index=False).first()
    return best[["scene", "light", "short_label", "rays_per_pixel"]]


def main() -> None:
    """Measure both sweeps and write the tables into --out."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="results/engines")
    ap.add_argument("--size", default="320x240")
    ap.add_argument("--only", choices=("smrt", "hybrid"), help="run one of the two sweeps")
    args = ap.parse_args()
    size = tuple(int(v) for v in args.size.lower().split("x"))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.only in (None, "smrt"):
        smrt = smrt_rows(size)
        smrt.to_csv(out / "smrt_sweep.csv", index=False)
        print(smrt.to_string(index=False))
    if args.only in (None, "hybrid"):
        hybrid = hybrid_rows(size)
        hybrid.to_csv(out / "hybrid_sweep.csv", index=False)
        exact = cheapest_exact(hybrid)
        exact.to_csv(out / "hybrid_exact.csv", index=False)
        print(exact.to_string(index=False))


if __name__ == "__main__":
    main()
