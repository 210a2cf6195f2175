"""The shadow-map bias family optimised exactly from one render (docs/tuning.md, issue 24).

A nearest-sample depth comparison lights pixel i when ``receiver_i − (b + extra_i) <= stored_i``
(``shadowlab/techniques/maps/shadow_lookup.glsl``: ``extra`` is the slope-scaled term, the adaptive bias of
variant ``adaptive``, 0 for the constant variant; ``receiver`` is the point's window depth, or for
variant ``receiver_plane`` its depth extrapolated along its plane to the tap's texel centre —
both per tap). The comparison is monotone in the constant bias b, so each tap of each pixel has one
*threshold* T: the smallest bias that lights it. The truth says whether the pixel is lit, so a
truly lit pixel is right for b >= T and a truly shadowed one for b < T. The oriented bias
(variant ``oriented``) turns the comparison round where the receiver faces away from the light,
``receiver + (b + extra) <= stored``: such an *away* tap is lit for b < T, T the smallest bias
that shadows it (:func:`tap_thresholds`' ``away``); the curve counts it down at T. One render gives every
T (:meth:`~shadowlab.techniques.maps.toolkit.DepthMapTechnique.comparison_terms` writes each tap's
terms with the lookup's own arithmetic); sorting them gives the error of **every** constant
bias at once — the exact optimum and the whole acne-versus-leak curve (:class:`BiasCurve`).

Exactness, stated:

- The thresholds are exact in float32: T is found by bisection over the float32 values of b
  (ordered as integers), evaluating ``fl(receiver − fl(b + extra)) <= stored`` in float32 as
  the shader does (IEEE round to nearest). Every run checks this: the visibility emulated at
  the render's own bias must equal the rendered visibility bit for bit
  (:attr:`ExactBiasTune.emulation_mismatch`, 0 on every scene we ran; a driver that fused
  ``u_bias + u_slope_scale · k`` into one rounding could differ by one ulp on a few pixels, and
  the check would say so).
- PCF (``pcf3``, ``pcf5``): visibility is the lit fraction of (2r+1)² taps, each with its own
  threshold; thresholded at 0.5 a pixel is lit once the ⌈n/2⌉-th smallest tap threshold is
  passed, and mean |V − G| is piecewise constant between tap thresholds. Both are exact.
- ``slope_scale`` (variant ``slope``), ``normal_offset`` (variant ``normal_offset``) and
  ``adaptive_epsilon`` (variant ``adaptive``) enter the comparison non-linearly, so they are optimised on a stated grid, the constant part exact
  for each grid value (one extra lookup pass per grid value and tap: the map is rendered once).
  The hardware polygon offset (``hardware_offset=true``) acts while the map is rendered, so it
  is not here: it is tuned by rendering (:mod:`shadowlab.tuning.search`).
- Decomposable objectives (a sum over pixels: ``error_rate``, ``false_shadow_rate``,
  ``false_lit_rate``, ``visibility_mae``) are exact for every bias. Any other metric column is
  evaluated exactly (the full metrics row of the emulated visibility) at the candidate biases of
  :func:`candidate_biases`, and the optimum is the best of those.

The **per-pixel oracle** gives each pixel its own best bias within the tuned range: the lower
bound of any adaptive bias scheme over this map. Pixels wrong even for the oracle are wrong for
every bias in the range: undersampling (a shadowed point whose texel saw no caster in front of
it, which no non-negative bias can darken) rather than acne.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..evaluation import metrics
from ..measurement.pipeline import Evaluator, Measurement, measure
from ..techniques import Technique, from_spec
from ..geometry.transforms import BIAS
from ..techniques.maps.toolkit import FILTERS, window_to_world

#: The objectives :class:`BiasCurve` computes for every bias (sums over the evaluated pixels).
EXACT_OBJECTIVES = ("error_rate", "false_shadow_rate", "false_lit_rate", "visibility_mae")
#: The variants whose comparison takes a constant bias the optimiser can sweep, and the grid
#: parameter each adds (None: bias only).
BIAS_VARIANTS = {"constant": None, "slope": "slope_scale", "normal_offset": "normal_offset",
                 "receiver_plane": None, "adaptive": "adaptive_epsilon", "oriented": None}
#: The shader uniform each grid parameter overrides in the lookup's comparison.
GRID_UNIFORMS = {"slope_scale": "u_slope_scale", "normal_offset": "u_normal_offset",
                 "adaptive_epsilon": "u_adaptive_epsilon"}
#: Bisection bracket for the thresholds: no window depth or bias term leaves (−BRACKET, BRACKET);
#: a tap lit already at −BRACKET has threshold −inf, one still shadowed at +BRACKET +inf.
BRACKET = np.float32(1e6)
#: Log-spaced candidate biases written to candidates.csv besides the optima and the default.
CANDIDATE_POINTS = 48


class ExactBiasError(ValueError):
    """The spec or the parameters are not a bias family the optimiser handles exactly."""


# --------------------------------------------------------------------------- thresholds

def _ordered(x: np.ndarray) -> np.ndarray:
    """Int64 keys ordered as the float32 values ``x`` (−0 and +0 adjacent, NaN excluded)."""
    bits = x.astype(np.float32).view(np.int32).astype(np.int64)
    return np.where(bits < 0, -(bits & 0x7FFFFFFF), bits)


def _from_ordered(k: np.ndarray) -> np.ndarray:
    """Float32 values of ordered keys (:func:`_ordered`'s inverse)."""
    k = np.asarray(k, np.int64)
    bits = np.where(k < 0, (-k) | np.int64(-0x80000000), k)
    return bits.astype(np.int32).view(np.float32)


def lit_at(bias, receiver: np.ndarray, stored: np.ndarray, extra: np.ndarray,
           away: np.ndarray | None = None) -> np.ndarray:
    """Bool: the lookup's comparison ``receiver − (bias + extra) <= stored`` in float32, as
    ``shadow_lookup.glsl`` computes it (``bias`` a scalar or an array broadcasting); where
    ``away`` (the oriented bias, the receiver facing away from the light) ``receiver + (bias +
    extra) <= stored``."""
    b = np.asarray(bias, np.float32)
    if away is None:
        return (receiver - (b + extra)) <= stored
    moved = b + extra
    return np.where(away, (receiver + moved) <= stored, (receiver - moved) <= stored)


def tap_thresholds(receiver: np.ndarray, stored: np.ndarray, extra: np.ndarray,
                   compared: np.ndarray, away: np.ndarray | None = None) -> np.ndarray:
    """Float32 (same shape): per tap the smallest float32 bias that lights it (−inf where it is
    lit whatever the bias: ``compared`` false, or lit at −:data:`BRACKET`; +inf where no bias up
    to :data:`BRACKET` lights it). Exact: bisection over the ordered float32 values of the bias,
    the comparison evaluated as the shader does (:func:`lit_at`). Where ``away`` (the oriented
    bias, compared taps only) the comparison falls as the bias grows: the threshold is then the
    smallest bias that *shadows* the tap (−inf: shadowed whatever the bias; +inf: lit up to
    :data:`BRACKET`), and the tap is lit for biases below it."""
    receiver, stored, extra = (np.asarray(a, np.float32) for a in (receiver, stored, extra))
    compared = np.asarray(compared, bool)
    away = np.zeros(receiver.shape, bool) if away is None else np.asarray(away, bool) & compared

    def passes(b) -> np.ndarray:  # monotone rising in b: lit (towards), shadowed (away)
        return lit_at(b, receiver, stored, extra, away) != away

    lo = np.full(receiver.shape, _ordered(np.array(-BRACKET))[()], np.int64)  # false here (or always true)
    hi = np.full(receiver.shape, _ordered(np.array(BRACKET))[()], np.int64)   # true here (or never)
    always = passes(-BRACKET) | ~compared
    never = ~passes(BRACKET) & ~always
    active = ~(always | never)
    while True:
        open_ = active & (hi - lo > 1)
        if not open_.any():
            break
        mid = (lo + hi) // 2
        lit = passes(_from_ordered(mid))
        hi = np.where(open_ & lit, mid, hi)
        lo = np.where(open_ & ~lit, mid, lo)
    out = _from_ordered(hi)
    out[always] = -np.inf
    out[never] = np.inf
    return out


def world_thresholds(tech: Technique, thresholds: np.ndarray, normal_offset: float,
                     away: np.ndarray | None = None) -> np.ndarray:
    """Float32 (taps, H·W): window-depth tap ``thresholds`` (rendered with no world bias) as
    thresholds of ``bias`` with ``bias_space=world`` on a perspective map (the lookup converts it
    there: ``converts_world_bias``) — the distance towards the light, as a
    fraction of the scene's extent, that lowers each pixel's window depth by its threshold
    (:func:`shadowlab.techniques.maps.toolkit.window_to_world` at the lookup point, the G-buffer point
    moved ``normal_offset`` texels along its normal as the lookup moves it). Thresholds ≤ 0 (lit
    without a bias) and ±inf stay as they are. ``away`` taps (the oriented bias) raise the window
    depth by their threshold: their distance is measured away from the light.

    Not exact to the bit, unlike the window form: the shader converts the world bias to window
    depth in float32 at each receiver and the inverse here is float64, so a pixel whose
    threshold lies within a rounding of the chosen bias can differ; the emulation check
    (:attr:`ExactBiasTune.emulation_mismatch`) counts them."""
    frame, light = tech.frame, tech.light
    pts = frame.position.reshape(-1, 3)
    normals = frame.to_image(frame.compact_normal, dtype=np.float64).reshape(-1, 3)
    ok = np.isfinite(pts).all(axis=1)
    out = np.array(thresholds, np.float32, copy=True)
    P, N = pts[ok], normals[ok]
    to_light, dist = light.to_light(P)
    N = N * np.where(np.einsum("ij,ij->i", N, to_light) < 0, -1.0, 1.0)[:, None]
    face = tech.atlas.faces[0]
    texel = face.texel_world if face.texel_world > 0 else face.texel_angle * dist
    Q = P + N * (normal_offset * np.asarray(texel))[..., None]
    to_light, _ = light.to_light(Q)
    mats = np.stack([BIAS @ f.view_proj for f in tech.atlas.faces])[tech.face_index(Q)]
    # one unit of bias as a world distance: the scene's extent (bias_space=world), 1 (units), a
    # texel at the far plane (texels): shadow_map's bias_unit
    unit = getattr(tech, "bias_unit", None)
    extent = unit()[1] if unit is not None else float(frame.scene.extent())
    for k in range(len(out)):
        t = out[k, ok].astype(np.float64)
        convert = np.isfinite(t) & (t > 0)
        world = np.array(t)
        sign = np.where(away[k, ok], -1.0, 1.0) if away is not None else np.ones(len(t))
        # towards the light the depth falls by t; away from it (oriented, facing away) it rises by t
        world[convert] = window_to_world(mats[convert], Q[convert], sign[convert, None] * to_light[convert],
                                         sign[convert] * t[convert]) / extent
        out[k, ok] = world.astype(np.float32)
    return out


# --------------------------------------------------------------------------- the curve

def _losses(truth: np.ndarray, taps: int) -> dict[str, np.ndarray]:
    """Per objective the per-pixel loss of having j = 0..taps lit taps: float64 (M, taps+1)."""
    v = (np.arange(taps + 1, dtype=np.float32) / np.float32(taps))[None, :]  # the shader's lit / n
    g = truth.astype(np.float32)[:, None]
    v_sh, g_sh = v < metrics.THRESHOLD, g < metrics.THRESHOLD
    return {"error_rate": (v_sh != g_sh).astype(np.float64),
            "false_shadow_rate": (v_sh & ~g_sh).astype(np.float64),
            "false_lit_rate": (~v_sh & g_sh).astype(np.float64),
            "visibility_mae": np.abs(v.astype(np.float64) - g.astype(np.float64))}


def _denominators(truth: np.ndarray) -> dict[str, int]:
    """Each exact objective's denominator (metrics.py's): evaluated, truly lit, truly shadowed."""
    g_sh = truth < metrics.THRESHOLD
    return {"error_rate": len(truth), "false_shadow_rate": int((~g_sh).sum()),
            "false_lit_rate": int(g_sh.sum()), "visibility_mae": len(truth)}


@dataclass
class BiasCurve:
    """Every exact objective as a step function of the constant bias over [``lo``, ``hi``].

    ``breaks`` (K,) float64 ascending, ``breaks[0] = lo``: the objective takes ``values[obj][k]``
    for b in [breaks[k], breaks[k+1]) (the last step up to ``hi`` included). ``sums`` are the
    numerators (pixel counts; the sum of |V − G|), ``denominators`` what metrics.py divides by.
    ``oracle`` per objective: the per-pixel oracle's value (each pixel its own best bias in the
    range)."""

    lo: float
    hi: float
    breaks: np.ndarray
    sums: dict[str, np.ndarray]
    denominators: dict[str, int]
    oracle: dict[str, float]

    @classmethod
    def build(cls, thresholds: np.ndarray, truth: np.ndarray, lo: float, hi: float,
              away: np.ndarray | None = None) -> "BiasCurve":
        """The curve of the evaluated pixels' tap ``thresholds`` (taps, M) against ``truth`` (M,);
        ``away`` (taps, M): the oriented bias's taps lit *below* their threshold
        (:meth:`build_signed`)."""
        if away is not None and np.asarray(away).any():
            return cls.build_signed(thresholds, truth, lo, hi, np.asarray(away, bool))
        taps, m = thresholds.shape
        losses = _losses(truth, taps)
        ts = np.sort(thresholds, axis=0)
        lo32, hi32 = np.float32(lo), np.float32(hi)
        count_lo = (ts <= lo32).sum(axis=0)
        count_hi = (ts <= hi32).sum(axis=0)
        rows = np.arange(m)
        # events: tap j of pixel i (sorted order) lights at ts[j, i] inside (lo, hi]: count j -> j+1
        inside = (ts > lo32) & (ts <= hi32)
        j_idx, i_idx = np.nonzero(inside)
        at = ts[j_idx, i_idx].astype(np.float64)
        order = np.argsort(at, kind="stable")
        at, j_idx, i_idx = at[order], j_idx[order], i_idx[order]
        breaks, first = np.unique(at, return_index=True)
        sums, oracle = {}, {}
        denominators = _denominators(truth)
        for name, loss in losses.items():
            start = loss[rows, count_lo].sum()
            delta = loss[i_idx, j_idx + 1] - loss[i_idx, j_idx]
            after = start + np.cumsum(delta)
            # the value after every event at one bias: the last event of each group
            last = np.r_[first[1:], len(at)] - 1
            sums[name] = np.r_[start, after[last]] if len(at) else np.array([start])
            # per-pixel oracle: the best count each pixel can reach with a bias in [lo, hi]
            j = np.arange(taps + 1)[None, :]
            reachable = (j >= count_lo[:, None]) & (j <= count_hi[:, None])
            oracle[name] = float(np.where(reachable, loss, np.inf).min(axis=1).sum())
        return cls(float(lo), float(hi), np.r_[float(lo), breaks], sums,
                   denominators, {k: _rate(v, denominators[k]) for k, v in oracle.items()})

    @classmethod
    def build_signed(cls, thresholds: np.ndarray, truth: np.ndarray, lo: float, hi: float,
                     away: np.ndarray) -> "BiasCurve":
        """:meth:`build` with taps of both kinds: a tap lights at its threshold (``away`` false)
        or goes dark there (``away``: lit for biases below it). Each tap inside (lo, hi] is an
        event moving its pixel's lit count by ±1; a pixel's loss follows its count event by
        event, and the per-pixel oracle takes the best count any bias in [lo, hi] reaches."""
        taps, m = thresholds.shape
        losses = _losses(truth, taps)
        th = np.asarray(thresholds, np.float32)
        lo32, hi32 = np.float32(lo), np.float32(hi)
        lit_lo = np.where(away, th > lo32, th <= lo32)
        count_lo = lit_lo.sum(axis=0)
        inside = (th > lo32) & (th <= hi32)
        j_idx, i_idx = np.nonzero(inside)
        at = th[j_idx, i_idx].astype(np.float64)
        step = np.where(away[j_idx, i_idx], -1, 1)
        # each pixel's count before each of its events: its events in bias order
        by_pixel = np.lexsort((at, i_idx))
        pix, d = i_idx[by_pixel], step[by_pixel]
        earlier = np.cumsum(d) - d                    # the steps before each event, all pixels
        starts = np.r_[True, pix[1:] != pix[:-1]] if len(pix) else np.zeros(0, bool)
        group = np.cumsum(starts) - 1                 # each event's pixel group
        before = np.empty(len(pix), np.int64)
        before[by_pixel] = count_lo[pix] + earlier - earlier[starts][group]
        after = before + step
        order = np.argsort(at, kind="stable")
        breaks, first = np.unique(at[order], return_index=True)
        last = np.r_[first[1:], len(at)] - 1
        rows = np.arange(m)
        sums, oracle = {}, {}
        denominators = _denominators(truth)
        for name, loss in losses.items():
            start = loss[rows, count_lo].sum()
            delta = (loss[i_idx, after] - loss[i_idx, before])[order]
            total = start + np.cumsum(delta)
            sums[name] = np.r_[start, total[last]] if len(at) else np.array([start])
            best = loss[rows, count_lo].astype(np.float64)
            np.minimum.at(best, i_idx, loss[i_idx, after])
            oracle[name] = float(best.sum())
        return cls(float(lo), float(hi), np.r_[float(lo), breaks], sums,
                   denominators, {k: _rate(v, denominators[k]) for k, v in oracle.items()})

    def values(self, objective: str) -> np.ndarray:
        """Float64 (K,): the objective (a rate, as metrics.py reports it) on each step."""
        return np.array([_rate(s, self.denominators[objective]) for s in self.sums[objective]])

    def step_of(self, bias: float) -> int:
        """Index of the step holding ``bias`` (float32, as the shader receives it)."""
        b = float(np.float32(bias))
        return int(np.searchsorted(self.breaks, b, side="right") - 1) if b >= self.breaks[0] else 0

    def at(self, bias: float) -> dict[str, float]:
        """Every exact objective at ``bias``."""
        k = self.step_of(bias)
        return {name: _rate(s[k], self.denominators[name]) for name, s in self.sums.items()}

    def optimum(self, objective: str) -> "Optimum":
        """The best bias for ``objective`` (:func:`best_run`)."""
        opt = best_run(self.breaks, self.sums[objective], self.hi)
        return dataclasses.replace(opt, value=_rate(opt.value, self.denominators[objective]))

    def frontier(self) -> tuple[np.ndarray, np.ndarray]:
        """(false-lit rate, false-shadow rate) per step: the acne-versus-leak curve as b runs."""
        return self.values("false_lit_rate"), self.values("false_shadow_rate")


def best_run(breaks: np.ndarray, values: np.ndarray, hi: float) -> "Optimum":
    """The minimum of a step function (``values[k]`` on [breaks[k], breaks[k+1]), the last step
    up to ``hi``): the middle of the widest run of optimal steps — the optimum is a set of
    intervals, and its middle keeps the most margin either way — with the run's ends and the
    number of separate optimal runs. ``value`` is the minimum of ``values``."""
    values = np.asarray(values, np.float64)
    best = values.min()
    optimal = np.isclose(values, best, rtol=0, atol=1e-9 * max(1.0, abs(best)))
    ends = np.r_[breaks[1:], hi]
    edges = np.diff(np.r_[0, optimal.astype(np.int8), 0])
    starts, stops = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0] - 1
    widths = ends[stops] - breaks[starts]
    k = int(np.argmax(widths))  # the first of the widest
    lo, top = float(breaks[starts[k]]), float(ends[stops[k]])
    bias = _inside(lo, top, closed_right=stops[k] == len(values) - 1)
    return Optimum(bias, float(best), lo, top, len(starts))


