"""The generic tuner (issue 24): search dimensions (shadowlab.tuning.space), the coordinate
search on synthetic functions, the ranges techniques declare, and one rendered tune with the
study cache (GL)."""
from __future__ import annotations

import math

import pytest

from helpers import SMALL
from shadowlab.output.cache import Cache
from shadowlab.gpu.timing import is_time_column
from shadowlab.techniques import REGISTRY, from_spec
from shadowlab.techniques.base import Param, TuneRange
from shadowlab.tuning.search import (
    OBJECTIVES, RenderedCandidates, Rejected, Trial, best_trial, check_objective, coordinate_search,
    objective_value,
)
from shadowlab.tuning.space import Dimension, TuneError, parse_params, with_params


# --------------------------------------------------------------------------- Dimension

def test_grid_linear_log_int_choice():
    assert Dimension("x", "float", 0.0, 1.0).grid(5) == [0.0, 0.25, 0.5, 0.75, 1.0]
    assert Dimension("x", "float", 1e-4, 1.0, log=True).grid(5) == [1e-4, 1e-3, 1e-2, 0.1, 1.0]
    assert Dimension("k", "int", 1, 15).grid(5) == [1, 5, 8, 12, 15]
    assert Dimension("r", "int", 256, 4096, log=True).grid(5) == [256, 512, 1024, 2048, 4096]
    # fewer powers of two than points: each once; more points than integers: each once
    assert Dimension("r", "int", 256, 1024, log=True).grid(9) == [256, 512, 1024]
    assert Dimension("n", "int", 1, 3).grid(9) == [1, 2, 3]
    # an int log range between other bounds: geometric, rounded, deduplicated
    assert Dimension("n", "int", 3, 300, log=True).grid(3) == [3, 30, 300]
    assert Dimension("f", "choice", choices=("nearest", "pcf3")).grid(7) == ["nearest", "pcf3"]


def test_grid_window_and_rounding():
    d = Dimension("x", "float", 0.0, 1.0)
    assert d.grid(3, 0.2, 0.4) == [0.2, 0.3, 0.4]
    assert d.grid(3, -1.0, 0.5) == [0.0, 0.25, 0.5]  # the window is cut to the range
    assert d.grid(1) == [0.5]
    # floats keep 6 significant digits (readable specs)
    assert Dimension("b", "float", 1e-6, 0.05, log=True).grid(5)[1] == 1.49535e-05
    assert Dimension("k", "int", 1, 15).grid(5, 5.6, 5.9) == [6]  # a window between integers: the nearest


def test_clip_and_describe():
    assert Dimension("x", "float", 0.0, 1.0).clip(2.0) == 1.0
    assert Dimension("k", "int", 1, 15).clip(7.6) == 8
    c = Dimension("d", "choice", choices=(16, 24, 32))
    assert c.clip(24) == 24 and c.clip(30) == 32
    assert Dimension("v", "choice", choices=("a", "b")).clip("zzz") == "a"
    assert Dimension("bias", "float", 1e-5, 0.05, log=True).describe() == "bias in [1e-05, 0.05], log"
    assert Dimension("resolution", "int", 256, 4096, log=True).describe() == "resolution in [256, 4096], powers of two"
    assert Dimension("blend", "choice", choices=(False, True)).describe() == "blend in {false, true}"
    with pytest.raises(ValueError):
        Dimension("x", "float", 1.0, 1.0)
    with pytest.raises(ValueError):
        Dimension("x", "float", 0.0, 1.0, log=True)


# --------------------------------------------------------------------------- parse_params

