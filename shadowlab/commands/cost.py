"""``shadowlab cost fit`` and ``shadowlab cost predict``: a device's cost model from a study's
rows, and predicted times from it (docs/cost.md; the model is :mod:`shadowlab.analysis.cost`).

``cost fit STUDY_DIR`` reads ``results.csv`` (or a CSV given directly) and writes the model as
JSON (default ``STUDY_DIR/cost_model.json``) and ``cost_fit.png`` beside it: predicted against
measured time, in-sample and left out by scene. ``cost predict STUDY_DIR MODEL`` writes
``STUDY_DIR/cost/<device>.csv`` (per row: measured here, predicted on the model's device,
relative error where the study ran on that device), records the prediction in ``study.json``
and draws the study page again, which then shows the predicted times in a table labelled as a
prediction with the model's cross-validated error. Files are written to temporary names and
renamed: a failed command leaves earlier files as they were.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd

from ..analysis import cost
from ..util.files import replacing
from ..util.format import fmt_whole_pct
from ..util.validation import RunError


def _results_path(study: Path) -> Path:
    path = study / "results.csv" if study.is_dir() else study
    if not path.is_file():
        raise RunError(f"{study}: no results.csv (a study directory or a results CSV is expected)")
    return path


def _read_results(study: Path) -> pd.DataFrame:
    """The study's rows (RunError naming the file when it is not a readable CSV)."""
    path = _results_path(study)
    try:
        return pd.read_csv(path)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, OSError) as exc:
        raise RunError(f"{path}: not a readable results CSV ({str(exc).splitlines()[0]})") from None


def _meta_path(study: Path) -> Path:
    return study / "study.json" if study.is_dir() else study.with_name("study.json")


def _read_meta(study: Path) -> dict:
    """The study's study.json ({} when there is none; RunError when it is not JSON)."""
    path = _meta_path(study)
    if not path.is_file():
        return {}
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise RunError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise RunError(f"{path}: not a study record (a JSON object is expected)")
    return meta


def fit_command(study, out=None, target: str = "time_ms_median", counters=None, per_pass: bool = False,
                device: str | None = None) -> tuple[cost.CostModel, Path]:
    """Fit and write a model (module docstring); returns it and its path."""
    study = Path(study)
    results = _read_results(study)
    device = device or str(_read_meta(study).get("device") or "") or "unknown device"
    try:
        model = cost.fit(results, device, target, counters, per_pass, source=str(_results_path(study)))
        table = cost.design(results, target, model.counters, per_pass)
    except cost.CostModelError as exc:
        raise RunError(f"{study}: {exc}") from None
    out = Path(out) if out else (study if study.is_dir() else study.parent) / "cost_model.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    with replacing(out, out.with_name("cost_fit.png")) as (model_tmp, plot_tmp):
        model.save(model_tmp)  # both files written before either replaces an earlier one
        fit_plot(model, table, plot_tmp)
    return model, out


def fit_plot(model: cost.CostModel, table: pd.DataFrame, path: Path) -> Path:
    """Predicted against measured time (log-log): every row in-sample, and each scene's rows as
    predicted by the model fitted without that scene; the diagonal and ±2× lines."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    measured = table["measured_ms"].to_numpy(float)
    fitted = model.predict(table)
    loso = cost.left_out_predictions(table, model.counters)
    fig, ax = plt.subplots(figsize=(6.4, 5.2))
    ax.scatter(measured, fitted, s=14, alpha=0.6, label="fitted on every scene")
    if np.isfinite(loso).any():
        ax.scatter(measured, loso, s=14, marker="x", alpha=0.7, label="scene left out (cross-validated)")
    lo, hi = float(np.nanmin(measured)) / 2, float(np.nanmax(measured)) * 2
    xs = np.array([lo, hi])
    ax.plot(xs, xs, "k-", lw=0.8)
    ax.plot(xs, 2 * xs, "k:", lw=0.6)
    ax.plot(xs, xs / 2, "k:", lw=0.6)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(f"measured {model.target} (ms)")
    ax.set_ylabel(f"{cost.PREDICTED_LABEL} (ms)")
    ax.set_title(f"cost model: {model.device[:60]}\nR² {model.r2:.3f}, "
                 f"leave-one-scene-out median error {fmt_whole_pct(model.cv_median_rel_error)}", fontsize=9)
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, format="png", dpi=110)
    plt.close(fig)
    return path


def slug(text: str) -> str:
    """A file name from a device name."""
    return re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_")[:60] or "device"


def predict_command(study, model_path) -> tuple[pd.DataFrame, Path, cost.CostModel]:
    """Predict every row's time on the model's device, write ``cost/<device>.csv``, record it in
    ``study.json`` and draw the study page again (when the directory is a study); returns the
    table, its path and the model."""
    study = Path(study)
    try:
        model = cost.CostModel.load(Path(model_path))
    except cost.CostModelError as exc:
        raise RunError(str(exc)) from None
    results = _read_results(study)
    meta = _read_meta(study)
    try:
        table = cost.predict(results, model, device=meta.get("device"))
    except cost.CostModelError as exc:
        raise RunError(f"{study}: {exc}") from None
    folder = (study if study.is_dir() else study.parent) / "cost"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{slug(model.device)}.csv"
    page = study.is_dir() and _meta_path(study).is_file()
    with replacing(path, *([_meta_path(study), study / "study.html"] if page else [])) as tmps:
        table.to_csv(tmps[0], index=False)
        if page:  # the record and the page: written before anything replaces the earlier files
            from ..study.report import write_study_html

            entries = [e for e in meta.get("cost_predictions", []) if e.get("device") != model.device]
            entries.append(prediction_entry(model, table, path.relative_to(study).as_posix()))
            meta["cost_predictions"] = entries
            tmps[1].write_text(json.dumps(meta, indent=2, default=str))
            write_study_html(study, results, meta, out_name=tmps[2].name)
    return table, path, model


def prediction_entry(model: cost.CostModel, table: pd.DataFrame, csv: str) -> dict:
    """What the study page shows of one prediction: the model and, per configuration, the median
    measured time here and the median predicted time on the model's device."""
    rows = []
    key = "label" if "label" in table.columns else "scene"
    predicted = f"{cost.PREDICTED_LABEL}_ms"
    for label, g in table.groupby(key, sort=False):
        here = g["measured_here_ms"] if "measured_here_ms" in g else g["measured_ms"]
        unmodelled = sorted({u for v in g.get("unmodelled", pd.Series(dtype=str)).fillna("") for u in v.split(", ") if u})
        rows.append({"label": str(g["short_label"].iloc[0]) if "short_label" in g else str(label),
                     "technique": str(g["technique"].iloc[0]) if "technique" in g else "",
                     "measured_here_ms": float(np.nanmedian(here)) if here.notna().any() else None,
                     # over the same rows as the measured median: none when any row has no prediction
                     "predicted_ms": float(np.median(g[predicted])) if g[predicted].notna().all() else None,
                     "unmodelled": ", ".join(unmodelled),
                     "extrapolated": bool(g["extrapolated"].any()) if "extrapolated" in g else False})
    return {"device": model.device, "target": model.target, "r2": model.r2,
            "cv_median_rel_error": model.cv_median_rel_error, "model_rows": model.rows,
            "model_scenes": len(model.scenes), "csv": csv, "rows": rows}
