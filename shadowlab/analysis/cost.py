"""Cost models: a device's time per unit of work, fitted from a study's own rows (docs/cost.md).

A row's work counters (:mod:`shadowlab.gpu.work`) are the same on every device; its time is not. A
cost model for one device is the non-negative linear map

    time ≈ c_0 + Σ_k c_k · counter_k        (c ≥ 0, ms per unit; c_0 per render)

fitted by non-negative least squares (Lawson & Hanson 1974, ``scipy.optimize.nnls``) over the
rows of a study run on that device. Times span decades (a planar shadow on a small scene
against a million-triangle truth), so each row is weighted by 1 / its measured time: the fit
minimises the relative error, and a slow configuration cannot buy its accuracy with every fast
one's. The coefficients' units are the counters' own (ms per sample passed, per byte cleared,
per ray ...), so a model says what a device charges for each kind of work.

The model is reported with R² (of the times, unweighted) and with its leave-one-scene-out
cross-validated error: every scene in turn is left out, the model refitted on the others and
its rows predicted — what a prediction for a scene the model has never seen is worth. With
``per_pass`` the rows are each configuration's passes (``pass_<name>_ms`` against
``work_<name>_<counter>``: the study needs ``pass_timing = true``) with the same coefficients
for every pass. A predicted time is always labelled as one (:data:`PREDICTED_LABEL`).
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..gpu import work

#: The counters a model uses unless told otherwise: the exact ones and the two declared models
#: (bytes written, texture taps). The driver-dependent shader-invocation counts are left out:
#: a model fitted on them would not travel to another driver's counts.
DEFAULT_COUNTERS = ("draws", "vertices", "primitives_generated", "samples_passed", "bytes_written",
                    "bytes_cleared", "bytes_uploaded", "bytes_read", "dispatches", "compute_invocations",
                    "texture_taps", "stencil_updates", "cpu_triangles", "cpu_points", "rays")
#: Work done on the CPU: left out of a model of a GPU timer's time (``gpu_time_ms_median``).
CPU_COUNTERS = ("cpu_triangles", "cpu_points", "rays")
#: The constant term's name: a fixed cost per render (per pass in a per-pass model).
INTERCEPT = "render"
#: How a predicted time is labelled wherever it is shown.
PREDICTED_LABEL = "predicted"
#: Model files carry this format number.
FORMAT = 1


class CostModelError(ValueError):
    """A study or model file that cannot give a cost model (no timed rows, no counters, a
    counter the rows lack, a malformed model file)."""


@dataclass
class CostModel:
    """A fitted cost model (module docstring): per counter ms per unit, the constant per render,
    and how good it is (R², in-sample and leave-one-scene-out relative errors)."""

    device: str
    target: str
    counters: list[str]
    coefficients: dict[str, float]
    intercept_ms: float
    per_pass: bool
    rows: int
    scenes: list[str]
    r2: float
    median_rel_error: float
    cv_median_rel_error: float
    cv_mean_rel_error: float
    cv_per_scene: dict[str, float] = field(default_factory=dict)
    #: Counters asked for that no fitted row did: the model has no cost for them, and a row that
    #: does such work gets no prediction (:func:`predict`).
    unseen: list[str] = field(default_factory=list)
    #: The techniques of the fitted rows: a prediction for another is an extrapolation.
    techniques: list[str] = field(default_factory=list)
    source: str = ""
    weighting: str = "1/measured (relative error)"
    format: int = FORMAT

    def predict(self, features: pd.DataFrame) -> np.ndarray:
        """Predicted times (ms) of rows of counter values (columns named as :attr:`counters`)."""
        X = features[self.counters].to_numpy(float)
        c = np.array([self.coefficients[k] for k in self.counters])
        return self.intercept_ms + X @ c

    def save(self, path: Path) -> None:
        """Write the model as JSON."""
        Path(path).write_text(json.dumps(asdict(self), indent=2) + "\n", encoding="utf-8")

    @classmethod
    def load(cls, path: Path) -> "CostModel":
        """Read a model written by :meth:`save` (CostModelError naming the file when it is not one)."""
        try:
            data = json.loads(Path(path).read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise CostModelError(f"{path}: not a readable cost model ({exc})") from None
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            raise CostModelError(f"{path}: not a cost model of format {FORMAT} (key 'format')")
        try:
            return cls(**data)
        except TypeError as exc:
            raise CostModelError(f"{path}: {exc}") from None

    def table(self) -> pd.DataFrame:
        """The coefficients as rows (counter, ms per unit, ns per unit), the constant first."""
        rows = [(INTERCEPT, self.intercept_ms)] + [(k, self.coefficients[k]) for k in self.counters]
        return pd.DataFrame([(k, v, v * 1e6) for k, v in rows], columns=["counter", "ms_per_unit", "ns_per_unit"])


def _timed(results: pd.DataFrame, target: str) -> pd.DataFrame:
    ok = results
    if "status" in ok.columns:
        ok = ok[ok["status"] == "ok"]
    if target not in ok.columns:
        raise CostModelError(f"the rows have no {target!r} column")
    t = pd.to_numeric(ok[target], errors="coerce")
    return ok[np.isfinite(t) & (t > 0)]


def _check_work(rows: pd.DataFrame) -> None:
    """CostModelError unless the rows have a scene and work counters on every row."""
    if "scene" not in rows.columns:
        raise CostModelError("the rows have no 'scene' column")
    cols = [c for c in rows.columns if work.is_work_column(c)]
    if not cols:
        raise CostModelError("the rows have no work_ columns: the study predates work counters; run it again")
    none = rows[cols].isna().all(axis=1)
    if none.any():
        first = rows[none].iloc[0]
        raise CostModelError(f"{int(none.sum())} row(s) have no work counters (e.g. {first['scene']} / "
                             f"{first.get('label', '?')}): rows from before work counters; run the study again")


def _pass_names(rows: pd.DataFrame) -> list[str]:
    """The passes named in the rows' ``work_<pass>_<counter>`` columns."""
    names = {work.counter_of(c)[0] for c in rows.columns if work.counter_of(c) is not None}
    return sorted(n for n in names if n)


