"""Study aggregation (docs/contracts.md#study-directory): plain pandas over ``results.csv`` rows — configurations
pooled over a scene's lights, failed runs, Pareto fronts, per-configuration and per-family
summaries, and what the verdicts (:mod:`shadowlab.analysis.verdicts`) and the pick
(:mod:`shadowlab.analysis.pick`) build on.

``results.csv`` has one row per scene × light × configuration, the ground truth's rows
included with ``reference`` True, plus the study columns ``scene_family, status, error,
run_dir, revision, renderer`` and the image columns. Nothing here draws or writes HTML: the
page (:mod:`shadowlab.study.report`) and the Pareto figure (:mod:`shadowlab.output.pareto`)
read these tables.
"""
from __future__ import annotations

import math
from collections import OrderedDict

import numpy as np
import pandas as pd

from ..util.format import fmt_table_pct, is_missing

#: A configuration *fails* a scene when its run failed or its error rate (pooled over the scene's
#: lights) exceeds this fraction of the evaluated pixels: 1 %.
FAIL_ERROR_RATE = 0.01


#: Soft scenes (an area light: visibility is fractional) are judged on the visibility error
#: mean |V − G| (``visibility_mae``); a configuration fails one when it exceeds this: 0.02.
FAIL_VISIBILITY_MAE = 0.02

#: Many-light scenes (the ``many lights`` family) are judged on the shaded image of every light at
#: once, ``radiance_error`` (mean relative luminance error over the covered pixels,
#: docs/metrics.md#the-shaded-image-radiance-many-lights); a configuration fails one when it
#: exceeds this: 5 % — a shaded image off by a twentieth of its brightness on average, a dropped
#: shadow or light anyone sees.
FAIL_RADIANCE_ERROR = 0.05

#: Columns of :func:`per_configuration`, in order.
CONFIG_COLUMNS = ["scene", "scene_family", "technique", "label", "short_label", "spec_label", "reference", "lights",
                  "evaluated_pixels", "frame_pixels", "truth_boundary_pixels", "error_rate", "edge_error_rate",
                  "false_shadow_rate", "false_lit_rate", "boundary_error_px", "visibility_mae", "radiance_error",
                  "radiance_bias", "time_ms", "time_iqr_ms", "time_lo_ms",
                  "time_hi_ms", "setup_ms", "preprocess_ms", "moving_ms", "scene_metric", "scene_metric_value",
                  "wrong_pixels", "degenerate", "run_dir", "shaded_image", "error_image", "signed_image",
                  "footprint_image"]
#: How the pages mark a degenerate configuration (:func:`shadowlab.evaluation.metrics.is_degenerate`: it draws
#: almost no shadow where the truth has one), beside its name or error, as ✗ marks a failure.
DEGENERATE_MARK = "✗ degenerate"
#: Why a degenerate configuration fails a scene, as the verdict table says it.
DEGENERATE_WHY = "degenerate: draws almost no shadow where the truth has one"


#: (rate, its pixel-count denominator column) — the rates pooled over lights by their denominators.
_RATE_WEIGHTS = {"error_rate": "evaluated_pixels", "edge_error_rate": "truth_boundary_pixels",
                 "false_shadow_rate": "truth_lit_pixels", "false_lit_rate": "truth_shadowed_pixels"}


#: How results.csv's ``config`` names a tuned configuration: ``<spec as written> [tuned <params>]``
#: (:attr:`shadowlab.study.suite.TunedEntry.name`). Its spec differs from scene to scene (each
#: scene's own optimum), so the study's tables and plots group its rows by this name instead.
TUNED_MARK = " [tuned "


def is_tuned_name(config: str) -> bool:
    """Whether a ``config`` name is a tuned configuration's (:data:`TUNED_MARK`)."""
    return TUNED_MARK in config and config.endswith("]")


_IMAGE_COLUMNS = ["run_dir", "shaded_image", "error_image", "signed_image", "footprint_image"]


