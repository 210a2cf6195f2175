"""Soft-shadow sweep: error against time for every soft technique on the soft hard cases.

On the six soft hard cases (contact hardening, overlapping penumbrae, banding, a large light
close above, a light straddling the receiver's horizon, two blocker heights), every hard family
renders N = 1, 4, 16, 64 times from stratified points of the rect light and averages
(``light_samples``); ``rt_soft`` traces 1, 4, 16 rays per pixel with and without its à-trous
denoiser; PCSS, moment soft shadows, penumbra wedges and the exact technique run with their
defaults and the toggles that show their known artefacts; the truth samples the light 1024
times per pixel. Plots ``visibility_mae`` (mean |V − G| over evaluated pixels) and
``penumbra_mae`` (the same over the truth's penumbra, 0.02 < G < 0.98) against
``time_ms_median`` (the N renders together), a curve per sample-count configuration (N marked
on the points), a marker per other configuration, and the truth's own per-pixel standard error
bound ``truth_stderr_max`` as a dotted line. Writes results/soft_shadows_sweep.csv (the rows
plotted), .png, and .md (penumbra_mae and time per configuration and scene).

The grid is the shipped suite ``shadowlab/suites/soft_shadows.toml`` (320x240, median of 3
timed runs after 1 warm-up); this script runs it as a study into
``<folder of --out>/study-soft_shadows`` (the directory ``shadowlab study soft_shadows`` uses, so
the two share one cache). About 4 minutes on a 2-core machine.

    python experiments/soft_shadows_sweep.py [--out results/soft_shadows_sweep] [--workers N] [--force]
"""
from __future__ import annotations

import pandas as pd

from shadowlab.study.experiment import run_experiment_suite
from shadowlab.techniques import REGISTRY

SUITE = "soft_shadows"
#: Hard families averaged over light samples (``light_samples``), in plot order.
FAMILIES = ["shadow_map", "shadow_volume", "planar", "shadow_polygons"]
#: Techniques drawn as curves over a sample count: technique → its count parameter.
COUNTS = {**{f: "light_samples" for f in FAMILIES}, "rt_soft": "samples"}
#: Techniques drawn as one point per configuration (no count), in legend order.
POINTS = ["exact_soft", "pcss", "moment_soft", "penumbra_wedges"]
COLUMNS = ["scene", "technique", "short_label", "count", "visibility_mae", "visibility_rmse",
           "penumbra_mae", "penumbra_pixels", "umbra_error_rate", "lit_error_rate", "error_rate",
           "flip_mean", "ssim", "truth_stderr_max", "time_ms_median", "setup_ms"]


def curve_label(row) -> str:
    """A configuration's curve: its short label without the count parameter (N is on the points)."""
    param = COUNTS.get(row["technique"])
    if not param:
        return row["short_label"]
    tech, _, rest = str(row["short_label"]).partition(":")
    kept = [kv for kv in rest.split(",") if kv and not kv.startswith(f"{param}=")]
    return tech + (":" + ",".join(kept) if kept else "")


def sweep_rows(results: pd.DataFrame) -> pd.DataFrame:
    """The study's configuration rows (light 0) with ``count`` (the sample count of a curve's
    technique, NaN for the others) and ``curve``, in scene, technique, curve, count order."""
    df = results[~results["reference"].astype(bool) & (results["light"] == 0)].copy()
    df["count"] = [pd.to_numeric(r.get(f"param_{COUNTS[r['technique']]}"), errors="coerce")
                   if r["technique"] in COUNTS else float("nan") for _, r in df.iterrows()]
    df["curve"] = [curve_label(r) for _, r in df.iterrows()]
    rank = {t: i for i, t in enumerate(FAMILIES + ["rt_soft"] + POINTS)}
    df["_rank"] = df["technique"].map(lambda t: rank.get(t, len(rank)))
    df = df.sort_values(["scene", "_rank", "curve", "count", "short_label"], kind="stable")
    return df.drop(columns="_rank").reset_index(drop=True)


