"""The study report (docs/contracts.md#study-directory): the comparison drawn across every scene of a suite.

Four files in the study directory, all made from ``results.csv`` (and ``tiles.npz``, which the
verdicts' significance tests resample) and the tables of :mod:`shadowlab.analysis` — aggregate,
verdicts, pick; plain pandas, nothing there draws:

- ``pareto.png`` — speed against error, one panel per scene, the Pareto front marked
  (:func:`shadowlab.output.pareto.pareto_plot`);
- ``summary.md`` — the verdicts (technique families × scenes), one sentence per scene family and
  the cheapest pick under each default budget, then per configuration its median and worst error
  and time across the suite, wins and fails (:func:`write_summary_md`);
- ``study.html`` — the verdicts and the pick first, then the Pareto panels, the configurations,
  the failed runs and per scene every configuration with the same zoom insets
  (:func:`write_study_html`, Jinja2 template ``study.html`` on the pages' base template);
- ``rank_agreement.csv`` — per scene family, how the perceptual metrics rank configurations
  against the exact ones (Kendall τ, :func:`shadowlab.study.agreement.rank_agreement`), also a
  section of both pages.
"""
from __future__ import annotations

import json
from pathlib import Path
from urllib.parse import quote

import pandas as pd

from ..evaluation import perceptual
from ..output.pareto import pareto_plot
from ..analysis.aggregate import (
    DEGENERATE_MARK, FAIL_ERROR_RATE, FAIL_RADIANCE_ERROR, as_text, failed_runs, family_table, judged_metric,
    names_text, normalised,
    per_configuration, scenes_in_order, summary_table,
)
from ..analysis.pick import pick_table
from ..analysis.verdicts import verdict_sentences, verdict_table
from .verdict_views import (
    metric_text, pick_legend, pick_markdown, pick_views, thresholds_text, value_text, verdict_blocks,
    verdict_legend,
)
from .tiles import read_tiles
from ..util.files import write_text_atomic
from ..util.markdown import md_table
from ..util.format import fmt_ms, fmt_num, fmt_table_ms, fmt_table_pct, is_missing
from .agreement import MIN_CONFIGURATIONS, agreement_sentences, rank_agreement


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
    items = [("size", size_text), ("device", as_text(meta.get("device"))), ("revision", as_text(meta.get("revision"))),
             ("date", as_text(meta.get("date"))), ("timing", as_text(meta.get("timing")))]
    return [(k, v) for k, v in items if v]


def verdict_markdown(results: pd.DataFrame, meta: dict | None = None, tiles: dict | None = None,
                     pick_level: str = "family") -> list[str]:
    """The verdicts as markdown lines: per block of scenes a table of technique families × scenes
    (each cell the family's best configuration's error and time, the best per scene in bold, ✗
    where it fails; :func:`~shadowlab.analysis.verdicts.verdict_table`,
    :func:`~shadowlab.study.verdict_views.verdict_blocks`), one sentence per scene family, and the
    cheapest pick under each default budget per scene family (``pick_level`` 'family') or per family
    and scene ('all'; :func:`pick_markdown_section`). The README's headline is made of these lines."""
    meta = meta or {}
    scenes_meta = meta.get("scenes") or {}
    verdicts = verdict_table(results, {k: v.get("metric") for k, v in scenes_meta.items()}, tiles)
    if not len(verdicts):
        return []

    def cell(c) -> str:
        if c is None:
            return "—"
        err = f"**{c['error']}**" if c["best_error"] else c["error"]
        time = f"**{c['time']} ms**" if c["best_time"] else f"{c['time']} ms"
        moving = ((f" (↻ **{c['moving']}**)" if c["best_moving"] else f" (↻ {c['moving']})")
                  if c["moves_differ"] else "")
        mark = f" {DEGENERATE_MARK}" if c["degenerate"] else " ✗" if c["failed"] else ""
        config = f" [{c['config']}]" if c["config"] else ""
        return f"{err}{mark} · {time}{moving}{config}"

    lines = ["## Verdicts", ""]
    for block in verdict_blocks(verdicts, scenes_meta, scenes_in_order(normalised(results))):
        header = ["technique"] + [f"{s['name']} ({s['family']})" for s in block["scenes"]]
        lines += [md_table(header, [[r["technique"]] + [cell(c) for c in r["cells"]] for r in block["rows"]]), ""]
    lines += [verdict_legend(verdicts, thresholds_text(), page=False)
              + (f" {DEGENERATE_MARK}: every configuration of the family draws almost no shadow where the truth "
                 f"has one (a fail)." if verdicts["degenerate"].astype(bool).any() else ""), ""]
    lines += [f"- {s}" for _, s in verdict_sentences(verdicts)]
    return lines + [""] + pick_markdown_section(results, pick_level)


