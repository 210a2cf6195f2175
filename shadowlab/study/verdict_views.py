"""The verdicts and the pick as the study page, ``summary.md`` and the README show them: display
strings only, from :func:`shadowlab.analysis.verdicts.verdict_table` and
:func:`shadowlab.analysis.pick.pick_table` (nothing here decides anything).

The verdict table is drawn with technique families as rows and scenes as columns, the scenes in
blocks of at most :data:`SCENES_PER_BLOCK` under their scene family's name: a suite may have a
dozen families and thirty scenes, and a table must not run off a 1400-pixel screen (nor a
1024-pixel one). Rows come in the tables' family order, the headline — shadow volumes, then
shadow maps — first (:func:`shadowlab.analysis.aggregate.family_order`).
"""
from __future__ import annotations

import pandas as pd

from ..analysis import significance
from ..analysis.aggregate import as_text, family_order, fmt_limit
from ..analysis.verdicts import FULL_HD, metric_name
from ..evaluation.metrics import COLUMN_BY_NAME
from ..util.format import fmt_ms, fmt_num, fmt_table_pct, is_missing
from ..util.markdown import md_table

#: Scene columns per verdict block: with a 150-pixel row header and 130-pixel cells a block fits a
#: 1024-pixel window, let alone 1400.
SCENES_PER_BLOCK = 6


def value_text(metric: str, value) -> str:
    """A verdict metric's value as the pages show it: a percentage for the rates and the radiance
    error, four decimals for mean |V − G|; '' when missing."""
    if is_missing(value):
        return ""
    if metric == "visibility_mae":
        return f"{float(value):.4f}"
    # an edge error can be many times the boundary (a lost or misplaced shadow), a radiance error
    # many times the truth (a dropped light's neighbour lit): whole per cents there
    return f"{100 * float(value):,.0f} %" if float(value) >= 1 else fmt_table_pct(value)


def budget_text(metric: str, value: float) -> str:
    """A budget as the pick tables head it ("edge error ≤ 1 %")."""
    shown = f"{100 * value:g} %" if metric != "visibility_mae" else f"{value:g}"
    return f"{metric_name(metric)} ≤ {shown}"


def metric_text(metric: str, value) -> str:
    """A value of metrics column ``metric`` as the tables show it (its format in
    :data:`shadowlab.evaluation.metrics.COLUMNS`); '' when missing."""
    if is_missing(value) or not metric:
        return ""
    col = COLUMN_BY_NAME.get(metric)
    return col.format(float(value)) if col is not None else fmt_num(value)


def _cell(r: pd.Series) -> dict:
    """One verdict cell: what it shows and its tooltip."""
    error = value_text(r["metric"], r["error"])
    scene_metric = metric_text(as_text(r["scene_metric"]), r["scene_metric_value"])
    tip = [as_text(r["short_label"])]
    if scene_metric:
        tip.append(f"{r['scene_metric']} {scene_metric}")
    if r["metric"] == "radiance_error":
        bias = r.get("radiance_bias")
        if not is_missing(bias):
            tip.append(f"shaded image {value_text('radiance_error', abs(bias))} "
                       f"{'brighter' if bias > 0 else 'darker'} than the truth on average"
                       + (" (shadows dropped)" if bias > 0 else " (lights dropped)" if bias < 0 else ""))
        if not is_missing(r["error_rate"]):
            tip.append(f"per light, {fmt_table_pct(r['error_rate'])} of the evaluated pixels' visibility wrong")
    elif r["metric"] != "visibility_mae" and not is_missing(r["error_rate"]):
        tip.append(f"{fmt_table_pct(r['error_rate'])} of the evaluated pixels wrong"
                   + (f"; {float(r['wrong_per_light']):,.0f} wrong pixels per light in this frame, "
                      f"≈ {float(r['wrong_full_hd']):,.0f} in a {FULL_HD[0]}×{FULL_HD[1]} frame with the same share of "
                      f"its pixels wrong" if not is_missing(r["wrong_full_hd"]) else ""))
    if not is_missing(r["time_ms"]):
        tip.append(f"{fmt_ms(r['time_ms'])} ms per frame, repeats {fmt_ms(r['time_lo_ms'])}–{fmt_ms(r['time_hi_ms'])}")
    if bool(r["failed"]) and as_text(r["why"]):
        tip.append(f"fails: {r['why']}")
    moving = r["moving_ms"]
    differs = not is_missing(moving) and not is_missing(r["time_ms"]) and moving > r["time_ms"] * 1.05
    label = as_text(r["short_label"])
    config = "" if label == r["technique"] else label.split(":", 1)[-1]
    return {"config": config,
            # on a many-light scene the family's configurations are its budgets and policies — which
            # one is best is the question — so the cell names it (spaced at commas: it may wrap)
            "shown_config": config.replace(",", ", ") if r["metric"] == "radiance_error" else "",
            "error": error, "time": fmt_ms(r["time_ms"]), "moving": fmt_ms(moving),
            # the moving time is shown where it differs, and where it wins (bold) though it does not
            "moves_differ": differs or bool(r["best_moving"]),
            "scene_metric": scene_metric,
            "failed": bool(r["failed"]), "why": as_text(r["why"]), "best_error": bool(r["best_error"]),
            "degenerate": bool(r["degenerate"]) if not is_missing(r["degenerate"]) else False,
            "best_time": bool(r["best_time"]), "best_moving": bool(r["best_moving"]), "tip": " · ".join(tip)}