def test_parse_params_forms():
    tech = from_spec("shadow_map:resolution=256")
    dims = parse_params(tech, ["bias", "resolution", "filter", "hardware_offset", "slope_scale=0:4",
                               "normal_offset=0.5:2:log", "depth_bits=16,32", "offset_units=1,8,64"])
    by = {d.name: d for d in dims}
    assert [d.name for d in dims][:3] == ["bias", "resolution", "filter"]
    assert by["bias"] == Dimension("bias", "float", 1e-6, 0.05, True)
    assert by["resolution"] == Dimension("resolution", "int", 256, 8192, True) and by["resolution"].powers_of_two
    assert by["filter"].kind == "choice" and "pcf3" in by["filter"].choices
    assert by["hardware_offset"].choices == (False, True)
    assert by["slope_scale"] == Dimension("slope_scale", "float", 0.0, 4.0, False)
    assert by["normal_offset"].log and by["normal_offset"].lo == 0.5
    assert by["depth_bits"].choices == (16, 32)
    assert by["offset_units"].choices == (1.0, 8.0, 64.0)
    # a range for an undeclared parameter (light_samples, shared by light-sampled techniques)
    (ls,) = parse_params(tech, ["light_samples=1:16:log"])
    assert ls.kind == "int" and ls.powers_of_two


@pytest.mark.parametrize("spec, args, key, words", [
    ("shadow_map", ["bais"], "bais", "did you mean 'bias'?"),
    ("shadow_map", ["bias", "bias=0:0.1"], "bias", "given twice"),
    ("shadow_map", ["bias=0.05:0.01"], "bias", "LO must be below HI"),
    ("shadow_map", ["bias=0.01:0.01"], "bias", "LO must be below HI"),
    ("shadow_map", ["bias=-1:0.05"], "bias", "must be >= 0.0"),
    ("shadow_map", ["bias=0:2"], "bias", "must be <= 1.0"),
    ("shadow_map", ["resolution=1e3:4096"], "resolution", "must be int"),
    ("shadow_map", ["light_samples"], "light_samples", "give a range: --param light_samples=LO:HI"),
    ("shadow_map", ["near"], "near", "give a range"),
    ("shadow_map", ["filter=0:1"], "filter", "give a list"),
    ("shadow_map", ["bias=0:0.1:log"], "bias", "a log range needs LO > 0"),
    ("shadow_map", ["bias=0:0.1:lin"], "bias", "expected LO:HI or LO:HI:log"),
    ("shadow_map", ["bias=0.1"], "bias", "expected bias"),
    ("shadow_map", ["bias="], "bias", "nothing after '='"),
    ("shadow_map", ["bias=0.1,0.1"], "bias", "two or more different values"),
    ("shadow_map", ["depth_bits=16,17"], "depth_bits", "must be one of 16, 24, 32"),
    ("filtered_map", ["kernel=2:9"], "kernel", "kernel must be odd"),
    ("filtered_map:variant=evsm2,precision=16,positive_exponent=5", ["positive_exponent"], "positive_exponent",
     "does not fit this configuration"),
    ("raytrace", ["samples"], "samples", "give a range"),
])
def test_parse_params_errors(spec, args, key, words):
    tech = from_spec(spec)
    with pytest.raises(TuneError) as err:
        parse_params(tech, args)
    msg = str(err.value)
    assert "\n" not in msg
    assert msg.startswith(f"{tech.name}: --param {key}"), msg
    assert words in msg, msg


def test_parse_params_nothing():
    with pytest.raises(TuneError, match="shadow_map: nothing to tune"):
        parse_params(from_spec("shadow_map"), [])


def test_with_params_round_trips():
    tech = from_spec("shadow_map:resolution=256,variant=slope")
    spec = with_params(tech, {"bias": 1e-4, "filter": "pcf3"})
    again = from_spec(spec)
    assert again.bias == 1e-4 and again.filter == "pcf3" and again.resolution == 256 and again.variant == "slope"
    assert again.spec() == spec
    assert tech.bias == 0.002  # the technique itself is unchanged


# --------------------------------------------------------------------------- declared ranges

def _declared():
    return [(name, key, p) for name, cls in REGISTRY.items() for key, p in cls.PARAMS.items() if p.tune is not None]