def as_text(value) -> str:
    """A cell as text: '' for None / NaN."""
    return "" if is_missing(value) else str(value)


def is_true(value) -> bool:
    """A bool cell that may have been read back from CSV as text ('True'/'False') or as NaN."""
    return (not is_missing(value)) and str(value).strip().lower() in ("true", "1", "1.0", "yes")


def truthy(series: pd.Series) -> pd.Series:
    """A bool column that may have been read back from CSV as text ('True'/'False') or with NaN."""
    if series.dtype == bool:
        return series
    return series.map(is_true)


def normalised(results: pd.DataFrame) -> pd.DataFrame:
    """``results`` with ``reference`` as bool and ``status`` filled ('ok' where the column is
    absent or empty), ``scene_family`` and ``short_label`` present, and a tuned configuration's
    rows labelled by its ``config`` name (:func:`is_tuned_name`)."""
    df = results.copy()
    df["spec_label"] = df["label"]  # the spec as run: what tiles.npz names a configuration by
    df["reference"] = truthy(df["reference"]) if "reference" in df.columns else False
    if "status" not in df.columns:
        df["status"] = "ok"
    df["status"] = df["status"].map(lambda v: as_text(v) or "ok")
    if "scene_family" not in df.columns:
        df["scene_family"] = ""
    if "short_label" not in df.columns:
        df["short_label"] = df["label"]
    if "error" not in df.columns:
        df["error"] = ""
    if "config" in df.columns:
        # a tuned configuration runs a different spec on each scene: one name across the study
        tuned = df["config"].map(lambda c: is_tuned_name(as_text(c)))
        df.loc[tuned, "label"] = df.loc[tuned, "config"]
        df.loc[tuned, "short_label"] = df.loc[tuned, "config"]
    return df


def numeric(df: pd.DataFrame, col: str) -> np.ndarray:
    if col not in df.columns:
        return np.full(len(df), np.nan)
    return pd.to_numeric(df[col], errors="coerce").to_numpy(dtype=float)


def pooled(rates: np.ndarray, weights: np.ndarray) -> float:
    """The weighted mean of per-light ``rates`` by their denominators ``weights`` (= the rate of
    the pooled counts); 0 for an empty pooled denominator (docs/metrics.md); the plain mean when a
    weight is unknown."""
    if np.isnan(rates).all():
        return math.nan
    if np.isnan(weights).any():
        return float(np.nanmean(rates))
    total = weights.sum()
    return float((rates * weights).sum() / total) if total > 0 else 0.0


def scenes_in_order(df: pd.DataFrame) -> list[str]:
    """Scene names in order of first appearance (the suite's order)."""
    return list(dict.fromkeys(df["scene"].astype(str)))


#: The technique folders (docs/architecture.md) in the order tables list their techniques: the lab's
#: headline comparison — shadow volumes against shadow maps — first.
HOUSE_ORDER = ("volumes", "maps", "geometric", "rays")
#: Within a folder, its plain technique comes first, the refinements after it.
HOUSE_LEADS = ("shadow_volume", "shadow_map")


def house_of(name: str) -> str:
    """The technique folder a registered technique lives in ('' for an unknown name)."""
    from ..techniques import REGISTRY

    cls = REGISTRY.get(name)
    parts = cls.__module__.split(".") if cls is not None else []
    return parts[-2] if len(parts) >= 2 and parts[-2] in HOUSE_ORDER else ""


def family_order(names) -> list[str]:
    """Technique families as tables list them: by folder in :data:`HOUSE_ORDER` (the headline,
    volumes and maps, first), the folder's plain technique first, then by name; unknown names
    (e.g. failed specs) last, sorted."""
    from ..techniques import REGISTRY

    names = set(names)
    known = [n for n in REGISTRY if n in names]
    rank = {h: i for i, h in enumerate(HOUSE_ORDER)}
    known.sort(key=lambda n: (rank.get(house_of(n), len(rank)), n not in HOUSE_LEADS, n))
    return known + sorted(names - set(REGISTRY))


