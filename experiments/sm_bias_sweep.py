"""Bias sweep: the acne / peter-panning trade-off of every shadow-map variant.

On the grazing case (light 3 degrees above the floor) and the contact case (casters resting on
the floor), with the classic fit over every visible receiver, 2048² maps: each biased variant
is swept over its own parameter — constant ``bias``, ``slope_scale`` (bias 0), ``normal_offset``
(bias 0), the ``dual`` offset cap, ``receiver_plane``'s constant ``bias``, ``adaptive``'s
``adaptive_epsilon`` (bias 0) — and second-depth and midpoint (no parameter) are drawn as
reference lines. Reports false-shadow rate (acne), false-lit rate (leaks) and the contact gap.
Writes results/sm_bias_sweep.csv (the rows plotted) and results/sm_bias_sweep.png.

The grid is the shipped suite ``shadowlab/suites/sm_bias.toml`` (320x240, 3 timed repeats);
this script runs it as a study into ``<folder of --out>/study-sm_bias`` — the directory
``shadowlab study sm_bias`` uses by default, so the two share one cache and whichever runs second
only reads it — and draws this figure from the study's results. ``shadowlab study sm_bias``
gives the full study report (Pareto plot, HTML, images of every configuration).

    python experiments/sm_bias_sweep.py [--out results/sm_bias_sweep] [--workers N] [--force]
    (the suite fixes the size and resolution: the former --size/--resolution flags are gone; the
    640x480 figures in earlier notes need a copy of the suite with size = [640, 480], run with
    ``shadowlab study COPY.toml``. A JSON record of provenance is written beside the CSV)
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from shadowlab.study.experiment import run_experiment_suite
from shadowlab.techniques.maps.shadow_map import ShadowMap

SUITE = "sm_bias"
# variants swept over an offset, in plot order
SWEPT = ["constant", "slope", "normal_offset", "dual", "receiver_plane", "adaptive"]
FIXED = ["second_depth", "midpoint"]                     # variants without one: reference lines
SCENES = ["sm_grazing", "sm_contact"]
PARAMS = [f"param_{k}" for k in ShadowMap.PARAMS]


def _fmt(value) -> str:
    """A parameter value for an axis label: numbers as %g (``bias=0``), the rest as in a spec."""
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    return f"{value:g}" if isinstance(value, (int, float, np.number)) else str(value)


def sweep_rows(results: pd.DataFrame) -> tuple[pd.DataFrame, dict]:
    """The study's shadow-map rows (light 0), with ``variant``, ``swept`` (the parameter that
    varies within the variant, "" for one configuration) and ``value``; and per variant the
    parameters held at a non-default value that are not common to every row (axis labels)."""
    df = results[~results["reference"].astype(bool) & (results["technique"] == "shadow_map")
                 & (results["light"] == 0)].copy()
    common = {p for p in PARAMS if df[p].nunique(dropna=False) == 1}
    parts, held = [], {}
    for variant, g in df.groupby("param_variant", sort=False):
        varying = [p for p in PARAMS if g[p].nunique(dropna=False) > 1]
        if len(varying) > 1:
            raise SystemExit(f"variant {variant}: more than one parameter varies ({', '.join(varying)})")
        g = g.assign(variant=variant, swept=varying[0][len("param_"):] if varying else "",
                     value=g[varying[0]].astype(float) if varying else np.nan)
        held[variant] = ",".join(f"{p[len('param_'):]}={_fmt(g[p].iloc[0])}" for p in PARAMS
                                 if p not in common and p not in varying and p != "param_variant"
                                 and g[p].iloc[0] != ShadowMap.PARAMS[p[len("param_"):]].default)
        parts.append(g)
    df = pd.concat(parts)
    order = {v: i for i, v in enumerate(SWEPT + FIXED)}
    df = df.sort_values(["scene", "variant", "value"], key=lambda s: s.map(SCENES.index) if s.name == "scene"
                        else s.map(order) if s.name == "variant" else s, kind="stable")
    front = ["scene", "variant", "swept", "value"]
    return df[front + [c for c in df.columns if c not in front]].reset_index(drop=True), held


def main():
    run = run_experiment_suite(SUITE, __doc__.splitlines()[0], "results/sm_bias_sweep")
    rows, held = sweep_rows(run.outcome.results)
    width, height = int(rows["width"].iloc[0]), int(rows["height"].iloc[0])
    resolution = int(rows["param_resolution"].iloc[0])
    out = run.out
    run.write_record(size=[width, height], resolution=resolution)
    rows.to_csv(out.with_suffix(".csv"), index=False)
    plot(rows, held, out.with_suffix(".png"), resolution, (width, height), run.renderer)
    cols = ["scene", "variant", "swept", "value", "false_shadow_rate", "false_lit_rate", "contact_gap_px"]
    with pd.option_context("display.width", 200, "display.max_rows", 200):
        print(rows[cols].to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    print(run.summary_line(out.with_suffix(".csv"), out.with_suffix(".png")))


def plot(df, held, path, resolution, size, renderer):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(SCENES), len(SWEPT), figsize=(4 * len(SWEPT), 7.5), dpi=100, squeeze=False)
    for r, scene in enumerate(SCENES):
        d = df[df["scene"] == scene]
        for c, variant in enumerate(SWEPT):
            ax = axes[r, c]
            g = d[d["variant"] == variant].sort_values("value")
            param, fixed = g["swept"].iloc[0], held[variant]
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
            unit = {"bias": "  [window depth]", "normal_offset": "  [texels]",
                    "adaptive_epsilon": "  [× scene diagonal]"}.get(param, "")
            ax.set_xlabel(f"{param}" + (f"  ({fixed})" if fixed else "") + unit)
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
                 f"{resolution}² maps fitted to all visible receivers, {size[0]}x{size[1]}, {renderer}", fontsize=11)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


if __name__ == "__main__":
    main()