def _rate(num: float, den: int) -> float:
    """num / den, or 0 when the denominator is empty (metrics._ratio's rule)."""
    return float(num) / float(den) if den else 0.0


def _inside(lo: float, hi: float, closed_right: bool) -> float:
    """A float32-representable bias in [lo, hi) (or [lo, hi] when ``closed_right``), as near the
    middle as float32 allows, returned as the float64 whose float32 is that value (so the spec
    ``bias=<repr>`` reaches the shader as exactly it)."""
    mid = np.float32((lo + hi) / 2.0)
    if not (lo <= float(mid) and (float(mid) < hi or (closed_right and float(mid) <= hi))):
        mid = np.float32(lo)
        if float(mid) < lo:
            mid = np.nextafter(mid, np.float32(np.inf))
    return float(mid)


@dataclass(frozen=True)
class Optimum:
    """The optimiser's answer for one objective: ``bias`` (inside the optimal run), ``value``,
    the optimal run [``lo``, ``hi``) and how many separate optimal runs there are."""

    bias: float
    value: float
    lo: float
    hi: float
    runs: int


# --------------------------------------------------------------------------- one render

@dataclass
class GridPoint:
    """One value of the grid parameter (slope_scale, normal_offset or adaptive_epsilon; {} for
    the constant and receiver_plane variants): its thresholds (taps, H·W) and the curve of its evaluated pixels."""

    params: dict
    thresholds: np.ndarray
    curve: BiasCurve
    #: Bool (taps, H·W): the oriented bias's taps lit below their threshold (None: no such tap).
    away: np.ndarray | None = None