def _features(rows: pd.DataFrame, counters, pass_name: str | None = None) -> np.ndarray:
    """(rows, counters) work of each row: the totals, or one pass's (0 where not done)."""
    cols = []
    for k in counters:
        col = f"work_{k}" if pass_name is None else f"work_{pass_name}_{k}"
        cols.append(pd.to_numeric(rows[col], errors="coerce").fillna(0.0).to_numpy(float) if col in rows
                    else np.zeros(len(rows)))
    return np.column_stack(cols) if cols else np.zeros((len(rows), 0))


def design(results: pd.DataFrame, target: str = "time_ms_median", counters=DEFAULT_COUNTERS,
           per_pass: bool = False) -> pd.DataFrame:
    """The fitting table: one row per timed row (or per timed pass with ``per_pass``), columns
    ``scene``, ``label``, ``technique``, ``light``, ``pass``, ``measured_ms`` and one per
    counter (0 where a row did no such work). CostModelError when nothing is timed, the rows
    have no counters, or a timed row has none (a study from before the counters)."""
    rows = _timed(results, target)
    _check_work(rows)
    keys = [c for c in ("scene", "label", "technique", "light") if c in rows.columns]
    counters = list(counters)
    out = []
    if not per_pass:
        table = rows[keys].copy().reset_index(drop=True)
        table["pass"] = ""
        table["measured_ms"] = pd.to_numeric(rows[target]).to_numpy(float)
        table[counters] = _features(rows, counters)
        out.append(table)
    else:
        passes = sorted(c[len("pass_"):-len("_ms")] for c in rows.columns if c.startswith("pass_") and c.endswith("_ms"))
        if not passes:
            raise CostModelError("per-pass fitting needs pass_<name>_ms columns: run the study with pass_timing = true")
        for p in passes:
            t = pd.to_numeric(rows[f"pass_{p}_ms"], errors="coerce")
            sel = rows[np.isfinite(t) & (t > 0)]
            if sel.empty:
                continue
            table = sel[keys].copy().reset_index(drop=True)
            table["pass"] = p
            table["measured_ms"] = t[sel.index].to_numpy(float)
            table[counters] = _features(sel, counters, p)
            out.append(table)
    table = pd.concat(out, ignore_index=True) if out else pd.DataFrame()
    if table.empty:
        raise CostModelError(f"no row has a positive {target}")
    return table