def _blocks_of(scenes_by_family: dict[str, list[str]]) -> list[list[tuple[str, list[str]]]]:
    """Scene families packed in order into blocks of at most :data:`SCENES_PER_BLOCK` scenes; a
    larger family is split over blocks. Each block: [(family, [scene, ...]), ...]."""
    blocks, current, size = [], [], 0
    for fam, scenes in scenes_by_family.items():
        for k in range(0, len(scenes), SCENES_PER_BLOCK):
            part = scenes[k:k + SCENES_PER_BLOCK]
            if size + len(part) > SCENES_PER_BLOCK and current:
                blocks.append(current)
                current, size = [], 0
            current.append((fam, part))
            size += len(part)
    if current:
        blocks.append(current)
    return blocks


def verdict_blocks(verdicts: pd.DataFrame, scenes_meta: dict, scene_order: list[str] | None = None) -> list[dict]:
    """The verdict table (:func:`~shadowlab.analysis.verdicts.verdict_table`) as blocks: per block
    ``groups`` ([(scene family, number of scenes)]), ``scenes`` (per column: name, family, verdict
    metric, the scene's own metric, its index in ``scene_order`` — the page's scene sections, the
    anchors' targets — or else among the verdicts' scenes) and ``rows``
    (per technique family that ran on one of the block's scenes: its name and per column a cell
    dict, or None where it did not run)."""
    if not len(verdicts):
        return []
    order = list(dict.fromkeys(list(scene_order or []) + list(verdicts["scene"])))
    shown = list(dict.fromkeys(verdicts["scene"]))
    by_family: dict[str, list[str]] = {}
    for scene in shown:
        fam = as_text(verdicts.loc[verdicts["scene"] == scene, "scene_family"].iloc[0])
        by_family.setdefault(fam, []).append(scene)
    cells = {(r["scene"], r["technique"]): _cell(r) for _, r in verdicts.iterrows()}
    out = []
    for block in _blocks_of(by_family):
        scenes = [s for _, part in block for s in part]
        techs = family_order(verdicts.loc[verdicts["scene"].isin(scenes), "technique"])
        columns = []
        for s in scenes:
            info = scenes_meta.get(s, {})
            first = verdicts[verdicts["scene"] == s].iloc[0]
            columns.append({"name": s, "family": as_text(first["scene_family"]), "metric": first["metric"],
                            "scene_metric": (info.get("metric") or "").replace("_", " "), "index": order.index(s) + 1})
        out.append({"groups": [(fam or "(none)", len(part)) for fam, part in block], "scenes": columns,
                    "rows": [{"technique": t, "cells": [cells.get((s, t)) for s in scenes]} for t in techs]})
    return out


