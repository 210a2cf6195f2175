"""Soft-shadow sweep: error against time as each hard family averages N light samples, and PCSS.

On the soft hard cases (contact hardening, overlapping penumbrae, banding), every hard family
renders N = 1, 4, 16, 64, 256 times from stratified points of the rect light and averages
(``light_samples``), against PCSS with and without its blocker search; the truth samples the
light 1024 times per pixel. Plots ``visibility_mae`` (mean |V − G| over evaluated pixels)
and ``penumbra_mae`` (the same over the truth's penumbra, 0.02 < G < 0.98, where the truth's
own per-pixel standard error bound ``truth_stderr_max`` applies: drawn as a dotted line)
against ``time_ms_median`` (the N renders together), one curve per family, N marked on the
points. Writes results/soft_shadows_sweep.csv (the rows plotted) and .png.

The grid is the shipped suite ``shadowlab/suites/soft_shadows.toml`` (320x240, median of 3
timed runs after 1 warm-up); this script runs it as a study into
``<folder of --out>/study-soft_shadows`` (the directory ``shadowlab study soft_shadows`` uses, so
the two share one cache). About 5 minutes on a 2-core machine.

    python experiments/soft_shadows_sweep.py [--out results/soft_shadows_sweep] [--workers N] [--force]
"""
from __future__ import annotations

import pandas as pd

from shadowlab.study.experiment import run_experiment_suite

SUITE = "soft_shadows"
FAMILIES = ["shadow_map", "shadow_volume", "planar", "shadow_polygons"]  # plot order
COLUMNS = ["scene", "technique", "short_label", "param_light_samples", "visibility_mae", "visibility_rmse",
           "penumbra_mae", "penumbra_pixels", "umbra_error_rate", "lit_error_rate", "error_rate",
           "truth_stderr_max", "time_ms_median", "setup_ms"]


def sweep_rows(results: pd.DataFrame) -> pd.DataFrame:
    """The study's configuration rows (light 0), in scene, family, N order."""
    df = results[~results["reference"].astype(bool) & (results["light"] == 0)].copy()
    df["param_light_samples"] = pd.to_numeric(df.get("param_light_samples"), errors="coerce")
    rank = {t: i for i, t in enumerate(FAMILIES + ["pcss"])}
    df["_rank"] = df["technique"].map(lambda t: rank.get(t, len(rank)))
    df = df.sort_values(["scene", "_rank", "param_light_samples", "short_label"], kind="stable")
    return df.drop(columns="_rank").reset_index(drop=True)


def plot(df, path, size, renderer):
    """One column per scene: visibility_mae (top) and penumbra_mae (bottom) against time,
    log-log, a curve per family."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(dict.fromkeys(df["scene"]))
    fig, axes = plt.subplots(2, len(scenes), figsize=(5.5 * len(scenes), 9), dpi=100, squeeze=False)
    for col, scene in enumerate(scenes):
        for row, metric in enumerate(("visibility_mae", "penumbra_mae")):
            _panel(axes[row, col], df[df["scene"] == scene], scene, metric)
    axes[0, 0].legend(fontsize=7, loc="lower left")
    axes[1, 0].legend(fontsize=7, loc="lower left")
    fig.suptitle(f"soft shadows: error against time, N = light samples ({size[0]}x{size[1]}, {renderer})",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _panel(ax, d, scene, metric):
    """One scene's curves of ``metric`` against time."""
    for fam in FAMILIES:
        g = d[d["technique"] == fam].sort_values("param_light_samples")
        if g.empty:
            continue
        line, = ax.loglog(g["time_ms_median"], g[metric], "o-", label=fam)
        for _, r in g.iterrows():
            ax.annotate(f"{int(r['param_light_samples'])}", (r["time_ms_median"], r[metric]),
                        textcoords="offset points", xytext=(4, 3), fontsize=7, color=line.get_color())
    for _, r in d[d["technique"] == "pcss"].iterrows():
        ax.loglog([r["time_ms_median"]], [r[metric]], "*", markersize=12, label=r["short_label"])
    bound = float(d["truth_stderr_max"].max())
    if metric == "penumbra_mae" and bound > 0:
        ax.axhline(bound, color="grey", linestyle=":", linewidth=1, label="truth's stderr bound (per pixel)")
    ax.set_title(f"{scene}: {metric}", fontsize=10)
    ax.set_xlabel("time per frame, ms (median; N renders)")
    ax.set_ylabel(f"{metric} (mean |V − G|)")
    ax.grid(True, which="both", alpha=0.3)


def main():
    run = run_experiment_suite(SUITE, __doc__.splitlines()[0], "results/soft_shadows_sweep")
    df = sweep_rows(run.outcome.results)
    size = run.save_table(df, COLUMNS)
    out = run.out
    plot(df, out.with_suffix(".png"), size, run.renderer)
    with pd.option_context("display.width", 220, "display.max_rows", 200):
        print(df[["scene", "short_label", "visibility_mae", "penumbra_mae", "time_ms_median"]].to_string(
            index=False, float_format=lambda x: f"{x:.4g}"))
    print(run.summary_line(out.with_suffix(".csv"), out.with_suffix(".png")))


if __name__ == "__main__":
    main()