@dataclass
class ExactBiasTune:
    """What :func:`exact_bias_tune` found: the base measurement (the spec as given, rendered and
    timed once), the grid points, the emulation self-check and the time it all took."""

    spec: str
    base: Measurement
    points: list[GridPoint]
    taps: int
    evaluated: np.ndarray
    #: Pixels where the visibility emulated at the spec's own bias differs from the render's.
    emulation_mismatch: int
    #: Wall time of the render, the terms passes and the curves, seconds (the figures' cost).
    seconds: dict = field(default_factory=dict)

    def best(self, objective: str) -> tuple[GridPoint, Optimum]:
        """The grid point and bias with the best ``objective`` (the earliest grid point on ties)."""
        scored = [(p, p.curve.optimum(objective)) for p in self.points]
        return min(scored, key=lambda s: s[1].value)

    def visibility(self, point: GridPoint, bias: float) -> np.ndarray:
        """Float32 (H, W): the visibility the lookup renders with ``bias`` at ``point``
        (lit taps / taps, as the shader divides)."""
        b = np.float32(bias)
        lit_taps = point.thresholds <= b
        if point.away is not None:
            lit_taps = np.where(point.away, point.thresholds > b, lit_taps)
        lit = lit_taps.sum(axis=0).astype(np.float32)
        h, w = self.evaluated.shape
        return (lit / np.float32(self.taps)).reshape(h, w)


