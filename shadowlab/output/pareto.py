"""The study's speed-against-error figure: one panel per scene, the Pareto front marked
(object-oriented matplotlib on an Agg canvas; no pyplot state)."""
from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pandas as pd

from ..study.aggregate import failed_runs, family_order, normalised, pareto_front, per_configuration, \
    scenes_in_order, as_text

#: Zero error has no place on a log axis: it is drawn at this many wrong pixels (half a pixel of
#: the configuration's evaluated pixels, below any real error, which is at least one pixel).
ZERO_FLOOR_PIXELS = 0.5


#: Panels per row of the Pareto figure (fewer when there are fewer scenes).
PANEL_COLUMNS = 4


#: Failed or untimed configurations listed by name in a panel before "... and N more".
PANEL_LIST_MAX = 5


def _styles(families) -> dict[str, tuple[str, str]]:
    """Colour and marker per family: each technique's declared ``STYLE`` (grey dots for names
    the registry does not know)."""
    from ..techniques import REGISTRY

    out = {}
    for fam in family_order(families):
        style = REGISTRY[fam].STYLE if fam in REGISTRY else None
        out[fam] = (style.color, style.marker) if style is not None else ("#999999", ".")
    return out


def _zero_floor(cfg: pd.DataFrame) -> np.ndarray:
    """Error rate at which a zero-error configuration is drawn: :data:`ZERO_FLOOR_PIXELS` of its
    evaluated pixels (NaN when unknown or empty)."""
    ev = cfg["evaluated_pixels"].to_numpy(dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(ev > 0, ZERO_FLOOR_PIXELS / ev, np.nan)


def _listing(prefix: str, names: list[str]) -> list[str]:
    lines = [f"{prefix}: {n}" for n in names[:PANEL_LIST_MAX]]
    if len(names) > PANEL_LIST_MAX:
        lines.append(f"... and {len(names) - PANEL_LIST_MAX} more")
    return lines


def pareto_figure(results: pd.DataFrame):
    """The speed-against-error figure of ``results`` (results.csv rows, pooled per configuration
    by :func:`per_configuration`) as a :class:`matplotlib.figure.Figure` on an Agg canvas (no
    pyplot state): one panel per scene in suite order, up to :data:`PANEL_COLUMNS` per row, the
    figure growing with the rows; one legend for the figure.

    Per panel: x = time per frame in ms (all lights, median; horizontal bar = the summed IQR,
    centred), y = error rate in % of evaluated pixels, both log scales; colour and marker by
    technique family. A configuration with no wrong pixel is drawn hollow at a floor of half a
    pixel (:data:`ZERO_FLOOR_PIXELS` / evaluated pixels, the dotted line, gid "zero-floor")
    since zero has no place on a log axis. The Pareto front (:func:`pareto_front`) is a
    staircase through its ringed, named points (gid "pareto-front"; from the top of the panel
    down to the first point, then right from the last). The ground truth is no point (its
    error is 0 by definition): its time is the dashed vertical line "truth" (gid "truth").
    Failed configurations, and ones without a time, are listed as text in the panel.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    df = normalised(results) if len(results) else results
    cfg = per_configuration(results)
    fails = failed_runs(results)
    scenes = scenes_in_order(df) if len(df) else []
    techniques = cfg.loc[~cfg["reference"].astype(bool), "technique"] if len(cfg) else []
    styles = _styles(list(techniques) + list(fails.loc[~fails["reference"].astype(bool), "technique"]))

    n = max(len(scenes), 1)
    ncols = n if n <= 3 else 2 if n == 4 else 3 if n <= 9 else PANEL_COLUMNS
    nrows = math.ceil(n / ncols)
    fig_w = max(3.9 * ncols, 6.4)
    fig_h = 3.2 * nrows + 1.3
    fig = Figure(figsize=(fig_w, fig_h), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, squeeze=False)
    plain = FuncFormatter(lambda v, _: f"{v:g}")
    any_zero = False
    for k, ax in enumerate(axes.ravel()):
        if k >= len(scenes):
            ax.set_axis_off()
            if not scenes:
                ax.text(0.5, 0.5, "no results", ha="center", va="center", transform=ax.transAxes)
            continue
        scene = scenes[k]
        c = cfg[cfg["scene"] == scene]
        conf = c[~c["reference"].astype(bool)]
        truth = c[c["reference"].astype(bool)]
        fam = as_text(df.loc[df["scene"].astype(str) == scene, "scene_family"].iloc[0])
        ax.set_title(f"{scene}" + (f"  ({fam})" if fam else ""), fontsize=9)
        t = conf["time_ms"].to_numpy(dtype=float)
        err = conf["error_rate"].to_numpy(dtype=float)
        floor = _zero_floor(conf)
        zero = err == 0
        y = np.where(zero, floor, err) * 100
        iqr = conf["time_iqr_ms"].to_numpy(dtype=float)
        placed = np.isfinite(t) & (t > 0) & np.isfinite(y) & (y > 0)
        for tech, idx in conf.groupby("technique", sort=False).indices.items():
            color, marker = styles[tech]
            for hollow in (False, True):
                sel = np.array([i for i in idx if placed[i] and zero[i] == hollow], dtype=int)
                if not len(sel):
                    continue
                xe = np.nan_to_num(iqr[sel] / 2)
                ax.errorbar(t[sel], y[sel], xerr=[np.minimum(xe, 0.5 * t[sel]), xe], fmt=marker, ms=5.5,
                            color=color, mfc="white" if hollow else color, mec=color, mew=1.4 if hollow else 0.6,
                            ecolor=color, elinewidth=0.8, capsize=2, alpha=0.9, zorder=3)
        if (zero & placed).any():
            any_zero = True
            for fl in np.unique(floor[zero & placed]):
                ax.axhline(100 * fl, color="0.55", ls=":", lw=0.8, zorder=1, gid="zero-floor")
        truth_t = truth["time_ms"].to_numpy(dtype=float) if len(truth) else np.array([])
        xs = list(t[placed]) + [v for v in truth_t if np.isfinite(v) and v > 0]
        for v in truth_t:
            if np.isfinite(v) and v > 0:
                ax.axvline(v, color="0.3", ls="--", lw=1.0, zorder=1, gid="truth")
                ax.annotate("truth", (v, 1), xycoords=("data", "axes fraction"), xytext=(-3, -3),
                            textcoords="offset points", ha="right", va="top", fontsize=7, color="0.3",
                            rotation=90)
        notes = []
        f = fails[(fails["scene"] == scene)]
        if f["reference"].astype(bool).any():
            notes.append("truth failed")
        notes += _listing("failed", [s for s in f.loc[~f["reference"].astype(bool), "short_label"]])
        notes += _listing("no time", list(conf["short_label"].to_numpy()[~placed & np.isfinite(y)]))
        if notes:
            ax.text(0.02, 0.02, "\n".join(notes), transform=ax.transAxes, fontsize=6.5, color="#b00000",
                    va="bottom", ha="left", zorder=5,
                    bbox=dict(boxstyle="round,pad=0.25", fc="white", ec="#b00000", lw=0.5, alpha=0.85))
        ys = list(y[placed])
        if xs and ys:
            ax.set_xscale("log")
            ax.set_yscale("log")
            lo, hi = min(xs), max(xs)
            ax.set_xlim(lo / 1.6, hi * 1.6)
            ylo, yhi = min(ys), max(ys)
            ax.set_ylim(ylo / 2.5, yhi * 2.5)
            for axis in (ax.xaxis, ax.yaxis):
                axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
                axis.set_major_formatter(plain)
                axis.set_minor_formatter(NullFormatter())
        else:
            ax.set_xticks([])
            ax.set_yticks([])
            ax.text(0.5, 0.55, "nothing to plot", ha="center", va="center", transform=ax.transAxes,
                    fontsize=8, color="0.4")
        front = pareto_front(np.where(placed, t, np.nan), np.where(placed, y, np.nan))
        if front.any() and xs and ys:
            # the staircase bounding the dominated region: down the first point's time from the
            # top, through the front, then right along the last point's error to the edge
            order = np.argsort(t[front], kind="stable")
            ft, fy = t[front][order], y[front][order]
            (x_lo, x_hi), (y_lo, y_hi) = ax.get_xlim(), ax.get_ylim()
            ax.plot(np.r_[ft[0], ft, x_hi], np.r_[y_hi, fy, fy[-1]], drawstyle="steps-post", color="k", lw=1.0,
                    alpha=0.7, zorder=2, gid="pareto-front")
            ax.scatter(ft, fy, s=70, facecolors="none", edgecolors="k", linewidths=0.9, zorder=4)
            names = conf["short_label"].to_numpy()[front][order]
            for x0, y0, label in zip(ft, fy, names):
                ax.annotate(label, (x0, y0), xytext=(5, 3), textcoords="offset points", fontsize=5.5,
                            color="0.15", zorder=4, annotation_clip=True, clip_on=True)
            ax.set_xlim(x_lo, x_hi)
            ax.set_ylim(y_lo, y_hi)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.25, which="major")
    handles = [Line2D([], [], ls="none", marker=m, color=c, label=fam) for fam, (c, m) in styles.items()]
    handles += [Line2D([], [], color="k", lw=1.0, alpha=0.7, marker="o", mfc="none", mec="k", ms=8,
                       label="Pareto front (named)"),
                Line2D([], [], color="0.3", ls="--", lw=1.0, label="truth (ray-traced): time")]
    if any_zero:
        handles.append(Line2D([], [], ls=":", color="0.55", marker="o", mfc="white", mec="0.3", mew=1.4,
                              label=f"no wrong pixel: drawn at {ZERO_FLOOR_PIXELS:g} px"))
    fig.legend(handles=handles, loc="outside upper center", ncol=min(len(handles), 4 if fig_w < 10 else 7),
               fontsize=8, frameon=False)
    fig.supxlabel("time per frame, ms (median, all lights; bar = IQR)  —  log scale", fontsize=9)
    fig.supylabel("error rate, % of evaluated pixels  —  log scale", fontsize=9)
    return fig


def pareto_plot(results: pd.DataFrame, path) -> Path:
    """Write ``pareto.png`` (:func:`pareto_figure`: speed against error per scene, log axes,
    Pareto front, truth's time, zero errors at a floor) to ``path``, through a temporary name so
    that a reader never sees half a file. Returns ``path``."""
    path = Path(path)
    fig = pareto_figure(results)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    fig.savefig(tmp, format="png")
    os.replace(tmp, path)
    return path
