"""What one measurement of a technique on one light holds (:class:`Measurement`): shared by the
measurement loop (:mod:`shadowlab.measurement.pipeline`) and the shadow budget applied to it
(:mod:`shadowlab.measurement.budget`)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..gpu import timing
from ..techniques import Technique


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
    #: Peak resident memory of the process during the measurement, bytes (:mod:`shadowlab.gpu.memory`).
    peak_rss_bytes: int = 0
    #: Texel footprint m per pixel, float32 (height, width), row 0 = top, NaN where not evaluated
    #: (:func:`shadowlab.evaluation.texel_footprint.footprint_image`); None for techniques without a map.
    footprint: np.ndarray | None = None
    #: The work of one render, {pass: {counter: value}} (:mod:`shadowlab.gpu.work`): measured by the
    #: counting render plus what the technique declares (:meth:`Technique.work`).
    work: dict = field(default_factory=dict)
    #: What the evaluator found wrong with the result as a whole (:meth:`Evaluator.row` fills it:
    #: a degenerate configuration, a bias beyond the casters' heights), one sentence each, naming
    #: the configuration; also appended to :attr:`notes`.
    judgement: list[str] = field(default_factory=list)
    #: The technique's component images (:meth:`Technique.component_images`), for the metrics that
    #: judge its parts (contact shadows, a hybrid's classifier); light-sampled: their average.
    components: dict = field(default_factory=dict)
    #: Where the light is drawn at all, float32 (height, width), row 0 = top: 0 where a shadow
    #: budget with ``drop=unlit`` leaves it out (:mod:`shadowlab.measurement.budget`); None: everywhere.
    weight: np.ndarray | None = None
    #: Where a shadow budget computes the light's shadow, bool (height, width), row 0 = top
    #: (:mod:`shadowlab.measurement.budget`); None without a budget (everywhere).
    budget_kept: np.ndarray | None = None
