"""The study's speed-against-error figure: one panel per scene, the Pareto front marked
(object-oriented matplotlib on an Agg canvas; no pyplot state)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..util.files import replacing
from ..analysis.aggregate import (
    FAIL_ERROR_RATE, FAIL_RADIANCE_ERROR, FAIL_VISIBILITY_MAE, as_text, fail_threshold, failed_runs, family_order,
    judged_metric,
    normalised, pareto_front, per_configuration, scenes_in_order, truthy,
)

#: The y axis of a panel by the metric its scene is judged on
#: (:func:`~shadowlab.analysis.aggregate.judged_metric`), in per cent.
AXIS_NAMES = {"error_rate": "error rate, % of evaluated pixels", "visibility_mae": "mean |V − G|, %",
              "radiance_error": "radiance error (shaded image), %"}

#: Zero error has no place on a log axis: it is drawn at this many wrong pixels (half a pixel of
#: the configuration's evaluated pixels, below any real error, which is at least one pixel).
ZERO_FLOOR_PIXELS = 0.5


#: Panels per row of the Pareto figure (fewer when there are fewer scenes).
PANEL_COLUMNS = 4


#: Failed or untimed configurations listed by name in a panel before "... and N more".
PANEL_LIST_MAX = 5


#: Failing points (error over :data:`FAIL_ERROR_RATE`) named beside them in a panel, the worst
#: first; past this many the names would cover each other, and the legend still tells them apart.
FAIL_LABEL_MAX = 4


# --- size: the study page shows pareto.png at its natural size up to the page's width (≈ 1350 px
# in a 1400-px-wide browser), so the figure is made that wide and its text sized in points at
# FIGURE_DPI reads as it would in print.

#: Pixels per inch of the figure (the PNG's pixels = inches × this).
FIGURE_DPI = 110
#: The widest the figure gets, in pixels: a little under the study page's ≈ 1350-px content
#: width, so that it is shown 1:1 there, not scaled down.
PAGE_WIDTH_PX = 1340
#: One panel's width and height in inches when the page's width does not bind (one or two
#: columns); with three or more columns the panels share :data:`PAGE_WIDTH_PX`.
PANEL_WIDTH_IN = 4.6
PANEL_HEIGHT_IN = 3.4
#: The narrowest figure, in inches: room for a few legend columns above a single panel.
MIN_FIGURE_WIDTH_IN = 7.0
#: Inches for the figure's axis labels and the margins constrained layout keeps around them.
FIGURE_MARGIN_IN = 0.7

# --- text sizes, points (≥ 8 pt for the axes' text, ≥ 7.5 pt beside points: legible at 1:1)

TITLE_PT = 10
AXIS_LABEL_PT = 10
TICK_PT = 8.5
LEGEND_PT = 8.5
POINT_LABEL_PT = 8
NOTE_PT = 8

# --- markers

#: Marker size of a configuration's point, points (≈ 11 px: the shape is recognisable at 1:1).
MARKER_PT = 7
#: Within a technique family the configurations take, in order of first appearance, the family's
#: own marker (its ``STYLE``), then these in turn (the family's own one skipped); every shape here
#: reads differently from the others at :data:`MARKER_PT`.
CONFIG_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*", "h", "<", ">", "p")
#: Once a family has used every marker, its further configurations repeat the markers in its
#: colour mixed with black (< 0) or white (> 0) by these fractions, round after round, so that
#: the (colour, marker) pairs stay distinct within the family (for 5 × 12 configurations).
CONFIG_SHADES = (0.0, -0.45, 0.45, -0.7, 0.7)

#: Colour of the fail threshold, its band and the panels' failed / untimed listings.
FAIL_COLOR = "#b00000"
#: Colour of the names of points that do not fail.
NAME_COLOR = "0.1"
#: Opacity of the band above the fail threshold (a tint, under everything else).
FAIL_BAND_ALPHA = 0.06
#: Width, points, of the fail threshold's line, in the panels and the legend alike.
FAIL_LINE_PT = 0.9

#: Room along an axis, inches, that one :data:`TICK_PT` tick label needs with the gap to the
#: next: across (x: up to four digits side by side) and up (y: a line of text). An axis gets
#: labelled ticks at 1, 2 and 5 per decade where that many fit, else at powers of ten only.
TICK_ROOM_X_IN = 0.45
TICK_ROOM_Y_IN = 0.2
#: Of a panel's cell, inches taken by other than the plot: beside it (the y tick labels) and
#: above and below it (title, x tick labels) — to estimate the plot's size before the layout.
PANEL_FRAME_W_IN = 0.6
PANEL_FRAME_H_IN = 0.7

#: Padding of a panel's data range on its log axes, as a factor each side.
X_PAD_FACTOR = 1.6
Y_PAD_FACTOR = 2.5


def _styles(families) -> dict[str, tuple[str, str]]:
    """Colour and marker per family: each technique's declared ``STYLE`` (grey dots for names
    the registry does not know)."""
    from ..techniques import REGISTRY

    out = {}
    for fam in family_order(families):
        style = REGISTRY[fam].STYLE if fam in REGISTRY else None
        out[fam] = (style.color, style.marker) if style is not None else ("#999999", ".")
    return out


def _shade(color: str, amount: float) -> str:
    """``color`` mixed with black (``amount`` < 0) or white (> 0) by ``|amount|``, as hex."""
    from matplotlib.colors import to_hex, to_rgb

    rgb = np.array(to_rgb(color))
    target = 1.0 if amount > 0 else 0.0
    return to_hex(rgb + (target - rgb) * abs(amount))


def configuration_styles(configs: pd.DataFrame) -> dict[str, tuple[str, str]]:
    """Colour and marker per configuration ``label`` of ``configs`` (rows with ``technique`` and
    ``label``; the ground truth's are skipped), in the registry's family order, each family's
    configurations in order of first appearance.

    Why: the family's colour (its ``STYLE``) says which technique a point is, and the marker
    says which of its configurations — the family's own marker first, then
    :data:`CONFIG_MARKERS` in turn, then the same markers in shades of the colour
    (:data:`CONFIG_SHADES`) — so that no two configurations of a family look alike."""
    if "reference" in configs.columns:
        configs = configs.loc[~truthy(configs["reference"]).to_numpy(dtype=bool)]
    labels = dict.fromkeys(zip(configs["technique"].astype(str), configs["label"].astype(str)))
    families = _styles([t for t, _ in labels])
    out: dict[str, tuple[str, str]] = {}
    for fam, (color, own) in families.items():
        markers = [own] + [m for m in CONFIG_MARKERS if m != own]
        for i, label in enumerate(lab for t, lab in labels if t == fam):
            rnd, k = divmod(i, len(markers))
            out[label] = (_shade(color, CONFIG_SHADES[rnd % len(CONFIG_SHADES)]), markers[k])
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


def _grid(n: int) -> tuple[int, int]:
    """(rows, columns) of panels for ``n`` scenes: one row up to three, 2 × 2 for four, three
    columns up to nine, then :data:`PANEL_COLUMNS`."""
    ncols = n if n <= 3 else 2 if n == 4 else 3 if n <= 9 else PANEL_COLUMNS
    return math.ceil(n / ncols), ncols


def _legend_columns(fig, labels: list[str], width_in: float) -> int:
    """How many legend columns of ``labels`` (at :data:`LEGEND_PT`) fit across ``width_in``,
    balanced so that the last column is not nearly empty."""
    from matplotlib.font_manager import FontProperties

    if not labels:
        return 1
    renderer = fig.canvas.get_renderer()
    prop = FontProperties(size=LEGEND_PT)
    text_px = max(renderer.get_text_width_height_descent(s, prop, ismath=False)[0] for s in labels)
    em_px = LEGEND_PT * fig.dpi / 72
    # an entry: the handle (handlelength 2 em), the pad to its text (0.8 em), the text, and the
    # gap to the next column (columnspacing 2 em) — matplotlib's legend defaults
    entry_px = text_px + (2.0 + 0.8 + 2.0) * em_px
    ncol = max(1, min(len(labels), int(width_in * fig.dpi // entry_px)))
    return math.ceil(len(labels) / math.ceil(len(labels) / ncol))


#: Where a point's name may go, tried in turn: (x, y offset from the point in points,
#: horizontal, vertical alignment) — upper right, upper left, lower right, lower left; 8 pt
#: sideways clears the Pareto front's ring (:data:`MARKER_PT` in radius).
LABEL_PLACES = ((8, 3, "left", "bottom"), (-8, 3, "right", "bottom"), (8, -3, "left", "top"),
                (-8, -3, "right", "top"))
#: Where the truth line's name may go, tried in turn: (y in axes fraction, x, y offset in
#: points, horizontal, vertical alignment) — along the line's top left, top right, bottom
#: left, bottom right.
TRUTH_PLACES = ((1, -3, -3, "right", "top"), (1, 3, -3, "left", "top"), (0, -3, 3, "right", "bottom"),
                (0, 3, 3, "left", "bottom"))
#: Width, points, of the white outline behind point names (legible over lines and the grid).
HALO_PT = 2.5
#: Room, points, kept free around a point beyond its marker when naming points.
POINT_CLEARANCE_PT = 1.0


def _halo():
    from matplotlib import patheffects

    return [patheffects.withStroke(linewidth=HALO_PT, foreground="white")]


class _PanelText:
    """What a panel wants written once the layout is final: its ``notes`` (a text artist or
    None), the ``points`` drawn (x, y in data units), the points to name — ``names``:
    (point index, name, colour, required) in order of priority — and the ``truths`` (times of
    the truth's lines)."""

    def __init__(self):
        self.notes = None
        self.points: list[tuple[float, float]] = []
        self.names: list[tuple[int, str, str, bool]] = []
        self.truths: list[float] = []


def _first_free(make, places, frame, taken, skip=None):
    """Add the text ``make(place)`` for the first of ``places`` whose box is inside ``frame``
    and overlaps none of ``taken`` (but the one at index ``skip``); returns its box, or None
    (nothing added) with the first place that was at least inside the frame, if any."""
    fallback = None
    for place in places:
        text = make(place)
        box = text.get_window_extent()
        inside = frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0 and box.y1 <= frame.y1
        if inside and not any(box.overlaps(o) for k, o in enumerate(taken) if k != skip):
            return box, None
        text.remove()
        if inside and fallback is None:
            fallback = place
    return None, fallback


def _place_text(fig, panels: dict) -> None:
    """Write the point names and truth labels of ``panels`` (panel → :class:`_PanelText`)
    without covering each other, the points or the notes: each takes the first of its places
    (:data:`LABEL_PLACES`, :data:`TRUTH_PLACES`) that stays inside the panel and is free. A
    required name (the Pareto front's) or a truth label that fits nowhere free takes its first
    place inside the panel anyway; another name is left out (the legend still tells its point
    apart). Call once the layout is final: the overlap test is in pixels."""
    from matplotlib.transforms import Bbox

    r = (MARKER_PT / 2 + POINT_CLEARANCE_PT) * fig.dpi / 72
    for ax, want in panels.items():
        frame = ax.get_window_extent()
        # one box per point, in the points' order (an unplaced point's is NaN and overlaps nothing)
        taken = [Bbox.from_extents(px - r, py - r, px + r, py + r)
                 for px, py in ax.transData.transform(np.array(want.points, float).reshape(-1, 2))]
        if want.notes is not None:
            taken.append(want.notes.get_window_extent())

        for i, name, color, required in want.names:
            def make(place, i=i, name=name, color=color):
                dx, dy, ha, va = place
                text = ax.annotate(name, want.points[i], xytext=(dx, dy), textcoords="offset points", ha=ha,
                                   va=va, fontsize=POINT_LABEL_PT, color=color, zorder=6, annotation_clip=True,
                                   clip_on=True, path_effects=_halo())
                text.set_in_layout(False)
                return text
            box, fallback = _first_free(make, LABEL_PLACES, frame, taken, skip=i)
            if box is None and required:
                box = make(fallback or LABEL_PLACES[0]).get_window_extent()
            if box is not None:
                taken.append(box)
        for v in want.truths:
            def make(place, v=v):
                y, dx, dy, ha, va = place
                text = ax.annotate("truth", (v, y), xycoords=("data", "axes fraction"), xytext=(dx, dy),
                                   textcoords="offset points", ha=ha, va=va, fontsize=POINT_LABEL_PT, color="0.3",
                                   rotation=90, zorder=6, path_effects=_halo())
                text.set_in_layout(False)
                return text
            box, fallback = _first_free(make, TRUTH_PLACES, frame, taken)
            taken.append(box if box is not None else make(fallback or TRUTH_PLACES[0]).get_window_extent())


def pareto_figure(results: pd.DataFrame):
    """The speed-against-error figure of ``results`` (results.csv rows, pooled per configuration
    by :func:`per_configuration`) as a :class:`matplotlib.figure.Figure` on an Agg canvas (no
    pyplot state): one panel per scene in suite order, up to :data:`PANEL_COLUMNS` per row, the
    figure growing with the rows and at most :data:`PAGE_WIDTH_PX` wide (so that the study page
    shows it 1:1, its text at the sizes set here); one legend for the figure.

    Why: it shows at a glance which configurations are fast, which are right, and which buy one
    with the other, scene by scene.

    Per panel: x = time per frame in ms (all lights, median; horizontal bar = the summed IQR,
    centred), y = error rate in % of evaluated pixels, both log scales. Colour by technique
    family (its ``STYLE``), marker by configuration within the family
    (:func:`configuration_styles`); the legend lists every drawn configuration, family by
    family, with its colour and marker. A configuration with no wrong pixel is drawn hollow at
    a floor of half a pixel (:data:`ZERO_FLOOR_PIXELS` / evaluated pixels, the dotted line, gid
    "zero-floor") since zero has no place on a log axis. A soft scene's panel (scene family
    "soft shadows") draws mean |V − G| instead of the error rate, and a many-light scene's (scene
    family "many lights") the shaded image's radiance error, as the verdicts judge them. The
    fail threshold
    (:data:`FAIL_ERROR_RATE`) is a horizontal line (gid "fail-threshold") with a tinted band
    above it, always in range, so that a failing configuration stands out and a scene nobody
    fails says so; failing points are named in :data:`FAIL_COLOR` (off the front, the worst
    :data:`FAIL_LABEL_MAX`, each where it finds room). The Pareto front (:func:`pareto_front`)
    is a staircase through its ringed, named points (gid "pareto-front";
    from the top of the panel down to the first point, then right from the last). The ground
    truth is no point (its error is 0 by definition): its time is the dashed vertical line
    "truth" (gid "truth"). Failed configurations, and ones without a time, are listed as text
    in the panel. Names are placed beside their points so as not to cover other names, points
    or notes; for that the constrained layout is computed once and then frozen (the returned
    figure's layout engine is "none": resizing it does not lay it out again).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.ticker import FuncFormatter, LogLocator, NullLocator

    df = normalised(results) if len(results) else results
    cfg = per_configuration(results)
    fails = failed_runs(results)
    scenes = scenes_in_order(df) if len(df) else []
    styles = configuration_styles(pd.concat([cfg[["technique", "label", "reference"]],
                                             fails[["technique", "label", "reference"]]]))
    short = dict(zip(cfg["label"].astype(str), cfg["short_label"].astype(str)))
    panel_metrics: dict = {}  # axes → the metric drawn: panels of other metrics are labelled on their own

    nrows, ncols = _grid(max(len(scenes), 1))
    fig_w = min(max(PANEL_WIDTH_IN * ncols, MIN_FIGURE_WIDTH_IN), PAGE_WIDTH_PX / FIGURE_DPI)
    fig = Figure(figsize=(fig_w, PANEL_HEIGHT_IN * nrows + FIGURE_MARGIN_IN), dpi=FIGURE_DPI,
                 layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, squeeze=False)
    # tick labels that fit along a panel's plot (estimated: the layout comes later)
    x_room = (fig_w / ncols - PANEL_FRAME_W_IN) / TICK_ROOM_X_IN
    y_room = (PANEL_HEIGHT_IN - PANEL_FRAME_H_IN) / TICK_ROOM_Y_IN
    plain = FuncFormatter(lambda v, _: f"{v:g}")
    any_zero = any_fail_line = False
    drawn: set[str] = set()
    wanted: dict = {}   # panel → its _PanelText: written once the layout is final
    for k, ax in enumerate(axes.ravel()):
        if k >= len(scenes):
            ax.set_axis_off()
            if not scenes:
                ax.text(0.5, 0.5, "no results", ha="center", va="center", transform=ax.transAxes,
                        fontsize=AXIS_LABEL_PT)
            continue
        scene = scenes[k]
        c = cfg[cfg["scene"] == scene]
        conf = c[~c["reference"].astype(bool)]
        truth = c[c["reference"].astype(bool)]
        fam = as_text(df.loc[df["scene"].astype(str) == scene, "scene_family"].iloc[0])
        ax.set_title(f"{scene}" + (f"  ({fam})" if fam else ""), fontsize=TITLE_PT)
        want = wanted[ax] = _PanelText()
        labels = conf["label"].astype(str).to_numpy()
        names = conf["short_label"].astype(str).to_numpy()
        t = conf["time_ms"].to_numpy(dtype=float)
        # soft scenes are judged (and drawn) on mean |V - G|, many-light scenes on the shaded
        # image's radiance error, as the verdicts judge them
        metric = judged_metric(fam)
        if metric == "radiance_error" and conf["radiance_error"].isna().all():
            metric = "error_rate"  # a study older than the column: the per-light rates
        threshold = 100 * fail_threshold(metric)
        panel_metrics[ax] = metric
        err = conf[metric].to_numpy(dtype=float)
        floor = _zero_floor(conf)
        zero = err == 0
        y = np.where(zero, floor, err) * 100
        iqr = conf["time_iqr_ms"].to_numpy(dtype=float)
        placed = np.isfinite(t) & (t > 0) & np.isfinite(y) & (y > 0)
        want.points = [(a, b) if ok else (math.nan, math.nan) for a, b, ok in zip(t, y, placed)]
        for i in np.flatnonzero(placed):
            color, marker = styles[labels[i]]
            xe = np.nan_to_num(iqr[i] / 2)
            bar = ax.errorbar([t[i]], [y[i]], xerr=[[min(xe, 0.5 * t[i])], [xe]], fmt=marker, ms=MARKER_PT,
                              color=color, mfc="white" if zero[i] else color, mec=color,
                              mew=1.4 if zero[i] else 0.6, ecolor=color, elinewidth=0.8, capsize=2, alpha=0.9,
                              zorder=3)
            # the point itself: findable by gid, named by the configuration's short label
            bar.lines[0].set_gid("configuration")
            bar.lines[0].set_label(names[i])
            drawn.add(labels[i])
        if (zero & placed).any():
            any_zero = True
            for fl in np.unique(floor[zero & placed]):
                ax.axhline(100 * fl, color="0.55", ls=":", lw=0.8, zorder=1, gid="zero-floor")
        truth_t = truth["time_ms"].to_numpy(dtype=float) if len(truth) else np.array([])
        xs = list(t[placed]) + [v for v in truth_t if np.isfinite(v) and v > 0]
        for v in truth_t:
            if np.isfinite(v) and v > 0:
                ax.axvline(v, color="0.3", ls="--", lw=1.0, zorder=1, gid="truth")
                want.truths.append(v)
        notes = []
        f = fails[(fails["scene"] == scene)]
        if f["reference"].astype(bool).any():
            notes.append("truth failed")
        notes += _listing("failed", [s for s in f.loc[~f["reference"].astype(bool), "short_label"]])
        notes += _listing("no time", list(names[~placed & np.isfinite(y)]))
        if notes:
            want.notes = ax.text(0.02, 0.02, "\n".join(notes), transform=ax.transAxes, fontsize=NOTE_PT,
                                 color=FAIL_COLOR, va="bottom", ha="left", zorder=7,
                                 bbox=dict(boxstyle="round,pad=0.25", fc="white", ec=FAIL_COLOR, lw=0.5, alpha=0.85))
        ys = list(y[placed])
        if xs and ys:
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlim(min(xs) / X_PAD_FACTOR, max(xs) * X_PAD_FACTOR)
            # the threshold always in range: a panel where nothing fails shows it
            ylo, yhi = min(ys + [threshold]), max(ys + [threshold])
            ax.set_ylim(ylo / Y_PAD_FACTOR, yhi * Y_PAD_FACTOR)
            for axis, (lo, hi), room in ((ax.xaxis, ax.get_xlim(), x_room), (ax.yaxis, ax.get_ylim(), y_room)):
                # three labels a decade where they fit in the panel's estimated length, else one
                subs = (1.0, 2.0, 5.0) if 3 * math.log10(hi / lo) <= room else (1.0,)
                axis.set_major_locator(LogLocator(base=10, subs=subs))
                axis.set_major_formatter(plain)
                # no minor ticks: on log axes matplotlib makes a tick object for each one, and laying
                # them out was most of the figure's time (measured on the quick study); the grid
                # follows the labelled ticks
                axis.set_minor_locator(NullLocator())
            ax.axhline(threshold, color=FAIL_COLOR, ls="-", lw=FAIL_LINE_PT, alpha=0.8, zorder=1, gid="fail-threshold")
            ax.axhspan(threshold, ax.get_ylim()[1], color=FAIL_COLOR, alpha=FAIL_BAND_ALPHA, lw=0, zorder=0)
            any_fail_line = True
        else:
            ax.set_xticks([])
            ax.set_yticks([])
            ax.text(0.5, 0.55, "nothing to plot", ha="center", va="center", transform=ax.transAxes,
                    fontsize=NOTE_PT, color="0.4")
        front = pareto_front(np.where(placed, t, np.nan), np.where(placed, y, np.nan))
        if front.any() and xs and ys:
            # the staircase bounding the dominated region: down the first point's time from the
            # top, through the front, then right along the last point's error to the edge
            order = np.argsort(t[front], kind="stable")
            ft, fy = t[front][order], y[front][order]
            (x_lo, x_hi), (y_lo, y_hi) = ax.get_xlim(), ax.get_ylim()
            ax.plot(np.r_[ft[0], ft, x_hi], np.r_[y_hi, fy, fy[-1]], drawstyle="steps-post", color="k", lw=1.0,
                    alpha=0.7, zorder=2, gid="pareto-front")
            ax.scatter(ft, fy, s=(2 * MARKER_PT) ** 2, facecolors="none", edgecolors="k", linewidths=0.9,
                       zorder=4)
            # named in the fail colour where over the threshold, like the failing points off the front
            want.names += [(int(i), names[i], FAIL_COLOR if y[i] > threshold else NAME_COLOR, True)
                           for i in np.flatnonzero(front)[order]]
            ax.set_xlim(x_lo, x_hi)
            ax.set_ylim(y_lo, y_hi)
        failing = np.flatnonzero(placed & ~front & (y > threshold))
        for i in failing[np.argsort(-y[failing], kind="stable")][:FAIL_LABEL_MAX]:
            want.names.append((int(i), names[i], FAIL_COLOR, False))
        ax.tick_params(labelsize=TICK_PT)
        ax.grid(alpha=0.25, which="major")
    handles = [Line2D([], [], ls="none", marker=m, ms=MARKER_PT, color=c, mec=c, label=short.get(lab, lab))
               for lab, (c, m) in styles.items() if lab in drawn]
    handles += [Line2D([], [], color="k", lw=1.0, alpha=0.7, marker="o", mfc="none", mec="k", ms=2 * MARKER_PT,
                       label="Pareto front (named)"),
                Line2D([], [], color="0.3", ls="--", lw=1.0, label="truth (ray-traced): time")]
    drawn_metrics = set(panel_metrics.values())
    if any_fail_line:
        rules = [text for m, text in (("error_rate", f"error > {100 * FAIL_ERROR_RATE:g} %"),
                                      ("visibility_mae", f"soft: mean |V − G| > {100 * FAIL_VISIBILITY_MAE:g} %"),
                                      ("radiance_error",
                                       f"many lights: radiance error > {100 * FAIL_RADIANCE_ERROR:g} %"))
                 if m in drawn_metrics]
        handles.append(Line2D([], [], color=FAIL_COLOR, lw=FAIL_LINE_PT,
                              label="fails: " + ", ".join(rules) + " (named)"))
    if any_zero:
        handles.append(Line2D([], [], ls=":", color="0.55", marker="o", mfc="white", mec="0.3", mew=1.4,
                              ms=MARKER_PT, label=f"no wrong pixel: drawn at {ZERO_FLOOR_PIXELS:g} px"))
    ncol = _legend_columns(fig, [h.get_label() for h in handles], fig_w)
    legend_rows = math.ceil(len(handles) / ncol)
    # grow the figure by the legend's height (a row: the text and matplotlib's default 0.5-em
    # label spacing) so that the panels keep theirs
    fig.set_figheight(fig.get_figheight() + legend_rows * LEGEND_PT * 1.5 / 72)
    fig.legend(handles=handles, loc="outside upper center", ncol=ncol, fontsize=LEGEND_PT, frameon=False)
    fig.supxlabel("time per frame, ms (median, all lights; bar = IQR)  —  log scale", fontsize=AXIS_LABEL_PT)
    # the figure's y label names the metric most panels draw; a panel of another metric says its own
    main = max(sorted(drawn_metrics), key=lambda m: sum(v == m for v in panel_metrics.values())) \
        if drawn_metrics else "error_rate"
    for ax, m in panel_metrics.items():
        if m != main:
            ax.set_ylabel(AXIS_NAMES[m], fontsize=TICK_PT)
    fig.supylabel(AXIS_NAMES[main] + "  —  log scale", fontsize=AXIS_LABEL_PT)
    # lay the panels out once, name the points in pixels of that layout (the names are kept out
    # of it), then freeze it: a second constrained-layout pass at save time would cost as much
    # again (the log axes' ticks dominate) for the same positions
    fig.get_layout_engine().execute(fig)
    _place_text(fig, wanted)
    fig.set_layout_engine("none")
    return fig


def pareto_plot(results: pd.DataFrame, path) -> Path:
    """Write ``pareto.png`` (:func:`pareto_figure`: speed against error per scene, log axes,
    Pareto front, truth's time, zero errors at a floor) to ``path``, through a temporary name so
    that a reader never sees half a file. Returns ``path``."""
    path = Path(path)
    fig = pareto_figure(results)
    with replacing(path) as (tmp,):
        fig.savefig(tmp, format="png")
    return path