def pick_markdown_section(results: pd.DataFrame, level: str = "family") -> list[str]:
    """The pick under the default budgets (:func:`shadowlab.analysis.pick.pick_table`) as a
    markdown section: per scene family (``level`` 'family'), or per family and scene ('all')."""
    picks = pick_table(results)
    if not len(picks):
        return []
    return ["## The cheapest pick under a budget", "", pick_legend(), ""] + pick_markdown(picks, level)


def tuned_markdown(meta: dict) -> list[str]:
    """summary.md's section on the ``[[tuned]]`` entries (:func:`tuned_tables`); [] without any."""
    lines = []
    for t in tuned_tables(meta):
        lines += [f"## {t['name']}: tuned against the spec as given", "",
                  f"Objective: {t['objective']}, light 0, each scene tuned on its own.", ""]
        lines += md_table(["scene", "as given", "tuned", "regret of the default", "tuned parameters",
                           "per-pixel oracle"],
                          [[r["scene"], "failed: " + r["failed"], "", "", "", ""] if r["failed"] else
                           [r["scene"], r["default"], r["tuned"], r["regret"], r["params"], r["oracle"]]
                           for r in t["rows"]]).splitlines()
        lines.append("")
        if t["global"]:
            lines += [t["global"], ""]
    return lines


