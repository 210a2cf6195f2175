"""The one measurement loop (DESIGN §3): setup → timed render → visibility → metrics row.

Everything that measures a technique goes through here — the ``shadowlab compare`` run, the
experiments and the tests — so a figure means the same wherever it was taken:

- :func:`measure`: one technique on one light of a frame (the only place a technique is timed);
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

import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
import pandas as pd

from . import gl, light_sampling, memory, metrics, texel_footprint, timing
from .frame import Frame
from .occluder_layers import occluder_layers
from .scene import load_scene
from .techniques import Technique, TechniqueError, from_spec
from .techniques.raytrace import RayTraced

#: ``on_step(what, total)``: called after each render run (warm-up or timed).
StepCallback = Callable[[str, int], None]


@dataclass
class Measurement:
    """One technique configuration measured on one light: visibility float32 (height, width),
    row 0 = top, 1 = lit; its timing; its cost figures (``Technique.stats``); its notes."""

    technique: Technique
    light: int
    visibility: np.ndarray
    timing: timing.Timing
    stats: dict
    notes: list[str] = field(default_factory=list)
    #: ``pass_<name>_ms`` per pass (only when per-pass timing was asked for).
    pass_times: dict = field(default_factory=dict)
    #: Wall time of ``setup`` for this light (GL work finished), ms: what a static light pays
    #: once and a moving light pays every frame (programs compiled there included).
    setup_ms: float = float("nan")
    #: Peak resident memory of the process during the measurement, bytes (:mod:`shadowlab.memory`).
    peak_rss_bytes: int = 0
    #: Texel footprint m per pixel, float32 (height, width), row 0 = top, NaN where not evaluated
    #: (:func:`shadowlab.texel_footprint.footprint_image`); None for techniques without a map.
    footprint: np.ndarray | None = None


def measure(tech: Technique, frame: Frame, light_index: int, repeat: int = 5, warmup: int = 1,
            on_step: Callable[[], None] | None = None, release: bool = True,
            pass_timing: bool = False) -> Measurement:
    """Set ``tech`` up for one light, time ``warmup`` + ``repeat`` renders of its passes, read its
    visibility and cost figures, check GL errors, and (``release``) free its GL objects.

    ``pass_timing``: then ``repeat`` further renders time each named pass
    (:class:`shadowlab.timing.PassTimer`); they run after the timed renders, so the finishes
    between passes do not perturb ``time_ms_median``.

    A light-sampled technique (``LIGHT_SAMPLED``) on an area light is measured as the average of
    ``light_samples`` hard measurements, one per point of the light
    (:func:`shadowlab.light_sampling.measure_sampled`: time, setup and stats are the frame's N
    renders'); on any other light it is measured once, its stats get ``light_samples`` = 1 and
    a ``light_samples`` > 1 gets a note saying it was ignored. Techniques with
    ``texel_coordinates`` get ``footprint`` and the ``texel_footprint_*`` columns (light-sampled:
    the first sample's)."""
    light = frame.scene.lights[light_index]
    if light_sampling.is_sampled(tech, light):
        samples = [0]

        def measure_one(*args, **kwargs) -> Measurement:
            # the texel footprint (image and columns) of the first light sample only: one image,
            # not N, and combined_stats then passes that sample's columns through unchanged
            samples[0] += 1
            return _measure_hard(*args, footprint=samples[0] == 1, **kwargs)

        return light_sampling.measure_sampled(tech, frame, light_index, measure_one, repeat, warmup, on_step,
                                              release=release, pass_timing=pass_timing)
    note = light_sampling.ignored_note(tech, light_index, light)
    if note is not None:
        tech.notes.append(note)
    m = _measure_hard(tech, frame, light_index, repeat, warmup, on_step, release, pass_timing)
    if note is not None:
        m.notes.insert(0, note)
    if getattr(tech, "LIGHT_SAMPLED", False):
        m.stats["light_samples"] = 1
    return m


def _measure_hard(tech: Technique, frame: Frame, light_index: int, repeat: int = 5, warmup: int = 1,
                  on_step: Callable[[], None] | None = None, release: bool = True,
                  pass_timing: bool = False, footprint: bool = True) -> Measurement:
    """:func:`measure` for the light that is in the scene now, rendered once per run; with
    ``footprint``, a technique with ``texel_coordinates`` also gets its texel-footprint image and
    columns (:mod:`shadowlab.texel_footprint`), taken before it is released."""
    before = len(tech.notes)
    memory.reset_peak()
    t0 = time.perf_counter()
    tech.setup(frame, light_index)
    try:
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
        vis = tech.visibility()
        stats = tech.stats()
        m_image = None
        if footprint and getattr(tech, "texel_coordinates", None) is not None:
            m_image = texel_footprint.footprint_image(frame, light_index, tech)
            stats.update(texel_footprint.footprint_columns(m_image))
        gl.check_errors(f"{tech.name} on light {light_index}")
        peak = memory.peak_bytes()
    except BaseException:
        tech.release()  # a failed measurement leaves no GL objects (nor a borrowed depth-stencil) behind
        raise
    if release:
        tech.release()
    return Measurement(tech, light_index, vis, t, stats, list(dict.fromkeys(tech.notes[before:])), pass_times,
                       setup_ms, peak, m_image)


class Evaluator:
    """Judges visibility images of one frame against its ground truth.

    The truth of each light is measured once, on first use, with ``truth`` (default: the
    default :class:`RayTraced`), as are each light's contact lines (contact gap, over-darkening) and its
    overlapping-casters mask (light bleeding).
    """

    def __init__(self, frame: Frame, truth: Technique | None = None, repeat: int = 1, warmup: int = 0,
                 pass_timing: bool = False):
        self.frame = frame
        self.truth_technique = truth or RayTraced()
        self.repeat, self.warmup, self.pass_timing = repeat, warmup, pass_timing
        self._truth: dict[int, Measurement] = {}
        self._contact: dict[int, np.ndarray] = {}
        self._overlap: dict[int, np.ndarray] = {}

    def truth(self, light_index: int, on_step: Callable[[], None] | None = None) -> Measurement:
        """The ground truth's measurement of one light (measured on first use)."""
        if light_index not in self._truth:
            self._truth[light_index] = measure(self.truth_technique, self.frame, light_index, self.repeat,
                                               self.warmup, on_step, pass_timing=self.pass_timing)
        return self._truth[light_index]

    def use_truth(self, light_index: int, visibility: np.ndarray, stats: dict | None = None) -> None:
        """Judge against a truth measured elsewhere (a study's cached truth): ``visibility``
        float32 (height, width), row 0 = top, and the cost figures ``stats`` that truth reported
        (its ``truth_stderr_max`` goes on every row)."""
        if visibility.shape != (self.frame.height, self.frame.width):
            raise ValueError(f"truth of shape {visibility.shape} for a {self.frame.width}x{self.frame.height} frame")
        self._truth[light_index] = Measurement(self.truth_technique, light_index, visibility,
                                               timing.Timing(float("nan"), float("nan"), []), dict(stats or {}))

    def contact_lines(self, light_index: int) -> np.ndarray:
        """Bool (height, width): evaluated receiver pixels where another object touches the
        receiver (:func:`shadowlab.metrics.contact_pixels`)."""
        if light_index not in self._contact:
            f = self.frame
            self._contact[light_index] = metrics.contact_pixels(f.object_id, f.position, f.pixel_footprint(),
                                                                f.evaluated(light_index))
        return self._contact[light_index]

    def overlap(self, light_index: int) -> np.ndarray:
        """Bool (height, width): evaluated pixels whose segment to the light crosses two or more
        casters (:func:`shadowlab.occluder_layers.occluder_layers`), for the light-bleeding metric."""
        if light_index not in self._overlap:
            self._overlap[light_index] = occluder_layers(self.frame, light_index) >= 2
        return self._overlap[light_index]

    def row(self, m: Measurement, reference: bool = False) -> dict:
        """The metrics.csv row of a measurement (columns: :data:`shadowlab.metrics.COLUMNS`, then
        ``param_<name>`` per parameter, then the technique's cost figures). Every row carries its
        light's truth's ``truth_stderr_max`` (0 when the truth reports none: a point-like light,
        or a truth measured elsewhere, :meth:`use_truth`)."""
        frame, tech, li = self.frame, m.technique, m.light
        row = {"scene": frame.scene.name, "light": li, "light_type": frame.scene.lights[li].type_name,
               "technique": tech.name, "params": tech.params_string(), "label": tech.spec(),
               "short_label": tech.short_label(), "reference": reference,
               "width": frame.width, "height": frame.height}
        truth_m = m if reference else self.truth(li)
        row.update(metrics.compare(m.visibility, truth_m.visibility, frame.evaluated(li), self.contact_lines(li),
                                   self.overlap(li)))
        # the sampled truth's standard error bound (DESIGN §9) beside every row of the light
        row["truth_stderr_max"] = float(truth_m.stats.get("truth_stderr_max", 0.0))
        row.update(m.timing.columns())
        row["setup_ms"] = m.setup_ms
        row["peak_rss_mib"] = memory.mib(m.peak_rss_bytes) if m.peak_rss_bytes else float("nan")
        row.update(m.pass_times)
        row.update({f"param_{k}": v for k, v in tech.params().items()})
        row.update(m.stats)
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
    from .techniques import REGISTRY

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
    lights = range(len(frame.scene.lights))
    total = total_steps(len(lights), len(techniques), repeat, warmup)
    evaluator = Evaluator(frame, truth, repeat, warmup, pass_timing)
    notes = []
    if frame.degenerate_triangles:
        notes.append(f"{frame.degenerate_triangles} degenerate (zero-area) triangles in the scene")
    truths = [evaluator.truth(li, _stepper(on_step, total, f"{evaluator.truth_technique.name} light {li}"))
              for li in lights]
    rows = [evaluator.row(m, reference=True) for m in truths]
    results = []
    for tech in techniques:
        ms = [measure(tech, frame, li, repeat, warmup, _stepper(on_step, total, f"{tech.name} light {li}"),
                      pass_timing=pass_timing) for li in lights]
        rows.extend(evaluator.row(m) for m in ms)
        notes.extend(f"{tech.spec()}: {n}" for n in dict.fromkeys(tech.notes))
        results.append(ms)
    df = pd.DataFrame(rows)
    return Comparison(frame, truths, results, df[metrics.order_columns(df.columns, pass_order())], notes)


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


def measure_configs(scene_ref, specs: Sequence[str], size: tuple[int, int] = (640, 480), repeat: int = 1,
                    warmup: int = 0, light_index: int = 0, frame: Frame | None = None,
                    evaluator: Evaluator | None = None, on_step: StepCallback | None = None,
                    pass_timing: bool = False) -> pd.DataFrame:
    """Rows (the metrics.csv columns, plus ``notes``) for several configurations on one scene
    and light, the ground truth's first (``reference`` = True); writes nothing. For sweeps and
    tests. Pass ``frame`` (or an ``evaluator`` of a frame, which also keeps its truth) to reuse
    them across calls."""
    if evaluator is not None:
        frame = evaluator.frame
    scene = frame.scene if frame is not None else load_scene(scene_ref)
    techniques = [from_spec(s) for s in specs]
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
