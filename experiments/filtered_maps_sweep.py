"""Filtered shadow maps and cheap baselines: light bleeding, over-darkening, contact leaks, cost.

Runs the shipped suite ``shadowlab/suites/filtered_maps.toml`` (VSM, ESM, EVSM 2/4 channels in
fp32 and fp16, MSM in float32 and 16-bit quantised, projective shadow textures, blob shadows and
the plain depth map, 640x480) as a study into ``<folder of --out>/study-filtered_maps`` and draws
four panels:

1. ``light_bleeding`` on sm_light_bleeding per configuration (mean wrongly passed light in the
   truth's umbra where two casters overlap in depth);
2. ``over_darkening_px`` and ``contact_gap_px`` on sm_contact (false shadow along lit contacts,
   false light along shadowed ones, both as mean band widths in pixels);
3. ``light_bleeding`` against the blur width (``kernel``) for VSM, EVSM4 and MSM;
4. ``visibility_mae`` against ``time_ms_median`` on every scene (median over the suite's scenes),
   with the map's bits per texel beside each filtered configuration.

Writes results/filtered_maps_sweep.csv (the rows plotted, with the cost columns
``memory_bytes``, ``bits_per_texel``, ``passes``) and .png. A few minutes on a 2-core machine.

    python experiments/filtered_maps_sweep.py [--out results/filtered_maps_sweep] [--workers N] [--force]
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from shadowlab.study.experiment import run_experiment_suite

SUITE = "filtered_maps"
COLUMNS = ["scene", "technique", "short_label", "param_variant", "param_kernel", "param_precision", "error_rate",
           "visibility_mae", "light_bleeding", "bleeding_pixels", "over_darkening_px", "contact_gap_px",
           "false_lit_rate", "false_shadow_rate", "time_ms_median", "setup_ms", "memory_bytes", "bits_per_texel",
           "passes"]


def sweep_rows(results: pd.DataFrame) -> pd.DataFrame:
    """The study's configuration rows of light 0, numeric columns made numeric."""
    df = results[~results["reference"].astype(bool) & (results["light"] == 0)].copy()
    for c in COLUMNS[6:] + ["param_kernel"]:
        if c in df.columns:
            df[c] = pd.to_numeric(df[c], errors="coerce")
    return df.reset_index(drop=True)


def short(label: str) -> str:
    """A configuration's label shortened for the figure (filtered_map's variant first)."""
    if label.startswith("filtered_map"):
        rest = label.partition(":")[2]
        parts = [p for p in rest.split(",") if p]
        variant = next((p.split("=")[1] for p in parts if p.startswith("variant=")), "vsm")
        others = [p.replace("positive_exponent", "c+").replace("negative_exponent", "c-")
                  for p in parts if not p.startswith("variant=")]
        return variant + (f" ({', '.join(others)})" if others else "")
    return label


def _bars(ax, d, metrics, title):
    """Grouped horizontal bars of ``metrics`` per configuration of ``d`` (symmetric-log axis:
    the filtered maps' small values and the fakes' large ones in one panel)."""
    d = d.drop_duplicates("short_label")
    y = np.arange(len(d))
    h = 0.8 / len(metrics)
    for i, m in enumerate(metrics):
        ax.barh(y + i * h, d[m].fillna(0.0), height=h, label=m)
    ax.set_xscale("symlog", linthresh=1e-4 if "light_bleeding" in metrics else 1e-2)
    ax.set_yticks(y + h * (len(metrics) - 1) / 2)
    ax.set_yticklabels([short(s) for s in d["short_label"]], fontsize=7)
    ax.invert_yaxis()
    ax.set_title(title, fontsize=9)
    ax.grid(True, axis="x", alpha=0.3)
    if len(metrics) > 1:
        ax.legend(fontsize=7)


def plot(df, path, size, renderer):
    """The four panels of the module docstring."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(16, 12), dpi=100)
    main = df[df["param_kernel"].isna() | ~df["short_label"].str.contains("kernel=")]
    _bars(axes[0, 0], main[main["scene"] == "sm_light_bleeding"], ["light_bleeding"],
          "sm_light_bleeding: light_bleeding (mean false light where casters overlap in depth)")
    _bars(axes[0, 1], main[main["scene"] == "sm_contact"], ["over_darkening_px", "contact_gap_px"],
          "sm_contact: false shadow along lit contacts / false light along shadowed contacts, px")
    ax = axes[1, 0]
    sweep = df[(df["scene"] == "sm_light_bleeding") & (df["technique"] == "filtered_map")
               & df["short_label"].str.contains("kernel=")]
    for variant, g in sweep.groupby(sweep["param_variant"].fillna("vsm")):
        g = g.sort_values("param_kernel")
        ax.plot(g["param_kernel"], g["light_bleeding"], "o-", label=variant)
    ax.set_xlabel("blur width (kernel, texels)")
    ax.set_ylabel("light_bleeding")
    ax.set_title("sm_light_bleeding: light bleeding against the filter width", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    ax = axes[1, 1]
    agg = main.groupby("short_label").agg(mae=("visibility_mae", "median"), ms=("time_ms_median", "median"),
                                          bits=("bits_per_texel", "max")).reset_index()
    for _, r in agg.iterrows():
        ax.semilogy([r["ms"]], [max(r["mae"], 1e-5)], "o")
        bits = "" if np.isnan(r["bits"]) else f" ({int(r['bits'])} b/texel)"
        ax.annotate(short(r["short_label"]) + bits, (r["ms"], max(r["mae"], 1e-5)), textcoords="offset points",
                    xytext=(4, 2), fontsize=6)
    ax.set_xlabel("time per frame, ms (median over scenes)")
    ax.set_ylabel("visibility_mae (median over scenes)")
    ax.set_title("accuracy against time", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"filtered shadow maps and baselines ({size[0]}x{size[1]}, {renderer})", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main():
    run = run_experiment_suite(SUITE, __doc__.splitlines()[0], "results/filtered_maps_sweep")
    df = sweep_rows(run.outcome.results)
    size = run.save_table(df, COLUMNS)
    out = run.out
    plot(df, out.with_suffix(".png"), size, run.renderer)
    show = [c for c in ["scene", "short_label", "error_rate", "visibility_mae", "light_bleeding",
                        "over_darkening_px", "contact_gap_px", "time_ms_median", "bits_per_texel"] if c in df.columns]
    with pd.option_context("display.width", 240, "display.max_rows", 400, "display.max_colwidth", 70):
        print(df[show].to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    print(run.summary_line(out.with_suffix(".csv"), out.with_suffix(".png")))


if __name__ == "__main__":
    main()