def verdict_legend(verdicts: pd.DataFrame, thresholds: dict, page: bool = True) -> str:
    """The sentence under the verdict table: what a cell holds and how ties are decided — by the
    paired tile bootstrap where the study has tiles (``verdicts['tested']``), else by equality;
    ``page``: the HTML page (hover for details) rather than markdown (the configuration in the
    cell)."""
    metrics = list(dict.fromkeys(verdicts["metric"])) if len(verdicts) else []
    what = "; ".join(f"{metric_name(m)}" + (": wrong pixels per pixel of the truth's shadow boundary"
                                            if m == "edge_error_rate" else
                                            ": share of the evaluated pixels" if m == "error_rate" else
                                            " on many-light scenes: the shaded image of every light against the "
                                            "truth's, mean relative luminance error" if m == "radiance_error" else
                                            " on soft scenes") for m in metrics)
    tested = bool(len(verdicts) and verdicts["tested"].astype(bool).any())
    per_pixel = [m for m in metrics if m != "radiance_error"]  # the metrics tiles.npz can resample
    if tested:
        ties = f"with every family a paired tile bootstrap cannot tell from it at {thresholds['level']}"
        if "radiance_error" in metrics:
            ties += " (radiance errors have no per-tile figures: they tie only when equal)"
    elif per_pixel:
        ties = "with every family of exactly the same error (this study has no tiles.npz: no significance test)"
    else:
        ties = "with every family of exactly the same radiance error (it has no per-tile figures: no significance test)"
    details = (f"hover for the configuration, its share of the evaluated pixels and the same share of a "
               f"{FULL_HD[0]}×{FULL_HD[1]} frame"
               + ("; on many-light scenes the configuration is named under its error, and hovering gives the "
                  "shaded image's bias and the per-light error rate" if "radiance_error" in metrics else "")
               if page else
               "the configuration's parameters in brackets where it is not the family's default")
    # what a fail is decided by, for the kinds of scene the table has
    rules = []
    if any(m in ("edge_error_rate", "error_rate") for m in metrics) or not metrics:
        rules.append(("decided by the share of the evaluated pixels, not by the edge error shown: "
                      if "edge_error_rate" in metrics else "") + f"error rate above {thresholds['error_rate']}")
    if "visibility_mae" in metrics:
        rules.append(f"soft scenes: mean |V − G| above {thresholds['visibility_mae']}")
    if "radiance_error" in metrics:
        rules.append(f"many-light scenes: radiance error above {thresholds.get('radiance_error', '5 %')}")
    fails = rules[0] + (f" ({'; '.join(rules[1:])})" if len(rules) > 1 else "")
    return (f"Each cell: the family's best configuration on the scene (lowest error) — its error ({what}) —, its ms "
            f"per frame for a static light and (↻, moving) for a moving light, where the technique redoes "
            f"preprocessing whenever the light moves or wins there; {details}. Bold: best in the scene's column, "
            f"{ties}; times whose repeat intervals (first to third quartile) overlap the fastest's, among the families "
            f"that do not fail. ✗ = fails — {fails}, or the run failed.")


# --------------------------------------------------------------------------- the pick

def pick_phrases(r: pd.Series) -> dict:
    """One pick (a row of :func:`~shadowlab.analysis.pick.pick_table`) in the words every output
    uses — the page, summary.md, the README and ``shadowlab pick``: ``name``, ``time``, ``share``
    (its error and the share of the budget it uses), ``scope`` (a family's: its worst scene and
    median time), ``runner`` (the runner-up, and whether it is a toss-up on time), ``tie``; or, when
    nothing is within the budget, ``name`` '' and ``closest``."""
    if not as_text(r["label"]):
        return {"name": "", "closest": (f"closest: {r['most_accurate']} at "
                                        f"{value_text(r['metric'], r['most_accurate_error'])}"
                                        if as_text(r["most_accurate"]) else "")}
    used = r["error"] / r["budget"] if r["budget"] else 0.0
    runner = (f"next {r['runner_up']} {fmt_ms(r['runner_up_ms'])} ms"
              + (" (tied on time)" if bool(r["runner_up_ties"]) else "")
              if as_text(r["runner_up"]) else "the only one within the budget")
    many = r["level"] == "family" and r["scenes"] > 1
    return {"name": as_text(r["short_label"]),
            "time": f"{fmt_ms(r['time_ms'])} ms" + (" predicted" if bool(r["predicted"]) else ""),
            "share": f"{value_text(r['metric'], r['error'])} = {100 * used:.0f} % of the budget",
            "scope": f"worst of {int(r['scenes'])} scenes, median time" if many else "",
            "runner": runner, "tie": bool(r["runner_up_ties"])}


def pick_line(r: pd.Series) -> str:
    """One pick as a line of text: "A: 1.50 ms, 0.05 % = 5 % of the budget; next B 2.00 ms"."""
    p = pick_phrases(r)
    if not p["name"]:
        return "nothing within the budget" + (f"; {p['closest']}" if p["closest"] else "")
    return f"{p['name']}: {p['time']}, {p['share']}" + (f" ({p['scope']})" if p["scope"] else "") + f"; {p['runner']}"


def _pick_cell(r: pd.Series) -> dict:
    """One pick as a page cell: its phrases and a tooltip."""
    p = pick_phrases(r)
    if not p["name"]:
        return {"name": "", "text": "nothing within it", "detail": p["closest"], "tip": p["closest"]}
    return {"name": p["name"], "text": p["time"], "detail": p["share"], "runner": p["runner"], "tie": p["tie"],
            "tip": " · ".join(x for x in (p["scope"], p["runner"]) if x)}


