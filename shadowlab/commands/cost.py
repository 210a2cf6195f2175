"""``shadowlab cost fit`` and ``shadowlab cost predict``: a device's cost model from a study's
rows, and predicted times from it (DESIGN §16; the model is :mod:`shadowlab.cost`).

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
import math
import os
import re
from pathlib import Path

import numpy as np
import pandas as pd

from .. import cost
from ..validation import RunError


def _results_path(study: Path) -> Path:
    path = study / "results.csv" if study.is_dir() else study
    if not path.is_file():
        raise RunError(f"{study}: no results.csv (a study directory or a results CSV is expected)")
    return path


def _device_of(study: Path) -> str:
    meta = study / "study.json" if study.is_dir() else study.with_name("study.json")
    if meta.is_file():
        try:
            return str(json.loads(meta.read_text()).get("device") or "")
        except json.JSONDecodeError:
            pass
    return ""


def _replace(path: Path, write) -> None:
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    write(tmp)
    os.replace(tmp, path)


def fit_command(study, out=None, target: str = "time_ms_median", counters=None, per_pass: bool = False,
                device: str | None = None) -> tuple[cost.CostModel, Path]:
    """Fit and write a model (module docstring); returns it and its path."""
    study = Path(study)
    results = pd.read_csv(_results_path(study))
    device = device or _device_of(study) or "unknown device"
    try:
        model = cost.fit(results, device, target, counters, per_pass, source=str(_results_path(study)))
    except cost.CostModelError as exc:
        raise RunError(f"{study}: {exc}") from None
    out = Path(out) if out else (study if study.is_dir() else study.parent) / "cost_model.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    _replace(out, model.save)
    table = cost.design(results, target, model.counters, per_pass)
    _replace(out.with_name("cost_fit.png"), lambda p: fit_plot(model, table, p))
    return model, out


def fit_plot(model: cost.CostModel, table: pd.DataFrame, path: Path) -> Path:
    """Predicted against measured time (log-log): every row in-sample, and each scene's rows as
    predicted by the model fitted without that scene; the diagonal and ±2× lines."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    measured = table["measured_ms"].to_numpy(float)
    fitted = model.predict(table)
    loso = np.full(len(table), np.nan)
    if len(model.scenes) > 1:
        for s in model.scenes:
            held = (table["scene"].astype(str) == s).to_numpy()
            sub = cost.fit(_as_results(table[~held], model), model.device, "measured_ms", model.counters,
                           False) if (~held).any() else None
            if sub is not None:
                loso[held] = sub.predict(table[held])
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
                 f"leave-one-scene-out median error {_pct(model.cv_median_rel_error)}", fontsize=9)
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, format="png", dpi=110)
    plt.close(fig)
    return path


def _as_results(table: pd.DataFrame, model: cost.CostModel) -> pd.DataFrame:
    """A design table as study rows again (``work_<counter>`` and the target ``measured_ms``)."""
    out = table[["scene", "measured_ms"]].copy()
    for k in model.counters:
        out[f"work_{k}"] = table[k].to_numpy(float)
    return out


def _pct(x: float) -> str:
    return "n/a" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{100 * x:.0f} %"


def slug(text: str) -> str:
    """A file name from a device name."""
    return re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_")[:60] or "device"


def predict_command(study, model_path) -> tuple[pd.DataFrame, Path, cost.CostModel]:
    """Predict every row's time on the model's device, write ``cost/<device>.csv``, record it in
    ``study.json`` and draw the study page again (when the directory is a study); returns the
    table, its path and the model."""
    study = Path(study)
    model = cost.CostModel.load(Path(model_path))
    results = pd.read_csv(_results_path(study))
    try:
        table = cost.predict(results, model)
    except cost.CostModelError as exc:
        raise RunError(f"{study}: {exc}") from None
    folder = (study if study.is_dir() else study.parent) / "cost"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{slug(model.device)}.csv"
    _replace(path, lambda p: table.to_csv(p, index=False))
    meta_path = study / "study.json" if study.is_dir() else None
    if meta_path is not None and meta_path.is_file():
        meta = json.loads(meta_path.read_text())
        entries = [e for e in meta.get("cost_predictions", []) if e.get("device") != model.device]
        entries.append(prediction_entry(model, table, path.relative_to(study).as_posix()))
        meta["cost_predictions"] = entries
        _replace(meta_path, lambda p: p.write_text(json.dumps(meta, indent=2, default=str)))
        from ..study.report import write_study_html

        write_study_html(study, results, meta)
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
                     "predicted_ms": float(np.nanmedian(g[predicted])) if g[predicted].notna().any() else None,
                     "unmodelled": ", ".join(unmodelled),
                     "extrapolated": bool(g["extrapolated"].any()) if "extrapolated" in g else False})
    return {"device": model.device, "target": model.target, "r2": model.r2,
            "cv_median_rel_error": model.cv_median_rel_error, "model_rows": model.rows,
            "model_scenes": len(model.scenes), "csv": csv, "rows": rows}