#: The last few :func:`per_configuration` tables, by a hash of their input: a study's report asks
#: for the same table a dozen times (verdicts, picks, summaries, pages), and on a study of 700
#: configurations each costs seconds.
_CONFIG_CACHE: OrderedDict = OrderedDict()
_CONFIG_CACHE_SIZE = 8


def per_configuration(results: pd.DataFrame, scene_metrics: dict | None = None) -> pd.DataFrame:
    """:func:`pooled_configurations` of ``results``, computed once per distinct input (a copy is
    returned, so a caller's changes never reach the cache)."""
    try:
        key = (int(pd.util.hash_pandas_object(results, index=True).sum()), tuple(results.columns),
               tuple(sorted((k, str(v)) for k, v in (scene_metrics or {}).items())))
    except (TypeError, ValueError, AttributeError):  # unhashable cells, or no table: no caching
        return pooled_configurations(results, scene_metrics)
    if key not in _CONFIG_CACHE:
        _CONFIG_CACHE[key] = pooled_configurations(results, scene_metrics)
        while len(_CONFIG_CACHE) > _CONFIG_CACHE_SIZE:
            _CONFIG_CACHE.popitem(last=False)
    _CONFIG_CACHE.move_to_end(key)
    return _CONFIG_CACHE[key].copy()


