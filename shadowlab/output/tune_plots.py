"""The figures of a tune run (``shadowlab tune``, docs/tuning.md).

- :func:`frontier_plot` (exact bias route): left, the error rates as the constant bias runs
  (log axis; every step of the exact curve, not samples); right, the acne-versus-leak frontier
  — false-shadow rate against false-lit rate as the bias runs, one curve per grid value of
  slope_scale / normal_offset — with the spec's default and the optimum marked, and the
  per-pixel oracle's error as a line.
- :func:`search_plot` (search route): the objective of every rendered candidate against each
  tuned parameter, in the order the search took them.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .pictures import PLOT_DPI

#: Where a log bias axis starts when the range starts at 0: the steps below are drawn at it.
LOG_FLOOR = 1e-7
FIGURE_SIZE = (11.0, 4.2)
DEFAULT_STYLE = {"marker": "s", "color": "#444444", "label": "default"}
BEST_STYLE = {"marker": "*", "color": "#d62728", "label": "optimum"}
MARKER_SIZE = 11
CURVES = (("error_rate", "error rate", "#000000"), ("false_shadow_rate", "false shadow (acne) / truly lit", "#1f77b4"),
          ("false_lit_rate", "false lit (leaks) / truly shadowed", "#ff7f0e"))


def _figure(columns: int):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=FIGURE_SIZE if columns == 2 else (4.8 * columns, 3.8), dpi=PLOT_DPI)
    FigureCanvasAgg(fig)
    return fig, fig.subplots(1, columns, squeeze=False)[0]


def _label(params: dict) -> str:
    return ", ".join(f"{k}={v:g}" for k, v in params.items()) or "bias only"


def frontier_plot(result, path: Path, default: tuple, best: tuple, objective: str = "error_rate") -> None:
    """The exact route's figure (module docstring). ``default`` and ``best`` are (grid point,
    bias); ``result`` an :class:`~shadowlab.tuning.exact_bias.ExactBiasTune`."""
    fig, (left, right) = _figure(2)
    point, bias = best
    curve = point.curve
    x = np.maximum(np.r_[curve.breaks, curve.hi], LOG_FLOOR)
    for name, label, color in CURVES:
        y = 100 * curve.values(name)
        left.step(x, np.r_[y, y[-1]], where="post", color=color, lw=1.2, label=label)
    oracle = curve.oracle.get("error_rate")
    if oracle is not None:
        left.axhline(100 * oracle, color="#2ca02c", ls=":", lw=1.2, label="per-pixel oracle (error rate)")
    for (p, b), style in ((default, DEFAULT_STYLE), (best, BEST_STYLE)):
        at = p.curve.at(b)
        left.plot([max(b, LOG_FLOOR)], [100 * at["error_rate"]], ls="none", ms=MARKER_SIZE, markeredgecolor="white",
                  **{**style, "label": f"{style['label']}: bias {b:.3g}" + (f" ({_label(p.params)})" if p.params else "")})
    left.set_xscale("log")
    left.set_xlabel("constant bias (window depth)" + (f"; {_label(point.params)}" if point.params else ""))
    left.set_ylabel("% of pixels")
    left.set_title("Every constant bias, exact from one render", fontsize=10)
    left.grid(alpha=0.3)
    left.legend(fontsize=7.5, loc="best")
    cmap = _colormap()
    n = len(result.points)
    for k, p in enumerate(result.points):
        fl, fs = p.curve.frontier()
        color = cmap(k / max(1, n - 1)) if n > 1 else "#000000"
        right.plot(100 * fl, 100 * fs, color=color, lw=1.2, drawstyle="default",
                   label=_label(p.params) if n > 1 else "as the bias runs")
    for (p, b), style in ((default, DEFAULT_STYLE), (best, BEST_STYLE)):
        at = p.curve.at(b)
        right.plot([100 * at["false_lit_rate"]], [100 * at["false_shadow_rate"]], ls="none", ms=MARKER_SIZE,
                   markeredgecolor="white", **style)
    right.set_xscale("symlog", linthresh=0.01)
    right.set_yscale("symlog", linthresh=0.01)
    right.set_xlabel("false lit (leaks), % of truly shadowed")
    right.set_ylabel("false shadow (acne), % of truly lit")
    right.set_title("Acne against leaks as the bias runs", fontsize=10)
    right.grid(alpha=0.3)
    right.legend(fontsize=7.5, loc="best")
    fig.tight_layout()
    fig.savefig(path)


def _colormap():
    from matplotlib import colormaps

    return colormaps["viridis"]


def search_plot(trials, dimensions, objective: str, path: Path) -> None:
    """The search route's figure: per tuned parameter, the objective of each rendered candidate
    (colour: evaluation order; infeasible candidates as crosses at the top; the best starred)."""
    fig, axes = _figure(max(1, len(dimensions)))
    feasible = [t for t in trials if math.isfinite(t.value)]
    best = min(feasible, key=lambda t: t.value) if feasible else None
    top = max((t.value for t in feasible), default=1.0)
    cmap = _colormap()
    for ax, d in zip(axes, dimensions):
        xs = [t.params[d.name] for t in trials]
        numeric = d.kind != "choice" or all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in xs)
        pos = xs if numeric else [list(map(str, d.choices)).index(str(v)) for v in xs]
        for i, (t, x) in enumerate(zip(trials, pos)):
            if math.isfinite(t.value):
                ax.plot([x], [t.value], "o", color=cmap(i / max(1, len(trials) - 1)), ms=6)
            else:
                ax.plot([x], [top], "x", color="#b00000", ms=7)
        if best is not None:
            x = best.params[d.name] if numeric else list(map(str, d.choices)).index(str(best.params[d.name]))
            ax.plot([x], [best.value], ls="none", ms=MARKER_SIZE + 3, markeredgecolor="white", **BEST_STYLE)
        if not numeric:
            ax.set_xticks(range(len(d.choices)), [str(c) for c in d.choices])
        else:
            if d.log:
                from matplotlib.ticker import NullFormatter

                ax.set_xscale("log", base=2 if d.powers_of_two else 10)
                ax.xaxis.set_minor_formatter(NullFormatter())  # labelled minor ticks overlap
            if d.lo is not None and d.hi is not None and d.hi > d.lo:
                # the whole searched range, also where the search tried one value only
                pad = (d.hi / d.lo) ** 0.05 if d.log and d.lo > 0 else None
                ax.set_xlim(*((d.lo / pad, d.hi * pad) if pad else
                              (d.lo - 0.05 * (d.hi - d.lo), d.hi + 0.05 * (d.hi - d.lo))))
        ax.set_xlabel(d.name)
        ax.set_ylabel(objective + (", %" if objective.endswith("_rate") else ""))
        if objective.endswith("_rate"):
            from matplotlib.ticker import PercentFormatter

            ax.yaxis.set_major_formatter(PercentFormatter(xmax=1.0, decimals=None, symbol=""))
        ax.grid(alpha=0.3)
    fig.suptitle(f"{len(trials)} rendered candidates (colour: order; ×: over the time budget)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
