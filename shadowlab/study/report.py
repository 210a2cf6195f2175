"""The study report (DESIGN §12): the comparison drawn across every scene of a suite.

Three files in the study directory, all made from ``results.csv`` (one row per scene × light ×
configuration, the ground truth's rows included with ``reference`` True, plus the study columns
``scene_family, status, error, run_dir, revision, renderer, shaded_image, error_image,
worst_crop_image, worst_box, worst_errors``):

- ``pareto.png`` — speed against error, one panel per scene, the Pareto front marked
  (:func:`pareto_plot`);
- ``summary.md`` — per configuration: median error and time across the suite, wins per
  hard-case family, fails (:func:`write_summary_md`);
- ``study.html`` — the above, failed runs, and per scene a strip of error maps with magnified
  crops of each configuration's worst region (:func:`write_study_html`).

A *configuration* is one ``label`` (the full spec) on one scene; its lights are pooled
(:func:`per_configuration`): a frame renders every light, so times add up and error rates are
pooled over every light's evaluated pixels. The run report's helpers (colours, table formats)
are reused so that the two reports read alike.
"""
from __future__ import annotations

import html
import math
import os
from pathlib import Path
from urllib.parse import quote

import numpy as np
import pandas as pd

from ..metrics import COLUMN_BY_NAME, format_table
from ..report import ERROR_COLORS, SIGNED_CAPTION

#: A configuration *fails* a scene when its run failed or its error rate (pooled over the scene's
#: lights) exceeds this fraction of the evaluated pixels: 1 %.
FAIL_ERROR_RATE = 0.01
#: Zero error has no place on a log axis: it is drawn at this many wrong pixels (half a pixel of
#: the configuration's evaluated pixels, below any real error, which is at least one pixel).
ZERO_FLOOR_PIXELS = 0.5
#: Panels per row of the Pareto figure (fewer when there are fewer scenes).
PANEL_COLUMNS = 4
#: Failed or untimed configurations listed by name in a panel before "... and N more".
PANEL_LIST_MAX = 5

#: Columns of :func:`per_configuration`, in order.
CONFIG_COLUMNS = ["scene", "scene_family", "technique", "label", "short_label", "reference", "lights",
                  "evaluated_pixels", "error_rate", "false_shadow_rate", "false_lit_rate", "boundary_error_px",
                  "time_ms", "time_iqr_ms", "setup_ms", "wrong_pixels", "run_dir", "shaded_image", "error_image",
                  "worst_crop_image", "worst_box", "worst_errors", "signed_image"]
#: (rate, its pixel-count denominator column) — the rates pooled over lights by their denominators.
_RATE_WEIGHTS = {"error_rate": "evaluated_pixels", "false_shadow_rate": "truth_lit_pixels",
                 "false_lit_rate": "truth_shadowed_pixels"}
_IMAGE_COLUMNS = ["run_dir", "shaded_image", "error_image", "worst_crop_image", "worst_box", "worst_errors",
                  "signed_image"]


# --------------------------------------------------------------------------- small helpers

def _is_missing(value) -> bool:
    if value is None:
        return True
    try:
        return bool(pd.isna(value))
    except (TypeError, ValueError):
        return False


def _text(value) -> str:
    """A cell as text: '' for None / NaN."""
    return "" if _is_missing(value) else str(value)


def _truthy(series: pd.Series) -> pd.Series:
    """A bool column that may have been read back from CSV as text ('True'/'False') or with NaN."""
    if series.dtype == bool:
        return series
    return series.map(lambda v: (not _is_missing(v)) and str(v).strip().lower() in ("true", "1", "1.0", "yes"))


def _normalised(results: pd.DataFrame) -> pd.DataFrame:
    """``results`` with ``reference`` as bool and ``status`` filled ('ok' where the column is
    absent or empty), ``scene_family`` and ``short_label`` present."""
    df = results.copy()
    df["reference"] = _truthy(df["reference"]) if "reference" in df.columns else False
    if "status" not in df.columns:
        df["status"] = "ok"
    df["status"] = df["status"].map(lambda v: _text(v) or "ok")
    if "scene_family" not in df.columns:
        df["scene_family"] = ""
    if "short_label" not in df.columns:
        df["short_label"] = df["label"]
    if "error" not in df.columns:
        df["error"] = ""
    return df


def _num(df: pd.DataFrame, col: str) -> np.ndarray:
    if col not in df.columns:
        return np.full(len(df), np.nan)
    return pd.to_numeric(df[col], errors="coerce").to_numpy(dtype=float)