def check_spec(tech: Technique, grid_param: str | None = None) -> None:
    """ExactBiasError unless ``tech`` is a depth-map comparison with a constant bias the
    optimiser can sweep exactly (and ``grid_param`` is the one its variant adds): one that
    declares the ``depth_bias`` capability (``PROVIDES``), asked of the declaration rather than
    guessed from its class and attributes."""
    if "depth_bias" not in tech.PROVIDES:
        from ..techniques import REGISTRY

        having = [name for name, cls in REGISTRY.items() if "depth_bias" in cls.PROVIDES]
        raise ExactBiasError(f"{tech.name}: the exact bias optimiser handles the techniques that provide depth_bias "
                             f"({', '.join(having)}); tune {tech.name}'s bias by rendering")
    if tech.variant not in BIAS_VARIANTS:
        raise ExactBiasError(f"{tech.spec()}: variant={tech.variant} has no constant bias to sweep; "
                             f"use one of {', '.join(BIAS_VARIANTS)}")
    if FILTERS[tech.filter] is None:
        raise ExactBiasError(f"{tech.spec()}: filter=hw2x2 compares in the texture unit, at a precision the "
                             f"driver chooses; use nearest, pcf3 or pcf5, or tune by rendering")
    if getattr(tech, "hardware_offset", False):
        raise ExactBiasError(f"{tech.spec()}: hardware_offset acts while the map is rendered; tune it by rendering")
    if tech.lookup_defines().get("CASCADES"):
        raise ExactBiasError(f"{tech.name}: cascade blending compares in two maps; tune it by rendering")
    if grid_param is not None and BIAS_VARIANTS[tech.variant] != grid_param:
        need = [v for v, p in BIAS_VARIANTS.items() if p == grid_param]
        hint = f"; it acts with variant={need[0]}" if need else ""
        raise ExactBiasError(f"{tech.spec()}: {grid_param} cannot be tuned with variant={tech.variant}{hint}")


