"""Coordinate search with refinement over rendered candidates, on a stated budget.

:func:`coordinate_search` is plain coordinate descent (one parameter at a time, the others held
at the best values so far; e.g. Nocedal & Wright, *Numerical Optimization*, 2nd ed., §9.3) over
a grid that is refined around the best value round after round:

- round 0 tries ``points`` values across each dimension's whole range (geometric for ``log``
  dimensions, every choice for a choice dimension), dimension by dimension, starting from the
  spec's own values; with a budget too small for that, (budget − 1) / dimensions values each
  (at least 3): every dimension is tried once the budget reaches 3 · dimensions + 1 renders
  (below that the later dimensions may get none);
- each later round tries ``points`` values across a window ``shrink`` times the previous one
  (never narrower than the previous spacing, so the window covers the gaps beside the best),
  centred on the best value; choice dimensions are tried again only when another dimension
  moved since; an integer window always reaches the best's neighbours (past values the
  technique refused), and integer dimensions stop once their window holds nothing new;
- it stops when ``budget`` evaluations are spent, or when a round changed nothing and every
  window is below 1e-3 of its range.

**What the budget counts**: evaluations, i.e. candidate configurations rendered and judged
(with :class:`RenderedCandidates`: one :func:`shadowlab.measurement.pipeline.measure` each, or a cache hit
standing in for one). A candidate already evaluated is never evaluated again (it costs
nothing), and one the technique refuses to build or set up (:class:`Rejected`: an even blur
kernel, an exponent that overflows the storage) costs nothing either. The ground truth, measured
once per light, is not a candidate.

**The search is local.** A grid of a few points per round can step over a narrow minimum, and
descent along one parameter at a time can stop where no single parameter improves although a
joint move would; an error curve that is not convex (the shadow-map bias: acne on one side,
peter-panning on the other, plateaus between) can hold a better optimum the search never visits.
For the shadow-map bias family, :mod:`shadowlab.tuning.exact_bias` has no such limit: it finds
the best constant bias from one render.

:class:`RenderedCandidates` turns a candidate (parameter → value) into its objective value by
rendering it: the tune's spec with those values, measured on one light of a frame and judged
against the truth by an :class:`~shadowlab.measurement.pipeline.Evaluator`; with a study cache
(:class:`shadowlab.output.cache.Cache`) a second tune of the same scene, spec and code renders
nothing.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any, Callable, Sequence

from ..gpu import gl
from ..evaluation import metrics
from ..output import provenance
from ..measurement.pipeline import Evaluator, measure
from ..output.cache import Cache, run_key, scene_content_hash
from ..techniques import TechniqueError, from_spec
from ..gpu.timing import is_time_column
from ..util.validation import did_you_mean
from .space import FLOAT_DIGITS, Dimension, TuneError, with_params

#: The columns a tune may minimise (``--objective``): every metric computed against the truth
#: (:data:`shadowlab.evaluation.metrics.METRIC_COLUMNS`: error rates, distances, visibility errors ...) and
#: the frame time. Lower is better for each.
OBJECTIVES: tuple[str, ...] = tuple(c.name for c in metrics.METRIC_COLUMNS) + ("time_ms_median",)
#: A window narrower than this share of its dimension's range counts as converged.
CONVERGED = 1e-3


@dataclass
class Trial:
    """One evaluated candidate: its parameter values (the searched parameters only), the
    objective ``value`` (lower is better; ``math.inf``: infeasible — over the time budget,
    refused by the technique, or no finite objective), the metrics row it came from (None when
    nothing was rendered), the search round it was tried in, and a note saying why it is
    infeasible or where it came from (``start``)."""

    params: dict
    value: float
    row: dict | None
    round: int
    note: str = ""


class Rejected(Exception):
    """Raised by an evaluation function for a candidate that cannot be evaluated at all (the
    technique refuses the configuration): the search records it as an infeasible trial with the
    message as its note, and it does not count against the budget."""


def best_trial(history: Sequence[Trial]) -> Trial | None:
    """The trial with the lowest value, the earliest among equals (so the start wins ties);
    None for an empty history."""
    best = None
    for t in history:
        if best is None or t.value < best.value:
            best = t
    return best


def check_objective(objective: str) -> str:
    """``objective`` if it is a column a tune may minimise (:data:`OBJECTIVES`), else TuneError
    naming it, with the closest column as a hint."""
    if objective not in OBJECTIVES:
        why = ("is a metrics column, but not one a tune minimises" if objective in metrics.COLUMN_BY_NAME
               else f"is not a metrics column{did_you_mean(objective, OBJECTIVES)}")
        raise TuneError(f"--objective {objective}: {why} (one of {', '.join(OBJECTIVES)})")
    return objective


def objective_value(row: dict, objective: str) -> float:
    """The value of ``objective`` in a metrics row, as a float (NaN when the row has none);
    TuneError for a column that is not an objective (:func:`check_objective`)."""
    check_objective(objective)
    value = row.get(objective)
    try:
        return float(value) if value is not None else math.nan
    except (TypeError, ValueError):
        return math.nan


# --------------------------------------------------------------------------- the search

def _outcome(out: Any) -> tuple[float, dict | None, str]:
    """An evaluation function's result — a number, (value, row) or (value, row, note) — as
    (value, row, note); NaN becomes infinite (infeasible), with a note."""
    value, row, note = out, None, ""
    if isinstance(out, tuple):
        if len(out) not in (2, 3):
            raise TypeError(f"an evaluation returns value, (value, row) or (value, row, note); got {len(out)} items")
        value, row, note = out if len(out) == 3 else (*out, "")
    value = float(value)
    if math.isnan(value):
        value, note = math.inf, note or "the objective is NaN"
    return value, row, note


class _Search:
    """The state of one :func:`coordinate_search`: the best point, the memo, the budget."""

    def __init__(self, dims, evaluate, budget):
        self.dims, self.evaluate, self.budget = dims, evaluate, budget
        self.history: list[Trial] = []
        self.memo: dict[tuple, float] = {}
        self.rejected: set[tuple] = set()  # keys of the candidates the evaluation refused
        self.spent = 0
        self.best: dict = {}
        self.best_value = math.inf

    def key(self, params: dict) -> tuple:
        return tuple(params[d.name] for d in self.dims)

    @property
    def exhausted(self) -> bool:
        return self.spent >= self.budget

    def window(self, dim: Dimension, width: float) -> tuple[float, float]:
        """The window of ``dim`` around its best value (:func:`_window`). An integer window
        always reaches the best's nearest neighbours that were not rejected (the best ± 1, or
        half and double for powers of two, or past them while the technique refused them), which
        the rounding of earlier grids may have skipped and an odd-only parameter needs."""
        centre = self.best[dim.name]
        lo, hi = _window(dim, centre, width)
        if dim.kind != "int":
            return lo, hi
        step_down, step_up = ((lambda v: v / 2), (lambda v: v * 2)) if dim.powers_of_two else \
            ((lambda v: v - 1), (lambda v: v + 1))
        down, up = step_down(centre), step_up(centre)
        while down > dim.lo and self.key({**self.best, dim.name: down}) in self.rejected:
            down = step_down(down)
        while up < dim.hi and self.key({**self.best, dim.name: up}) in self.rejected:
            up = step_up(up)
        return max(min(lo, down), dim.lo), min(max(hi, up), dim.hi)

    def settled(self, dim: Dimension, width: float, points: int) -> bool:
        """Whether ``dim`` is done refining at ``width``: a choice dimension always; a float
        window narrower than :data:`CONVERGED` of the range; an integer window whose grid holds
        no value not yet evaluated (the other parameters at their best)."""
        if dim.kind == "choice":
            return True
        if dim.kind == "float":
            return width < CONVERGED * dim.span
        return all(self.key({**self.best, dim.name: v}) in self.memo
                   for v in dim.grid(points, *self.window(dim, width)))

    def try_(self, params: dict, rnd: int, note: str = "") -> bool:
        """Evaluate ``params`` unless done before or the budget is spent; True when it became
        the best (strictly lower than the best so far: the earlier wins ties)."""
        key = self.key(params)
        if key in self.memo or self.exhausted:
            return False
        try:
            value, row, why = _outcome(self.evaluate(dict(params)))
        except Rejected as exc:
            value, row, why = math.inf, None, f"rejected: {exc}"
            self.rejected.add(key)
        else:
            self.spent += 1
        self.memo[key] = value
        self.history.append(Trial(dict(params), value, row, rnd, "; ".join(filter(None, (note, why)))))
        if not self.history[:-1] or value < self.best_value:
            self.best, self.best_value = dict(params), value
            return len(self.history) > 1
        return False


def _window(dim: Dimension, centre: Any, width: float) -> tuple[float, float]:
    """[lo, hi] in values: ``width`` (in the dimension's coordinate) around ``centre``, shifted
    to lie inside the range."""
    u, lo, hi = dim.coordinate(centre), dim.coordinate(dim.lo), dim.coordinate(dim.hi)
    a = max(min(max(u - width / 2, lo), hi - width), lo)
    b = min(a + width, hi)
    return dim.value_at(a), dim.value_at(b)


def coordinate_search(dimensions: Sequence[Dimension], start: dict,
                      evaluate: Callable[[dict], Any], budget: int, points: int = 5,
                      shrink: float = 0.25) -> list[Trial]:
    """Minimise ``evaluate`` over ``dimensions`` by coordinate descent with refinement (see the
    module docstring), from ``start`` (parameter → value; each searched parameter's value is
    clipped into its dimension, other keys are ignored), spending at most ``budget``
    evaluations. Deterministic: the same function gives the same history.

    ``evaluate(params)`` gets a dict of the searched parameters and returns the objective value
    (lower is better; ``math.inf`` for an infeasible candidate, NaN counts as infinite), or
    ``(value, row)``, or ``(value, row, note)``; it raises :class:`Rejected` for a candidate
    that cannot be evaluated at all (recorded as infeasible, not counted). Every evaluation is a
    :class:`Trial` in the returned history, in order, the start first; no parameter dict is
    evaluated twice. A candidate becomes the best only when strictly lower than the best so
    far, so the start (the spec's own values) is never replaced by an equal value, and an
    infeasible candidate never replaces a feasible one (:func:`best_trial` picks the best)."""
    dims = list(dimensions)
    names = [d.name for d in dims]
    if not dims:
        raise ValueError("coordinate_search needs at least one dimension")
    if len(set(names)) != len(names):
        raise ValueError(f"dimensions named twice: {names}")
    missing = [n for n in names if n not in start]
    if missing:
        raise ValueError(f"start has no value for {', '.join(missing)}")
    if budget < 1:
        raise ValueError(f"budget must be >= 1, got {budget}")
    if points < 3:
        raise ValueError(f"points must be >= 3 (the windows need a middle to shrink around), got {points}")
    if not 0 < shrink < 1:
        raise ValueError(f"shrink must be in (0, 1), got {shrink}")

    # The first sweep shares the budget between the dimensions (a small budget must not be spent
    # on the first parameter alone), with at least 3 points each so the windows have a middle.
    first_points = max(3, min(points, (budget - 1) // len(dims)))
    s = _Search(dims, evaluate, budget)
    first = {d.name: d.clip(start[d.name]) for d in dims}
    clipped = [f"{n} clipped from {start[n]!r}" for n in names if first[n] != start[n]]
    s.try_(first, 0, "start" + (f" ({', '.join(clipped)})" if clipped else ""))
    width = {d.name: d.span for d in dims}
    stale = {d.name: True for d in dims}  # a choice dimension to sweep (again)
    rnd = 0
    while not s.exhausted:
        changed = False
        for d in dims:
            if s.exhausted:
                break
            if d.kind == "choice":
                if not stale[d.name]:
                    continue
                values = d.grid(points)
                stale[d.name] = False
            elif rnd == 0:
                values = d.grid(first_points)
            else:
                if d.kind == "int" and s.settled(d, width[d.name], points):
                    continue
                values = d.grid(points, *s.window(d, width[d.name]))
                if d.kind == "float":  # the centre is the best itself (a memo hit), not its rounding
                    here = float(f"{s.best[d.name]:.{FLOAT_DIGITS}g}")
                    values = [s.best[d.name] if v == here else v for v in values]
            moved = False
            for v in values:
                if s.try_({**s.best, d.name: v}, rnd):
                    moved = True
            if moved:
                changed = True
                for other in dims:
                    if other.name != d.name:
                        stale[other.name] = True
        if rnd > 0 and not changed and all(s.settled(d, width[d.name], points) for d in dims):
            break
        rnd += 1
        for d in dims:  # never below the last spacing: the window covers the gaps beside the best
            width[d.name] = max(shrink * width[d.name], width[d.name] / (points - 1))
    return s.history


# --------------------------------------------------------------------------- rendered candidates

def _plain(row: dict) -> dict:
    """A metrics row as plain JSON values (numpy scalars → Python numbers), the form the cache
    gives back, so that a fresh row and a cached one are equal."""
    return json.loads(json.dumps(row, default=provenance.json_default))


class RenderedCandidates:
    """The evaluation function of a tune (for :func:`coordinate_search`): a candidate's values
    put into ``base_spec`` (:func:`~shadowlab.tuning.space.with_params`), the configuration
    measured on light ``light`` of ``evaluator``'s frame (:func:`shadowlab.measurement.pipeline.measure`,
    ``warmup`` + ``repeat`` renders) and judged against the truth (:meth:`Evaluator.row`); the
    value is the row's ``objective`` column. With ``time_budget_ms``, a candidate whose
    ``time_ms_median`` exceeds it is infeasible (infinite value, a note saying so) — the row
    is still returned. A configuration the technique refuses (TechniqueError while building or
    setting it up) raises :class:`Rejected`.

    ``cache`` (a :class:`~shadowlab.output.cache.Cache`): each measured candidate is stored,
    keyed as a study keys its runs (:func:`~shadowlab.output.cache.run_key` of the scene content
    hash — ``scene_hash``, default :func:`~shadowlab.output.cache.scene_content_hash` of the
    scene's file —, the spec, the size, :func:`shadowlab.output.provenance.code_fingerprint` and the
    GL device :func:`shadowlab.gpu.gl.device`), plus the light and the truth's spec, so that its
    entries never collide with a study's (which hold every light); the timing entry adds the
    repeat and warm-up, as a study's does. The accuracy entry holds the row without its time
    columns (``meta["rows"]``, one row, as a study's holds one per light), the timing entry its
    time columns (``columns``). A candidate found in both renders nothing. ``renders``,
    ``hits`` and ``rejected`` count what happened.

    ``on_step(what)``: called after each candidate with a line naming it (and "cached" for a hit).
    Every row has a ``notes`` column (the measurement's notes, "; "-joined) and plain Python
    values (the cached form)."""

    def __init__(self, evaluator: Evaluator, base_spec: str, light: int = 0, objective: str = "error_rate",
                 time_budget_ms: float | None = None, repeat: int = 3, warmup: int = 1, cache: Cache | None = None,
                 scene_hash: str | None = None, on_step: Callable[[str], None] | None = None):
        self.evaluator = evaluator
        self.tech = from_spec(base_spec)
        self.base_spec = self.tech.spec()
        self.light = int(light)
        self.objective = check_objective(objective)
        if time_budget_ms is not None and not time_budget_ms > 0:
            raise TuneError(f"--time-budget must be > 0 ms, got {time_budget_ms}")
        self.time_budget_ms = time_budget_ms
        self.repeat, self.warmup = int(repeat), int(warmup)
        self.cache = cache
        self.on_step = on_step
        self.renders = self.hits = self.rejected = 0
        self.scene_hash = scene_hash
        if cache is not None:
            if self.scene_hash is None:
                path = evaluator.frame.scene.path
                if path is None or not path.is_file():
                    raise ValueError("a cached tune needs scene_hash: the scene was not read from a file")
                self.scene_hash = scene_content_hash(path)
            self._revision = provenance.code_fingerprint()
            self._device = gl.device()

    def keys(self, spec: str) -> tuple[str, str]:
        """The cache keys (accuracy, timing) of one candidate's spec."""
        f = self.evaluator.frame
        base = (self.scene_hash, spec, (f.width, f.height), self._revision, self._device)
        acc = run_key(*base, light=self.light, truth=self.evaluator.truth_technique.spec())
        tim = run_key(*base, light=self.light, repeat=self.repeat, warmup=self.warmup, pass_timing=False)
        return acc, tim

    def _load(self, spec: str) -> dict | None:
        if self.cache is None:
            return None
        acc_key, time_key = self.keys(spec)
        acc, tim = self.cache.load_result(acc_key), self.cache.load_timing(time_key)
        try:
            row = {**acc["meta"]["rows"][0], **tim["columns"][0]}
            order = acc["meta"]["columns"]
        except (TypeError, KeyError, IndexError):
            return None
        return {k: row[k] for k in order if k in row} | row  # the measured row's column order

    def _store(self, spec: str, row: dict, notes: list[str]) -> None:
        if self.cache is None:
            return
        acc_key, time_key = self.keys(spec)
        self.cache.store_result(acc_key, {"meta": {"rows": [{k: v for k, v in row.items() if not is_time_column(k)}],
                                                   "columns": list(row), "notes": notes, "spec": spec,
                                                   "light": self.light},
                                          "arrays": {}, "files": {}})
        self.cache.store_timing(time_key, {"columns": [{k: v for k, v in row.items() if is_time_column(k)}]})

    def judge(self, row: dict) -> tuple[float, str]:
        """(value, note) of a metrics row: the objective, infinite over the time budget or when
        the objective is not a number."""
        value = objective_value(row, self.objective)
        t = row.get("time_ms_median")
        if self.time_budget_ms is not None and t is not None and t > self.time_budget_ms:
            return math.inf, f"over the time budget: time_ms_median {t:.3f} ms > {self.time_budget_ms:g} ms"
        if not math.isfinite(value):
            return math.inf, f"{self.objective} is {value}"
        return value, ""

    def __call__(self, params: dict) -> tuple[float, dict, str]:
        """(value, metrics row, note) of one candidate (see the class docstring)."""
        try:
            spec = with_params(self.tech, params)
        except TechniqueError as exc:
            self.rejected += 1
            raise Rejected(str(exc)) from None
        row = self._load(spec)
        cached = row is not None
        if cached:
            self.hits += 1
        else:
            try:
                m = measure(from_spec(spec), self.evaluator.frame, self.light, self.repeat, self.warmup)
            except TechniqueError as exc:
                self.rejected += 1
                raise Rejected(str(exc)) from None
            self.renders += 1
            row = _plain({**self.evaluator.row(m), "notes": "; ".join(m.notes)})
            self._store(spec, row, list(m.notes))
        value, note = self.judge(row)
        if self.on_step is not None:
            self.on_step(f"{from_spec(spec).short_label()}: {self.objective} = {value:g}"
                         + (" (cached)" if cached else ""))
        return value, row, note