def _pooled(rates: np.ndarray, weights: np.ndarray) -> float:
    """The weighted mean of per-light ``rates`` by their denominators ``weights`` (= the rate of
    the pooled counts); 0 for an empty pooled denominator (DESIGN §7); the plain mean when a
    weight is unknown."""
    if np.isnan(rates).all():
        return math.nan
    if np.isnan(weights).any():
        return float(np.nanmean(rates))
    total = weights.sum()
    return float((rates * weights).sum() / total) if total > 0 else 0.0


def _scenes(df: pd.DataFrame) -> list[str]:
    """Scene names in order of first appearance (the suite's order)."""
    return list(dict.fromkeys(df["scene"].astype(str)))


def _family_order(names) -> list[str]:
    """Technique families in the registry's order (unknown names, e.g. failed specs, last, sorted)."""
    from ..techniques import REGISTRY

    names = set(names)
    return [n for n in REGISTRY if n in names] + sorted(names - set(REGISTRY))


def _styles(families) -> dict[str, tuple[str, str]]:
    """Colour and marker per family: each technique's declared ``STYLE`` (grey dots for names
    the registry does not know)."""
    from ..techniques import REGISTRY

    out = {}
    for fam in _family_order(families):
        style = REGISTRY[fam].STYLE if fam in REGISTRY else None
        out[fam] = (style.color, style.marker) if style is not None else ("#999999", ".")
    return out


def _pct(rate) -> str:
    return COLUMN_BY_NAME["error_rate"].format(None if _is_missing(rate) else float(rate))


def _ms(value) -> str:
    return COLUMN_BY_NAME["time_ms_median"].format(None if _is_missing(value) else float(value))