def _one_motion_if_same(g: pd.DataFrame) -> pd.DataFrame:
    """``g`` (one metric's picks) with the still and moving rows merged into one "still or moving"
    when every pick and time is the same for both (no candidate redoes work when the light moves):
    two identical columns say nothing."""
    key = ["level", "scene_family", "scene", "budget"]
    still, moving = g[g["motion"] == "still"], g[g["motion"] == "moving"]
    if not len(still) or not len(moving):
        return g
    both = still.merge(moving, on=key, suffixes=("", "_m"))
    same = len(both) == len(still) == len(moving) and (both["label"] == both["label_m"]).all() and \
        ((both["time_ms"] == both["time_ms_m"]) | (both["time_ms"].isna() & both["time_ms_m"].isna())).all()
    return still.assign(motion="still or moving") if same else g


def pick_views(picks: pd.DataFrame) -> list[dict]:
    """The pick table (:func:`~shadowlab.analysis.pick.pick_table`) as the page draws it: one table
    per verdict metric, ``columns`` (budget × motion) and ``rows`` (each scene family, then — under
    it — its scenes when it has more than one; per column a cell dict)."""
    out = []
    if not len(picks):
        return out
    for metric, g in picks.groupby("metric", sort=False):
        g = _one_motion_if_same(g)
        keys = list(dict.fromkeys(zip(g["budget"], g["motion"])))
        columns = [{"budget": budget_text(metric, b), "motion": m} for b, m in keys]
        rows = []
        for fam, f in g.groupby("scene_family", sort=False):
            scenes = list(dict.fromkeys(f.loc[f["level"] == "scene", "scene"]))
            levels = [("family", "")] + ([("scene", s) for s in scenes] if len(scenes) > 1 else [])
            for level, scene in levels:
                part = f[(f["level"] == level) & (f["scene"] == scene)] if level == "scene" else f[f["level"] == level]
                cells = {(b, m): {**_pick_cell(r), "line": pick_line(r)} for _, r in part.iterrows()
                         for b, m in [(r["budget"], r["motion"])]}
                title = (f"{fam or '(none)'} ({len(scenes)} scene{'s' if len(scenes) != 1 else ''}"
                         + (f": {scenes[0]}" if len(scenes) == 1 else "") + ")") if level == "family" else scene
                rows.append({"title": title, "level": level, "cells": [cells.get(k) for k in keys]})
        out.append({"metric": metric, "name": metric_name(metric), "columns": columns, "rows": rows})
    return out


def pick_markdown(picks: pd.DataFrame, level: str = "family") -> list[str]:
    """The pick as markdown lines: per verdict metric a table of scene families (``level``
    'family') or of every scene and family ('all') × budget and motion."""
    lines = []
    for view in pick_views(picks):
        header = ["scene family" if level == "family" else "scenes"] + [f"{c['budget']}, {c['motion']} light"
                                                                         for c in view["columns"]]
        rows = []
        for r in view["rows"]:
            if level == "family" and r["level"] != "family":
                continue
            rows.append([r["title"] if r["level"] == "family" else f"· {r['title']}"]
                        + ["—" if c is None else c["line"] for c in r["cells"]])
        lines += [md_table(header, rows), ""]
    return lines


def pick_legend(predicted: str = "") -> str:
    """The sentence under a pick table."""
    return ("Per scene family: the configuration with the least median time per frame among those within the "
            "budget on every scene of the family (its worst scene's error shown, with the share of the budget it "
            "uses); per scene, likewise on that scene. Every configuration that ran may be picked, not only each "
            "family's most accurate; degenerate ones never are. Still light: time per frame; moving light: plus the "
            "per-light preprocessing redone every frame. \"Tied on time\": the runner-up's repeat interval overlaps "
            "the pick's — on this machine the two are a toss-up." + (f" {predicted}" if predicted else ""))


def thresholds_text() -> dict:
    """The fail thresholds and the test level as the legends print them."""
    from ..analysis.aggregate import FAIL_ERROR_RATE, FAIL_RADIANCE_ERROR, FAIL_VISIBILITY_MAE

    return {"error_rate": fmt_limit("error_rate", FAIL_ERROR_RATE),
            "visibility_mae": fmt_limit("visibility_mae", FAIL_VISIBILITY_MAE),
            "radiance_error": fmt_limit("radiance_error", FAIL_RADIANCE_ERROR),
            "level": f"{100 * significance.LEVEL:g} %"}

