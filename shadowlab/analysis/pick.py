"""The cheapest pick under an error budget (docs/metrics.md#the-pick): per scene and per scene
family, the configuration that costs least per frame among those whose error stays within a
budget — for a still light (``time_ms``) and for a moving one (``moving_ms``: plus the per-light
preprocessing redone every frame) — with its margins: how much of the budget it uses, and the
runner-up's time and whether their repeat intervals overlap (then the pick is a toss-up on time).

It answers what a user of the lab asks ("which is the cheapest configuration that stays under my
error budget on this scene?") from a study's ``results.csv`` alone, over *every* configuration
that ran — not only each family's most accurate — since the cheapest acceptable one is often a
cheaper setting of a family whose best is costlier. A configuration that is degenerate or whose
run failed is never picked. Per family of scenes, a configuration qualifies when it ran on every
scene of the family and is within the budget on each (its worst scene decides), and it is ranked
by its median time over them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import pandas as pd

from .aggregate import as_text, normalised, per_configuration, scenes_in_order
from .significance import intervals_overlap
from .verdicts import verdict_metric

#: The budgets the study page, summary.md and ``shadowlab pick`` use by default, per verdict
#: metric: hard scenes in wrong pixels per pixel of the truth's shadow boundary (10 %: a visibly
#: wobbly edge; 1 %: an edge wrong in a few places; 0.1 %: as good as exact at the lab's sizes),
#: soft scenes in mean |V − G| (0.02: the fail threshold; 0.005: a penumbra off by a shade),
#: many-light scenes in the shaded image's mean relative luminance error (5 %: the fail threshold;
#: 2 %: a dropped shadow here and there; 1 %: hard to tell from every light's exact shadow).
DEFAULT_BUDGETS = {"edge_error_rate": (0.1, 0.01, 0.001), "visibility_mae": (0.02, 0.005),
                   "radiance_error": (0.05, 0.02, 0.01), "error_rate": (0.001, 0.0001)}
#: The two ways a frame's cost is counted: a still light and a moving one.
MOTIONS = {"still": "time_ms", "moving": "moving_ms"}

#: Columns of :func:`pick_table`.
PICK_COLUMNS = ["level", "scene_family", "scene", "metric", "budget", "motion", "label", "short_label", "technique",
                "error", "time_ms", "time_lo_ms", "time_hi_ms", "scenes", "runner_up", "runner_up_ms",
                "runner_up_ties", "most_accurate", "most_accurate_error", "predicted"]


@dataclass(frozen=True)
class Budget:
    """One error budget: the verdict metric it bounds and its value."""

    metric: str
    value: float


def default_budgets() -> list[Budget]:
    """:data:`DEFAULT_BUDGETS` as a list."""
    return [Budget(m, v) for m, values in DEFAULT_BUDGETS.items() for v in values]


def _candidates(cfg: pd.DataFrame) -> pd.DataFrame:
    """The configurations a pick may choose: not the truth, not degenerate, timed."""
    ok = cfg[~cfg["reference"].astype(bool) & ~cfg["degenerate"].astype(bool)]
    return ok[ok["time_ms"].notna()]


def _choose(group: pd.DataFrame, error_col: str, time_col: str, budget: float) -> dict:
    """The cheapest row of ``group`` with ``error_col`` ≤ ``budget`` by ``time_col``, and its
    runner-up; or, when none qualifies, the most accurate (the caller says nothing qualifies)."""
    under = group[group[error_col] <= budget].sort_values([time_col, error_col], kind="stable")
    out = {"label": "", "short_label": "", "technique": "", "error": math.nan, "time_ms": math.nan,
           "time_lo_ms": math.nan, "time_hi_ms": math.nan, "runner_up": "", "runner_up_ms": math.nan,
           "runner_up_ties": False, "most_accurate": "", "most_accurate_error": math.nan}
    scored = group[group[error_col].notna()]
    if len(scored):
        best = scored.sort_values([error_col, time_col], kind="stable").iloc[0]
        out.update(most_accurate=best["short_label"], most_accurate_error=float(best[error_col]))
    if not len(under):
        return out
    pick = under.iloc[0]
    out.update(label=pick["label"], short_label=pick["short_label"], technique=pick["technique"],
               error=float(pick[error_col]), time_ms=float(pick[time_col]), time_lo_ms=float(pick["_lo"]),
               time_hi_ms=float(pick["_hi"]))
    if len(under) > 1:
        second = under.iloc[1]
        out.update(runner_up=second["short_label"], runner_up_ms=float(second[time_col]),
                   runner_up_ties=intervals_overlap((pick["_lo"], pick["_hi"]), (second["_lo"], second["_hi"])))
    return out


def pick_table(results: pd.DataFrame, budgets: list[Budget] | None = None, times: pd.DataFrame | None = None,
               motions=("still", "moving")) -> pd.DataFrame:
    """The pick for every scene and every scene family of ``results`` (results.csv), for each of
    ``budgets`` whose metric is the scene's verdict metric
    (:func:`~shadowlab.analysis.verdicts.verdict_metric`) and each motion of ``motions``
    ('still', 'moving'). ``times``: per (scene, spec_label) a ``time_ms`` to rank by instead of the
    measured one, with its band ``time_lo_ms``, ``time_hi_ms`` (a cost model's prediction and its
    error: ``predicted`` is then True); configurations without one are left out.

    Columns (:data:`PICK_COLUMNS`): ``level`` ('scene' or 'family'), ``scene_family``, ``scene``
    ('' for a family), ``metric``, ``budget``, ``motion``; the pick (``label``, ``short_label``,
    ``technique``; '' when nothing is within the budget), its ``error`` (a family: its worst scene)
    and ``time_ms`` (a family: the median over its scenes) with its repeat interval; ``scenes``
    (how many the family's candidates had to cover); ``runner_up`` and ``runner_up_ms`` (the next
    cheapest within the budget) and ``runner_up_ties`` (their repeat intervals overlap);
    ``most_accurate`` and ``most_accurate_error`` (whatever the budget: what comes closest when
    nothing is within it)."""
    budgets = default_budgets() if budgets is None else budgets
    cfg = per_configuration(results)
    cand = _candidates(cfg)
    if times is not None:
        cand = cand.drop(columns=["time_ms", "time_lo_ms", "time_hi_ms"]).merge(
            times[["scene", "spec_label", "time_ms", "time_lo_ms", "time_hi_ms"]], on=["scene", "spec_label"])
        cand = cand[cand["time_ms"].notna()]
        cand = cand.assign(moving_ms=cand["time_ms"] + cand["preprocess_ms"])
    rows = []
    df = normalised(results) if len(results) else results
    scenes = scenes_in_order(df) if len(df) else []
    fam_of = df.drop_duplicates("scene").set_index("scene")["scene_family"].map(as_text) if len(df) else {}
    families: dict[str, list[str]] = {}
    for scene in scenes:
        families.setdefault(fam_of.get(scene, ""), []).append(scene)
    for fam, fam_scenes in families.items():
        metric = verdict_metric(fam, cfg[cfg["scene"].isin(fam_scenes)])
        for budget in [b for b in budgets if b.metric == metric]:
            for motion in motions:
                time_col = MOTIONS[motion]
                pre = "preprocess_ms" if motion == "moving" else None
                # a family's candidates: a value on every one of its scenes (NaN is no value)
                g = cand[cand["scene"].isin(fam_scenes) & cand[metric].notna()]
                covers = g.groupby("label", sort=False)["scene"].nunique()
                g = g[g["label"].isin(covers.index[covers == len(fam_scenes)])]
                g = g.assign(_lo=g["time_lo_ms"] + (g[pre] if pre else 0.0),
                             _hi=g["time_hi_ms"] + (g[pre] if pre else 0.0))
                pooled = g.groupby("label", sort=False).agg(
                    short_label=("short_label", "first"), technique=("technique", "first"), err=(metric, "max"),
                    t=(time_col, "median"), _lo=("_lo", "median"), _hi=("_hi", "median")).reset_index()
                rows.append({"level": "family", "scene_family": fam, "scene": "", "metric": metric,
                             "budget": budget.value, "motion": motion, "scenes": len(fam_scenes),
                             "predicted": times is not None,
                             **_choose(pooled.rename(columns={"err": metric, "t": time_col}), metric, time_col,
                                       budget.value)})
                for scene in fam_scenes:
                    g = cand[cand["scene"] == scene].assign(
                        _lo=lambda d: d["time_lo_ms"] + (d[pre] if pre else 0.0),
                        _hi=lambda d: d["time_hi_ms"] + (d[pre] if pre else 0.0))
                    rows.append({"level": "scene", "scene_family": fam, "scene": scene, "metric": metric,
                                 "budget": budget.value, "motion": motion, "scenes": 1,
                                 "predicted": times is not None, **_choose(g, metric, time_col, budget.value)})
    return pd.DataFrame(rows, columns=PICK_COLUMNS)
