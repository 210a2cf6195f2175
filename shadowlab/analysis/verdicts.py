"""The study's verdicts (docs/metrics.md#verdicts-and-significance): per scene and technique family its best
configuration, who is best on each scene by error and by time — ties decided by the tests
of :mod:`shadowlab.analysis.significance`, not by fixed tolerances — and one sentence per scene
family with medians and their intervals over the family's scenes.

Plain pandas over ``results.csv`` (:mod:`shadowlab.analysis.aggregate`) and, where the study has
it, ``tiles.npz`` (:mod:`shadowlab.study.tiles`): without tiles, errors tie only when equal.
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ..util.format import fmt_table_ms, fmt_table_pct, is_missing
from . import significance as sig
from .aggregate import (
    DEGENERATE_WHY, as_text, fail_threshold, failed_runs, family_order, fmt_limit, judged_metric, normalised,
    per_configuration, scenes_in_order,
)

#: How the pages and sentences name each verdict metric.
METRIC_NAMES = {"edge_error_rate": "edge error", "error_rate": "error rate", "visibility_mae": "mean |V − G|",
                "radiance_error": "radiance error"}
#: The verdict metrics that are their own fail metric (:func:`fail_metric`): each is what a
#: configuration fails by on its family's scenes. The edge error is not: hard scenes fail by
#: ``error_rate``.
SELF_JUDGED = ("visibility_mae", "radiance_error")


def metric_name(metric: str) -> str:
    """The words a page uses for a verdict metric ("edge error", "mean |V − G|", "radiance error")."""
    return METRIC_NAMES.get(metric, metric)


#: The frame the tooltips restate a wrong-pixel count at: the same share of a 1920×1080 frame.
FULL_HD = (1920, 1080)


def verdict_metric(scene_family: str, configurations: pd.DataFrame | None = None) -> str:
    """The error a scene family's verdicts are decided by: ``visibility_mae`` on soft scenes and
    ``radiance_error`` on many-light scenes
    (:func:`~shadowlab.analysis.aggregate.judged_metric`; the shaded image of every light at once,
    where a light's error weighs as much as its light), else ``edge_error_rate`` — wrong pixels
    per pixel of the truth's shadow boundary: what differs between hard-shadow techniques happens
    along edges, and as a share of every evaluated pixel their errors are tiny numbers nobody can
    read. ``error_rate`` where ``configurations`` (the family's per-configuration rows) have no
    edge figures (a study older than the column) or a scene whose truth has no shadow boundary
    (no edge to count errors against). A many-light family whose ``configurations`` have no
    radiance figure at all (a study older than the column) is judged like a hard one."""
    metric = judged_metric(scene_family)
    if metric == "radiance_error" and configurations is not None and len(configurations) \
            and configurations["radiance_error"].isna().all():
        metric = "error_rate"  # no shaded-image figures: the per-light rates are all there is
    if metric != "error_rate":
        return metric
    if configurations is not None and len(configurations):
        boundary = configurations.groupby("scene")["truth_boundary_pixels"].max()
        if configurations["edge_error_rate"].isna().all() or not (boundary > 0).all():
            return "error_rate"
    return "edge_error_rate"


def fail_metric(metric: str) -> str:
    """The column a configuration fails by where ``metric`` (:func:`verdict_metric`) decides the
    verdicts: the verdict metric itself on soft and many-light scenes (:data:`SELF_JUDGED`), else
    the thresholded ``error_rate`` (the edge error is shown, the share of the pixels decides a
    fail)."""
    return metric if metric in SELF_JUDGED else "error_rate"


def numerator_row(metric: str) -> int | None:
    """The row of a tile array (:func:`shadowlab.evaluation.tiles.tile_sums`) holding ``metric``'s
    numerator: wrong pixels for the thresholded rates, Σ|V − G| for ``visibility_mae``; None for
    ``radiance_error``, which has no per-tile numerator in ``tiles.npz`` (the tiles are per light,
    the shaded image is every light at once): its verdicts tie only on equal values."""
    from ..evaluation.tiles import ABS_DIFF, WRONG

    if metric == "radiance_error":
        return None
    return ABS_DIFF if metric == "visibility_mae" else WRONG


#: Columns of :func:`verdict_table`.
VERDICT_COLUMNS = ["scene", "scene_family", "technique", "label", "short_label", "metric", "error", "error_rate",
                   "wrong_per_light", "wrong_full_hd", "radiance_bias", "time_ms", "time_lo_ms", "time_hi_ms", "moving_ms", "moving_lo_ms", "moving_hi_ms",
                   "setup_ms", "scene_metric", "scene_metric_value", "configurations", "failed", "why", "degenerate",
                   "best_error", "best_time", "best_moving", "tested", "tiles", "denominator"]


def _tiles_of(tiles: dict | None, scene: str, spec_label: str, metric: str):
    arr = (tiles or {}).get((scene, spec_label))
    row = numerator_row(metric)
    return None if arr is None or row is None else np.asarray(arr)[row]


def rows_tie_on_error(a: pd.Series, b: pd.Series) -> bool:
    """Whether two verdict rows of one scene tie on error: the paired tile bootstrap
    (:func:`shadowlab.analysis.significance.errors_tie`) where both have tiles of the same layout,
    else equal values."""
    ta, tb = a.get("tiles"), b.get("tiles")
    if ta is not None and tb is not None and not is_missing(ta) and not is_missing(tb) and ta.shape == tb.shape:
        return sig.errors_tie(ta, tb)
    return bool(a["error"] == b["error"])


def _interval(row, col: str) -> tuple[float, float]:
    return float(row[f"{col}_lo_ms"]), float(row[f"{col}_hi_ms"])


def rows_tie_on_time(a, b, col: str = "time") -> bool:
    """Whether two verdict rows tie on static (``col`` 'time') or moving ('moving') time: their
    repeat intervals overlap (:func:`shadowlab.analysis.significance.intervals_overlap`)."""
    return sig.intervals_overlap(_interval(a, col), _interval(b, col))


def verdict_table(results: pd.DataFrame, scene_metrics: dict | None = None, tiles: dict | None = None) -> pd.DataFrame:
    """The study's headline, long form: one row per (scene, technique family) that was asked to
    run there — the family's *best configuration* on the scene, i.e. the lowest verdict error
    (:func:`verdict_metric`), ties broken by time, among its configurations that are not
    degenerate (:func:`shadowlab.evaluation.metrics.is_degenerate`: they draw almost no shadow where
    the truth has one, and their error understates what is lost). Only when every configuration of
    the family is degenerate is one chosen, and then it is marked (``degenerate``) and fails.

    Columns (:data:`VERDICT_COLUMNS`): ``metric`` (the verdict error's column) and ``error`` (its
    value); ``error_rate`` (the share of all evaluated pixels), ``wrong_per_light`` (the wrong
    pixels per light) and ``wrong_full_hd`` (those restated for a 1920×1080 frame with the same
    share of its pixels wrong); ``radiance_bias`` (the shaded image's signed error: > 0 brighter
    than the truth, shadows dropped; < 0 darker, lights dropped; NaN without the column); ``time_ms``
    (static light: per-frame time), ``moving_ms`` (moving light: plus the light-dependent
    preprocessing), each with its repeat interval (``*_lo_ms``, ``*_hi_ms``); ``setup_ms``; the
    scene's own metric and its value; ``configurations`` (how many of the family's ran);
    ``failed`` (bool: the chosen configuration's error is above
    :func:`~shadowlab.analysis.aggregate.fail_threshold` in :func:`fail_metric` — thresholded
    ``error_rate`` above 1 %, soft scenes mean |V − G| above 0.02, many-light scenes
    ``radiance_error`` above 5 % —, it is degenerate, or every run failed) and ``why``;
    ``degenerate``; ``best_error`` (bool: the lowest error of the scene among the families
    whose choice is not degenerate, or not told apart from it by the paired tile bootstrap at
    95 %, :mod:`shadowlab.analysis.significance`); ``best_time`` / ``best_moving`` (the fastest of
    the scene among the families that do not fail, or whose repeat interval overlaps its);
    ``tested`` (the error tie was tested on tiles, not by equality); ``tiles`` (the per-tile
    numerators of the verdict error, or None: ``tiles`` not given or missing for it, or the
    verdict error is ``radiance_error``, which has none — :func:`numerator_row`);
    ``denominator`` (the verdict error's pooled denominator: the truth's boundary pixels or the
    evaluated pixels). The verdict metric is decided per scene family (:func:`verdict_metric`)."""
    if results is None or not len(results):
        return pd.DataFrame(columns=VERDICT_COLUMNS)
    cfg = per_configuration(results, scene_metrics)
    conf = cfg[~cfg["reference"].astype(bool)] if len(cfg) else cfg
    fails = failed_runs(results)
    fails = fails[~fails["reference"].astype(bool)] if len(fails) else fails
    df = normalised(results)
    fam_of = df.drop_duplicates("scene").set_index("scene")["scene_family"].map(as_text)
    rows = []
    family_metric = {fam: verdict_metric(fam, conf[conf["scene"].isin(fam_of.index[fam_of == fam])])
                     for fam in dict.fromkeys(fam_of)}
    for scene in scenes_in_order(df):
        g = conf[conf["scene"] == scene]
        metric = family_metric[fam_of.get(scene, "")]
        failing_by = fail_metric(metric)
        limit = fail_threshold(failing_by)
        f = fails[fails["scene"] == scene] if len(fails) else fails
        techs = family_order(list(g["technique"]) + list(f["technique"] if len(f) else []))
        for tech in techs:
            gt = g[g["technique"] == tech].assign(_err=lambda d: d[metric])
            ft = f[f["technique"] == tech] if len(f) else f
            row = dict.fromkeys(VERDICT_COLUMNS, math.nan)
            row.update(scene=scene, scene_family=fam_of.get(scene, ""), technique=tech, metric=metric,
                       configurations=len(gt), degenerate=False, best_error=False, best_time=False,
                       best_moving=False, tested=False, tiles=None)
            # a degenerate configuration is never the family's best while a sound one ran
            scored = gt[gt["_err"].notna()].assign(_deg=lambda d: d["degenerate"].astype(bool)).sort_values(
                ["_deg", "_err", "time_ms"], kind="stable", na_position="last")
            if len(scored):
                best = scored.iloc[0]
                row.update(label=best["label"], short_label=best["short_label"], error=float(best["_err"]),
                           error_rate=best["error_rate"], radiance_bias=best["radiance_bias"],
                           time_ms=best["time_ms"], time_lo_ms=best["time_lo_ms"],
                           time_hi_ms=best["time_hi_ms"], moving_ms=best["moving_ms"],
                           moving_lo_ms=best["time_lo_ms"] + best["preprocess_ms"],
                           moving_hi_ms=best["time_hi_ms"] + best["preprocess_ms"], setup_ms=best["setup_ms"],
                           scene_metric=best["scene_metric"], scene_metric_value=best["scene_metric_value"],
                           tiles=_tiles_of(tiles, scene, best["spec_label"], metric),
                           denominator=best["truth_boundary_pixels" if metric == "edge_error_rate"
                                         else "evaluated_pixels"])
                pixels, lights = best["frame_pixels"], best["lights"]
                if not (is_missing(best["wrong_pixels"]) or is_missing(pixels)) and pixels > 0:
                    row["wrong_per_light"] = best["wrong_pixels"] / lights
                    row["wrong_full_hd"] = row["wrong_per_light"] * FULL_HD[0] * FULL_HD[1] / pixels
                row["degenerate"] = bool(best["_deg"])
                over = bool(best[failing_by] > limit)
                row["failed"] = over or row["degenerate"]
                row["why"] = "; ".join(([f"{failing_by} above {fmt_limit(failing_by, limit)}"] if over else [])
                                       + ([DEGENERATE_WHY] if row["degenerate"] else []))
            else:
                first = ft.iloc[0] if len(ft) else None
                row.update(label=first["label"] if first is not None else "", short_label=first["short_label"]
                           if first is not None else "", failed=True,
                           why=f"run failed: {first['error']}" if first is not None else "no result")
            rows.append(row)
    out = pd.DataFrame(rows, columns=VERDICT_COLUMNS)
    for _, idx in out.groupby("scene", sort=False).groups.items():
        part = out.loc[idx]
        sound = part[~part["degenerate"].astype(bool) & part["error"].notna()]  # a lost shadow's small error is no scene's best
        if len(sound):
            best = sound.loc[sound["error"].idxmin()]
            for i, r in sound.iterrows():
                out.at[i, "best_error"] = bool(i == best.name or rows_tie_on_error(r, best))
                out.at[i, "tested"] = (r["tiles"] is not None and best["tiles"] is not None
                                       and r["tiles"].shape == best["tiles"].shape)
        ok = part[~part["failed"].astype(bool)]
        for col, flag in (("time", "best_time"), ("moving", "best_moving")):
            timed = ok[ok[f"{col}_ms"].notna()]
            if len(timed):
                fastest = timed.loc[timed[f"{col}_ms"].idxmin()]
                for i, r in timed.iterrows():
                    out.at[i, flag] = bool(i == fastest.name or rows_tie_on_time(r, fastest, col))
    return out


# --------------------------------------------------------------------------- sentences

def _median_text(show, med: float, lo: float, hi: float, coverage: float, n: int) -> str:
    """A median over the scenes with its interval: "95 % interval" when the order statistics give
    one, else the range over the scenes (:func:`~shadowlab.analysis.significance.median_interval`)."""
    if n <= 1 or lo == hi:
        return show(med)
    what = f"{100 * sig.LEVEL:g} % interval" if coverage >= sig.LEVEL else f"range over the {n} scenes"
    return f"{show(med)}; {what} {show(lo)}–{show(hi)}"


def _pairs(g: pd.DataFrame, tech: str, best: str):
    """Per scene of ``g`` (verdict rows of one scene family) where both techniques have a row: the
    two verdict rows."""
    for _, s in g.groupby("scene", sort=False):
        a, b = s[s["technique"] == tech], s[s["technique"] == best]
        if len(a) and len(b):
            yield a.iloc[0], b.iloc[0]


def _outcomes(g: pd.DataFrame, tech: str, best: str, value: str, tie) -> tuple[list[float], int, int]:
    """``tech`` against ``best`` scene by scene: the differences of ``value`` (0 where ``tie`` says
    the scene's own test ties them), and on how many scenes ``tech`` is worse and better."""
    diffs = []
    for a, b in _pairs(g, tech, best):
        if is_missing(a[value]) or is_missing(b[value]):
            continue
        diffs.append(0.0 if tie(a, b) else float(a[value]) - float(b[value]))
    return diffs, sum(d > 0 for d in diffs), sum(d < 0 for d in diffs)


def _errors_separated(g: pd.DataFrame, tech: str, best: str) -> bool | None:
    """Whether ``tech``'s error differs from ``best``'s over the family's scenes by the tile
    bootstrap of all of them at once (:func:`~shadowlab.analysis.significance.stratified_interval`);
    None when a scene lacks tiles (the caller then compares scene by scene)."""
    pairs = []
    for a, b in _pairs(g, tech, best):
        ta, tb = a["tiles"], b["tiles"]
        if ta is None or tb is None or is_missing(a["denominator"]) or ta.shape != tb.shape:
            return None
        pairs.append((ta, tb, float(a["denominator"])))
    if not pairs:
        return None
    lo, hi = sig.stratified_interval(pairs)
    return not (lo <= 0.0 <= hi)


def _leaders(g: pd.DataFrame, techs: list[str], value: str, tie,
             pooled_test=None) -> tuple[str, list[tuple[str, int, int, int]], tuple, int]:
    """The technique with the lowest median ``value`` over the family's scenes (then the lowest
    mean); the others it is not told apart from, each with (name, scenes compared, scenes where it
    is worse, better) — ``pooled_test`` (tech, best) → separated, or None, decides where it can,
    else :func:`~shadowlab.analysis.significance.separated` on the per-scene differences; and the
    leader's (median, low, high, coverage) with its scene count."""
    med = {t: sig.median_interval(g.loc[g["technique"] == t, value]) for t in techs}
    med = {t: m for t, m in med.items() if not math.isnan(m[0])}
    if not med:
        return "", [], (math.nan, math.nan, math.nan, math.nan), 0
    # equal medians (several exact techniques at 0) are told apart by the mean: the leader is never
    # worse than a technique the tests then separate from it
    mean = {t: float(np.nanmean(pd.to_numeric(g.loc[g["technique"] == t, value], errors="coerce"))) for t in med}
    best = min(med, key=lambda t: (med[t][0], mean[t], techs.index(t)))
    tied = []
    for t in sorted((t for t in med if t != best), key=lambda t: (med[t][0], mean[t], techs.index(t))):
        diffs, worse, better = _outcomes(g, t, best, value, tie)
        apart = pooled_test(t, best) if pooled_test is not None else None
        if not (sig.separated(diffs) if apart is None else apart):
            tied.append((t, len(diffs), worse, better))
    return best, tied, med[best], int(g.loc[g["technique"] == best, value].notna().sum())


def _tied_text(tied, lead: str, level: str) -> str:
    """", not told apart from it at 95 %: A (worse on 2 of 3 scenes), B" — each with its record."""
    def record(name, n, worse, better):
        if n <= 1 or not (worse or better):
            return name
        parts = ([f"worse on {worse}"] if worse else []) + ([f"better on {better}"] if better else [])
        return f"{name} ({' and '.join(parts)} of {n} scenes)"

    return f", {lead} at {level}: " + ", ".join(record(*t) for t in tied) if tied else ""


def verdict_sentences(verdicts: pd.DataFrame) -> list[tuple[str, str]]:
    """One sentence per scene family, from :func:`verdict_table`: (family, sentence) saying who is
    most accurate — the lowest median error over the family's scenes, with its order-statistic
    interval over the scenes (or their range), among the techniques that ran on most of them and
    fail none (the median would hide a failure) — and which techniques cannot be told apart from
    it (the tile bootstrap over all the family's scenes at once,
    :func:`~shadowlab.analysis.significance.stratified_interval`; without tiles,
    :func:`~shadowlab.analysis.significance.separated` on the per-scene differences), each with
    the scenes where it is worse or better; who is fastest for a static and for a moving light
    among the techniques that fail none of those scenes (per-scene differences, 0 where the repeat
    intervals overlap, :func:`~shadowlab.analysis.significance.separated`); and who fails where."""
    out = []
    if not len(verdicts):
        return out
    level = f"{100 * sig.LEVEL:g} %"
    for fam, g in verdicts.groupby("scene_family", sort=False):
        scenes = list(dict.fromkeys(g["scene"]))
        n = len(scenes)
        per = g.groupby("technique", sort=False).agg(scenes=("scene", "nunique"), fails=("failed", "sum"))
        per = per.loc[[t for t in family_order(per.index) if t in per.index]]
        full = per[per["scenes"] == per["scenes"].max()]
        metric = g["metric"].iloc[0]
        show = fmt_table_pct if metric != "visibility_mae" else (lambda v: f"{v:.4f}")
        where = f"{n} scene{'s' if n != 1 else ''}: {', '.join(scenes)}"
        parts = []
        scored = full[full.index.map(lambda t: g.loc[g["technique"] == t, "error"].notna().any())]
        if (scored["fails"] == 0).any():  # a technique that fails a scene of the family is not its most accurate
            scored = scored[scored["fails"] == 0]
        if len(scored):
            best, tied, (med, lo, hi, cover), k = _leaders(g, list(scored.index), "error", rows_tie_on_error,
                                                           lambda t, b: _errors_separated(g, t, b))
            parts.append(f"most accurate: {best} (median {metric_name(metric)} "
                         f"{_median_text(show, med, lo, hi, cover, k)})"
                         + _tied_text(tied, "not told apart from it", level))
        sound = list(full.index[full["fails"] == 0])
        sound = [t for t in sound if g.loc[g["technique"] == t, "time_ms"].notna().all()]
        if sound:
            ms = lambda v: f"{fmt_table_ms(v)} ms"  # noqa: E731 - a local formatter
            fast, fast_tied, (m, lo, hi, cover), k = _leaders(g, sound, "time_ms",
                                                              lambda a, b: rows_tie_on_time(a, b, "time"))
            parts.append(f"fastest for a static light: {fast} ({_median_text(ms, m, lo, hi, cover, k)})"
                         + _tied_text(fast_tied, "tied with it", level))
            move, move_tied, (m, lo, hi, cover), k = _leaders(g, sound, "moving_ms",
                                                              lambda a, b: rows_tie_on_time(a, b, "moving"))
            names = lambda lead, ties: [lead] + [t[0] for t in ties]  # noqa: E731
            if names(move, move_tied) == names(fast, fast_tied):
                parts.append("the same for a moving light")
            else:
                text = (f"for a moving light: {move} ({_median_text(ms, m, lo, hi, cover, k)})"
                        + _tied_text(move_tied, "tied with it", level))
                if fast not in names(move, move_tied):
                    pre = sig.median_interval(g.loc[g["technique"] == fast, "moving_ms"])[0]
                    text += f"; {fast} needs {ms(pre)} with its per-light preprocessing"
                parts.append(text)
        else:
            parts.append("no technique passes every scene")
        failing = per[per["fails"] > 0]
        if len(failing):
            parts.append("fails: " + ", ".join(f"{t} on {int(r['fails'])} of {int(r['scenes'])}"
                                               for t, r in failing.iterrows()))
        else:
            parts.append("no technique fails")
        out.append((fam or "(none)", f"{(fam or 'Other scenes').capitalize()} ({where}) — " + "; ".join(parts) + "."))
    return out
