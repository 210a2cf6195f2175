"""Resolution sweep: boundary error and time against shadow-map resolution, per variant.

On the perspective-aliasing case (a wide spot cone, the camera close to a receiver far from the
light) and the spot scene, maps from 128² to 4096²: ``boundary_error_px`` (mean distance of the
technique's shadow boundary to the truth's) and the median time of the technique's passes.
Writes results/sm_resolution_sweep.csv (the rows plotted) and .png.

The grid is the shipped suite ``shadowlab/suites/sm_resolution.toml`` (320x240, median of 3
timed runs after 1 warm-up); this script runs it as a study into
``<folder of --out>/study-sm_resolution`` — the directory ``shadowlab study sm_resolution`` uses
by default, so the two share one cache and whichever runs second only reads it — and draws this
figure from the study's results. Times come from the study's separate timing phase (each
configuration rendered alone, on every core). ``shadowlab study sm_resolution`` gives the full
study report.

    python experiments/sm_resolution_sweep.py [--out results/sm_resolution_sweep] [--workers N] [--force]
    (the suite fixes the size and the repeats: the former --size/--repeat flags are gone; the
    640x480 figures in earlier notes need a copy of the suite with size = [640, 480], run with
    ``shadowlab study COPY.toml``. A JSON record of provenance is written beside the CSV)
"""
from __future__ import annotations

import pandas as pd

from shadowlab.study.experiment import run_experiment_suite

SUITE = "sm_resolution"
SCENES = ["sm_aliasing", "spot_scene"]
VARIANTS = ["constant", "slope", "normal_offset", "second_depth", "midpoint"]  # plot order


def sweep_rows(results: pd.DataFrame) -> pd.DataFrame:
    """The study's shadow-map rows (light 0), in scene, variant, resolution order."""
    df = results[~results["reference"].astype(bool) & (results["technique"] == "shadow_map")
                 & (results["light"] == 0)].copy()
    df["param_resolution"] = df["param_resolution"].astype(int)
    rank = {v: i for i, v in enumerate(VARIANTS)}
    df = df.sort_values(["scene", "param_variant", "param_resolution"], kind="stable",
                        key=lambda s: s.map(SCENES.index) if s.name == "scene"
                        else s.map(lambda v: rank.get(v, len(rank))) if s.name == "param_variant" else s)
    return df.reset_index(drop=True)


def main():
    run = run_experiment_suite(SUITE, __doc__.splitlines()[0], "results/sm_resolution_sweep")
    df = sweep_rows(run.outcome.results)
    size = run.save_table(df)
    out = run.out
    plot(df, out.with_suffix(".png"), size, run.renderer)
    cols = ["scene", "param_variant", "param_resolution", "boundary_error_px", "error_rate", "time_ms_median"]
    with pd.option_context("display.width", 200, "display.max_rows", 200):
        print(df[cols].to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    print(run.summary_line(out.with_suffix(".csv"), out.with_suffix(".png")))


def plot(df, path, size, renderer):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    resolutions = sorted(df["param_resolution"].unique())
    variants = [v for v in VARIANTS if v in set(df["param_variant"])]
    variants += [v for v in df["param_variant"].unique() if v not in variants]
    fig, axes = plt.subplots(2, len(SCENES), figsize=(12, 8), dpi=100, squeeze=False)
    for c, scene in enumerate(SCENES):
        d = df[df["scene"] == scene]
        for v in variants:
            g = d[d["param_variant"] == v].sort_values("param_resolution")
            axes[0, c].loglog(g["param_resolution"], g["boundary_error_px"], "o-", label=v)
            axes[1, c].loglog(g["param_resolution"], g["time_ms_median"], "o-", label=v)
        axes[0, c].set_title(f"{scene}: boundary error", fontsize=10)
        axes[0, c].set_ylabel("mean distance to the true shadow boundary, px")
        axes[1, c].set_title(f"{scene}: time of the technique's passes", fontsize=10)
        axes[1, c].set_ylabel("ms (median)")
        for ax in axes[:, c]:
            ax.set_xticks(resolutions, [str(r) for r in resolutions])
            ax.minorticks_off()
            ax.set_xlabel("shadow map resolution (texels per side)")
            ax.grid(alpha=0.3, which="both")
            ax.legend(fontsize=7)
    fig.suptitle(f"Shadow-map resolution sweep — {size[0]}x{size[1]}, {renderer} (wall clock)", fontsize=11)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


if __name__ == "__main__":
    main()