def exact_bias_tune(evaluator: Evaluator, spec: str, light: int = 0, lo: float = 0.0, hi: float = 1.0,
                    grid: dict[str, list] | None = None, repeat: int = 3, warmup: int = 1,
                    on_step: Callable[[str], None] | None = None) -> ExactBiasTune:
    """Render ``spec`` once on ``light`` of the evaluator's frame (timed like any measurement),
    read every tap's comparison terms — for each value of the one ``grid`` parameter, if any —
    and build the exact curve of every constant bias in [``lo``, ``hi``] against the truth."""
    tech = from_spec(spec)
    grid = dict(grid or {})
    if len(grid) > 1:
        raise ExactBiasError(f"{spec}: at most one of {', '.join(GRID_UNIFORMS)} besides bias")
    grid_param = next(iter(grid), None)
    check_spec(tech, grid_param)
    frame = evaluator.frame
    slot = frame.slot(light)
    truth = evaluator.truth(slot).visibility
    ev = frame.evaluated_image(slot)
    radius = FILTERS[tech.filter]
    taps = [(dx, dy) for dy in range(-radius, radius + 1) for dx in range(-radius, radius + 1)]
    seconds = {}
    t0 = time.perf_counter()
    base = measure(tech, frame, slot, repeat, warmup, release=False)
    seconds["render"] = time.perf_counter() - t0
    values = grid[grid_param] if grid_param else [None]
    points = []
    try:
        for value in values:
            t0 = time.perf_counter()
            uniforms = {GRID_UNIFORMS[grid_param]: float(value)} if grid_param else {}
            world = "world_bias" in tech.PROVIDES and tech.converts_world_bias()
            if world:
                uniforms["u_bias_world"] = 0.0  # window thresholds first, converted below
            terms = tech.comparison_terms(taps, uniforms)
            seconds["terms"] = seconds.get("terms", 0.0) + time.perf_counter() - t0
            t0 = time.perf_counter()
            flat = terms.reshape(len(taps), -1, 4)
            away = flat[..., 3] < 0  # the oriented bias's taps facing away from the light
            away = away if away.any() else None
            th = tap_thresholds(flat[..., 0], flat[..., 1], flat[..., 2], flat[..., 3] != 0, away)
            if world:
                offset = float(value) if grid_param == "normal_offset" else \
                    (float(tech.normal_offset) if tech.variant == "normal_offset" else 0.0)
                th = world_thresholds(tech, th, offset, away)
            elif hasattr(tech, "bias_unit") and tech.bias_unit()[1] != 1.0:
                # a window-depth bias in other units (units, texels on an orthographic map): the
                # thresholds in those units; float32 rounding of the product can differ from the
                # shader's by one step, which emulation_mismatch counts
                unit = tech.bias_unit()[1]
                finite = np.isfinite(th)
                th = np.where(finite, th.astype(np.float64) / unit, th).astype(np.float32)
            curve = BiasCurve.build(th[:, ev.ravel()], truth[ev], lo, hi,
                                    None if away is None else away[:, ev.ravel()])
            seconds["curves"] = seconds.get("curves", 0.0) + time.perf_counter() - t0
            points.append(GridPoint({grid_param: value} if grid_param else {}, th, curve, away))
            if on_step is not None:
                on_step(f"{grid_param}={value}" if grid_param else "bias")
    finally:
        tech.release()
    result = ExactBiasTune(tech.spec(), base, points, len(taps), ev, 0, seconds)
    own = next((p for p in points if not grid_param or p.params[grid_param] == getattr(tech, grid_param)), None)
    if own is not None:
        emulated = result.visibility(own, tech.bias)
        result.emulation_mismatch = int((emulated != base.visibility).sum())
    else:
        result.emulation_mismatch = -1  # the spec's own grid value was not among the grid's
    return result