def test_declared_ranges_inside_limits():
    declared = _declared()
    names = {(n, k) for n, k, _ in declared}
    for expected in [("shadow_map", "bias"), ("cascaded_map", "split_lambda"), ("filtered_map", "exponent"),
                     ("shadow_polygons", "epsilon"), ("pcss", "fixed_filter"), ("lispsm", "resolution")]:
        assert expected in names
    for name, key, p in declared:
        t = p.tune
        assert t.lo < t.hi and (not t.log or t.lo > 0), (name, key)
        kind = type(p.default)
        assert kind in (int, float) and p.choices is None, (name, key)
        for bound in (t.lo, t.hi):
            p.parse(name, key, kind(bound))  # inside min/max (TechniqueError otherwise)
            with_params(REGISTRY[name](), {key: kind(bound)})  # and the technique (defaults) takes it
        if kind is int and t.log:
            assert Dimension(key, "int", t.lo, t.hi, True).powers_of_two, (name, key)


def test_a_range_outside_the_limits_is_a_declaration_error():
    with pytest.raises(TypeError, match="above the parameter's max"):
        Param(1.0, "x", min=0.0, max=2.0, tune=TuneRange(0.5, 3.0))
    with pytest.raises(TypeError, match="below the parameter's min"):
        Param(1.0, "x", min=0.0, min_open=True, tune=TuneRange(0.0, 1.0))
    with pytest.raises(TypeError, match="lo > 0"):
        Param(1.0, "x", tune=TuneRange(0.0, 1.0, log=True))
    with pytest.raises(TypeError, match="without choices"):
        Param("a", "x", choices=("a", "b"), tune=TuneRange(0.0, 1.0))


# --------------------------------------------------------------------------- coordinate_search

class Counted:
    """A synthetic objective that records every call."""

    def __init__(self, fn):
        self.fn, self.calls = fn, []

    def __call__(self, params):
        self.calls.append(dict(params))
        return self.fn(params)


def test_quadratic_in_log_space_found_within_the_final_window():
    d = Dimension("bias", "float", 1e-5, 0.05, log=True)
    target = 3.1e-3
    f = Counted(lambda p: (math.log(p["bias"]) - math.log(target)) ** 2)
    history = coordinate_search([d], {"bias": 0.002}, f, budget=200)
    best = best_trial(history)
    assert abs(math.log(best.params["bias"]) - math.log(target)) <= 1e-3 * d.span
    assert len(history) == len(f.calls) < 200  # it stopped on its own
    assert history[0].params == {"bias": 0.002} and history[0].note == "start"
    assert [t.round for t in history] == sorted(t.round for t in history)


def test_two_separable_dimensions():
    x = Dimension("x", "float", -4.0, 4.0)
    n = Dimension("n", "int", 1, 63)
    f = Counted(lambda p: (p["x"] - 1.3) ** 2 + 0.01 * (p["n"] - 21) ** 2)
    best = best_trial(coordinate_search([x, n], {"x": 0.0, "n": 5}, f, budget=300))
    assert best.params["n"] == 21
    assert abs(best.params["x"] - 1.3) <= 1e-3 * x.span


def test_categorical_dimension():
    c = Dimension("filter", "choice", choices=("nearest", "pcf3", "pcf5"))
    x = Dimension("x", "float", 0.0, 1.0)
    cost = {"nearest": 1.0, "pcf3": 0.0, "pcf5": 0.5}
    f = Counted(lambda p: cost[p["filter"]] + (p["x"] - 0.5) ** 2)
    history = coordinate_search([c, x], {"filter": "nearest", "x": 0.5}, f, budget=50)
    assert best_trial(history).params == {"filter": "pcf3", "x": 0.5}
    # the choices were swept in round 0 and not again (x never moved off 0.5, the start)
    assert sum(1 for t in history if t.params["filter"] != "pcf3") == 2


def test_budget_counts_evaluations_exactly():
    d = Dimension("x", "float", 0.0, 1.0)
    for budget in (1, 2, 6, 13):
        f = Counted(lambda p: (p["x"] - 0.37) ** 2)
        history = coordinate_search([d], {"x": 0.9}, f, budget=budget)
        assert len(f.calls) == len(history) == budget