def _write_text(path: Path, text: str) -> None:
    """Write ``text`` to a temporary name beside ``path`` and rename it into place."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


# --------------------------------------------------------------------------- aggregation

def per_configuration(results: pd.DataFrame) -> pd.DataFrame:
    """One row per (scene, configuration) that ran: the ``status == "ok"`` rows of
    ``results`` (results.csv) pooled over the scene's lights, in the order of ``results``.

    Why: a frame renders every light, so a configuration's cost on a scene is the sum of its
    per-light times, and its error is the share of wrong pixels among all the lights' evaluated
    pixels — the two numbers the study compares configurations by.

    Columns (:data:`CONFIG_COLUMNS`): ``scene, scene_family, technique, label, short_label,
    reference`` (bool: the ground truth) copied; ``lights`` (rows pooled); ``evaluated_pixels``
    (sum over lights); ``error_rate`` = the evaluated-pixel-weighted mean of the lights'
    error rates (= pooled wrong / pooled evaluated); ``false_shadow_rate`` and
    ``false_lit_rate`` weighted likewise by their own denominators, ``truth_lit_pixels`` and
    ``truth_shadowed_pixels``, where those count columns exist (else by evaluated pixels);
    a pooled denominator of 0 gives 0 (DESIGN §7); ``boundary_error_px`` = the mean over lights;
    ``time_ms`` = sum of ``time_ms_median`` over lights (NaN if any light has no time);
    ``time_iqr_ms`` = sum of ``time_ms_iqr`` (the lights were timed separately, so this is the
    spread of a frame if their fluctuations go together — a conservative bar); ``setup_ms`` =
    sum of the lights' set-up times (NaN where not measured);
    ``wrong_pixels`` = error_rate × evaluated_pixels (rounded); and from the first light's row
    (the one with images): ``run_dir, shaded_image, error_image, worst_crop_image, worst_box,
    worst_errors, signed_image`` ('' / NaN where absent; ``signed_image``: the signed difference
    map V − G of a soft configuration, :func:`shadowlab.report.signed_picture`).
    """
    if results is None or len(results) == 0:
        return pd.DataFrame(columns=CONFIG_COLUMNS)
    df = _normalised(results)
    df = df[df["status"] == "ok"]
    rows = []
    for (scene, label), g in df.groupby(["scene", "label"], sort=False):
        g = g.sort_values("light", kind="stable") if "light" in g.columns else g
        first = g.iloc[0]
        ev = _num(g, "evaluated_pixels")
        row = {"scene": scene, "scene_family": _text(first["scene_family"]), "technique": first["technique"],
               "label": label, "short_label": _text(first["short_label"]) or label,
               "reference": bool(g["reference"].any()), "lights": len(g),
               "evaluated_pixels": float(np.nansum(ev)) if not np.isnan(ev).all() else math.nan}
        for rate, weight in _RATE_WEIGHTS.items():
            w = _num(g, weight) if weight in g.columns else ev
            row[rate] = _pooled(_num(g, rate), w)
        be = _num(g, "boundary_error_px")
        row["boundary_error_px"] = float(np.nanmean(be)) if not np.isnan(be).all() else math.nan
        t, iqr = _num(g, "time_ms_median"), _num(g, "time_ms_iqr")
        row["time_ms"] = float(t.sum())  # NaN when any light has no time
        row["time_iqr_ms"] = float(np.nansum(iqr)) if not np.isnan(iqr).all() else math.nan
        row["setup_ms"] = float(_num(g, "setup_ms").sum()) if "setup_ms" in g.columns else math.nan
        n = row["evaluated_pixels"]
        row["wrong_pixels"] = (float(round(row["error_rate"] * n)) if not (_is_missing(n) or
                                                                            _is_missing(row["error_rate"]))
                               else math.nan)
        for col in _IMAGE_COLUMNS:
            row[col] = first[col] if col in g.columns else (math.nan if col == "worst_errors" else "")
        rows.append(row)
    return pd.DataFrame(rows, columns=CONFIG_COLUMNS)


def failed_runs(results: pd.DataFrame) -> pd.DataFrame:
    """One row per (scene, configuration) whose run failed (``status == "failed"``): columns
    ``scene, scene_family, technique, label, short_label, reference, error`` (the first light's
    message), in the order of ``results``."""
    cols = ["scene", "scene_family", "technique", "label", "short_label", "reference", "error"]
    if results is None or len(results) == 0:
        return pd.DataFrame(columns=cols)
    df = _normalised(results)
    df = df[df["status"] != "ok"]
    out = df.drop_duplicates(["scene", "label"])[cols].copy()
    out["error"] = out["error"].map(_text)
    return out.reset_index(drop=True)


def pareto_front(time, error) -> np.ndarray:
    """Bool mask of the points on the Pareto front of (``time``, ``error``) — both to be
    minimised, same-length 1-D arrays: a point is on the front when no other point is at least
    as good in both and strictly better in one. Points with exactly equal (time, error) do not
    dominate each other, so ties are all kept. Points with a NaN coordinate are never on the
    front and dominate nothing."""
    t = np.asarray(time, dtype=float).ravel()
    e = np.asarray(error, dtype=float).ravel()
    if t.shape != e.shape:
        raise ValueError(f"time and error differ in length: {t.shape} vs {e.shape}")
    ok = ~(np.isnan(t) | np.isnan(e))
    tv, evv = t[ok], e[ok]
    # dominated[i] = any j: t_j <= t_i and e_j <= e_i and (t_j < t_i or e_j < e_i)
    le = (tv[None, :] <= tv[:, None]) & (evv[None, :] <= evv[:, None])
    lt = (tv[None, :] < tv[:, None]) | (evv[None, :] < evv[:, None])
    front = np.zeros(t.shape, bool)
    front[ok] = ~(le & lt).any(axis=1)
    return front


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


# --------------------------------------------------------------------------- the Pareto figure

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

    df = _normalised(results) if len(results) else results
    cfg = per_configuration(results)
    fails = failed_runs(results)
    scenes = _scenes(df) if len(df) else []
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
        fam = _text(df.loc[df["scene"].astype(str) == scene, "scene_family"].iloc[0])
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


# --------------------------------------------------------------------------- the summary

def summary_table(results: pd.DataFrame) -> pd.DataFrame:
    """One row per non-reference configuration (``label``) across the suite, sorted by technique
    family, then median error, then median time: ``technique, label, short_label,
    median_error_rate, median_time_ms`` (medians over the scenes it ran on, from
    :func:`per_configuration`), ``scenes`` (ran, ok), ``failed`` (scenes whose run failed),
    ``wins`` (list of (scene_family, scene) where its error rate is the lowest among the
    scene's non-reference configurations; ties count for each), ``fails`` (list of (scene,
    reason): its run failed, or its error rate exceeds :data:`FAIL_ERROR_RATE`)."""
    cfg = per_configuration(results)
    conf = cfg[~cfg["reference"].astype(bool)]
    fails = failed_runs(results)
    fails = fails[~fails["reference"].astype(bool)]
    wins: dict[str, list] = {}
    for scene, g in conf.groupby("scene", sort=False):
        best = g["error_rate"].min()
        if pd.isna(best):
            continue
        for _, r in g[g["error_rate"] == best].iterrows():
            wins.setdefault(r["label"], []).append((r["scene_family"], scene))
    labels: dict[str, dict] = {}
    for _, r in pd.concat([conf[["technique", "label", "short_label"]],
                           fails[["technique", "label", "short_label"]]]).iterrows():
        labels.setdefault(r["label"], {"technique": r["technique"], "short_label": r["short_label"]})
    rows = []
    for label, info in labels.items():
        g = conf[conf["label"] == label]
        f = fails[fails["label"] == label]
        bad = [(s, f"failed: {e}" if e else "failed") for s, e in zip(f["scene"], f["error"])]
        bad += [(s, _pct(e)) for s, e in zip(g["scene"], g["error_rate"]) if e > FAIL_ERROR_RATE]
        rows.append({"technique": info["technique"], "label": label, "short_label": info["short_label"],
                     "median_error_rate": g["error_rate"].median() if len(g) else math.nan,
                     "median_time_ms": g["time_ms"].median() if len(g) else math.nan,
                     "median_setup_ms": g["setup_ms"].median() if len(g) else math.nan,
                     "scenes": len(g), "failed": len(f), "wins": wins.get(label, []), "fails": bad})
    out = pd.DataFrame(rows, columns=["technique", "label", "short_label", "median_error_rate", "median_time_ms",
                                      "median_setup_ms", "scenes", "failed", "wins", "fails"])
    if len(out):
        rank = {fam: i for i, fam in enumerate(_family_order(out["technique"]))}
        out["_fam"] = out["technique"].map(rank)
        out = out.sort_values(["_fam", "median_error_rate", "median_time_ms", "short_label"], kind="stable",
                              na_position="last").drop(columns="_fam").reset_index(drop=True)
    return out


def family_table(results: pd.DataFrame) -> pd.DataFrame:
    """Per scene family (in suite order): ``scene_family, scenes`` (count), ``best`` (the
    configurations with the lowest median error rate over the family's scenes; ties all listed),
    ``best_error_rate``, ``fastest`` (lowest median time), ``fastest_time_ms``, ``fastest_ok``
    (fastest with median error ≤ :data:`FAIL_ERROR_RATE`; '' if none) and ``fastest_ok_time_ms``.
    Candidates: the non-reference configurations that ran on the most of the family's scenes
    (all of them when any did), so that one lucky scene cannot win a family; ``coverage`` =
    "ran / scenes". Names are short labels."""
    cfg = per_configuration(results)
    conf = cfg[~cfg["reference"].astype(bool)]
    df = _normalised(results) if len(results) else results
    rows = []
    if not len(df):
        return pd.DataFrame(columns=["scene_family", "scenes", "coverage", "best", "best_error_rate", "fastest",
                                     "fastest_time_ms", "fastest_ok", "fastest_ok_time_ms"])
    fam_of = df.drop_duplicates("scene").set_index("scene")["scene_family"].map(_text)
    for fam in dict.fromkeys(fam_of):
        scenes = list(fam_of.index[fam_of == fam])
        g = conf[conf["scene"].isin(scenes)]
        med = g.groupby("label", sort=False).agg(short_label=("short_label", "first"), n=("scene", "nunique"),
                                                 err=("error_rate", "median"), time=("time_ms", "median"))
        row = {"scene_family": fam or "(none)", "scenes": len(scenes), "coverage": "", "best": "",
               "best_error_rate": math.nan, "fastest": "", "fastest_time_ms": math.nan, "fastest_ok": "",
               "fastest_ok_time_ms": math.nan}
        if len(med):
            med = med[med["n"] == med["n"].max()]
            row["coverage"] = f"{int(med['n'].max())}/{len(scenes)}"
            if med["err"].notna().any():
                best = med["err"].min()
                row["best"] = _names(med.loc[med["err"] == best, "short_label"])
                row["best_error_rate"] = best
            timed = med[med["time"].notna()]
            if len(timed):
                fast = timed.sort_values(["time", "err"], kind="stable").iloc[0]
                row["fastest"], row["fastest_time_ms"] = fast["short_label"], fast["time"]
                good = timed[timed["err"] <= FAIL_ERROR_RATE].sort_values(["time", "err"], kind="stable")
                if len(good):
                    row["fastest_ok"], row["fastest_ok_time_ms"] = good.iloc[0]["short_label"], good.iloc[0]["time"]
        rows.append(row)
    return pd.DataFrame(rows)


def _md_cell(value) -> str:
    return _text(value).replace("|", "\\|").replace("\n", " ")


def _md_table(header: list[str], rows: list[list]) -> str:
    """A pipe table padded to aligned columns (readable as plain text)."""
    cells = [[_md_cell(c) for c in header]] + [[_md_cell(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    lines = ["| " + " | ".join(c.ljust(w) for c, w in zip(r, widths)) + " |" for r in cells]
    lines.insert(1, "|" + "|".join("-" * (w + 2) for w in widths) + "|")
    return "\n".join(lines)


def _names(names, keep: int = 2) -> str:
    """Up to ``keep`` names, then "(+N tied)"."""
    names = list(dict.fromkeys(names))
    more = len(names) - keep
    return ", ".join(names[:keep]) + (f" (+{more} tied)" if more > 0 else "")


def _wins_text(wins: list[tuple[str, str]]) -> str:
    by_fam: dict[str, list[str]] = {}
    for fam, scene in wins:
        by_fam.setdefault(fam or "(none)", []).append(scene)
    return "; ".join(f"{fam} ({', '.join(s)})" for fam, s in by_fam.items())


def _wins_count(wins: list[tuple[str, str]]) -> str:
    if not wins:
        return "0"
    by_fam: dict[str, int] = {}
    for fam, _ in wins:
        by_fam[fam or "(none)"] = by_fam.get(fam or "(none)", 0) + 1
    return f"{len(wins)} (" + ", ".join(f"{f} {k}" for f, k in by_fam.items()) + ")"


def _meta_lines(meta: dict) -> list[tuple[str, str]]:
    size = meta.get("size")
    size_text = f"{size[0]}×{size[1]} pixels" if size and len(size) == 2 else ""
    if meta.get("repeat") is not None:
        size_text += f", {meta['repeat']} timed repeats after {meta.get('warmup', 0)} warm-up"
    items = [("size", size_text), ("device", _text(meta.get("device"))), ("revision", _text(meta.get("revision"))),
             ("date", _text(meta.get("date"))), ("timing", _text(meta.get("timing")))]
    return [(k, v) for k, v in items if v]


def write_summary_md(results: pd.DataFrame, path, meta: dict | None = None) -> Path:
    """Write ``summary.md``: the study at a glance, readable as plain text.

    Header: suite name, description and the facts of ``meta`` (size, device, revision, date,
    timing sentence). Then per configuration (short label; grouped by technique family, best
    median error first, from :func:`summary_table`): median error rate and median time per
    frame across the scenes it ran on, the number of scenes, wins (scenes where its error rate
    is the lowest of the scene's configurations, per scene family; ties count for each) and
    fails (runs that failed, or error rate > :data:`FAIL_ERROR_RATE`), with the scenes named
    below the table; per scene family the most accurate and the fastest configuration
    (:func:`family_table`); per scene its most accurate configuration; the failed runs.
    Returns ``path``."""
    meta = meta or {}
    path = Path(path)
    cfg = per_configuration(results)
    table = summary_table(results)
    fams = family_table(results)
    fails = failed_runs(results)
    truth = cfg[cfg["reference"].astype(bool)]
    lines = [f"# Study: {meta.get('name', '(unnamed)')}", ""]
    if meta.get("description"):
        lines += [str(meta["description"]), ""]
    lines += [f"- {k}: {v}" for k, v in _meta_lines(meta)]
    n_scenes = len(_scenes(results)) if len(results) else 0
    lines += [f"- {n_scenes} scenes, {len(table)} configurations, {len(fails)} failed runs", ""]
    lines += ["Error rate = wrong / evaluated pixels, pooled over a scene's lights; time = ms per frame, the "
              "sum of the lights' median times; setup = ms to set up for the lights (paid once for static lights, every "
              "frame for moving ones). Medians are taken across the scenes a configuration ran on. "
              "A win = the lowest error rate among a scene's configurations (ties count for each); a fail = "
              f"the run failed or its error rate exceeds {100 * FAIL_ERROR_RATE:g} % of the evaluated pixels.",
              ""]
    if len(truth):
        lines += [f"Ground truth ({', '.join(dict.fromkeys(truth['short_label']))}): median "
                  f"{_ms(truth['time_ms'].median())} ms per frame over {len(truth)} scenes.", ""]
    lines += ["## Configurations", ""]
    for tech, g in table.groupby("technique", sort=False):
        lines += [f"### {tech}", ""]
        lines.append(_md_table(["configuration", "median error", "median time ms", "setup ms", "scenes", "wins",
                                "fails"],
                               [[r["short_label"], _pct(r["median_error_rate"]), _ms(r["median_time_ms"]),
                                 _ms(r["median_setup_ms"]),
                                 f"{r['scenes']}" + (f" (+{r['failed']} failed)" if r["failed"] else ""),
                                 _wins_count(r["wins"]), str(len(r["fails"]))] for _, r in g.iterrows()]))
        notes = []
        for _, r in g.iterrows():
            parts = []
            if r["wins"]:
                parts.append("wins: " + _wins_text(r["wins"]))
            if r["fails"]:
                parts.append("fails: " + ", ".join(f"{s} ({why})" for s, why in r["fails"]))
            if parts:
                notes.append(f"- {r['short_label']} — " + "; ".join(parts))
        lines += [""] + notes + ([""] if notes else [])
    if len(fams):
        lines += ["## By scene family", "",
                  "Median over the family's scenes, among the configurations that ran on most of them "
                  f"(coverage); \"fastest ≤ {100 * FAIL_ERROR_RATE:g} %\" = the fastest whose median error "
                  "is within the fail threshold.", ""]
        lines.append(_md_table(
            ["scene family", "scenes", "coverage", "most accurate", "error", "fastest", "ms",
             f"fastest ≤ {100 * FAIL_ERROR_RATE:g} %", "ms"],
            [[r["scene_family"], r["scenes"], r["coverage"], r["best"], _pct(r["best_error_rate"]), r["fastest"],
              _ms(r["fastest_time_ms"]), r["fastest_ok"] or "(none)", _ms(r["fastest_ok_time_ms"])]
             for _, r in fams.iterrows()]))
        lines.append("")
    conf = cfg[~cfg["reference"].astype(bool)]
    if len(conf):
        lines += ["## By scene", ""]
        rows = []
        for scene, g in conf.groupby("scene", sort=False):
            best = g["error_rate"].min()
            winners = g[g["error_rate"] == best]
            fastest = g[g["time_ms"].notna()].sort_values(["time_ms", "error_rate"], kind="stable")
            rows.append([scene, g["scene_family"].iloc[0], _names(winners["short_label"]), _pct(best),
                         fastest["short_label"].iloc[0] if len(fastest) else "",
                         _ms(fastest["time_ms"].iloc[0]) if len(fastest) else "", len(g)])
        lines.append(_md_table(["scene", "family", "most accurate", "error", "fastest", "ms", "configurations"], rows))
        lines.append("")
    if len(fails):
        lines += ["## Failed runs", ""]
        lines.append(_md_table(["scene", "configuration", "error"],
                               [[r["scene"], r["label"], r["error"]] for _, r in fails.iterrows()]))
        lines.append("")
    _write_text(path, "\n".join(lines))
    return path


# --------------------------------------------------------------------------- the HTML page

def _rel(study_dir: Path, value) -> str | None:
    """A path of results.csv (relative to the study dir) as a relative URL, or None when empty
    or the file is not there. Absolute paths inside the study dir are made relative; others are
    not linked (the page must work when the study dir is copied elsewhere)."""
    text = _text(value).strip()
    if not text:
        return None
    p = Path(text)
    if p.is_absolute():
        try:
            p = p.resolve().relative_to(Path(study_dir).resolve())
        except ValueError:
            return None
    if not (Path(study_dir) / p).is_file():
        return None
    return quote(p.as_posix())


def _box_text(box) -> str:
    parts = _text(box).split(",")
    if len(parts) != 4:
        return ""
    x0, y0, x1, y1 = (p.strip() for p in parts)
    return f"x {x0}–{x1}, y {y0}–{y1}"


def _figure(study_dir: Path, r: pd.Series) -> str:
    """One configuration of a scene's strip: its error map, caption, its worst-region crop, and —
    for a soft configuration whose results row names one (``signed_image``) — its signed
    difference map V − G under them."""
    e = html.escape
    cap = (f'<b>{e(_text(r["short_label"]))}</b><br>error {e(_pct(r["error_rate"]))}'
           f' · {e(_ms(r["time_ms"]))} ms')
    err_img = _rel(study_dir, r["error_image"])
    img = (f'<img class="map" src="{e(err_img)}" alt="error map of {e(_text(r["short_label"]))}">'
           if err_img else '<div class="missing">no error map</div>')
    crop = _rel(study_dir, r["worst_crop_image"])
    worst = r["worst_errors"]
    wrong = r["wrong_pixels"]
    if crop:
        n = "" if _is_missing(worst) else f"{int(float(worst))} wrong px"
        box = _box_text(r["worst_box"])
        crop_html = (f'<img class="crop" src="{e(crop)}" alt="worst region of {e(_text(r["short_label"]))}">'
                     f'<figcaption>worst region{(" " + e(box)) if box else ""}: {e(n)} '
                     f'(magnified, first light)</figcaption>')
    elif (not _is_missing(worst) and float(worst) == 0) or (not _is_missing(wrong) and float(wrong) == 0):
        crop_html = '<div class="none">no wrong pixels</div>'
    else:
        crop_html = '<div class="missing">no crop</div>'
    signed = _rel(study_dir, r.get("signed_image"))
    signed_html = (f'<figure class="signed"><img class="map" src="{e(signed)}" alt="signed map of '
                   f'{e(_text(r["short_label"]))}"><figcaption>signed V − G (first light; blue too bright, '
                   f'red too dark; scale in the run report)</figcaption></figure>' if signed else "")
    return (f'<div class="cfg"><figure>{img}<figcaption>{cap}</figcaption></figure>'
            f'<figure class="worst">{crop_html}</figure>{signed_html}</div>')


def _summary_html(results: pd.DataFrame) -> str:
    table = summary_table(results)
    if not len(table):
        return "<p>No configuration ran.</p>"
    shown = pd.DataFrame({
        "technique": table["technique"], "configuration": table["short_label"],
        "median error": table["median_error_rate"].map(_pct), "median time, ms": table["median_time_ms"].map(_ms),
        "median setup, ms": table["median_setup_ms"].map(_ms),
        "scenes": [f"{s}" + (f" (+{f} failed)" if f else "") for s, f in zip(table["scenes"], table["failed"])],
        "wins": table["wins"].map(lambda w: _wins_text(w) or "—"),
        "fails": table["fails"].map(lambda fl: ", ".join(f"{s} ({why})" for s, why in fl) or "—")})
    return shown.to_html(index=False, escape=True, classes="summary")


def _scene_table(cfg_scene: pd.DataFrame) -> str:
    """The scene's metrics, formatted like the run report's table (pooled over lights)."""
    t = cfg_scene.rename(columns={"time_ms": "time_ms_median", "time_iqr_ms": "time_ms_iqr"})
    return format_table(t, "summary").to_html(index=False, escape=True)


def write_study_html(study_dir, results: pd.DataFrame, meta: dict, pareto_png: str = "pareto.png") -> Path:
    """Write ``study_dir/study.html`` and return its path.

    Sections: the header (suite, description, size, device, revision, date, timing sentence,
    workers, elapsed time, runs / cached / failed counts from ``meta``); the Pareto figure
    ``pareto_png`` (relative to the study dir); the summary table (per configuration, as in
    summary.md); the failed runs (scene, configuration, error) if any; the error-map legend
    (:data:`shadowlab.report.ERROR_COLORS`; and the signed map's caption when a configuration has
    one); then per scene a link to its run report
    (``run_dir``/report.html), its metrics pooled over lights, and a horizontal strip: the
    truth's shaded image, then per configuration its error map (caption: short label, error
    rate, time) with the magnified crop of its worst region under it (caption: the box and the
    number of wrong pixels; "no wrong pixels" when there are none) and, for a soft
    configuration with a ``signed_image``, its signed difference map V − G. Images are referenced by
    their paths relative to the study dir (missing files are named, not linked); all text is
    HTML-escaped."""
    e = html.escape
    study_dir = Path(study_dir)
    df = _normalised(results) if len(results) else results
    cfg = per_configuration(results)
    fails = failed_runs(results)
    name = _text(meta.get("name")) or "study"
    facts = [f"{k}: {e(v)}" for k, v in _meta_lines(meta)]
    if meta.get("workers") is not None:
        facts.append(f"workers: {e(_text(meta['workers']))}")
    if not _is_missing(meta.get("elapsed_s")):
        facts.append(f"elapsed: {float(meta['elapsed_s']):.1f} s")
    counts = [f"{meta[k]} {k}" for k in ("runs", "cached", "failed") if meta.get(k) is not None]
    if counts:
        facts.append("runs: " + e(" · ".join(counts)))
    if meta.get("suite_file"):
        facts.append(f"suite file: {e(Path(str(meta['suite_file'])).name)}")
    legend = "".join(f'<span class="sw" style="background:rgb({",".join(str(int(255 * v)) for v in col)})"></span>'
                     f"{e(label)} &nbsp; " for label, col in ERROR_COLORS.values())
    pareto = _rel(study_dir, pareto_png) or quote(Path(pareto_png).as_posix())
    has_signed = "signed_image" in cfg.columns and any(_rel(study_dir, v) for v in cfg["signed_image"])
    signed_note = (f'<p class="signed-legend">Soft configurations: {e(SIGNED_CAPTION)}; each run report has the '
                   f'colour bar of its scale.</p>' if has_signed else "")
    failed_html = ""
    if len(fails):
        ft = pd.DataFrame({"scene": fails["scene"], "configuration": fails["label"], "error": fails["error"]})
        failed_html = f'<h2 id="failed">Failed runs ({len(fails)})</h2>{ft.to_html(index=False, escape=True)}'
    scenes = _scenes(df) if len(df) else []
    nav = " · ".join(f'<a href="#scene-{k}">{e(s)}</a>' for k, s in enumerate(scenes))
    sections = []
    for k, scene in enumerate(scenes):
        rows = df[df["scene"].astype(str) == scene]
        fam = _text(rows["scene_family"].iloc[0])
        c = cfg[cfg["scene"] == scene]
        truth = c[c["reference"].astype(bool)]
        conf = c[~c["reference"].astype(bool)]
        run_dirs = [d for d in map(_text, rows.get("run_dir", pd.Series(dtype=str))) if d]
        link = ""
        if run_dirs:
            report = _rel(study_dir, f"{run_dirs[0].rstrip('/')}/report.html")
            link = (f'<a href="{e(report)}">run report</a>' if report
                    else f'run report: {e(run_dirs[0])}/report.html (missing)')
        strip = []
        if len(truth):
            tr = truth.iloc[0]
            shaded = _rel(study_dir, tr["shaded_image"])
            img = (f'<img class="map" src="{e(shaded)}" alt="ground truth, shaded">' if shaded
                   else '<div class="missing">no image</div>')
            strip.append(f'<div class="cfg"><figure>{img}<figcaption><b>truth</b> '
                         f'({e(_text(tr["short_label"]))})<br>shaded · {e(_ms(tr["time_ms"]))} ms</figcaption>'
                         f'</figure></div>')
        strip += [_figure(study_dir, r) for _, r in conf.iterrows()]
        f = fails[fails["scene"] == scene]
        strip += [f'<div class="cfg failed"><b>{e(_text(r["short_label"]))}</b>'
                  f'{" (ground truth)" if r["reference"] else ""}<br>failed: {e(r["error"])}</div>'
                  for _, r in f.iterrows()]
        table = _scene_table(conf) if len(conf) else ""
        sections.append(
            f'<h2 id="scene-{k}">{e(scene)}</h2>'
            f'<p class="fam">{e(fam) + " · " if fam else ""}{link}</p>'
            f'<div class="scroll">{table}</div>'
            f'<div class="strip">{"".join(strip)}</div>')
    doc = f"""<!doctype html>
<html><head><meta charset="utf-8"><title>shadowlab study — {e(name)}</title>
<style>
body {{ font-family: system-ui, sans-serif; margin: 1.5em; color: #222; }}
table {{ border-collapse: collapse; font-size: 0.85em; margin-bottom: 0.8em; }}
td, th {{ border: 1px solid #ccc; padding: 0.25em 0.5em; text-align: right; }}
table.summary td {{ text-align: left; }}
.scroll {{ overflow-x: auto; }}
.strip {{ display: flex; gap: 0.7em; overflow-x: auto; align-items: flex-start; padding-bottom: 0.6em; }}
.cfg {{ flex: 0 0 auto; width: 260px; }}
.cfg.failed {{ color: #b00000; font-size: 0.85em; border: 1px dashed #b00000; padding: 0.4em; }}
figure {{ margin: 0 0 0.4em 0; }}
img.map {{ width: 260px; border: 1px solid #999; }}
img.crop {{ width: 192px; image-rendering: pixelated; border: 1px solid #999; }}
figcaption {{ font-size: 0.78em; color: #444; word-break: break-word; }}
.none {{ font-size: 0.8em; color: #2a7a2a; }} .missing {{ font-size: 0.8em; color: #888; }}
.fam {{ margin-top: -0.6em; color: #555; }}
.sw {{ display: inline-block; width: 1em; height: 1em; vertical-align: middle; margin-right: 0.3em; border: 1px solid #666; }}
</style></head><body>
<h1>shadowlab study: {e(name)}</h1>
{f'<p>{e(_text(meta.get("description")))}</p>' if meta.get("description") else ''}
<p>{'<br>'.join(facts)}</p>
<h2>Speed vs error</h2>
<p><img src="{e(pareto)}" alt="speed against error per scene, Pareto front marked" style="max-width: 100%"></p>
<p class="fam">One panel per scene: time per frame (all lights) against error rate, both log scales; hollow
markers = no wrong pixel, drawn at half a pixel; step line = Pareto front; dashed = the ray-traced truth's time.</p>
<h2>Configurations across the suite</h2>
<p>Medians over the scenes each configuration ran on (error pooled over a scene's lights, time summed over
them). Win = lowest error rate of a scene; fail = the run failed or its error rate exceeds
{100 * FAIL_ERROR_RATE:g} % of the evaluated pixels.</p>
<div class="scroll">{_summary_html(results)}</div>
{failed_html}
<h2>Scenes</h2>
<p>{nav}</p>
<p>Error map legend: {legend} dimmed: not evaluated. Maps and crops show the first light; errors and times
pool every light. Crops are magnified with nearest-neighbour so single wrong pixels stay visible.</p>
{signed_note}
{''.join(sections)}
</body></html>
"""
    out = study_dir / "study.html"
    _write_text(out, doc)
    return out


def write_study_report(study_dir, results: pd.DataFrame, meta: dict) -> dict:
    """Draw the study's comparison into ``study_dir``: ``pareto.png`` (:func:`pareto_plot`),
    ``summary.md`` (:func:`write_summary_md`) and ``study.html`` (:func:`write_study_html`).
    Returns {"pareto": path, "html": path, "summary": path}."""
    study_dir = Path(study_dir)
    study_dir.mkdir(parents=True, exist_ok=True)
    pareto = pareto_plot(results, study_dir / "pareto.png")
    summary = write_summary_md(results, study_dir / "summary.md", meta)
    page = write_study_html(study_dir, results, meta, pareto.name)
    return {"pareto": pareto, "html": page, "summary": summary}