def pooled_configurations(results: pd.DataFrame, scene_metrics: dict | None = None) -> pd.DataFrame:
    """One row per (scene, configuration) that ran: the ``status == "ok"`` rows of
    ``results`` (results.csv) pooled over the scene's lights, in the order of ``results``.

    Why: a frame renders every light, so a configuration's cost on a scene is the sum of its
    per-light times, and its error is the share of wrong pixels among all the lights' evaluated
    pixels — the two numbers the study compares configurations by.

    Columns (:data:`CONFIG_COLUMNS`): ``scene, scene_family, technique, label, short_label,
    reference`` (bool: the ground truth) copied; ``spec_label`` (the spec as run: a tuned
    configuration's ``label`` is its entry's name); ``lights`` (rows pooled); ``evaluated_pixels``
    (sum over lights); ``frame_pixels`` (width × height); ``error_rate`` = the evaluated-pixel-weighted mean of the lights'
    error rates (= pooled wrong / pooled evaluated); ``truth_boundary_pixels`` (sum over lights) and
    ``edge_error_rate`` = pooled wrong / pooled boundary, from the counts (NaN in a study without
    the columns, or when no light's truth has a boundary and some pixel is wrong); ``false_shadow_rate`` and
    ``false_lit_rate`` weighted likewise by their own denominators, ``truth_lit_pixels`` and
    ``truth_shadowed_pixels``, where those count columns exist (else by evaluated pixels);
    a pooled denominator of 0 gives 0 (docs/metrics.md); ``boundary_error_px`` = the mean over lights;
    ``time_ms`` = sum of ``time_ms_median`` over lights (NaN if any light has no time);
    ``time_iqr_ms`` = sum of ``time_ms_iqr`` (the lights were timed separately, so this is the
    spread of a frame if their fluctuations go together — a conservative bar); ``time_lo_ms``,
    ``time_hi_ms``: the repeat interval (:func:`repeat_interval`); ``setup_ms`` =
    sum of the lights' set-up times (NaN where not measured);
    ``visibility_mae`` weighted like ``error_rate``; ``radiance_error`` and ``radiance_bias``: the
    error of the configuration's shaded image (every light at once), the same on each of its light
    rows — the first light's value that is not NaN, NaN where results.csv has no such column (a
    study older than issue 40); ``preprocess_ms`` = the lights' summed
    light-dependent preprocessing (0 where a technique has none); ``moving_ms`` = ``time_ms`` +
    ``preprocess_ms``, a frame's cost when the light moves (the preprocessing is redone every
    frame; GL set-up — textures, programs — is not, so ``setup_ms`` is not in it);
    ``scene_metric`` = the column ``scene_metrics[scene]`` names (the metric the scene exists for;
    '' when none) and ``scene_metric_value`` its mean over lights;
    ``wrong_pixels`` = error_rate × evaluated_pixels (rounded); ``degenerate`` (bool: degenerate on
    any of the lights, :func:`shadowlab.evaluation.metrics.is_degenerate`; False where results.csv has no such
    column, a study older than issue 35); and from the first light's row
    (the one with images): ``run_dir, shaded_image, error_image, signed_image, footprint_image``
    ('' where absent; ``signed_image``: the signed difference
    map V − G of a soft configuration, :func:`shadowlab.output.pictures.signed_picture`).
    """
    if results is None or len(results) == 0:
        return pd.DataFrame(columns=CONFIG_COLUMNS)
    df = normalised(results)
    df = df[df["status"] == "ok"].reset_index(drop=True)
    # every numeric column converted once (the per-group work is then array slicing): None where
    # results.csv has no such column
    converted: dict[str, np.ndarray | None] = {}

    def column(name: str) -> np.ndarray | None:
        if name not in converted:
            converted[name] = (pd.to_numeric(df[name], errors="coerce").to_numpy(dtype=float)
                               if name in df.columns else None)
        return converted[name]

    def values(name: str, pos: np.ndarray) -> np.ndarray:
        arr = column(name)
        return np.full(len(pos), np.nan) if arr is None else arr[pos]

    light = column("light")
    degenerate = truthy(df["degenerate"]).to_numpy(bool) if "degenerate" in df.columns else None
    reference = df["reference"].to_numpy(bool)
    rows = []
    for (scene, label), pos in df.groupby(["scene", "label"], sort=False).indices.items():
        if light is not None:
            pos = pos[np.argsort(light[pos], kind="stable")]
        first = df.iloc[pos[0]]
        ev = values("evaluated_pixels", pos)
        row = {"scene": scene, "scene_family": as_text(first["scene_family"]), "technique": first["technique"],
               "label": label, "short_label": as_text(first["short_label"]) or label,
               "spec_label": as_text(first["spec_label"]), "reference": bool(reference[pos].any()),
               "lights": len(pos), "evaluated_pixels": float(np.nansum(ev)) if not np.isnan(ev).all() else math.nan,
               "frame_pixels": float(values("width", pos[:1])[0] * values("height", pos[:1])[0])}
        for rate, weight in _RATE_WEIGHTS.items():
            w = values(weight, pos) if column(weight) is not None else ev
            row[rate] = pooled(values(rate, pos), w)
        tb = values("truth_boundary_pixels", pos)
        row["truth_boundary_pixels"] = float(tb.sum()) if not np.isnan(tb).any() else math.nan
        edge = _pooled_edge(tb, values("false_shadow_pixels", pos) + values("false_lit_pixels", pos))
        if edge is not None:
            row["edge_error_rate"] = edge
        be = values("boundary_error_px", pos)
        row["boundary_error_px"] = float(np.nanmean(be)) if not np.isnan(be).all() else math.nan
        t, iqr = values("time_ms_median", pos), values("time_ms_iqr", pos)
        row["time_ms"] = float(t.sum())  # NaN when any light has no time
        row["time_iqr_ms"] = float(np.nansum(iqr)) if not np.isnan(iqr).all() else math.nan
        row["time_lo_ms"], row["time_hi_ms"] = repeat_interval(t, iqr, values("time_ms_q25", pos),
                                                               values("time_ms_q75", pos))
        row["setup_ms"] = float(values("setup_ms", pos).sum()) if column("setup_ms") is not None else math.nan
        vm = values("visibility_mae", pos)
        row["visibility_mae"] = pooled(vm, ev) if not np.isnan(vm).all() else math.nan
        for col in ("radiance_error", "radiance_bias"):
            # one value per configuration, repeated on its light rows: the first that is there
            rv = values(col, pos)
            known = rv[~np.isnan(rv)]
            row[col] = float(known[0]) if len(known) else math.nan
        pre = values("preprocess_ms", pos)
        row["preprocess_ms"] = float(np.nansum(pre)) if not np.isnan(pre).all() else 0.0
        row["moving_ms"] = row["time_ms"] + row["preprocess_ms"]
        metric = (scene_metrics or {}).get(scene)
        row["scene_metric"] = metric or ""
        mv = values(metric, pos) if metric else np.array([math.nan])
        row["scene_metric_value"] = float(np.nanmean(mv)) if not np.isnan(mv).all() else math.nan
        n = row["evaluated_pixels"]
        row["wrong_pixels"] = (float(round(row["error_rate"] * n)) if not (is_missing(n) or
                                                                            is_missing(row["error_rate"]))
                               else math.nan)
        row["degenerate"] = bool(degenerate[pos].any()) if degenerate is not None else False
        for col in _IMAGE_COLUMNS:
            row[col] = first[col] if col in df.columns else ""
        rows.append(row)
    return pd.DataFrame(rows, columns=CONFIG_COLUMNS)