def test_no_candidate_evaluated_twice():
    dims = [Dimension("k", "int", 1, 5), Dimension("c", "choice", choices=("a", "b")),
            Dimension("x", "float", 0.0, 1.0)]
    f = Counted(lambda p: abs(p["k"] - 3) + (p["c"] == "a") + abs(p["x"] - 0.25))
    history = coordinate_search(dims, {"k": 1, "c": "a", "x": 0.0}, f, budget=500)
    keys = [tuple(sorted(c.items())) for c in f.calls]
    assert len(keys) == len(set(keys)) == len(history)
    assert best_trial(history).params["k"] == 3


def test_start_wins_ties():
    d = Dimension("x", "float", 0.0, 1.0)
    history = coordinate_search([d], {"x": 0.3}, lambda p: 1.0, budget=20)
    assert best_trial(history).params == {"x": 0.3}
    # equal to the start elsewhere, worse between: still the start
    history = coordinate_search([d], {"x": 0.3}, lambda p: 0.0 if p["x"] in (0.3, 0.0, 1.0) else 1.0, budget=20)
    assert best_trial(history) is history[0]
    # the refinement centres on the start: its windows hold 0.3, never a tie-breaking move
    assert all(t.round == 0 or abs(t.params["x"] - 0.3) <= 0.125 + 1e-12 for t in history)


def test_infeasible_candidates_never_chosen():
    d = Dimension("x", "float", 0.0, 1.0)

    def f(p):  # the unconstrained minimum at 0.8 is infeasible (a time budget), 0.6 is the edge
        return (math.inf, None, "over budget") if p["x"] > 0.6 else (p["x"] - 0.8) ** 2

    history = coordinate_search([d], {"x": 0.1}, f, budget=100)
    best = best_trial(history)
    assert math.isfinite(best.value) and best.params["x"] <= 0.6
    assert abs(best.params["x"] - 0.6) < 0.01
    assert any(t.value == math.inf and t.note == "over budget" for t in history)
    # an infeasible start keeps its place only until something feasible turns up
    history = coordinate_search([d], {"x": 0.9}, f, budget=10)
    assert math.isfinite(best_trial(history).value)
    # NaN counts as infeasible
    history = coordinate_search([d], {"x": 0.5}, lambda p: math.nan if p["x"] > 0.5 else p["x"], budget=8)
    assert all(t.value == math.inf for t in history if t.params["x"] > 0.5)


def test_rejected_candidates_cost_nothing():
    d = Dimension("k", "int", 1, 15)

    def f(p):
        if p["k"] % 2 == 0:
            raise Rejected(f"kernel must be odd, got {p['k']}")
        return abs(p["k"] - 7)

    history = coordinate_search([d], {"k": 5}, f, budget=6)
    rejected = [t for t in history if t.note.startswith("rejected: kernel must be odd")]
    assert rejected and all(t.value == math.inf and t.row is None for t in rejected)
    assert len(history) - len(rejected) == 6
    assert best_trial(history).params == {"k": 7}


def test_sparse_accepted_values_end_the_search():
    """Integer windows reach past refused neighbours, and the search still ends on its own when
    only every fourth value is accepted."""
    d = Dimension("k", "int", 1, 63)

    def f(p):
        if p["k"] % 4:
            raise Rejected("multiples of 4 only")
        return abs(p["k"] - 22)

    history = coordinate_search([d], {"k": 8}, f, budget=1000)
    assert best_trial(history).params["k"] in (20, 24)
    assert sum(1 for t in history if not t.note.startswith("rejected")) < 20


