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
from pathlib import Path
from urllib.parse import quote

import pandas as pd

from ..metrics import format_table
from ..output.pictures import ERROR_COLORS, SIGNED_CAPTION
from ..output.pareto import pareto_plot
from .aggregate import (FAIL_ERROR_RATE, as_text, failed_runs, family_table, fmt_ms, fmt_pct, is_missing, names_text,
                        normalised, per_configuration, scenes_in_order, summary_table, write_text_atomic)


def _md_cell(value) -> str:
    return as_text(value).replace("|", "\\|").replace("\n", " ")


def _md_table(header: list[str], rows: list[list]) -> str:
    """A pipe table padded to aligned columns (readable as plain text)."""
    cells = [[_md_cell(c) for c in header]] + [[_md_cell(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    lines = ["| " + " | ".join(c.ljust(w) for c, w in zip(r, widths)) + " |" for r in cells]
    lines.insert(1, "|" + "|".join("-" * (w + 2) for w in widths) + "|")
    return "\n".join(lines)


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
    n_scenes = len(scenes_in_order(results)) if len(results) else 0
    lines += [f"- {n_scenes} scenes, {len(table)} configurations, {len(fails)} failed runs", ""]
    lines += ["Error rate = wrong / evaluated pixels, pooled over a scene's lights; time = ms per frame, the "
              "sum of the lights' median times; setup = ms to set up for the lights (paid once for static lights, every "
              "frame for moving ones). Medians are taken across the scenes a configuration ran on. "
              "A win = the lowest error rate among a scene's configurations (ties count for each); a fail = "
              f"the run failed or its error rate exceeds {100 * FAIL_ERROR_RATE:g} % of the evaluated pixels.",
              ""]
    if len(truth):
        lines += [f"Ground truth ({', '.join(dict.fromkeys(truth['short_label']))}): median "
                  f"{fmt_ms(truth['time_ms'].median())} ms per frame over {len(truth)} scenes.", ""]
    lines += ["## Configurations", ""]
    for tech, g in table.groupby("technique", sort=False):
        lines += [f"### {tech}", ""]
        lines.append(_md_table(["configuration", "median error", "median time ms", "setup ms", "scenes", "wins",
                                "fails"],
                               [[r["short_label"], fmt_pct(r["median_error_rate"]), fmt_ms(r["median_time_ms"]),
                                 fmt_ms(r["median_setup_ms"]),
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
            [[r["scene_family"], r["scenes"], r["coverage"], r["best"], fmt_pct(r["best_error_rate"]), r["fastest"],
              fmt_ms(r["fastest_time_ms"]), r["fastest_ok"] or "(none)", fmt_ms(r["fastest_ok_time_ms"])]
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
            rows.append([scene, g["scene_family"].iloc[0], names_text(winners["short_label"]), fmt_pct(best),
                         fastest["short_label"].iloc[0] if len(fastest) else "",
                         fmt_ms(fastest["time_ms"].iloc[0]) if len(fastest) else "", len(g)])
        lines.append(_md_table(["scene", "family", "most accurate", "error", "fastest", "ms", "configurations"], rows))
        lines.append("")
    if len(fails):
        lines += ["## Failed runs", ""]
        lines.append(_md_table(["scene", "configuration", "error"],
                               [[r["scene"], r["label"], r["error"]] for _, r in fails.iterrows()]))
        lines.append("")
    write_text_atomic(path, "\n".join(lines))
    return path


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


def _box_text(box) -> str:
    parts = as_text(box).split(",")
    if len(parts) != 4:
        return ""
    x0, y0, x1, y1 = (p.strip() for p in parts)
    return f"x {x0}–{x1}, y {y0}–{y1}"


def _figure(study_dir: Path, r: pd.Series) -> str:
    """One configuration of a scene's strip: its error map, caption, its worst-region crop, and —
    for a soft configuration whose results row names one (``signed_image``) — its signed
    difference map V − G under them."""
    e = html.escape
    cap = (f'<b>{e(as_text(r["short_label"]))}</b><br>error {e(fmt_pct(r["error_rate"]))}'
           f' · {e(fmt_ms(r["time_ms"]))} ms')
    err_img = _rel(study_dir, r["error_image"])
    img = (f'<img class="map" src="{e(err_img)}" alt="error map of {e(as_text(r["short_label"]))}">'
           if err_img else '<div class="missing">no error map</div>')
    crop = _rel(study_dir, r["worst_crop_image"])
    worst = r["worst_errors"]
    wrong = r["wrong_pixels"]
    if crop:
        n = "" if is_missing(worst) else f"{int(float(worst))} wrong px"
        box = _box_text(r["worst_box"])
        crop_html = (f'<img class="crop" src="{e(crop)}" alt="worst region of {e(as_text(r["short_label"]))}">'
                     f'<figcaption>worst region{(" " + e(box)) if box else ""}: {e(n)} '
                     f'(magnified, first light)</figcaption>')
    elif (not is_missing(worst) and float(worst) == 0) or (not is_missing(wrong) and float(wrong) == 0):
        crop_html = '<div class="none">no wrong pixels</div>'
    else:
        crop_html = '<div class="missing">no crop</div>'
    signed = _rel(study_dir, r.get("signed_image"))
    signed_html = (f'<figure class="signed"><img class="map" src="{e(signed)}" alt="signed map of '
                   f'{e(as_text(r["short_label"]))}"><figcaption>signed V − G (first light; blue too bright, '
                   f'red too dark; scale in the run report)</figcaption></figure>' if signed else "")
    return (f'<div class="cfg"><figure>{img}<figcaption>{cap}</figcaption></figure>'
            f'<figure class="worst">{crop_html}</figure>{signed_html}</div>')


def _summary_html(results: pd.DataFrame) -> str:
    table = summary_table(results)
    if not len(table):
        return "<p>No configuration ran.</p>"
    shown = pd.DataFrame({
        "technique": table["technique"], "configuration": table["short_label"],
        "median error": table["median_error_rate"].map(fmt_pct), "median time, ms": table["median_time_ms"].map(fmt_ms),
        "median setup, ms": table["median_setup_ms"].map(fmt_ms),
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
    df = normalised(results) if len(results) else results
    cfg = per_configuration(results)
    fails = failed_runs(results)
    name = as_text(meta.get("name")) or "study"
    facts = [f"{k}: {e(v)}" for k, v in _meta_lines(meta)]
    if meta.get("workers") is not None:
        facts.append(f"workers: {e(as_text(meta['workers']))}")
    if not is_missing(meta.get("elapsed_s")):
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
    scenes = scenes_in_order(df) if len(df) else []
    nav = " · ".join(f'<a href="#scene-{k}">{e(s)}</a>' for k, s in enumerate(scenes))
    sections = []
    for k, scene in enumerate(scenes):
        rows = df[df["scene"].astype(str) == scene]
        fam = as_text(rows["scene_family"].iloc[0])
        c = cfg[cfg["scene"] == scene]
        truth = c[c["reference"].astype(bool)]
        conf = c[~c["reference"].astype(bool)]
        run_dirs = [d for d in map(as_text, rows.get("run_dir", pd.Series(dtype=str))) if d]
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
                         f'({e(as_text(tr["short_label"]))})<br>shaded · {e(fmt_ms(tr["time_ms"]))} ms</figcaption>'
                         f'</figure></div>')
        strip += [_figure(study_dir, r) for _, r in conf.iterrows()]
        f = fails[fails["scene"] == scene]
        strip += [f'<div class="cfg failed"><b>{e(as_text(r["short_label"]))}</b>'
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
{f'<p>{e(as_text(meta.get("description")))}</p>' if meta.get("description") else ''}
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
    write_text_atomic(out, doc)
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
