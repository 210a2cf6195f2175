"""``shadowlab pick STUDY_DIR [--budget METRIC=VALUE ...] [--model MODEL]``: the cheapest
configuration within an error budget, per scene family and per scene, for a still and a moving
light, from a finished study's ``results.csv`` (:func:`shadowlab.analysis.pick.pick_table`).

With ``--model`` (a cost model written by ``shadowlab cost fit``) the ranking uses the model's
predicted times on its device instead of the times measured here; the answer is then labelled a
prediction with the model's cross-validated error, and configurations whose work the model cannot
price are left out and named.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd

from ..analysis.aggregate import truthy
from ..analysis.pick import Budget, default_budgets, pick_table
from ..util.validation import RunError, did_you_mean

#: The names a budget may be given by, and the verdict metric each means.
BUDGET_METRICS = {"edge": "edge_error_rate", "edge_error_rate": "edge_error_rate", "mae": "visibility_mae",
                  "visibility_mae": "visibility_mae", "error": "error_rate", "error_rate": "error_rate",
                  "radiance": "radiance_error", "radiance_error": "radiance_error"}


def parse_budget(text: str) -> Budget:
    """``edge=1%``, ``mae=0.005``, ``error_rate=0.0001``, ``radiance=2%`` → :class:`Budget`; a rate may be given in
    per cent. RunError, naming the option and what was wrong, on anything else."""
    m = re.fullmatch(r"\s*([A-Za-z_]+)\s*=\s*([0-9.eE+-]+)\s*(%?)\s*", text or "")
    if not m:
        raise RunError(f"--budget must look like METRIC=VALUE (edge=1%, mae=0.005, error=0.1%), got {text!r}")
    name, number, pct = m.group(1).lower(), m.group(2), m.group(3)
    if name not in BUDGET_METRICS:
        raise RunError(f"--budget {text!r}: unknown metric '{name}'{did_you_mean(name, BUDGET_METRICS)} "
                       f"(known: edge, mae, error, radiance, or the column names edge_error_rate, visibility_mae, "
                       f"error_rate, radiance_error)")
    try:
        value = float(number)
    except ValueError:
        raise RunError(f"--budget {text!r}: '{number}' is not a number") from None
    metric = BUDGET_METRICS[name]
    if pct and metric == "visibility_mae":
        raise RunError(f"--budget {text!r}: mean |V − G| is not a percentage (e.g. mae=0.005)")
    if not pct and metric != "visibility_mae" and value >= 1:
        raise RunError(f"--budget {text!r} would be {100 * value:g} % of the pixels; did you mean {name}={number}%?")
    value = value / 100 if pct else value
    if not (np.isfinite(value) and value > 0):
        raise RunError(f"--budget {text!r}: the budget must be a positive number")
    return Budget(metric, value)


def _read(study: Path) -> pd.DataFrame:
    path = study / "results.csv" if study.is_dir() else study
    if not path.is_file():
        raise RunError(f"{study}: no results.csv (a study directory or a results CSV is expected)")
    try:
        results = pd.read_csv(path)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, OSError) as exc:
        raise RunError(f"{path}: not a readable results CSV ({exc})") from None
    missing = [c for c in ("scene", "label", "technique", "error_rate", "time_ms_median") if c not in results.columns]
    if missing:
        raise RunError(f"{path}: not a study's results.csv (no column {', '.join(missing)})")
    return results


def predicted_times(results: pd.DataFrame, model_path: Path) -> tuple[pd.DataFrame, object]:
    """Per (scene, configuration as run) the model's predicted time per frame — the sum over the
    scene's lights, NaN where a light has none — with a band of the model's leave-one-scene-out
    median relative error either side (two picks tie on time when their bands overlap), and the
    model."""
    from ..analysis import cost

    try:
        model = cost.CostModel.load(model_path)
        table = cost.predict(results, model)
    except (cost.CostModelError, ValueError) as exc:
        raise RunError(str(exc)) from None
    # a tuned entry's copies of a spec's rows (same label, light) would count the light twice
    table = table.drop_duplicates(["scene", "label", "light"]).assign(spec_label=table["label"])
    col = f"{cost.PREDICTED_LABEL}_ms"
    per = table.groupby(["scene", "spec_label"], sort=False)[col].agg(lambda v: v.sum(min_count=len(v)))
    per = per.rename("time_ms").reset_index()
    # the prediction's band: its cross-validated median relative error either side
    band = model.cv_median_rel_error if model.cv_median_rel_error == model.cv_median_rel_error else 0.0
    return per.assign(time_lo_ms=per["time_ms"] * (1 - band), time_hi_ms=per["time_ms"] * (1 + band)), model


def pick_command(study, budgets: list[str] | None = None, model: str | None = None, scene: str | None = None,
                 motion: str | None = None) -> tuple[pd.DataFrame, str]:
    """The pick table of a study for ``budgets`` (texts for :func:`parse_budget`; the defaults
    when none) — only ``scene`` (a scene or scene family name) and ``motion`` ('still' or 'moving')
    when given — and a line saying what the times are (measured here, or predicted by ``model``)."""
    study = Path(study)
    results = _read(study)
    parsed = [parse_budget(b) for b in budgets] if budgets else default_budgets()
    times, what = None, "times measured in the study"
    if model is not None:
        times, m = predicted_times(results, Path(model))
        cv = m.cv_median_rel_error
        what = (f"times PREDICTED for {m.device} by {model} (not measured: the model's leave-one-scene-out median "
                f"error is {'n/a' if cv != cv else f'{100 * cv:.0f} %'})")
        # the truth is never ranked: that the model cannot price it (its rays, CPU work only) leaves nothing out
        truth = set(results.loc[truthy(results["reference"]), "label"]) if "reference" in results.columns else set()
        unpriced = times[times["time_ms"].isna() & ~times["spec_label"].isin(truth)]
        if len(unpriced):
            what += f"; {unpriced['spec_label'].nunique()} configuration(s) it cannot price are left out"
    if model is not None and motion == "moving":
        raise RunError("--model predicts a still light's time per frame only: a moving light adds CPU "
                       "preprocessing measured on this machine, which the model does not price (drop --motion moving)")
    # the model prices a frame's GPU work, not the CPU preprocessing of a moving light
    motions = ("still",) if model is not None else ("still", "moving") if motion is None else (motion,)
    table = pick_table(results, parsed, times, motions)
    if scene is not None:
        known = sorted(set(table["scene"]) - {""} | set(table["scene_family"]))
        if scene not in known:
            everything = pick_table(results, default_budgets(), None, ("still",))
            judged = everything[(everything["scene"] == scene) | (everything["scene_family"] == scene)]
            if len(judged):
                raise RunError(f"--scene {scene!r} is judged on {judged['metric'].iloc[0]}: give a budget in it "
                               f"(hard scenes: edge=…, soft scenes: mae=…)")
            raise RunError(f"--scene {scene!r}: no such scene or scene family in {study}"
                           f"{did_you_mean(scene, known)}")
        table = table[(table["scene"] == scene) | (table["scene_family"] == scene)]  # a family: with its scenes
    if not len(table):
        metrics = sorted({b.metric for b in parsed})
        raise RunError(f"no scene of {study} is judged on {', '.join(metrics)}: give a budget in its metric "
                       f"(hard scenes: edge=…, soft scenes: mae=…)")
    return table, what


def pick_text(table: pd.DataFrame, what: str) -> str:
    """The pick table as the command prints it: per metric, budget and motion a block with one
    line per scene family (its scenes indented under it; a family of one scene on one line), each
    pick in the words of the page (:func:`shadowlab.study.verdict_views.pick_line`)."""
    from ..study.verdict_views import budget_text, pick_line

    lines = [f"The cheapest configuration within each budget ({what}):"]
    for (metric, budget, motion), g in table.groupby(["metric", "budget", "motion"], sort=False):
        lines += ["", f"{budget_text(metric, budget)}, {motion} light:"]
        width = max(len(r["scene"]) + len(r["scene_family"]) for _, r in g.iterrows()) + 6
        single = set(g.loc[(g["level"] == "family") & (g["scenes"] == 1), "scene_family"])
        for _, r in g.iterrows():
            if r["level"] == "scene" and r["scene_family"] in single and (g["level"] == "family").any():
                continue  # a family of one scene: its line says it all
            only = g.loc[(g["level"] == "scene") & (g["scene_family"] == r["scene_family"]), "scene"]
            name = (f"  {r['scene_family'] or '(none)'}" + (f" ({r['scenes']} scenes)" if r["scenes"] > 1 else
                                                              f" ({only.iloc[0]})" if len(only) else "")
                    if r["level"] == "family" else f"    {r['scene']}")
            lines.append(f"{name:{width}s}  {pick_line(r)}")
    return "\n".join(lines)