def test_start_clipped_and_deterministic():
    d = Dimension("x", "float", 0.0, 1.0)
    f = lambda p: (p["x"] - 0.2) ** 2  # noqa: E731
    a = coordinate_search([d], {"x": 3.0, "other": "ignored"}, f, budget=15)
    b = coordinate_search([d], {"x": 3.0}, f, budget=15)
    assert a[0].params == {"x": 1.0} and "clipped from 3.0" in a[0].note
    assert [(t.params, t.value) for t in a] == [(t.params, t.value) for t in b]
    with pytest.raises(ValueError, match="no value for x"):
        coordinate_search([d], {}, f, budget=3)


def test_objectives():
    assert "error_rate" in OBJECTIVES and "time_ms_median" in OBJECTIVES and "contact_gap_px" in OBJECTIVES
    assert "scene" not in OBJECTIVES and "time_ms_iqr" not in OBJECTIVES
    assert objective_value({"error_rate": 0.25}, "error_rate") == 0.25
    assert math.isnan(objective_value({}, "error_rate"))
    with pytest.raises(TuneError, match="did you mean 'error_rate'"):
        check_objective("eror_rate")
    with pytest.raises(TuneError, match="label: is a metrics column, but not one a tune minimises"):
        objective_value({"label": "x"}, "label")


def test_trial_fields():
    t = Trial({"x": 1.0}, 0.5, None, 0)
    assert t.note == ""


# --------------------------------------------------------------------------- rendered (GL)

def test_rendered_candidates_with_the_study_cache(lab, tmp_path):
    """Tune shadow_map's bias on sm_contact (6 renders), then again from the cache: nothing
    rendered, the same rows (time columns aside) and so the same search."""
    evaluator = lab.evaluator("sm_contact", SMALL)
    spec = "shadow_map:resolution=256"
    tech = from_spec(spec)
    dims = parse_params(tech, ["bias"])
    cache = Cache(tmp_path / "cache")
    steps = []
    first = RenderedCandidates(evaluator, spec, cache=cache, on_step=steps.append)
    history = coordinate_search(dims, tech.params(), first, budget=6)
    assert len(history) == 6 and first.renders == 6 and first.hits == 0 and len(steps) == 6
    start = history[0]
    assert start.params == {"bias": tech.bias} and start.row["label"] == tech.spec()
    assert best_trial(history).value <= start.value
    assert all(t.row["light"] == 0 and t.value == t.row["error_rate"] for t in history)
    assert {t.row["param_bias"] for t in history} == {t.params["bias"] for t in history}

    again = RenderedCandidates(evaluator, spec, cache=cache)
    replay = coordinate_search(dims, tech.params(), again, budget=6)
    assert again.renders == 0 and again.hits == 6
    assert [t.params for t in replay] == [t.params for t in history]
    for a, b in zip(history, replay):
        assert {k: v for k, v in a.row.items() if not is_time_column(k)} == \
            {k: v for k, v in b.row.items() if not is_time_column(k)}
        assert a.row["time_ms_median"] == b.row["time_ms_median"]  # the cached timing
        assert list(a.row) == list(b.row)  # in the same column order

    # a time budget no render meets makes every candidate infeasible, with a note (from the cache)
    strict = RenderedCandidates(evaluator, spec, cache=cache, time_budget_ms=1e-9)
    value, row, note = strict(history[0].params)
    assert value == math.inf and "over the time budget" in note and row is not None and strict.renders == 0
    # a candidate the technique refuses is rejected before anything renders
    with pytest.raises(Rejected, match="bias must be <= 1.0"):
        strict({"bias": 2.0})


def test_a_small_budget_tries_every_dimension():
    """Seven evaluations over two dimensions, starting off the grid: the first sweep must not
    spend them all on the first dimension (the old rule tried 5 values of a, then b once)."""
    dims = [Dimension("a", "float", 0.0, 1.0), Dimension("b", "float", 0.0, 1.0)]
    history = coordinate_search(dims, {"a": 0.3, "b": 0.3}, lambda p: (p["a"] - 0.2) ** 2 + (p["b"] - 0.9) ** 2,
                                budget=7)
    assert len(history) == 7
    tried_b = {t.params["b"] for t in history} - {0.3}
    assert len(tried_b) >= 2