def write_summary_md(results: pd.DataFrame, path, meta: dict | None = None, tiles: dict | None = None) -> Path:
    """Write ``summary.md``: the study at a glance, readable as plain text.

    Header: suite name, description and the facts of ``meta`` (size, device, revision, date,
    timing sentence). Then the verdicts (:func:`verdict_markdown`: technique families × scenes,
    their ties tested on ``tiles`` — the study's tiles.npz, :func:`shadowlab.study.tiles.read_tiles`
    —, one sentence per scene family, the cheapest pick per scene family and scene), as at the top
    of study.html. Then per configuration (short label; grouped by technique family, best
    median error first, from :func:`summary_table`): median error rate and median time per
    frame across the scenes it ran on, the number of scenes, wins (scenes where its error rate
    is the lowest of the scene's configurations, per scene family; ties count for each) and
    fails (runs that failed, or error rate > :data:`FAIL_ERROR_RATE`; on many-light scenes both by
    the radiance error, > :data:`FAIL_RADIANCE_ERROR`), with the scenes named
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
    lines += verdict_markdown(results, meta, tiles, pick_level="all")
    lines += tuned_markdown(meta)
    lines += [f"- {k}: {v}" for k, v in _meta_lines(meta)]
    n_scenes = len(scenes_in_order(results)) if len(results) else 0
    lines += [f"- {n_scenes} scenes, {len(table)} configurations, {len(fails)} failed runs", ""]
    many = bool(len(cfg)) and (cfg["scene_family"].map(judged_metric) == "radiance_error").any()
    lines += ["Error rate = wrong / evaluated pixels, pooled over a scene's lights; time = ms per frame, the "
              "sum of the lights' median times; setup = ms to set up for the lights (GL objects and programs, and "
              "any per-light preprocessing). Medians are taken across the scenes a configuration ran on. "
              "A win = the lowest error rate among a scene's configurations (ties count for each); a fail = "
              f"the run failed or its error rate exceeds {100 * FAIL_ERROR_RATE:g} % of the evaluated pixels"
              + (f" (many-light scenes: wins and fails by the shaded image's radiance error, a fail above "
                 f"{100 * FAIL_RADIANCE_ERROR:g} %)" if many else "") + ".", ""]
    if len(truth):
        lines += [f"Ground truth ({', '.join(dict.fromkeys(truth['short_label']))}): median "
                  f"{fmt_table_ms(truth['time_ms'].median())} ms per frame over {len(truth)} scenes.", ""]
    lines += ["## Configurations", ""]
    for tech, g in table.groupby("technique", sort=False):
        lines += [f"### {tech}", ""]
        lines.append(md_table(["configuration", "median error", "median time ms", "setup ms", "scenes", "wins",
                               "fails"],
                              [[r["short_label"], fmt_table_pct(r["median_error_rate"]),
                                fmt_table_ms(r["median_time_ms"]), fmt_table_ms(r["median_setup_ms"]),
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
                  "Median over the family's scenes of each configuration's judged error (error rate; soft "
                  "scenes: mean |V − G|; many-light scenes: radiance error), among the configurations that ran "
                  "on most of them (coverage), equal values all named — exact values, no test: the verdicts "
                  "above say which differences are significant; \"fastest within the fail threshold\" = the fastest whose median error is "
                  f"within it ({100 * FAIL_ERROR_RATE:g} %; soft: 0.02; many lights: "
                  f"{100 * FAIL_RADIANCE_ERROR:g} %).", ""]
        lines.append(md_table(
            ["scene family", "scenes", "coverage", "most accurate", "error", "fastest", "ms",
             "fastest within the fail threshold", "ms"],
            [[r["scene_family"], r["scenes"], r["coverage"], r["best"],
              value_text(judged_metric(r["scene_family"]), r["best_error_rate"]),
              r["fastest"], fmt_table_ms(r["fastest_time_ms"]), r["fastest_ok"] or "(none)",
              fmt_table_ms(r["fastest_ok_time_ms"])]
             for _, r in fams.iterrows()]))
        lines.append("")
    lines += agreement_markdown(results)
    conf = cfg[~cfg["reference"].astype(bool)]
    if len(conf):
        lines += ["## By scene", "", "Each scene's configuration of least judged error (error rate; soft scenes: mean "
                  "|V − G|; many-light scenes: radiance error; exact values, no test) and its fastest.", ""]
        rows = []
        for scene, g in conf.groupby("scene", sort=False):
            metric = judged_metric(g["scene_family"].iloc[0])
            best = g[metric].min()
            winners = g[g[metric] == best]
            fastest = g[g["time_ms"].notna()].sort_values(["time_ms", metric], kind="stable")
            rows.append([scene, g["scene_family"].iloc[0], names_text(winners["short_label"]), value_text(metric, best),
                         fastest["short_label"].iloc[0] if len(fastest) else "",
                         fmt_table_ms(fastest["time_ms"].iloc[0]) if len(fastest) else "", len(g)])
        lines.append(md_table(["scene", "family", "most accurate", "error", "fastest", "ms", "configurations"], rows))
        lines.append("")
    if len(fails):
        lines += ["## Failed runs", ""]
        lines.append(md_table(["scene", "configuration", "error"],
                              [[r["scene"], r["label"], r["error"]] for _, r in fails.iterrows()]))
        lines.append("")
    write_text_atomic(path, "\n".join(lines))
    return path


def agreement_markdown(results: pd.DataFrame) -> list[str]:
    """summary.md's section on what people see: the Kendall τ table of
    :func:`~shadowlab.study.agreement.rank_agreement` and one sentence per scene family, or the
    line saying why there is none (packages missing, too few configurations)."""
    table = rank_agreement(results)
    lines = ["## What people see: perceptual metrics against pixel error", ""]
    note = perceptual.missing_note()
    if not len(table):
        return lines + [note or f"No scene has {MIN_CONFIGURATIONS} or more configurations with perceptual "
                                "metrics: no rank agreement.", ""]
    lines += ["Kendall τ between each perceptual metric (FLIP; SSIM as 1 − SSIM) and each exact metric, taken "
              "per scene over its configurations and averaged over the family's scenes: 1 = the same order, "
              "0 = unrelated, < 0 = reversed.", ""]
    lines.append(md_table(["scene family", "perceptual", "exact", "τ (mean)", "τ range", "scenes", "pairs",
                           "most discordant pair"], agreement_rows(table)))
    lines += [""] + [f"- {s}" for s in agreement_sentences(table)] + [""] + ([note, ""] if note else [])
    return lines


def agreement_rows(table: pd.DataFrame) -> list[list[str]]:
    """The τ table's rows as text (summary.md and study.html)."""
    return [[as_text(r["scene_family"]) or "general", r["perceptual"], r["exact"], f"{r['tau']:.2f}",
             f"{r['tau_min']:.2f} – {r['tau_max']:.2f}", str(r["scenes"]), str(r["pairs"]),
             f"{r['discordant_pair']} ({r['discordant_scene']})" if r["discordant_pair"] else ""]
            for _, r in table.iterrows()]


