"""The one measurement loop (docs/architecture.md): setup → timed render → visibility → metrics row.

Everything that measures a technique goes through here — the ``shadowlab compare`` run, the
experiments and the tests — so a figure means the same wherever it was taken:

- :func:`check_lights`: before anything renders, every technique against the lights it will meet
  (``Technique.LIGHTS``);
- :func:`measure`: one technique on one light slot of a frame (the only place a technique is
  timed), and :func:`measure_sampled`, the light-sampling loop it runs for a light-sampled
  technique on an area light (stand-in slots, one combined measurement);
- :class:`Evaluator`: judges visibility images of one frame against its ground truth (measured
  once per light) and turns a :class:`Measurement` into a metrics.csv row;
- :func:`compare_frame`: the ground truth and N configurations on every light of a frame;
- :func:`measure_configs`: a table of rows for several configurations on one light (sweeps,
  tests), sharing one frame and one truth.

Progress is reported through ``on_step(what, total)``, called after every warm-up and timed
render with a description and the total number of such steps; writing results (masks, images,
run.json, the report) is :mod:`shadowlab.commands.compare`'s job, not this loop's.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
import pandas as pd

from .scenes import load_measured_scene
from ..gpu import gl, memory, timing, work
from . import light_sampling
from ..evaluation import metrics, radiance, texel_footprint
from ..lighting.radiance import RadianceTerms
from ..gpu.frame import Frame, LightSlot
from ..evaluation.occluder_layers import first_occluder_distance, occluder_layers
from ..techniques import Technique, TechniqueError, from_spec
from ..techniques.base import FIRST
from ..techniques.rays.raytrace import RayTraced
from ..util.format import fmt_table_pct
from ..util.sizes import SWEEP_SIZE
from . import budget
from .result import Measurement

#: ``on_step(what, total)``: called after each render run (warm-up or timed).
StepCallback = Callable[[str, int], None]


#: How the pipeline's own columns combine over light samples: the texel footprint is the first
#: sample's (one image, not N), ``light_samples`` is set once.
PIPELINE_STATS = {**{k: FIRST for k in texel_footprint.COLUMNS}, "light_samples": FIRST}


def measure(tech: Technique, frame: Frame, light: LightSlot | int, repeat: int = 5, warmup: int = 1,
            on_step: Callable[[], None] | None = None, release: bool = True,
            pass_timing: bool = False, count: bool = True, budgeted: bool = True,
            footprint: bool = True) -> Measurement:
    """Set ``tech`` up for one light slot (or a scene light's index), time ``warmup`` +
    ``repeat`` renders of its passes, read its visibility and cost figures, check GL errors,
    and (``release``) free its GL objects — also when any step fails.

    ``pass_timing``: then ``repeat`` further renders time each named pass
    (:class:`shadowlab.gpu.timing.PassTimer`); they run after the timed renders, so the finishes
    between passes do not perturb ``time_ms_median``. ``count`` (default): one more render
    counts the work (:func:`count_work`, ``Measurement.work``); False leaves ``work`` empty (the
    test suite's shared measurements, which do not read it, save that render). ``footprint``
    False skips the texel-footprint image and columns (the viewer, which shows them only in its
    footprint view, saves their cost on every other frame).

    A light-sampled technique (``LIGHT_SAMPLED``) on an area light is measured as the average of
    ``light_samples`` hard measurements, one per point of the light, each on a stand-in slot
    (:func:`measure_sampled`: time, setup and stats are the frame's N renders'); on any other
    light it is measured once, its stats get ``light_samples`` = 1 and a ``light_samples`` > 1
    gets a note saying it was ignored. Techniques with a texel mapping (the map family) get
    ``footprint`` and the ``texel_footprint_*`` columns (light-sampled: the first sample's).

    A configuration with a shadow budget (``budget=K``; ``budgeted``, the default) is measured
    through :func:`shadowlab.measurement.budget.measure_budgeted`: the technique alone where the
    light is kept, the budget's drop policy elsewhere, not rendered at all where the light is
    kept nowhere."""
    slot = frame.as_slot(light)
    if tech.budget_settings() and budgeted:
        return budget.measure_budgeted(
            tech, frame, slot, lambda t: measure(t, frame, slot, repeat, warmup, on_step, release, pass_timing, count,
                                                 budgeted=False, footprint=footprint), repeat)
    if light_sampling.is_sampled(tech, slot.light):
        return measure_sampled(tech, frame, slot, repeat, warmup, on_step, release, pass_timing, count, footprint)
    note = light_sampling.ignored_note(tech, slot)
    if note is not None:
        tech.notes.append(note)
    m = _measure_hard(tech, frame, slot, repeat, warmup, on_step, release, pass_timing, footprint, count)
    if note is not None:
        m.notes.insert(0, note)
    if tech.LIGHT_SAMPLED:
        m.stats["light_samples"] = 1
    return m


def check_lights(techniques, scene, light_indices=None, where: str = "") -> None:
    """TechniqueError, before any rendering, naming the first technique that does not render
    for one of ``scene``'s lights (those of ``light_indices``; default every light, as compare,
    study and animate measure every technique on every light)."""
    indices = range(len(scene.lights)) if light_indices is None else light_indices
    for tech in techniques:
        for i in indices:
            light = scene.lights[i]
            if not tech.supports(light):
                raise TechniqueError(f"{where}{tech.short_label()} does not render for light {i} of scene "
                                     f"{scene.name} ({light.type_name}); it {tech.light_requirement()}")


class _EveryNth:
    """Progress for N renders that count as one: calls ``on_step()`` once every ``n`` calls."""

    def __init__(self, on_step: Callable[[], None] | None, n: int):
        self.on_step, self.n, self.calls = on_step, n, 0

    def __call__(self) -> None:
        self.calls += 1
        if self.on_step is not None and self.calls % self.n == 0:
            self.on_step()


def measure_sampled(tech: Technique, frame: Frame, slot: LightSlot, repeat: int = 5, warmup: int = 1,
                    on_step: Callable[[], None] | None = None, release: bool = True,
                    pass_timing: bool = False, count: bool = True, footprint: bool = True) -> Measurement:
    """The light-sampling loop (:mod:`shadowlab.measurement.light_sampling`): ``tech`` measured on a stand-in
    point-light slot at each of the ``light_samples`` points of ``slot``'s area light, one
    sample set up, rendered and released at a time, combined into one Measurement — the
    average visibility, summed timing, setup and pass times, stats combined as ``tech.STATS``
    declares (plus ``light_samples``), peak memory the maximum, notes deduplicated. The shared
    scene is never changed. ``release=False`` keeps the last sample's technique set up (its
    visibility() is that sample's hard image, not the average)."""
    if not light_sampling.is_sampled(tech, slot.light):
        raise TypeError(f"{tech.name} on light {slot.index}: not a light-sampled technique on an area light")
    n = int(tech.light_samples)
    before = len(tech.notes)
    average = light_sampling.VisibilityAverage(frame, slot)
    points = light_sampling.sample_lights(slot.light, n, light_sampling.evaluated_centre(frame, slot))
    step = _EveryNth(on_step, n)
    ms = []
    parts: dict = {}
    for i, point_light in enumerate(points):
        try:
            m = _measure_hard(tech, frame, frame.stand_in(slot, point_light), repeat, warmup, step,
                              release=release or i < n - 1, pass_timing=pass_timing, footprint=footprint and i == 0,
                              count=count)
        except Exception as exc:
            exc.add_note(f"{tech.name}: light sample {i + 1} of {n} at {point_light.position.tolist()} "
                         f"of light {slot.index}")
            raise
        average.add(point_light.position, m.visibility)
        for key, image in m.components.items():
            # the technique alone (``base``) is averaged as its visibility would be without the
            # other part (the horizon and the light's facing included), so it equals the same
            # technique's result without it; the other parts as a plain mean
            if key == "base":
                parts.setdefault(key, light_sampling.VisibilityAverage(frame, slot)).add(point_light.position, image)
            else:
                parts[key] = parts.get(key, 0.0) + image / n
        ms.append(dataclasses.replace(m, visibility=None, components={}))  # one image at a time
    notes = list(dict.fromkeys(tech.notes[before:]))
    tech.notes[before:] = notes
    pass_times: dict = {}
    per_pass_work: dict = {}
    for m in ms:
        for k, v in m.pass_times.items():
            pass_times[k] = pass_times.get(k, 0.0) + v
        per_pass_work = work.merge(per_pass_work, m.work)  # the frame's N renders' work
    stats = {**light_sampling.combined_stats([m.stats for m in ms], {**tech.STATS, **PIPELINE_STATS}, tech.name),
             "light_samples": n}
    return dataclasses.replace(ms[0], visibility=average.result(),
                               timing=light_sampling.combined_timing([m.timing for m in ms]),
                               stats=stats, notes=notes, pass_times=pass_times,
                               setup_ms=float(sum(m.setup_ms for m in ms)),
                               peak_rss_bytes=max(m.peak_rss_bytes for m in ms), work=per_pass_work,
                               components={k: v.result() if isinstance(v, light_sampling.VisibilityAverage)
                                           else v for k, v in parts.items()})


def _measure_hard(tech: Technique, frame: Frame, slot: LightSlot, repeat: int = 5, warmup: int = 1,
                  on_step: Callable[[], None] | None = None, release: bool = True,
                  pass_timing: bool = False, footprint: bool = True, count: bool = True) -> Measurement:
    """:func:`measure` for one slot, rendered once per run; with ``footprint``, a technique with
    ``texel_coordinates`` also gets its texel-footprint image and columns
    (:mod:`shadowlab.evaluation.texel_footprint`), taken before it is released. Whatever fails — setup
    included — the technique's GL objects are released."""
    before = len(tech.notes)
    memory.reset_peak()
    t0 = time.perf_counter()
    try:
        tech.prepare(frame, slot)
        frame.ctx.finish()
        setup_ms = 1e3 * (time.perf_counter() - t0)
        t = timing.time_passes(tech.render, repeat=repeat, warmup=warmup, gpu=not tech.cpu, on_step=on_step)
        pass_times = {}
        if pass_timing:
            timer = timing.PassTimer()
            tech.pass_timer = timer
            try:
                for _ in range(repeat):
                    tech.render()
                    timer.end_run()
            finally:
                tech.pass_timer = None
            pass_times = timer.columns()
        counted = count_work(tech) if count else {}
        vis = tech.visibility()
        components = tech.component_images()
        stats = tech.stats()
        undeclared = [k for k in stats if k not in tech.STATS]
        if undeclared:
            raise TypeError(f"{tech.name}: stats {undeclared} are not declared in {type(tech).__name__}.STATS")
        if count:
            counted = work.merge(counted, tech.work(counted, stats))
        m_image = None
        if footprint and texel_footprint.has_texel_mapping(tech):
            m_image = texel_footprint.footprint_image(frame, slot, tech)
            stats.update(texel_footprint.footprint_columns(m_image))
        gl.check_errors(f"{tech.name} on light {slot.index}")
        peak = memory.peak_bytes()
    except BaseException:
        tech.release()  # a failed measurement leaves no GL objects (nor a borrowed depth-stencil) behind
        raise
    if release:
        tech.release()
    return Measurement(tech, slot.index, vis, t, stats, list(dict.fromkeys(tech.notes[before:])), pass_times,
                       setup_ms, peak, m_image, counted, components=components)


def count_work(tech: Technique) -> dict:
    """The work of one more render of ``tech`` (set up), per pass (:class:`shadowlab.gpu.work.WorkCounter`):
    draws, samples, bytes and invocations as the GL was asked for them. A CPU technique
    (``tech.cpu``) is not rendered again: its work is what it declares (:meth:`Technique.work`)."""
    if tech.cpu:
        return {}
    counter = work.WorkCounter()
    tech.work_counter = counter
    try:
        with counter.counting():
            tech.render()
        tech.frame.ctx.finish()
    finally:
        tech.work_counter = None
    return counter.passes()


class Evaluator:
    """Judges visibility images of one frame against its ground truth.

    The truth of each light is measured once, on first use, with ``truth`` (default: the
    default :class:`RayTraced`), as are each light's contact lines (contact gap, over-darkening)
    and its overlapping-casters mask (light bleeding). Lights are given as slots or as the
    scene light's index; every cache is keyed by the light object of the slot.
    """

    def __init__(self, frame: Frame, truth: Technique | None = None, repeat: int = 1, warmup: int = 0,
                 pass_timing: bool = False):
        self.frame = frame
        self.truth_technique = truth or RayTraced()
        self.repeat, self.warmup, self.pass_timing = repeat, warmup, pass_timing
        # id(light) → (light, value): keyed by the light object, kept alive by the entry
        self._truth: dict[int, tuple] = {}
        self._contact: dict[int, tuple] = {}
        self._overlap: dict[int, tuple] = {}
        self._height: dict[int, tuple] = {}

    def _cached(self, cache: dict, light: LightSlot | int, compute: Callable[[LightSlot], object]):
        """``cache``'s value for the slot's light, computed on first use; keyed by the light
        object, which the entry keeps alive (so its id is never reused)."""
        slot = self.frame.as_slot(light)
        key = id(slot.light)
        if key not in cache:
            cache[key] = (slot.light, compute(slot))
        return cache[key][1]

    def truth(self, light: LightSlot | int, on_step: Callable[[], None] | None = None) -> Measurement:
        """The ground truth's measurement of one light (measured on first use)."""
        return self._cached(self._truth, light, lambda slot: measure(
            self.truth_technique, self.frame, slot, self.repeat, self.warmup, on_step, pass_timing=self.pass_timing))

    def use_truth(self, light: LightSlot | int, visibility: np.ndarray, stats: dict | None = None) -> None:
        """Judge against a truth measured elsewhere (a study's cached truth): ``visibility``
        float32 (height, width), row 0 = top, and the cost figures ``stats`` that truth reported
        (its ``truth_stderr_max`` goes on every row)."""
        if visibility.shape != (self.frame.height, self.frame.width):
            raise ValueError(f"truth of shape {visibility.shape} for a {self.frame.width}x{self.frame.height} frame")
        slot = self.frame.as_slot(light)
        self._truth[id(slot.light)] = (slot.light, Measurement(
            self.truth_technique, slot.index, visibility, timing.Timing(float("nan"), float("nan"), []),
            dict(stats or {})))

    def contact_lines(self, light: LightSlot | int) -> np.ndarray:
        """Bool (height, width): evaluated receiver pixels where another object touches the
        receiver (:func:`shadowlab.evaluation.metrics.contact_pixels`)."""
        f = self.frame
        return self._cached(self._contact, light, lambda slot: metrics.contact_pixels(
            f.object_id, f.position, f.pixel_footprint(), f.evaluated_image(slot)))

    def overlap(self, light: LightSlot | int) -> np.ndarray:
        """Bool (height, width): evaluated pixels whose segment to the light crosses two or more
        casters (:func:`shadowlab.evaluation.occluder_layers.occluder_layers`), for the light-bleeding metric."""
        return self._cached(self._overlap, light, lambda slot: occluder_layers(self.frame, slot) >= 2)

    def occluder_height(self, light: LightSlot | int, truth: np.ndarray | None = None) -> float:
        """The casters' median height above the shadows they cast, for one light: the median,
        over the truth's shadowed evaluated pixels (G < 0.5) whose shadow ray meets a caster, of
        the distance along that ray to the first caster
        (:func:`shadowlab.evaluation.occluder_layers.first_occluder_distance`, free beside the light-bleeding
        mask); NaN when no such pixel. A shadow map's bias that amounts to more than this in world
        units at the receivers lifts most shadows off their casters or removes them: the figure the
        bias notes compare with (:meth:`judge`). Computed once per light; ``truth``: the light's
        truth visibility when the caller has it (else :meth:`truth`'s)."""
        def compute(slot: LightSlot) -> float:
            distance = first_occluder_distance(self.frame, slot)
            g = truth if truth is not None else self.truth(slot).visibility
            shadowed = (g < metrics.THRESHOLD) & self.frame.evaluated_image(slot)
            d = distance[shadowed & np.isfinite(distance)]
            return float(np.median(d)) if d.size else float("nan")

        return self._cached(self._height, light, compute)

    def judge(self, m: Measurement, row: dict) -> list[str]:
        """Notes on a configuration's result as a whole, from its metrics ``row``: one when it is
        degenerate (``row["degenerate"]``: it draws almost no shadow where the truth has one;
        :func:`shadowlab.evaluation.metrics.is_degenerate`), or when its stats say its bias amounts to more
        world distance at the receivers (``bias_world_median``) than the casters' height above
        their shadows (:meth:`occluder_height`). The note names the configuration, the truth's and
        the configuration's shadowed shares of the evaluated pixels and the likely causes, which
        the technique gives (:meth:`shadowlab.techniques.base.Technique.degenerate_causes`: the core
        does not guess them). Why: a configuration that draws no shadow scores only the truth's
        small shadowed share as its error, and its page would show a lit scene with a modest
        number and nothing else (issue 35). [] for a sound result."""
        tech = m.technique
        height = row.get("occluder_height_median", float("nan"))
        bias_world = m.stats.get("bias_world_median")
        bias_over = (bias_world is not None and np.isfinite(height) and np.isfinite(float(bias_world))
                     and float(bias_world) > height)
        degenerate = bool(row.get("degenerate"))
        if not (degenerate or bias_over):
            return []
        if m.stats.get("budget_kept_share", 1.0) < budget.MOSTLY_DROPPED and not bias_over:
            return []  # the budget dropped most of the light's shadow: said once per configuration (budget_note)
        n = int(row["evaluated_pixels"])
        truth_share = row["truth_shadowed_pixels"] / n if n else 0.0
        share = metrics.shadowed_pixels(row) / n if n else 0.0
        stats = {**m.stats, "occluder_height_median": height, "truth_shadowed_share": truth_share,
                 "shadowed_share": share}
        causes = list(tech.degenerate_causes(stats))
        kept = m.stats.get("budget_kept_share")
        if kept is not None and kept < 1.0:  # a shadow budget left the light's shadow out: that is the cause
            b = tech.budget_settings()
            causes = [f"the shadow budget (budget={b['budget']}, select={b['select']}) computes this light's shadow on "
                      f"{fmt_table_pct(kept)} of its evaluated pixels"] + (causes if kept > 0 else [])
        if bias_over and not causes:
            causes = [f"the bias: it amounts to {bias_world:.3g} world units at the receivers (median), more than "
                      f"the casters' median height {height:.3g} above their shadows"]
        what = "draws almost no shadow" if degenerate else "has a bias above its casters' heights"
        kept = (f" (under {100 * metrics.DEGENERATE_KEPT_SHARE:g} % of the truth's shadowed pixels)" if degenerate
                else "")
        cause = (f"likely cause{'s' if len(causes) > 1 else ''}: {'; '.join(causes)}" if causes
                 else "cause unknown")
        return [f"{tech.short_label()} {what} on light {m.light}: the truth shadows {fmt_table_pct(truth_share)} "
                f"of the evaluated pixels, this configuration {fmt_table_pct(share)} of them{kept}; {cause}"]

    def row(self, m: Measurement, reference: bool = False) -> dict:
        """The metrics.csv row of a measurement (columns: :data:`shadowlab.evaluation.metrics.COLUMNS`, then
        ``param_<name>`` per parameter, then the technique's cost figures). Every row carries its
        light's truth's ``truth_stderr_max`` (0 when the truth reports none: a point-like light,
        or a truth measured elsewhere, :meth:`use_truth`), the casters' median height above their
        shadows (``occluder_height_median``, :meth:`occluder_height`) and ``degenerate``
        (:func:`shadowlab.evaluation.metrics.row_is_degenerate`; False on the truth's rows). A configuration's
        :meth:`judge` notes go to ``m.judgement`` and are appended to ``m.notes``, so that every
        caller that reports a measurement's notes (compare's run notes, measure_configs' and a
        study's ``notes`` column) carries them."""
        frame, tech, li = self.frame, m.technique, m.light
        slot = frame.slot(li)
        row = {"scene": frame.scene.name, "light": li, "light_type": slot.light.type_name,
               "technique": tech.name, "params": tech.params_string(), "label": tech.spec(),
               "short_label": tech.short_label(), "reference": reference,
               "width": frame.width, "height": frame.height}
        truth_m = m if reference else self.truth(slot)
        row.update(metrics.compare(m.visibility, truth_m.visibility, frame.evaluated_image(slot),
                                   self.contact_lines(slot), self.overlap(slot), m.components))
        # the sampled truth's standard error bound (docs/architecture.md#evaluation-evaluator-in-shadowlabmeasurementpipelinepy) beside every row of the light
        row["truth_stderr_max"] = float(truth_m.stats.get("truth_stderr_max", 0.0))
        # a light whose shadow a budget mostly dropped has lost it by policy, not by a failure of
        # the technique: it is not degenerate (the budget's run note says what it dropped)
        dropped = m.stats.get("budget_kept_share", 1.0) < budget.MOSTLY_DROPPED
        row["degenerate"] = False if reference or dropped else metrics.row_is_degenerate(row)
        row["occluder_height_median"] = self.occluder_height(slot, truth_m.visibility)
        row.update(m.timing.columns())
        row["setup_ms"] = m.setup_ms
        row["peak_rss_mib"] = memory.mib(m.peak_rss_bytes) if m.peak_rss_bytes else float("nan")
        row.update(m.pass_times)
        row.update({f"param_{k}": v for k, v in tech.params().items()})
        row.update(m.stats)
        row.update(work.columns(m.work))
        if not reference:
            m.judgement = self.judge(m, row)
            m.notes.extend(n for n in m.judgement if n not in m.notes)
        return row


@dataclass
class Comparison:
    """What :func:`compare_frame` measured: per light the truth, per technique and light its
    measurement, the metrics rows (DataFrame, CSV column order) and the run notes."""

    frame: Frame
    truth: list[Measurement]
    results: list[list[Measurement]]
    rows: pd.DataFrame
    notes: list[str]


def pass_order() -> list[str]:
    """Every registered technique's passes, each technique's in drawing order."""
    from ..techniques import REGISTRY

    return [p for cls in REGISTRY.values() for p in cls.PASSES]


def total_steps(lights: int, configurations: int, repeat: int, warmup: int) -> int:
    """Render runs :func:`compare_frame` makes (the truth counted as a configuration)."""
    return lights * (1 + configurations) * (repeat + warmup)


def _stepper(on_step: StepCallback | None, total: int, what: str) -> Callable[[], None] | None:
    return None if on_step is None else (lambda: on_step(what, total))


def compare_frame(frame: Frame, techniques: Sequence[Technique], repeat: int = 5, warmup: int = 1,
                  on_step: StepCallback | None = None, truth: Technique | None = None,
                  pass_timing: bool = False) -> Comparison:
    """The ground truth and every technique on every light of ``frame`` (``pass_timing``: also
    per-pass times, see :func:`measure`)."""
    check_lights(techniques, frame.scene)
    lights = range(len(frame.scene.lights))
    total = total_steps(len(lights), len(techniques), repeat, warmup)
    evaluator = Evaluator(frame, truth, repeat, warmup, pass_timing)
    notes = list(frame.scene.notes)  # what reading the scene left out (a glTF file's skins, ...)
    if frame.degenerate_triangles:
        notes.append(f"{frame.degenerate_triangles} degenerate (zero-area) triangles in the scene")
    truths = [evaluator.truth(li, _stepper(on_step, total, f"{evaluator.truth_technique.name} light {li}"))
              for li in lights]
    rows = [evaluator.row(m, reference=True) for m in truths]
    truth_images = [m.visibility for m in truths]
    add_radiance(frame, rows, truths, truth_images)
    results = []
    for tech in techniques:
        ms = [measure(tech, frame, li, repeat, warmup, _stepper(on_step, total, f"{tech.name} light {li}"),
                      pass_timing=pass_timing) for li in lights]
        tech_rows = [evaluator.row(m) for m in ms]
        add_radiance(frame, tech_rows, ms, truth_images)
        rows.extend(tech_rows)
        notes.extend(f"{tech.spec()}: {n}" for n in dict.fromkeys(tech.notes))
        notes.extend(n for m in ms for n in m.judgement)  # they name the configuration themselves
        notes.extend(budget.budget_note(tech, ms))
        results.append(ms)
    df = pd.DataFrame(rows)
    return Comparison(frame, truths, results, df[metrics.order_columns(df.columns, pass_order())], notes)


def add_radiance(frame: Frame, rows: list[dict], ms: Sequence[Measurement], truth: Sequence[np.ndarray]) -> None:
    """Put the radiance columns (:mod:`shadowlab.evaluation.radiance`) of one configuration — its
    measurements ``ms``, one per scene light, in order — on its ``rows`` (one per light, in the
    same order): the image-wide columns on every row, each light's own on its row. The terms of
    the shaded image are the frame's, made once (:func:`radiance_terms`)."""
    image, per_light = radiance.radiance_columns(frame, [m.visibility for m in ms], truth,
                                                 [m.weight for m in ms], radiance_terms(frame))
    for row, light in zip(rows, per_light):
        row.update(image)
        row.update(light)


def radiance_terms(frame: Frame) -> RadianceTerms:
    """The frame's :class:`shadowlab.lighting.radiance.RadianceTerms`, made on first use and kept
    on the frame (every configuration of a frame is shaded with the same terms)."""
    terms = getattr(frame, "_radiance_terms", None)
    if terms is None:
        terms = frame._radiance_terms = RadianceTerms(frame)
    return terms


def build_techniques(specs: Sequence[str], truth: Technique | None = None) -> list[Technique]:
    """Techniques from spec strings; duplicates and the ground truth itself are rejected
    (TechniqueError), before any GL work."""
    techs = [from_spec(s) for s in specs]
    seen: set[str] = set()
    reference = (truth or RayTraced()).spec()
    for t in techs:
        if t.spec() == reference:
            raise TechniqueError(f"'{t.spec()}' is the ground truth itself, which every run computes; "
                                 f"give raytrace other parameters to compare against it")
        if t.spec() in seen:
            raise TechniqueError(f"configuration given twice: {t.spec()}")
        seen.add(t.spec())
    return techs


def measure_configs(scene_ref, specs: Sequence[str], size: tuple[int, int] = SWEEP_SIZE, repeat: int = 1,
                    warmup: int = 0, light_index: int = 0, frame: Frame | None = None,
                    evaluator: Evaluator | None = None, on_step: StepCallback | None = None,
                    pass_timing: bool = False) -> pd.DataFrame:
    """Rows (the metrics.csv columns, plus ``notes``) for several configurations on one scene
    and light, the ground truth's first (``reference`` = True); writes nothing. For sweeps and
    tests. Pass ``frame`` (or an ``evaluator`` of a frame, which also keeps its truth) to reuse
    them across calls."""
    if evaluator is not None:
        frame = evaluator.frame
    scene = frame.scene if frame is not None else load_measured_scene(scene_ref)
    techniques = [from_spec(s) for s in specs]
    check_lights(techniques, scene, [light_index])
    frame = frame or Frame(scene, *size)
    evaluator = evaluator or Evaluator(frame, repeat=repeat, warmup=warmup, pass_timing=pass_timing)
    total = (1 + len(techniques)) * (repeat + warmup)
    truth = evaluator.truth(light_index, _stepper(on_step, total, "ground truth"))
    rows = [dict(evaluator.row(truth, reference=True), notes="")]
    for tech in techniques:
        m = measure(tech, frame, light_index, repeat, warmup, _stepper(on_step, total, tech.short_label()),
                    pass_timing=pass_timing)
        rows.append(dict(evaluator.row(m), notes="; ".join(m.notes)))
    df = pd.DataFrame(rows)
    return df[metrics.order_columns(df.columns, pass_order())]