def _nnls(table: pd.DataFrame, counters: list[str]) -> tuple[float, np.ndarray]:
    """(c_0, c) minimising Σ ((c_0 + X c − t) / t)² with c_0, c ≥ 0. Columns are scaled to unit
    norm before the solve (counts run from 1 draw to 10⁹ bytes) and the solution scaled back."""
    from scipy.optimize import nnls

    t = table["measured_ms"].to_numpy(float)
    X = np.column_stack([np.ones(len(t))] + [table[k].to_numpy(float) for k in counters])
    A = X / t[:, None]
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    sol, _ = nnls(A / scale, np.ones(len(t)), maxiter=50 * A.shape[1])
    sol = sol / scale
    return float(sol[0]), sol[1:]


def _relative_errors(predicted: np.ndarray, measured: np.ndarray) -> np.ndarray:
    return np.abs(predicted - measured) / measured


def left_out_predictions(table: pd.DataFrame, counters: list[str]) -> np.ndarray:
    """Each row of a :func:`design` table predicted by the model fitted without its scene
    (leave one scene out); NaN everywhere when the table has a single scene."""
    out = np.full(len(table), np.nan)
    scenes = table["scene"].astype(str)
    if scenes.nunique() < 2:
        return out
    for s in scenes.unique():
        held = (scenes == s).to_numpy()
        c0, c = _nnls(table[~held], counters)
        out[held] = c0 + table.loc[held, counters].to_numpy(float) @ c
    return out


def fit(results: pd.DataFrame, device: str, target: str = "time_ms_median", counters=None, per_pass: bool = False,
        source: str = "") -> CostModel:
    """Fit a :class:`CostModel` for ``device`` from study rows (module docstring). ``counters``:
    the counters to use (default :data:`DEFAULT_COUNTERS`); an unknown name is an error, a
    counter no row ever did is dropped (it cannot be fitted). Leave-one-scene-out needs two or
    more scenes (otherwise the cross-validated errors are NaN)."""
    if counters is None:  # a GPU timer does not see the CPU's work
        counters = [k for k in DEFAULT_COUNTERS if not (target.startswith("gpu_") and k in CPU_COUNTERS)]
    counters = list(counters)
    unknown = [k for k in counters if k not in work.COUNTERS]
    if unknown:
        from ..util.validation import did_you_mean

        raise CostModelError(f"unknown counter {unknown[0]!r}{did_you_mean(unknown[0], work.COUNTERS)} "
                             f"(known: {', '.join(work.COUNTERS)})")
    table = design(results, target, counters, per_pass)
    unseen = [k for k in counters if table[k].abs().sum() == 0]
    counters = [k for k in counters if k not in unseen]
    if not counters:
        raise CostModelError("no row did any of the counted work")
    c0, c = _nnls(table, counters)
    measured = table["measured_ms"].to_numpy(float)
    predicted = c0 + table[counters].to_numpy(float) @ c
    ss_res = float(np.sum((predicted - measured) ** 2))
    ss_tot = float(np.sum((measured - measured.mean()) ** 2))
    scenes = sorted(table["scene"].astype(str).unique())
    cv_pred = left_out_predictions(table, counters)
    per_scene = {}
    if len(scenes) > 1:
        for s in scenes:
            held = (table["scene"].astype(str) == s).to_numpy()
            per_scene[s] = float(np.median(_relative_errors(cv_pred[held], measured[held])))
    cv_err = _relative_errors(cv_pred, measured)
    return CostModel(device=device, target=target, counters=counters,
                     coefficients={k: float(v) for k, v in zip(counters, c)}, intercept_ms=c0, per_pass=per_pass,
                     rows=len(table), scenes=scenes, r2=1.0 - ss_res / ss_tot if ss_tot > 0 else float("nan"),
                     median_rel_error=float(np.median(_relative_errors(predicted, measured))),
                     cv_median_rel_error=float(np.nanmedian(cv_err)) if len(scenes) > 1 else float("nan"),
                     cv_mean_rel_error=float(np.nanmean(cv_err)) if len(scenes) > 1 else float("nan"),
                     cv_per_scene=per_scene, unseen=unseen, source=source,
                     techniques=sorted(map(str, table["technique"].dropna().unique()))
                     if "technique" in table.columns else [])