def plot(df, path, size, renderer):
    """One column per scene: visibility_mae (top) and penumbra_mae (bottom) against time,
    log-log, a curve per family and sample-count technique, a marker per other technique."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(dict.fromkeys(df["scene"]))
    fig, axes = plt.subplots(2, len(scenes), figsize=(4.6 * len(scenes), 9), dpi=100, squeeze=False)
    for col, scene in enumerate(scenes):
        for row, metric in enumerate(("visibility_mae", "penumbra_mae")):
            _panel(axes[row, col], df[df["scene"] == scene], scene, metric)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=7, loc="lower center", ncol=min(6, len(labels)))
    fig.suptitle(f"soft shadows: error against time, N = samples ({size[0]}x{size[1]}, {renderer})",
                 fontsize=10)
    fig.tight_layout(rect=(0, 0.06, 1, 0.97))
    fig.savefig(path)
    plt.close(fig)


def _panel(ax, d, scene, metric):
    """One scene's curves and points of ``metric`` against time."""
    for curve, g in d[d["technique"].isin(list(COUNTS))].groupby("curve", sort=False):
        g = g.sort_values("count")
        line, = ax.loglog(g["time_ms_median"], g[metric].clip(lower=1e-5), "o-", label=curve, markersize=4)
        for _, r in g.iterrows():
            ax.annotate(f"{int(r['count'])}", (r["time_ms_median"], max(r[metric], 1e-5)),
                        textcoords="offset points", xytext=(4, 3), fontsize=7, color=line.get_color())
    for _, r in d[~d["technique"].isin(list(COUNTS))].iterrows():
        # the technique's own colour and marker; its default filled, a toggle hollow
        style = REGISTRY[r["technique"]].STYLE
        toggle = r["short_label"] != r["technique"]
        ax.loglog([r["time_ms_median"]], [max(r[metric], 1e-5)], style.marker, markersize=9,
                  color=style.color, markerfacecolor="none" if toggle else style.color, markeredgewidth=1.5,
                  label=r["short_label"])
        if toggle:  # which toggle: its parameters beside the hollow marker
            ax.annotate(str(r["short_label"]).partition(":")[2], (r["time_ms_median"], max(r[metric], 1e-5)),
                        textcoords="offset points", xytext=(5, -8), fontsize=6, color=style.color)
    bound = float(d["truth_stderr_max"].max())
    if bound > 0:
        ax.axhline(bound, color="grey", linestyle=":", linewidth=1, label="truth's stderr bound (per pixel)")
    ax.set_title(f"{scene}: {metric}", fontsize=10)
    ax.set_xlabel("time per frame, ms (median)")
    ax.set_ylabel(f"{metric} (mean |V − G|)")
    ax.grid(True, which="both", alpha=0.3)


def penumbra_table(df: pd.DataFrame) -> str:
    """Markdown: per configuration (rows) and scene (columns), penumbra_mae and time — the
    soft techniques on the soft hard cases in one table."""
    scenes = list(dict.fromkeys(df["scene"]))
    lines = ["| configuration | " + " | ".join(scenes) + " |", "|---|" + "---|" * len(scenes)]
    for label in dict.fromkeys(df["short_label"]):
        cells = []
        for scene in scenes:
            r = df[(df["short_label"] == label) & (df["scene"] == scene)]
            cells.append("" if r.empty else f"{r['penumbra_mae'].iloc[0]:.4f} / {r['time_ms_median'].iloc[0]:.3g} ms")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main():
    run = run_experiment_suite(SUITE, __doc__.splitlines()[0], "results/soft_shadows_sweep")
    df = sweep_rows(run.outcome.results)
    size = run.save_table(df, COLUMNS)
    out = run.out
    plot(df, out.with_suffix(".png"), size, run.renderer)
    out.with_suffix(".md").write_text(f"penumbra_mae / time per frame ({size[0]}x{size[1]}, {run.renderer})\n\n"
                                      + penumbra_table(df))
    with pd.option_context("display.width", 220, "display.max_rows", 300):
        print(df[["scene", "short_label", "visibility_mae", "penumbra_mae", "time_ms_median"]].to_string(
            index=False, float_format=lambda x: f"{x:.4g}"))
    print(run.summary_line(out.with_suffix(".csv"), out.with_suffix(".png"), out.with_suffix(".md")))


if __name__ == "__main__":
    main()
