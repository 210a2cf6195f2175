"""Holding artefact metrics (docs/contracts.md#study-directory): a study's results against a committed baseline.

A baseline is a CSV with one row per (scene, light, config) — ``config`` is the configuration as
the suite writes it (``shadow_map:variant=slope``), so a changed default is seen as changed
metrics of the same configuration, not as a run gone missing — the full spec it resolved to
(``label``, for information: a spec that resolves differently is reported) and one column per
held metric (:data:`shadowlab.evaluation.metrics.HELD_COLUMNS`: error and false rates, boundary distances,
contact gap, umbra spread, visibility MAE). A metric regresses when the study's value exceeds the baseline's
by more than its tolerance (``max(abs, rel × baseline)``; larger is worse for every held
metric); a configuration of the baseline that is missing from the study, or failed there,
regresses too. Improvements beyond tolerance are reported, not failed: update the baseline
(``--update``) to hold the new level.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from ..evaluation.metrics import HELD_COLUMNS

KEY = ["scene", "light", "config"]
#: Kept beside the key for information: the full spec the configuration resolved to.
INFO = ["label"]


class CheckError(ValueError):
    """The study directory or the baseline cannot be read."""


@dataclass
class CheckResult:
    """Regressions and improvements (DataFrames with key, metric, baseline, value, allowed), the
    configurations the study has that the baseline does not, and those that now resolve to
    another full spec than the baseline's (a changed default: ``"key: old → new"``)."""

    regressions: pd.DataFrame
    improvements: pd.DataFrame
    new: list[str]
    checked: int
    respecified: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """True when nothing regressed."""
        return self.regressions.empty


def read_results(study_dir: Path) -> pd.DataFrame:
    """A study's results.csv (CheckError when absent or unreadable)."""
    path = Path(study_dir) / "results.csv"
    if not path.is_file():
        raise CheckError(f"{study_dir}: no results.csv (is it a study directory? run 'shadowlab study' first)")
    try:
        return pd.read_csv(path, keep_default_na=False, na_values=[""])
    except (OSError, pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise CheckError(f"{path}: cannot read: {exc}") from exc


def baseline_from(results: pd.DataFrame) -> pd.DataFrame:
    """The baseline of a study's results: its finished non-reference rows, key and held metrics."""
    ok = results[(results["status"] == "ok") & (~results["reference"].astype(bool))]
    cols = KEY + INFO + [c.name for c in HELD_COLUMNS if c.name in ok.columns]
    return ok[cols].sort_values(KEY).reset_index(drop=True)


def read_baseline(path: Path) -> pd.DataFrame:
    """A baseline CSV (CheckError when absent, unreadable or without the key columns)."""
    path = Path(path)
    if not path.is_file():
        raise CheckError(f"{path}: no such baseline (write one with --update)")
    try:
        df = pd.read_csv(path)
    except (OSError, pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise CheckError(f"{path}: cannot read: {exc}") from exc
    missing = [k for k in KEY if k not in df.columns]
    if missing:
        raise CheckError(f"{path}: not a baseline: no column {missing[0]!r}")
    unknown = [c for c in df.columns if c not in KEY + INFO and c not in {h.name for h in HELD_COLUMNS}]
    if unknown:
        raise CheckError(f"{path}: column {unknown[0]!r} is not a held metric "
                         f"(held: {', '.join(h.name for h in HELD_COLUMNS)})")
    return df


def check(results: pd.DataFrame, baseline: pd.DataFrame) -> CheckResult:
    """Compare a study's results with a baseline (see the module docstring)."""
    missing = [k for k in KEY if k not in results.columns]
    if missing:
        raise CheckError(f"the study's results have no column {missing[0]!r} (written by an older shadowlab? "
                         f"run the study again)")
    res = results.set_index(KEY)
    regressions, improvements, respecified, checked = [], [], [], 0
    tolerance = {c.name: c.tolerance for c in HELD_COLUMNS}
    for _, base in baseline.iterrows():
        key = tuple(base[k] for k in KEY)
        where = dict(zip(KEY, key))
        if key not in res.index:
            regressions.append({**where, "metric": "(run)", "baseline": math.nan, "value": math.nan,
                                "allowed": math.nan, "problem": "missing from the study"})
            continue
        now = res.loc[[key]].iloc[0]
        if now.get("status", "ok") not in ("ok", "untimed"):  # untimed rows still have their metrics
            regressions.append({**where, "metric": "(run)", "baseline": math.nan, "value": math.nan,
                                "allowed": math.nan, "problem": f"failed: {now.get('error', '')}"})
            continue
        if "label" in baseline.columns and "label" in now and base["label"] != now["label"]:
            respecified.append(f"{key[0]} / light {key[1]} / {key[2]}: {_spec_change(base['label'], now['label'])}")
        for metric, (abs_tol, rel_tol) in tolerance.items():
            if metric not in baseline.columns or pd.isna(base[metric]):
                continue
            checked += 1
            b, v = float(base[metric]), float(now.get(metric, math.nan))
            allowed = max(abs_tol, rel_tol * abs(b))
            entry = {**where, "metric": metric, "baseline": b, "value": v, "allowed": allowed}
            if math.isnan(v) or v > b + allowed:
                regressions.append({**entry, "problem": "worse" if not math.isnan(v) else "not measured"})
            elif v < b - allowed:
                improvements.append({**entry, "problem": "better"})
    base_keys = {tuple(r) for r in baseline[KEY].itertuples(index=False)}
    new = sorted({f"{s} / light {l} / {lab}" for s, l, lab, ref in
                  results[KEY + ["reference"]].itertuples(index=False)
                  if not bool(ref) and (s, l, lab) not in base_keys})
    columns = KEY + ["metric", "baseline", "value", "allowed", "problem"]
    return CheckResult(pd.DataFrame(regressions, columns=columns), pd.DataFrame(improvements, columns=columns),
                       new, checked, respecified)


def _spec_change(old: str, new: str) -> str:
    """What differs between two full specs (``name:key=value,...``), e.g. ``bias 0.002 → 0.0002``."""
    def parts(spec: str) -> tuple[str, dict[str, str]]:
        name, _, params = str(spec).partition(":")
        return name, dict(p.split("=", 1) for p in params.split(",") if "=" in p)

    (n0, p0), (n1, p1) = parts(old), parts(new)
    if n0 != n1:
        return f"{old} → {new}"
    changes = [f"{k} {p0.get(k, '(none)')} → {p1.get(k, '(none)')}" for k in dict.fromkeys([*p0, *p1])
               if p0.get(k) != p1.get(k)]
    return ", ".join(changes)


def format_findings(df: pd.DataFrame) -> str:
    """A findings table for the terminal."""
    if df.empty:
        return ""
    shown = df.copy()
    for col in ("baseline", "value", "allowed"):
        shown[col] = shown[col].map(lambda x: "" if pd.isna(x) else f"{x:.5g}")
    with pd.option_context("display.width", 220, "display.max_colwidth", 70):
        return shown.to_string(index=False)