def _rel(study_dir: Path, value) -> str | None:
    """A path of results.csv (relative to the study dir) as a relative URL, or None when empty
    or the file is not there. Absolute paths inside the study dir are made relative; others are
    not linked (the page must work when the study dir is copied elsewhere)."""
    text = as_text(value).strip()
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


def tuned_tables(meta: dict) -> list[dict]:
    """study.json's ``tuned`` (:func:`shadowlab.study.tuning_phase.tuning_summary`) as the page and
    summary.md show it: per ``[[tuned]]`` entry its name, objective, one row per scene (the
    objective as given and tuned, the regret of the default, the tuned parameters, the per-pixel
    oracle; or the failure) and, on the exact bias route, the sentence on one global bias."""
    out = []
    for t in meta.get("tuned") or []:
        metric = t["objective"]
        rows = []
        for sc in t["scenes"]:
            if sc["status"] != "ok":
                rows.append({"scene": sc["scene"], "failed": sc.get("error") or "failed"})
                continue
            params = ", ".join(f"{k}={fmt_num(v, 4) if isinstance(v, float) else v}" for k, v in sc["params"].items())
            rows.append({"scene": sc["scene"], "failed": "", "default": metric_text(metric, sc["default_value"]),
                         "tuned": metric_text(metric, sc["value"]), "regret": metric_text(metric, sc["regret"]),
                         "params": params, "route": sc["route"],
                         # only the exact bias route knows each pixel's own best value
                         "oracle": (metric_text(metric, sc["oracle"]) if sc.get("oracle") is not None
                                    else f"— ({sc['route']} route)")})
        out.append({"name": t["name"], "spec": t["written"], "objective": metric, "rows": rows,
                    "global": global_sentence(t)})
    return out