def _pooled_edge(boundary: np.ndarray, wrong: np.ndarray) -> float | None:
    """The edge error rate of a configuration's lights pooled from their counts (the truth's
    ``boundary`` pixels and the ``wrong`` pixels, per light): Σ wrong / Σ boundary, so that a light
    whose truth has no boundary loses none of its wrong pixels; NaN when there is no boundary to
    count against and some pixel is wrong; None when a count is missing (the rate column's own
    pooling stands then)."""
    if np.isnan(boundary).any() or np.isnan(wrong).any():
        return None
    b, w = float(boundary.sum()), float(wrong.sum())
    return w / b if b > 0 else (0.0 if w == 0 else math.nan)


def repeat_interval(median: np.ndarray, iqr: np.ndarray, q25: np.ndarray, q75: np.ndarray) -> tuple[float, float]:
    """A configuration's repeat interval on a scene from its lights' timing columns: the sums of
    the first and third quartiles (``time_ms_q25``, ``time_ms_q75``); median ∓ IQR/2 where a study
    has no quartile columns; the median itself where it has no IQR either; NaN without a time."""
    half = np.where(np.isnan(iqr), 0.0, iqr / 2)
    lo = np.where(np.isnan(q25), median - half, q25)
    hi = np.where(np.isnan(q75), median + half, q75)
    return float(lo.sum()), float(hi.sum())


def failed_runs(results: pd.DataFrame) -> pd.DataFrame:
    """One row per (scene, configuration) whose run failed (``status == "failed"``): columns
    ``scene, scene_family, technique, label, short_label, reference, error`` (the first light's
    message), in the order of ``results``."""
    cols = ["scene", "scene_family", "technique", "label", "short_label", "reference", "error"]
    if results is None or len(results) == 0:
        return pd.DataFrame(columns=cols)
    df = normalised(results)
    df = df[df["status"] != "ok"]
    out = df.drop_duplicates(["scene", "label"])[cols].copy()
    out["error"] = out["error"].map(as_text)
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