def candidate_biases(tune: ExactBiasTune, point: GridPoint, objective: str, lo: float, hi: float,
                     default: float, n: int = CANDIDATE_POINTS) -> list[float]:
    """The biases written as candidate rows for one grid point: ``n`` log-spaced across the
    range (from max(lo, 1e-7)), the default, and each exact objective's optimum — sorted,
    distinct as float32."""
    start = max(lo, 1e-7)
    biases = list(np.geomspace(start, hi, n)) if hi > start else [lo]
    if lo == 0.0:
        biases.append(0.0)
    biases.append(default)
    biases.extend(point.curve.optimum(o).bias for o in EXACT_OBJECTIVES)
    out = sorted({float(np.float32(b)) for b in biases if lo <= b <= hi})
    return out


def candidate_row(evaluator: Evaluator, tune: ExactBiasTune, point: GridPoint, spec: str) -> dict:
    """The metrics row (every column, as ``compare`` writes it) of the configuration ``spec`` —
    the tuned spec with one bias — from the emulated visibility: no render. Time and cost
    columns are the base render's: the bias family costs the same at every bias."""
    tech = from_spec(spec)
    m = dataclasses.replace(tune.base, technique=tech, visibility=tune.visibility(point, tech.bias),
                            notes=list(tune.base.notes))
    return evaluator.row(m)