def global_sentence(entry: dict) -> str:
    """One sentence on whether one bias serves every scene of a tuned entry (leave-one-out: the
    bias tuned on the other scenes, judged on the held-out one), or '' without the exact curves."""
    g = entry.get("global")
    if not g:
        return ""
    metric = entry["objective"]
    held = g["held_out"]
    worst = max(held, key=lambda h: h["regret"])
    regrets = sorted(h["regret"] for h in held)
    median = regrets[len(regrets) // 2]
    lo = max(v[0] for v in g["optima"].values())
    hi = min(v[1] for v in g["optima"].values())
    mids = {scene: (v[0] + v[1]) / 2 for scene, v in g["optima"].items()}
    low, high = min(mids, key=mids.get), max(mids, key=mids.get)
    common = (f"one bias, {fmt_num((lo + hi) / 2, 3)}, lies in every scene's widest optimal interval"
              if lo < hi else f"no single bias lies in every scene's widest optimal interval (the per-scene optima "
                              f"run from {fmt_num(mids[low], 3)} on {low} to {fmt_num(mids[high], 3)} on {high})")
    fixed = ", ".join(f"{k}={fmt_num(v, 3)}" for k, v in (g.get("held") or {}).items())
    question = f"One bias for every scene ({fixed} held, as the spec gives it)?" if fixed else "One bias for every scene?"
    return (f"{question} {common[0].upper() + common[1:]}. Tuned on the other scenes and judged on "
            f"the one held out, a single bias misses that scene's own optimum by a median of "
            f"{metric_text(metric, median)} (worst: {metric_text(metric, worst['regret'])} on {worst['scene']}); "
            f"the default bias {fmt_num(g['default_bias'], 3)} by a median of "
            f"{metric_text(metric, sorted(h['default_regret'] for h in held)[len(held) // 2])}.")


def _scene_table(c: pd.DataFrame, metric: str, scene_metric: str) -> dict:
    """A scene's configurations pooled over its lights (:func:`per_configuration`) as display
    strings: the judged error first (on a hard scene with the edge error beside it, the error the
    verdicts decide by; on a many-light scene the shaded image's signed bias and the per-light
    error rate beside the radiance error), the scene's own metric, then times."""
    edge = metric == "error_rate" and c["edge_error_rate"].notna().any()
    radiance = metric == "radiance_error"
    columns = ["configuration", metric] + (["edge error"] if edge else []) \
        + (["radiance bias", "error rate"] if radiance else []) + ["false shadow", "false lit", "boundary px",
                                                                    "visibility MAE"]
    if scene_metric:
        columns.append(scene_metric)
    columns += ["ms per frame", "set-up ms", "moving-light ms"]
    rows = []
    for _, r in c.iterrows():
        name = as_text(r["short_label"]) + (f" {DEGENERATE_MARK}" if r.get("degenerate") else "")
        row = [name, value_text(metric, r[metric])] + ([value_text("edge_error_rate", r["edge_error_rate"])]
                                                        if edge else [])
        if radiance:
            row += [metric_text("radiance_bias", r["radiance_bias"]), value_text("error_rate", r["error_rate"])]
        row += [metric_text("false_shadow_rate", r["false_shadow_rate"]),
                metric_text("false_lit_rate", r["false_lit_rate"]),
                metric_text("boundary_error_px", r["boundary_error_px"]), fmt_num(r["visibility_mae"])]
        if scene_metric:
            row.append(metric_text(scene_metric, r["scene_metric_value"]))
        row += [fmt_ms(r["time_ms"]), fmt_ms(r["setup_ms"]), fmt_ms(r["moving_ms"])]
        rows.append(row)
    return {"columns": columns, "rows": rows}


def _scene_section(study_dir: Path, scene: str, c: pd.DataFrame, fails: pd.DataFrame, info: dict,
                   family: str) -> dict:
    """Everything the page shows of one scene: its purpose, metrics table, run report link and
    the grid of every configuration with the run directory's common insets (its run.json)."""
    from ..output.insets import Inset

    metric = judged_metric(family)
    conf = c[~c["reference"].astype(bool)]
    run_dirs = [d for d in map(as_text, c["run_dir"]) if d]
    run_dir = run_dirs[0].rstrip("/") if run_dirs else ""
    record = {}
    if run_dir:
        try:
            record = json.loads((study_dir / run_dir / "run.json").read_text())
        except (OSError, json.JSONDecodeError):
            record = {}
    images = record.get("images", [])
    size = record.get("size", [1, 1])
    insets = [Inset(tuple(i["box"]), tuple(size), i["wrong"], k + 1) for k, i in enumerate(record.get("insets", []))]
    captions = {}
    for _, r in c.iterrows():
        lines = [] if r["reference"] else [f"{metric.replace('_', ' ')} {value_text(metric, r[metric])}"
                                           + (f" {DEGENERATE_MARK}: almost no shadow drawn" if r["degenerate"] else "")]
        lines.append(f"{fmt_ms(r['time_ms'])} ms per frame" + (f" · moving {fmt_ms(r['moving_ms'])} ms"
                                                               if r["preprocess_ms"] else ""))
        if info.get("metric") and not r["reference"]:
            lines.append(f"{info['metric']} {metric_text(info['metric'], r['scene_metric_value'])}")
        captions[as_text(r["label"])] = lines
    report = _rel(study_dir, f"{run_dir}/report.html") if run_dir else None
    return {"name": scene, "family": family, "purpose": info.get("purpose") or "", "metric": info.get("metric") or "",
            "report": report, "table": _scene_table(conf, metric, info.get("metric") or ""),
            "prefix": f"{quote(run_dir)}/" if run_dir else "", "images": images, "insets": insets,
            "captions": captions, "legends": record.get("legends", {}),
            "failed": [{"title": as_text(r["short_label"]), "error": as_text(r["error"])}
                       for _, r in fails[fails["scene"] == scene].iterrows()]}


def _summary_rows(results: pd.DataFrame) -> list[list[str]]:
    """The per-configuration table across the suite: median and worst error, median time and
    set-up, scenes, fails (k of n) and wins."""
    table = summary_table(results)
    rows = []
    for _, r in table.iterrows():
        n = int(r["scenes"]) + int(r["failed"])
        rows.append([r["technique"], r["short_label"], fmt_table_pct(r["median_error_rate"]),
                     fmt_table_pct(r["worst_error_rate"]), fmt_ms(r["median_time_ms"]), fmt_ms(r["median_setup_ms"]),
                     f"{len(r['fails'])} of {n}" if r["fails"] else f"0 of {n}",
                     ", ".join(f"{s} ({why})" for s, why in r["fails"]), _wins_text(r["wins"]) or "—"])
    return rows


def _study_provenance(meta: dict) -> list[tuple[str, str]]:
    """The footer's facts of a study: size and repeats, device, revision, date, timing, workers,
    elapsed time, run counts, suite file."""
    items = list(_meta_lines(meta))
    if meta.get("workers") is not None:
        items.append(("workers", as_text(meta["workers"])))
    if not is_missing(meta.get("elapsed_s")):
        items.append(("elapsed", f"{float(meta['elapsed_s']):.1f} s"))
    counts = [f"{meta[k]} {k}" for k in ("runs", "cached", "failed") if meta.get(k) is not None]
    if counts:
        items.append(("runs", " · ".join(counts)))
    if meta.get("suite_file"):
        items.append(("suite file", Path(str(meta["suite_file"])).name))
    return items


def write_study_html(study_dir, results: pd.DataFrame, meta: dict, pareto_png: str = "pareto.png",
                     out_name: str = "study.html") -> Path:
    """Write ``study_dir/study.html`` (template ``study.html``; ``out_name``: another file name in
    the same directory, e.g. a temporary one renamed later) and return its path.

    The page opens with the verdicts — technique families × scenes in blocks that fit the screen
    (:func:`~shadowlab.study.verdict_views.verdict_blocks`), each cell the family's best
    configuration on the scene with its error and time (the best of each scene and those a test
    cannot tell from it in bold, failures marked; :func:`~shadowlab.analysis.verdicts.verdict_table`
    on the study's ``tiles.npz``) and one generated sentence per scene family — and the cheapest
    pick under each default budget (:func:`~shadowlab.analysis.pick.pick_table`), then the Pareto panels, the configurations across the suite (median and worst
    error), the failed runs, and per scene its purpose, its table (with the metric the scene
    exists for) and every configuration in a wrapping grid with the run directory's zoom insets.
    A software rasteriser's times are flagged at the top; provenance is in the footer."""
    from ..output.pages import render_page
    from ..output.rundir import error_legend

    study_dir = Path(study_dir)
    scenes_meta = meta.get("scenes") or {}
    scene_metrics = {k: v.get("metric") for k, v in scenes_meta.items()}
    df = normalised(results) if len(results) else results
    cfg = per_configuration(results, scene_metrics)
    fails = failed_runs(results)
    verdicts = verdict_table(results, scene_metrics, read_tiles(study_dir))
    sections = []
    for scene in (scenes_in_order(df) if len(df) else []):
        family = as_text(df.loc[df["scene"].astype(str) == scene, "scene_family"].iloc[0])
        sections.append(_scene_section(study_dir, scene, cfg[cfg["scene"] == scene], fails,
                                       scenes_meta.get(scene, {}), family))
    renderer = as_text(meta.get("renderer")) or (as_text(results["renderer"].iloc[0])
                                                 if len(results) and "renderer" in results.columns else "")
    name = as_text(meta.get("name")) or "study"
    return render_page(
        "study.html", study_dir / out_name, title=f"shadowlab study: {name}", renderer=renderer,
        provenance=_study_provenance(meta), description=as_text(meta.get("description")),
        verdicts=verdict_blocks(verdicts, scenes_meta, scenes_in_order(df) if len(df) else []),
        sentences=[s for _, s in verdict_sentences(verdicts)],
        verdict_legend=verdict_legend(verdicts, thresholds_text()), picks=pick_views(pick_table(results)),
        pick_legend=pick_legend(),
        pareto=_rel(study_dir, pareto_png) or quote(Path(pareto_png).as_posix()),
        summary=_summary_rows(results),
        failed=[[as_text(r["scene"]), as_text(r["label"]), as_text(r["error"])] for _, r in fails.iterrows()],
        scenes=sections, error_colors=error_legend(), tuned=tuned_tables(meta), degenerate_mark=DEGENERATE_MARK,
        predictions=prediction_tables(meta), agreement=agreement_section(results))


def agreement_section(results: pd.DataFrame) -> dict:
    """The study page's section on what people see: the τ table's rows, the sentences, and the
    note when perceptual metrics are missing (:func:`agreement_markdown` in HTML)."""
    table = rank_agreement(results)
    return {"rows": agreement_rows(table), "sentences": agreement_sentences(table),
            "note": perceptual.missing_note() or ("" if len(table) else
                                                  f"No scene has {MIN_CONFIGURATIONS} or more configurations with "
                                                  "perceptual metrics: no rank agreement.")}


def prediction_tables(meta: dict) -> list[dict]:
    """The study page's tables of predicted times (``shadowlab cost predict`` records them in
    study.json's ``cost_predictions``): per modelled device, what the model is worth in words and
    per configuration the median time measured here beside the median predicted there."""
    out = []
    for entry in meta.get("cost_predictions") or []:
        cv = entry.get("cv_median_rel_error")
        cv_text = ("not cross-validated (one scene)" if cv is None or (isinstance(cv, float) and cv != cv)
                   else f"leave-one-scene-out median error {100 * float(cv):.0f} %")
        what = (f"a cost model fitted on {entry.get('model_rows')} rows of {entry.get('model_scenes')} scenes "
                f"(R² {float(entry.get('r2', float('nan'))):.3f}; {cv_text}) turns this study's work counters "
                f"into {entry.get('target')} on that device. Rows: {entry.get('csv')}.")
        rows = [[as_text(r.get("technique")), as_text(r.get("label")), fmt_ms(r.get("measured_here_ms")),
                 (fmt_ms(r.get("predicted_ms")) + (" (extrapolated: no such technique in the fitted rows)"
                                                   if r.get("extrapolated") else ""))
                 if r.get("predicted_ms") is not None
                 else f"— (no cost for {as_text(r.get('unmodelled')) or 'its work'})"]
                for r in entry.get("rows", [])]
        out.append({"device": as_text(entry.get("device")), "what": what, "rows": rows,
                    "here": as_text(meta.get("renderer")) or "here"})
    return out


def write_study_report(study_dir, results: pd.DataFrame, meta: dict) -> dict:
    """Draw the study's comparison into ``study_dir``: ``pareto.png`` (:func:`pareto_plot`),
    ``summary.md`` (:func:`write_summary_md`) and ``study.html`` (:func:`write_study_html`).
    Returns {"pareto": path, "html": path, "summary": path}."""
    study_dir = Path(study_dir)
    study_dir.mkdir(parents=True, exist_ok=True)
    pareto = pareto_plot(results, study_dir / "pareto.png")
    write_text_atomic(study_dir / "rank_agreement.csv", rank_agreement(results).to_csv(index=False))
    summary = write_summary_md(results, study_dir / "summary.md", meta, read_tiles(study_dir))
    page = write_study_html(study_dir, results, meta, pareto.name)
    return {"pareto": pareto, "html": page, "summary": summary}