def summary_table(results: pd.DataFrame) -> pd.DataFrame:
    """One row per non-reference configuration (``label``) across the suite, sorted by technique
    family, then median error, then median time: ``technique, label, short_label,
    median_error_rate, median_time_ms, median_setup_ms`` (medians over the scenes it ran on, from
    :func:`per_configuration`), ``worst_error_rate`` (its largest: the median hides a
    configuration that fails a few scenes), ``scenes`` (ran, ok), ``failed`` (scenes whose run failed),
    ``wins`` (list of (scene_family, scene) where its error rate is the lowest among the
    scene's non-reference configurations that are not degenerate; ties count for each), ``fails``
    (list of (scene, reason): its run failed, its error rate exceeds :data:`FAIL_ERROR_RATE`, or
    it is degenerate there — :data:`DEGENERATE_MARK` in the reason). On a many-light scene
    (:func:`judged_metric` ``radiance_error``, where the study has the column) wins and fails go by
    the shaded image's radiance error instead (above :data:`FAIL_RADIANCE_ERROR`; the reason names
    it), as the verdicts judge it: a budget's per-light error rate counts the dropped shadows of
    lights that barely matter like the rest."""
    cfg = per_configuration(results)
    conf = cfg[~cfg["reference"].astype(bool)]
    # the column each configuration is won and failed by on its scene
    radiance = (conf["scene_family"].map(judged_metric) == "radiance_error") & conf["radiance_error"].notna()
    conf = conf.assign(_judged=np.where(radiance, conf["radiance_error"], conf["error_rate"]), _radiance=radiance)
    fails = failed_runs(results)
    fails = fails[~fails["reference"].astype(bool)]
    wins: dict[str, list] = {}
    for scene, g in conf.groupby("scene", sort=False):
        sound = g[~g["degenerate"].astype(bool)]  # a configuration that draws no shadow wins nothing
        best = sound["_judged"].min()
        if pd.isna(best):
            continue
        for _, r in sound[sound["_judged"] == best].iterrows():
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
        bad += [(s, ("radiance error " if rad else "") + fmt_table_pct(e) + (f" {DEGENERATE_MARK}" if d else ""))
                for s, e, d, rad in zip(g["scene"], g["_judged"], g["degenerate"].astype(bool), g["_radiance"])
                if e > (FAIL_RADIANCE_ERROR if rad else FAIL_ERROR_RATE) or d]
        rows.append({"technique": info["technique"], "label": label, "short_label": info["short_label"],
                     "median_error_rate": g["error_rate"].median() if len(g) else math.nan,
                     "median_time_ms": g["time_ms"].median() if len(g) else math.nan,
                     "median_setup_ms": g["setup_ms"].median() if len(g) else math.nan,
                     "worst_error_rate": g["error_rate"].max() if len(g) else math.nan,
                     "scenes": len(g), "failed": len(f), "wins": wins.get(label, []), "fails": bad})
    out = pd.DataFrame(rows, columns=["technique", "label", "short_label", "median_error_rate", "median_time_ms",
                                      "median_setup_ms", "worst_error_rate", "scenes", "failed", "wins", "fails"])
    if len(out):
        rank = {fam: i for i, fam in enumerate(family_order(out["technique"]))}
        out["_fam"] = out["technique"].map(rank)
        out = out.sort_values(["_fam", "median_error_rate", "median_time_ms", "short_label"], kind="stable",
                              na_position="last").drop(columns="_fam").reset_index(drop=True)
    return out