def predict(results: pd.DataFrame, model: CostModel, device: str | None = None) -> pd.DataFrame:
    """Per row of ``results`` (its work counters): the time measured where the rows were run
    (``measured_here_ms``: ``time_ms_median``), the model's prediction (``predicted_ms``; a
    per-pass model sums the passes each row ran, each with the constant), and — only when
    ``device`` (where the rows ran) is the model's own — the measured target (``measured_ms``)
    and the relative error; NaN otherwise. A row doing work the model has no cost for
    (:attr:`CostModel.unseen`: the truth's rays under a GPU model fitted without them) gets no
    prediction and ``unmodelled`` names that work; ``extrapolated`` marks techniques the
    model never saw."""
    rows = results
    if "status" in rows.columns:
        rows = rows[rows["status"] == "ok"]
    _check_work(rows)
    keys = [c for c in ("scene", "label", "short_label", "light", "technique") if c in rows.columns]
    table = rows[keys].copy().reset_index(drop=True)
    here = pd.to_numeric(rows["time_ms_median"], errors="coerce") if "time_ms_median" in rows else None
    table["measured_here_ms"] = here.to_numpy(float) if here is not None else np.nan
    same = device is not None and device == model.device and model.target in rows
    table["measured_ms"] = pd.to_numeric(rows[model.target], errors="coerce").to_numpy(float) if same else np.nan
    c = np.array([model.coefficients[k] for k in model.counters])
    if model.per_pass:
        predicted = np.zeros(len(rows))
        for p in _pass_names(rows):
            done = _features(rows, list(work.COUNTERS), p).any(axis=1)  # the row ran this pass
            predicted += np.where(done, model.intercept_ms + _features(rows, model.counters, p) @ c, 0.0)
    else:
        predicted = model.intercept_ms + _features(rows, model.counters) @ c
    unseen = {k: _features(rows, [k])[:, 0] > 0 for k in model.unseen}
    if model.target.startswith("gpu_"):  # a GPU timer's model: a row that drew and dispatched nothing has no GPU time
        unseen["CPU work only"] = ~_features(rows, ["draws", "dispatches"]).any(axis=1)
    table["unmodelled"] = [", ".join(k for k, did in unseen.items() if did[i]) for i in range(len(rows))]
    predicted[table["unmodelled"].astype(bool).to_numpy()] = np.nan
    if model.techniques and "technique" in table.columns:  # no such technique among the fitted rows
        table["extrapolated"] = ~table["technique"].astype(str).isin(model.techniques)
    table[f"{PREDICTED_LABEL}_ms"] = predicted
    table["rel_error"] = _relative_errors(predicted, table["measured_ms"].to_numpy(float))
    return table


def summary_line(model: CostModel) -> str:
    """One line: the device, what was fitted and how good it is."""
    cv = ("n/a (one scene)" if math.isnan(model.cv_median_rel_error)
          else f"{100 * model.cv_median_rel_error:.0f} % median, {100 * model.cv_mean_rel_error:.0f} % mean")
    return (f"{model.device}: {model.target} ≈ Σ c_k·counter_k over {model.rows} "
            f"{'passes' if model.per_pass else 'rows'} of {len(model.scenes)} scenes; R² {model.r2:.3f}; "
            f"in-sample median error {100 * model.median_rel_error:.0f} %; leave-one-scene-out error {cv}")