def family_table(results: pd.DataFrame) -> pd.DataFrame:
    """Per scene family (in suite order): ``scene_family, scenes`` (count), ``best`` (the
    configurations with the lowest median judged error — error rate, mean |V − G| on soft
    scenes, the shaded image's radiance error on many-light scenes, :func:`judged_metric` — over
    the family's scenes; equal values all listed),
    ``best_error_rate`` (that median, in the judged metric), ``fastest`` (lowest median time),
    ``fastest_time_ms``, ``fastest_ok`` (fastest with median error within :func:`fail_threshold`;
    '' if none) and ``fastest_ok_time_ms``.
    Candidates: the non-reference configurations that ran on the most of the family's scenes
    (all of them when any did), so that one lucky scene cannot win a family; ``coverage`` =
    "ran / scenes". Names are short labels."""
    cfg = per_configuration(results)
    conf = cfg[~cfg["reference"].astype(bool)]
    df = normalised(results) if len(results) else results
    rows = []
    if not len(df):
        return pd.DataFrame(columns=["scene_family", "scenes", "coverage", "best", "best_error_rate", "fastest",
                                     "fastest_time_ms", "fastest_ok", "fastest_ok_time_ms"])
    fam_of = df.drop_duplicates("scene").set_index("scene")["scene_family"].map(as_text)
    for fam in dict.fromkeys(fam_of):
        scenes = list(fam_of.index[fam_of == fam])
        g = conf[conf["scene"].isin(scenes)]
        med = g.groupby("label", sort=False).agg(short_label=("short_label", "first"), n=("scene", "nunique"),
                                                 err=(judged_metric(fam), "median"), time=("time_ms", "median"))
        row = {"scene_family": fam or "(none)", "scenes": len(scenes), "coverage": "", "best": "",
               "best_error_rate": math.nan, "fastest": "", "fastest_time_ms": math.nan, "fastest_ok": "",
               "fastest_ok_time_ms": math.nan}
        if len(med):
            med = med[med["n"] == med["n"].max()]
            row["coverage"] = f"{int(med['n'].max())}/{len(scenes)}"
            if med["err"].notna().any():
                best = med["err"].min()
                row["best"] = names_text(med.loc[med["err"] == best, "short_label"])
                row["best_error_rate"] = best
            timed = med[med["time"].notna()]
            if len(timed):
                fast = timed.sort_values(["time", "err"], kind="stable").iloc[0]
                row["fastest"], row["fastest_time_ms"] = fast["short_label"], fast["time"]
                good = timed[timed["err"] <= fail_threshold(judged_metric(fam))].sort_values(["time", "err"],
                                                                                             kind="stable")
                if len(good):
                    row["fastest_ok"], row["fastest_ok_time_ms"] = good.iloc[0]["short_label"], good.iloc[0]["time"]
        rows.append(row)
    return pd.DataFrame(rows)


def names_text(names, keep: int = 2) -> str:
    """Up to ``keep`` names, then "(+N tied)"."""
    names = list(dict.fromkeys(names))
    more = len(names) - keep
    return ", ".join(names[:keep]) + (f" (+{more} tied)" if more > 0 else "")


# --------------------------------------------------------------------------- verdicts

#: The judged metrics that are shares and are shown in per cent (``visibility_mae`` is a mean
#: visibility difference, shown as a plain number).
PERCENT_METRICS = ("error_rate", "edge_error_rate", "radiance_error")


def judged_metric(scene_family: str) -> str:
    """The error a scene is judged on: ``visibility_mae`` for a soft scene (its family is
    :data:`shadowlab.scene.model.SOFT_FAMILY`, which its file declares: fractional visibility is
    the answer there, a threshold at 0.5 would hide it); ``radiance_error`` for a many-light scene
    (:data:`shadowlab.scene.model.MANY_LIGHTS_FAMILY`: a shadow budget drops the shadows of the
    lights that matter least, and only the shaded image of every light at once weighs each light's
    error by its light); else the thresholded ``error_rate``. The one place this is decided from a
    family: the verdicts, the Pareto panels, the report and the rank agreement all ask here."""
    # imported on first use: importing the scene package loads its file reader (trimesh)
    from ..scene.model import MANY_LIGHTS_FAMILY, SOFT_FAMILY

    if scene_family == SOFT_FAMILY:
        return "visibility_mae"
    return "radiance_error" if scene_family == MANY_LIGHTS_FAMILY else "error_rate"


def fail_threshold(metric: str) -> float:
    """The value of ``metric`` (:func:`judged_metric`) above which a configuration fails."""
    return {"visibility_mae": FAIL_VISIBILITY_MAE, "radiance_error": FAIL_RADIANCE_ERROR}.get(metric,
                                                                                             FAIL_ERROR_RATE)


def fmt_limit(metric: str, limit: float) -> str:
    """A fail threshold as the page states it ("1 %", "5 %", "0.02")."""
    return f"{100 * limit:g} %" if metric in PERCENT_METRICS else f"{limit:g}"
