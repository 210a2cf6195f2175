"""What every shadow technique is: declared parameters, declared capabilities, and a
visibility image per light slot.

A technique is built from a spec string ``name`` or ``name:key=value,...``. Its parameters are
declared (:class:`Param`) with defaults; an unknown or ill-typed parameter is an error (pbrt's
unused-parameter report), and :meth:`Technique.spec` round-trips: ``from_spec(t.spec())``
rebuilds ``t``. The pipeline (:mod:`shadowlab.measurement.pipeline`) calls, per (frame, light slot):
:meth:`Technique.prepare` (which calls the technique's :meth:`setup`: untimed allocation and
fitting), :meth:`render` repeatedly (the timed passes), then :meth:`visibility`, :meth:`stats`
and :meth:`release` — the last also when setup or a render failed.

What a technique declares instead of the core guessing (class attributes):

- ``name``, ``summary``, ``PARAMS``, ``PASSES`` (the passes :meth:`render` names, in order);
- ``LIGHTS``: the light types it renders for (:data:`ALL_LIGHTS` by default); checked once, when
  a compare, study or animation is planned (:func:`shadowlab.measurement.pipeline.check_lights`), before any
  rendering;
- ``LIGHT_SAMPLED``: a hard technique the pipeline may average over points of an area light
  (Heckbert & Herf 1997); it then gets the shared parameter ``light_samples``
  (:data:`LIGHT_SAMPLES`) and sees only point lights, one per sample;
- ``STATS``: every cost figure :meth:`stats` reports, and how it combines over the light samples
  of one frame: :data:`SUM` (work per render), :data:`MAX` (a size or peak held while one sample
  is set up) or :data:`FIRST` (describes the configuration or the view);
- ``STYLE``: its colour and marker in plots (:class:`PlotStyle`);
- ``cpu``: work on the CPU (no GL finish around it);
- ``READS``, ``WRITES`` and ``PROVIDES``: what it reads of the frame, what shared resource it
  overwrites, and what capabilities it offers the layers above (below);
- ``FAMILY`` is not written but derived: the folder of its module (``techniques/<family>/``).

Declared, not guessed (issue 36). Falcor's render passes declare their inputs and outputs
(``RenderPassReflection``) and the render graph binds resources to them from the declaration:
a pass never reaches for a texture it did not declare, and the graph can check, schedule and
explain every pass from its declaration alone. A technique here is such a pass over the
frame, so it declares the same three things, and the base class and the layers above act on
the declarations instead of on isinstance or hasattr guesses:

- ``READS``: the G-buffer channels its shaders sample (:data:`shadowlab.gpu.frame.GBUFFER_CHANNELS`:
  ``position``, ``normal``, ``ids``). :meth:`Technique.bind_gbuffer` binds them — no technique
  names a G-buffer texture or its texture unit itself — and refuses a program that samples a
  channel the technique did not declare. The frame's exact points (the float64 arrays on the
  CPU) are not channels: every technique may read them.
- ``WRITES``: the shared frame resources it overwrites (:data:`shadowlab.gpu.frame.FRAME_WRITABLE`:
  ``depth_stencil``, the G-buffer's depth-stencil attachment, lent by
  :meth:`shadowlab.gpu.frame.Frame.depth_stencil_for` to the techniques that declare it).
- ``PROVIDES``: the capabilities other layers ask for (:data:`CAPABILITIES`: ``texel_mapping``
  for the texel-footprint metric, ``depth_bias`` and ``world_bias`` for the exact bias
  optimiser). A capability promises members (methods or parameters, listed in
  :data:`CAPABILITIES`); the layer that needs one asks ``"texel_mapping" in tech.PROVIDES``,
  not which class the technique is, so a new technique offers a capability by declaring it
  and implementing what it promises (a registry-wide test holds the two together).

A technique registers itself by subclassing :class:`Technique` with its own ``name`` in a
module of a family folder of :mod:`shadowlab.techniques` (modules there are discovered): no list
or table in the core names it (docs/adding-a-technique.md says what else a new one brings: its
GLSL beside it, its test file, a line in a suite; its reference page is generated from these
declarations).

Inputs and outputs (the stage contract of docs/architecture.md): a technique reads the frame (G-buffer
textures, vertex buffers, exact points) and its :class:`~shadowlab.gpu.frame.LightSlot` (the light,
its index, its evaluated mask) and never ``frame.scene.lights``; it writes only its own GL
objects, registered with :meth:`Technique.own` (released by :meth:`release`), and its
visibility image. Its programs come from :meth:`Technique.program`: compiled once per process
and shared, so it sets their uniforms in :meth:`setup` and holds them until released. The one shared resource it may overwrite is the G-buffer's depth-stencil
attachment, and only if it says so in ``WRITES`` (see
:meth:`shadowlab.gpu.frame.Frame.depth_stencil_for`). Its notes (fallbacks, skipped objects) go to
:attr:`Technique.notes`, which the run reports.
"""
from __future__ import annotations

import contextlib
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..gpu import gl, programs, targets
from ..gpu.frame import FRAME_WRITABLE, GBUFFER_CHANNELS
from ..lighting.selection import POLICIES
from ..util.validation import did_you_mean


class TechniqueError(ValueError):
    """A technique spec names an unknown technique, an unknown parameter or a bad value,
    or a technique cannot handle the scene it was given."""


_TRUE, _FALSE = {"1", "true", "yes", "on"}, {"0", "false", "no", "off"}
#: Bytes per component of moderngl's texture and renderbuffer dtypes (depth formats by their
#: storage: "f4" depth is 4 bytes).
_DTYPE_BYTES = {"f1": 1, "u1": 1, "i1": 1, "f2": 2, "u2": 2, "i2": 2, "f4": 4, "u4": 4, "i4": 4}


@dataclass(frozen=True)
class TuneRange:
    """The range a tuner searches by default for a numeric parameter (``shadowlab tune``,
    :mod:`shadowlab.tuning.space`): ``lo`` < ``hi``, geometric spacing when ``log`` (then
    ``lo`` > 0). It lies inside the parameter's ``min``/``max`` (checked when the :class:`Param`
    is made) and is usually much narrower: the values worth trying, not every legal one."""

    lo: float
    hi: float
    log: bool = False


@dataclass(frozen=True)
class Param:
    """One declared parameter: default (its type is the parameter's type), doc, limits, and
    (numeric parameters) the range a tuner searches by default (``tune``; choice and bool
    parameters need none: their values are the dimension)."""

    default: Any
    doc: str
    choices: tuple | None = None
    min: float | None = None
    max: float | None = None
    min_open: bool = False  # the lower bound itself is excluded
    tune: TuneRange | None = None

    def __post_init__(self):
        """A declared ``tune`` range must be numeric, ordered, positive when ``log``, and inside
        ``min``/``max`` (TypeError when the class is made: a declaration error)."""
        t = self.tune
        if t is None:
            return
        kind = type(self.default)
        where = f"Param({self.default!r}, {self.doc[:40]!r}...): tune={t}"
        if kind not in (int, float) or self.choices is not None:
            raise TypeError(f"{where}: only int and float parameters without choices take a tune range")
        if kind is int and not (float(t.lo).is_integer() and float(t.hi).is_integer()):
            raise TypeError(f"{where}: an int parameter's range has int bounds")
        if not t.lo < t.hi:
            raise TypeError(f"{where}: lo must be < hi")
        if t.log and t.lo <= 0:
            raise TypeError(f"{where}: a log range needs lo > 0")
        if self.min is not None and (t.lo <= self.min if self.min_open else t.lo < self.min):
            raise TypeError(f"{where}: lo is below the parameter's min {self.min}")
        if self.max is not None and t.hi > self.max:
            raise TypeError(f"{where}: hi is above the parameter's max {self.max}")

    def parse(self, owner: str, key: str, value: Any) -> Any:
        """Convert ``value`` (a string from the command line, or a Python value) and check it."""
        kind = type(self.default)
        try:
            if kind is bool:
                if isinstance(value, str):
                    low = value.strip().lower()
                    if low not in _TRUE | _FALSE:
                        raise ValueError
                    value = low in _TRUE
                elif not isinstance(value, (bool, np.bool_)):
                    raise ValueError
                value = bool(value)
            elif kind is int:
                if isinstance(value, float) and not value.is_integer():
                    raise ValueError
                value = int(value)
            elif kind is float:
                value = float(value)
                if not np.isfinite(value):
                    raise ValueError
            else:
                value = str(value)
        except (TypeError, ValueError):
            raise TechniqueError(f"{owner}: {key} must be {kind.__name__}, got {value!r}") from None
        if self.choices is not None and value not in self.choices:
            hint = did_you_mean(value, self.choices) if isinstance(value, str) else ""
            raise TechniqueError(f"{owner}: {key} must be one of {', '.join(map(str, self.choices))}, "
                                 f"got {value!r}{hint}")
        if self.min is not None and (value <= self.min if self.min_open else value < self.min):
            raise TechniqueError(f"{owner}: {key} must be {'>' if self.min_open else '>='} {self.min}, got {value!r}")
        if self.max is not None and value > self.max:
            raise TechniqueError(f"{owner}: {key} must be <= {self.max}, got {value!r}")
        return value


def format_value(value: Any) -> str:
    """A parameter value as written in a spec (``true``, ``0.002``, ``1024``)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return str(value)


#: The shared parameter of light-sampled techniques (:attr:`Technique.LIGHT_SAMPLED`): how many
#: points of an area light the hard technique renders from and averages
#: (:mod:`shadowlab.measurement.light_sampling`).
LIGHT_SAMPLES = Param(1, "area lights: hard renders averaged, one from each of N stratified points of the "
                         "light (1 = its centre); ignored, with a note, on other lights", min=1, max=4096)


#: What a light outside the budget does at a face (``drop``).
DROP_POLICIES = ("unshadowed", "unlit", "imperfect")
#: The smallest atlas (and per-face tile) a budget's ``atlas`` takes, texels on a side.
ATLAS_MIN_SIZE = 32
#: The shadow budget every technique's spec accepts (docs/many-lights.md): at most ``budget`` lights
#: get their shadows computed on each face, chosen by the ``select`` policy
#: (:mod:`shadowlab.lighting.selection`); the others are drawn without a shadow there
#: (``drop=unshadowed``), not drawn there at all (``unlit``, the seed's and Godot's/Unity's
#: per-object lists) or shadowed by an imperfect shadow map (``imperfect``); ``atlas`` > 0 sizes the
#: kept lights' maps as one shared atlas of that many texels on a side would, each light's
#: resolution from its screen-space importance (:mod:`shadowlab.lighting.atlas`). Not part of ``PARAMS``: a spec
#: without them is the technique alone, and its label is what it always was; the pipeline applies
#: them (:mod:`shadowlab.measurement.budget`).
BUDGET_PARAMS: dict[str, Param] = {
    "budget": Param(0, "shadow budget: the most lights whose shadows are computed on one face (0 = every light)",
                    min=0, max=65536),
    "select": Param("face", "which lights get the budget's shadows: " + ", ".join(POLICIES), choices=POLICIES),
    "drop": Param("unshadowed", "what a light outside the budget does at a face: lit without a shadow, not drawn, "
                                "or shadowed by an imperfect shadow map", choices=DROP_POLICIES),
    "atlas": Param(0, "size the kept lights' maps as one shadow atlas of this many texels on a side allocates them, "
                      "each light's resolution from its screen-space importance, overflow reported (0 = each map at "
                      "the technique's resolution)",
                   min=0, max=32768),
}

#: Every light type a scene file can hold (``Light.type_name``).
ALL_LIGHTS = frozenset({"point", "directional", "spot", "target_direct", "area"})
#: How a stat combines over the light samples of one frame (:mod:`shadowlab.measurement.light_sampling`):
#: summed (work done per render: passes, rays, preprocessing time) ...
SUM = "sum"
#: ... the maximum (a size or a peak held while one sample is set up: memory, stencil peak) ...
MAX = "max"
#: ... or the first sample's (describes the configuration or one view: faces, depth range).
FIRST = "first"
COMBINE_RULES = (SUM, MAX, FIRST)


#: Every capability a technique may declare in ``PROVIDES`` → the members it promises (methods,
#: attributes or declared parameters of the class), which the layer asking for the capability
#: calls or reads:
#:
#: - ``texel_mapping``: it renders a map per face and says where a world point's texels lie
#:   (:mod:`shadowlab.evaluation.texel_footprint`; valid between setup and release);
#: - ``depth_bias``: its lookup compares one depth per tap with a constant bias the exact bias
#:   optimiser can sweep (:mod:`shadowlab.tuning.exact_bias`: the per-tap comparison terms, the
#:   lookup's defines, the ``bias``, ``variant`` and ``filter`` parameters);
#: - ``world_bias``: its bias can be a world distance the lookup converts at each receiver, which
#:   the optimiser converts back (:func:`shadowlab.tuning.exact_bias.world_thresholds`).
CAPABILITIES: dict[str, tuple[str, ...]] = {
    "texel_mapping": ("face_index", "texel_coordinates"),
    "depth_bias": ("comparison_terms", "lookup_defines", "bias", "variant", "filter"),
    "world_bias": ("converts_world_bias", "face_index", "normal_offset"),
}


def family_of_module(module: str) -> str | None:
    """The technique family of a module name: ``<family>`` for ``shadowlab.techniques.<family>.<module>``
    (its folder), None for a module outside a family folder (the base, a test's own technique).
    Why from the folder: the folder is where a family's code and shaders live and what the
    layer test keeps apart, so the name cannot drift from it."""
    parts = module.split(".")
    if len(parts) >= 4 and parts[:2] == ["shadowlab", "techniques"]:
        return parts[2]
    return None


@dataclass(frozen=True)
class PlotStyle:
    """A technique family's colour (any matplotlib colour) and marker in plots."""

    color: str
    marker: str


#: A program's cache key (:func:`shadowlab.gpu.programs.program_key`) → the technique that holds it
#: (:meth:`Technique.program`).
_HOLDERS: dict = {}

#: Every registered technique class by name; :mod:`shadowlab.techniques` imports every module of
#: the package and then orders it: the ground truth first, then by name.
REGISTRY: dict[str, type] = {}


class Technique:
    """Base class. Subclasses set ``name``, ``summary``, ``PARAMS``, ``PASSES``, ``STATS``,
    ``STYLE`` (and ``LIGHTS``, ``LIGHT_SAMPLED``, ``READS``, ``WRITES``, ``PROVIDES`` where they
    differ from the defaults: the module docstring says why they are declared) and
    implement :meth:`setup`, :meth:`render` and, unless they draw into the visibility target of
    :meth:`visibility_target`, :meth:`visibility`.

    A subclass that sets ``LIGHT_SAMPLED = True`` gets the shared parameter ``light_samples``
    (:data:`LIGHT_SAMPLES`) appended to its ``PARAMS`` when the class is made, so it parses,
    round-trips in :meth:`spec` and becomes a ``param_light_samples`` column like a declared one;
    the pipeline then averages the technique over that many points of an area light. A subclass
    with its own ``name`` registers itself in :data:`REGISTRY`."""

    name = "technique"
    summary = ""
    PARAMS: dict[str, Param] = {}
    #: True for a hard technique that the pipeline may average over points of an area light
    #: (Heckbert & Herf 1997): it then has the ``light_samples`` parameter.
    LIGHT_SAMPLED = False
    #: The light types (``Light.type_name``) the technique renders for. A light-sampled
    #: technique renders "area" as the average of point lights on it; others that list "area"
    #: handle the area light themselves (most: as a point light at its centre).
    LIGHTS: frozenset[str] = ALL_LIGHTS
    #: Each stat :meth:`stats` reports → how it combines over light samples (:data:`SUM`,
    #: :data:`MAX`, :data:`FIRST`). A stat not declared here is an error when measured.
    STATS: dict[str, str] = {}
    #: Colour and marker of the technique in plots.
    STYLE: PlotStyle | None = None
    #: True when the work is on the CPU (no GL finish needed around it when timing).
    cpu = False
    #: The G-buffer channels its shaders sample (of :data:`shadowlab.gpu.frame.GBUFFER_CHANNELS`),
    #: bound by :meth:`bind_gbuffer` on the texture units the declaration gives them.
    READS: frozenset[str] = frozenset()
    #: Shared frame resources this technique overwrites (of :data:`shadowlab.gpu.frame.FRAME_WRITABLE`):
    #: empty, or {"depth_stencil"} to borrow the G-buffer's depth-stencil
    #: (:meth:`shadowlab.gpu.frame.Frame.depth_stencil_for`).
    WRITES: frozenset[str] = frozenset()
    #: The capabilities other layers may ask of it (keys of :data:`CAPABILITIES`).
    PROVIDES: frozenset[str] = frozenset()
    #: Its family: the folder of its module under ``shadowlab/techniques/`` (``maps``, ``volumes``,
    #: ``geometric``, ``rays``), derived when the class is made (:func:`family_of_module`); None
    #: for a class defined elsewhere.
    FAMILY: str | None = None
    #: The passes :meth:`render` names with :meth:`timed_pass`, in drawing order.
    PASSES: tuple[str, ...] = ()
    #: Set by the pipeline while it times passes (a :class:`shadowlab.gpu.timing.PassTimer`).
    pass_timer = None
    #: Set by the pipeline during its counting render (a :class:`shadowlab.gpu.work.WorkCounter`).
    work_counter = None

    def __init_subclass__(cls, **kwargs):
        """Merge the shared ``light_samples`` parameter into an opted-in class's ``PARAMS`` (last,
        so declared parameters keep their order), check the declarations, and register a class
        that names itself."""
        super().__init_subclass__(**kwargs)
        declared = {k: p for k, p in cls.PARAMS.items() if k != "light_samples" or p is not LIGHT_SAMPLES}
        if "light_samples" in declared:
            raise TypeError(f"{cls.__name__}: 'light_samples' is the shared parameter of light-sampled "
                            f"techniques; set LIGHT_SAMPLED = True instead of declaring it")
        cls.PARAMS = {**declared, "light_samples": LIGHT_SAMPLES} if cls.LIGHT_SAMPLED else declared
        bad = {k: v for k, v in cls.STATS.items() if v not in COMBINE_RULES}
        if bad:
            raise TypeError(f"{cls.__name__}: STATS rules must be one of {COMBINE_RULES}, got {bad}")
        unknown = set(cls.LIGHTS) - ALL_LIGHTS
        if unknown:
            raise TypeError(f"{cls.__name__}: LIGHTS names unknown light types {sorted(unknown)}")
        for attr, known in (("READS", GBUFFER_CHANNELS), ("WRITES", FRAME_WRITABLE), ("PROVIDES", CAPABILITIES)):
            declared = getattr(cls, attr)
            if not isinstance(declared, frozenset):
                raise TypeError(f"{cls.__name__}: {attr} must be a frozenset, got {declared!r}")
            if declared - set(known):
                raise TypeError(f"{cls.__name__}: {attr} names unknown entries {sorted(declared - set(known))} "
                                f"(known: {', '.join(sorted(known))})")
        if "FAMILY" in cls.__dict__:
            raise TypeError(f"{cls.__name__}: FAMILY is derived from the module's folder, not declared")
        cls.FAMILY = family_of_module(cls.__module__)
        if "name" in cls.__dict__:
            if cls.name in REGISTRY and REGISTRY[cls.name].__qualname__ != cls.__qualname__:
                raise TypeError(f"technique name {cls.name!r} is taken by {REGISTRY[cls.name].__name__}")
            REGISTRY[cls.name] = cls

    def __init__(self, **params):
        budget = {k: params.pop(k) for k in list(params) if k in BUDGET_PARAMS and k not in self.PARAMS}
        unknown = sorted(set(params) - set(self.PARAMS))
        if unknown:
            known = ", ".join(list(self.PARAMS) + list(BUDGET_PARAMS)) or "none"
            hint = did_you_mean(unknown[0], list(self.PARAMS) + list(BUDGET_PARAMS))
            raise TechniqueError(f"{self.name}: unknown parameter '{unknown[0]}'{hint} (known: {known})")
        self._params = {k: p.parse(self.name, k, params.get(k, p.default)) for k, p in self.PARAMS.items()}
        #: The shadow budget's settings (:data:`BUDGET_PARAMS`, every key) when the spec gave one,
        #: else {} (:meth:`budget_settings`).
        self._budget = self._parse_budget(budget)
        self.notes: list[str] = []
        self._owned: list = []
        self._kept: dict = {}  # GL objects kept across setups (see keep)
        #: Set by a caller that renders this technique frame after frame (``shadowlab animate``):
        #: what :meth:`keep` holds then survives :meth:`release` until :meth:`forget`.
        self.keep_across_frames = False
        #: What ``shadowlab animate`` said about the frame being measured (:meth:`begin_frame`):
        #: a :class:`shadowlab.geometry.reprojection.FrameStep`, or None outside an animation.
        self.animation_step = None
        self._programs: list = []  # cache keys of the programs held
        self._visibility_texture = None

    def __getattr__(self, key):
        params = self.__dict__.get("_params")
        if params is not None and key in params:
            return params[key]
        raise AttributeError(key)

    def _parse_budget(self, given: dict) -> dict:
        """The budget settings of a spec's ``budget``/``select``/``drop``/``atlas`` values: {} when
        none was given, else every key (defaults filled). ``select``, ``drop`` or ``atlas``
        without ``budget`` ≥ 1 is an error: they describe a budget."""
        if not given:
            return {}
        out = {k: p.parse(self.name, k, given.get(k, p.default)) for k, p in BUDGET_PARAMS.items()}
        if out["budget"] < 1:
            others = ", ".join(k for k in given if k != "budget")
            raise TechniqueError(f"{self.name}: {others or 'budget'} needs a shadow budget: give budget=K with K >= 1 "
                                 f"(the most lights with shadows per face)")
        if out["atlas"]:
            if "resolution" not in self.PARAMS:
                raise TechniqueError(f"{self.name}: atlas={out['atlas']} sets each kept light's map resolution, and "
                                     f"{self.name} has no resolution parameter")
            size, res = out["atlas"], self._params["resolution"]
            if size & (size - 1) or size < ATLAS_MIN_SIZE:
                raise TechniqueError(f"{self.name}: atlas must be a power of two >= {ATLAS_MIN_SIZE} (texels on a side), "
                                     f"got {size}")
            if res & (res - 1) or not ATLAS_MIN_SIZE <= res <= size:
                raise TechniqueError(f"{self.name}: with atlas={size}, resolution (the largest per-face tile) must be a "
                                     f"power of two from {ATLAS_MIN_SIZE} to {size}, got {res}")
        if out["drop"] == "imperfect" and self.name == "imperfect_map":
            raise TechniqueError(f"{self.name}: drop=imperfect would give the dropped lights the technique itself")
        return out

    def budget_settings(self) -> dict:
        """The shadow budget of this configuration (:data:`BUDGET_PARAMS`, every key), or {} for
        none: every light's shadow is computed everywhere."""
        return dict(self._budget)

    def params(self) -> dict:
        """Every parameter's value (defaults included), in declaration order; then the shadow
        budget's settings when the spec gave one."""
        return {**self._params, **self._budget}

    def params_string(self) -> str:
        """``key=value,...`` for every parameter (the metrics.csv ``params`` column)."""
        return ",".join(f"{k}={format_value(v)}" for k, v in self.params().items())

    def spec(self) -> str:
        """The full spec ``name:key=value,...``; ``from_spec(spec())`` rebuilds this technique."""
        ps = self.params_string()
        return f"{self.name}:{ps}" if ps else self.name

    def short_label(self) -> str:
        """The name and the parameters that differ from their defaults (for legends and headings)."""
        diff = [f"{k}={format_value(v)}" for k, v in self._params.items() if v != self.PARAMS[k].default]
        # a budget always shows its K and policy (the default policy is not implied by "budget=8")
        diff += [f"{k}={format_value(v)}" for k, v in self._budget.items()
                 if k in ("budget", "select") or v != BUDGET_PARAMS[k].default]
        return f"{self.name}:{','.join(diff)}" if diff else self.name

    def __repr__(self) -> str:
        return f"<{self.spec()}>"

    # -- capabilities ------------------------------------------------------------
    @classmethod
    def supports(cls, light) -> bool:
        """True when the technique renders for ``light`` (:meth:`supports_type` of its type)."""
        return cls.supports_type(light.type_name)

    @classmethod
    def supports_type(cls, type_name: str) -> bool:
        """True when the technique renders for lights of ``type_name`` (in ``LIGHTS``): what
        compare, animate (:func:`shadowlab.measurement.pipeline.check_lights`) and suite planning (from
        the scene files' light types) ask before anything renders."""
        return type_name in cls.LIGHTS

    @classmethod
    def light_requirement(cls) -> str:
        """``LIGHTS`` in words, for errors: "needs a directional light", "needs an area light",
        or "renders for point, spot, ... lights"."""
        names = sorted(cls.LIGHTS)
        if len(names) == 1:
            return f"needs {'an' if names[0][0] in 'aeiou' else 'a'} {names[0]} light"
        return f"renders for {', '.join(names)} lights"

    # -- the per-light protocol -------------------------------------------------
    def prepare(self, frame, slot) -> None:
        """Bind the technique to ``frame`` and ``slot`` (a :class:`~shadowlab.gpu.frame.LightSlot`,
        or a scene light's index) as ``self.frame``, ``self.slot`` and ``self.light``, then
        :meth:`setup`. What the pipeline calls; a failure leaves whatever was made registered,
        for :meth:`release`."""
        slot = frame.as_slot(slot)
        if not self.supports(slot.light):
            raise TechniqueError(f"{self.name} does not render for a {slot.light.type_name} light "
                                 f"(light {slot.index}); it {self.light_requirement()}")
        self.frame, self.slot, self.light = frame, slot, slot.light
        self.setup(frame, slot)

    def setup(self, frame, slot) -> None:
        """Untimed preparation for one light slot of ``frame`` (allocate, fit frusta); GL
        objects made here are registered with :meth:`own`."""

    def render(self) -> None:
        """The technique's own passes for the slot given to :meth:`setup` (timed)."""
        raise NotImplementedError

    def visibility(self) -> np.ndarray:
        """Visibility in [0, 1], float32 (height, width), row 0 = top; 1 = lit. By default the
        texture of :meth:`visibility_target`."""
        if self._visibility_texture is None:
            raise NotImplementedError(f"{self.name}: no visibility target was made and visibility() "
                                      f"is not overridden")
        return targets.read_texture(self._visibility_texture, 1)[..., 0]

    def component_images(self) -> dict[str, np.ndarray]:
        """Images the technique combined into its visibility, for metrics that judge the parts
        against the truth (after :meth:`visibility`): name → float32 (height, width), row 0 =
        top. ``base`` and ``contact_shadow`` (a map technique with contact shadows: its own
        visibility and the contact shadow's), ``classifier`` (1 called surely lit, 0 surely shadowed, NaN
        undecided: hybrid ray tracing's classification). Empty by default."""
        return {}

    def timed_pass(self, name: str, cpu: bool = False):
        """Context manager around one pass of :meth:`render` (``name`` from :attr:`PASSES`;
        ``cpu`` for work on the CPU): timed only while the pipeline asks for per-pass times, and
        its work booked to ``name`` during the pipeline's counting render (:mod:`shadowlab.gpu.work`)."""
        if self.work_counter is not None:
            return self.work_counter.measure(name, cpu)
        if self.pass_timer is None:
            return contextlib.nullcontext()
        return self.pass_timer.measure(name, cpu)

    @staticmethod
    def taps_work(counted: dict, taps_per_fragment: dict[str, float]) -> dict:
        """Texture taps of the passes in ``taps_per_fragment`` ({pass: texels its shader reads
        per fragment or compute invocation}, G-buffer reads included): the samples each pass
        passed plus its compute invocations (``counted``) times that number — the model
        :meth:`work` implementations declare ``texture_taps`` with."""
        return {p: {"texture_taps": (counted[p].get("samples_passed", 0) + counted[p].get("compute_invocations", 0))
                    * float(n)} for p, n in taps_per_fragment.items() if p in counted}

    def work(self, counted: dict, stats: dict) -> dict:
        """The work only the technique knows, per pass, for one render: {pass: {counter: value}}
        with counters of :data:`shadowlab.gpu.work.COUNTERS` whose source is "technique" (rays,
        CPU triangles, texture taps, stencil updates). ``counted`` is what the counting render
        measured per pass (empty for a CPU technique, which the pipeline does not render again),
        ``stats`` what :meth:`stats` reported. Added to ``counted`` by the pipeline."""
        return {}

    def stats(self) -> dict:
        """Cost figures beside time (memory, passes ...), as extra metrics.csv columns; every
        key declared in :attr:`STATS`."""
        return {}

    def degenerate_causes(self, stats: dict) -> list[str]:
        """The likely causes, as short phrases, of a result that draws almost no shadow where the
        truth has one (a *degenerate* result, :func:`shadowlab.evaluation.metrics.is_degenerate`) or whose bias
        exceeds the casters' heights, for the run's note (:meth:`shadowlab.measurement.pipeline.Evaluator.judge`).
        Why here: only the technique knows what its figures mean (a near plane, a bias in window
        depth), so the core names no cause itself. ``stats``: the measurement's :meth:`stats` (the
        light's, combined over light samples) plus the evaluator's ``occluder_height_median``
        (world distance from the truth's shadowed pixels to their first caster; NaN when unknown),
        ``truth_shadowed_share`` and ``shadowed_share`` (the truth's and this result's shadowed
        shares of the evaluated pixels). Read it with ``stats.get``: keys come and go with the
        technique's version. The default names none: the note then says "cause unknown"."""
        return []

    # -- resources ---------------------------------------------------------------
    def program(self, name: str, defines: dict | None = None, varyings: tuple[str, ...] = ()):
        """The cached program of the GLSL file ``name``, found by its file name on the loader's
        search path (:func:`shadowlab.gpu.programs.program`, :func:`shadowlab.gpu.glsl.shader_path`), held
        by this technique until :meth:`release`. Programs are shared within a process, and a technique
        sets their uniforms in :meth:`setup`: a program another live technique holds is an error
        (RuntimeError), never a render with someone else's uniforms."""
        key = programs.program_key(name, defines, varyings)
        holder = _HOLDERS.get(key)
        if holder is not None and holder is not self:  # asked before programs.program resets its uniforms
            raise RuntimeError(f"{self.name}: program {name} {defines or ''} is held by {holder.name}, which is "
                               f"still set up; release it first (programs are shared, their uniforms are not)")
        prog = programs.program(name, defines, varyings)
        _HOLDERS[key] = self
        self._programs.append(key)
        return prog

    def own(self, obj):
        """Register a GL object (anything with ``release()``) made for the current slot: it is
        released with the technique (:meth:`release`). Returns ``obj``."""
        self._owned.append(obj)
        return obj

    def keep(self, key, make):
        """A GL object (or anything with ``release()``) the technique may keep from one frame's
        setup to the next (a cache of rendered pages, say): made by ``make()`` the first time
        ``key`` is asked for, then handed back. While :attr:`keep_across_frames` is False (compare, study) :meth:`release`
        frees it like any owned object; while True (animate) it survives until :meth:`forget`."""
        if key not in self._kept:
            self._kept[key] = make()
        return self._kept[key]

    def kept(self, key):
        """The object :meth:`keep` holds under ``key``, or None."""
        return self._kept.get(key)

    def begin_frame(self, step) -> None:
        """Called by ``shadowlab animate`` before it measures one light of one frame, with a
        :class:`shadowlab.geometry.reprojection.FrameStep` (the frame's index and the light's), and with None
        once the animation is over. The default keeps it as :attr:`animation_step`, where :meth:`setup`
        can read it; a technique that keeps state across frames (temporal accumulation,
        ``rt_soft``) overrides this to roll that state forward — it gets what it needs from the
        step, never from shared state. Compare and study never call it (still frames: None)."""
        self.animation_step = step

    def forget(self) -> None:
        """Free what :meth:`keep` holds (the end of an animation; :meth:`release` otherwise)."""
        kept, self._kept = self._kept, {}
        if kept:
            targets.park()
        for obj in kept.values():
            obj.release()

    def free(self, *objs) -> None:
        """Release registered objects now (a buffer or vertex array replaced during rendering;
        not framebuffers, which :meth:`release` frees after parking the binding)."""
        for obj in objs:
            self._owned.remove(obj)
            obj.release()

    def owned_bytes(self) -> int:
        """Bytes of the GL buffers, textures and renderbuffers the technique owns now (what
        :meth:`own` registered and what :meth:`keep` holds; the frame's shared G-buffer and
        depth-stencil are not counted): a
        memory figure every technique has, whether or not its :meth:`stats` reports one."""
        total = 0
        for obj in self._owned + list(self._kept.values()):  # kept objects (page caches) count too
            if isinstance(getattr(obj, "nbytes", None), int):  # the lab's own wrappers (targets.DepthTexture)
                total += obj.nbytes
            elif hasattr(obj, "components"):  # a texture or renderbuffer
                total += obj.width * obj.height * obj.components * _DTYPE_BYTES.get(obj.dtype, 4)
            elif isinstance(getattr(obj, "size", None), int):  # a buffer
                total += obj.size
        return total

    def visibility_target(self, size: tuple[int, int], share_depth_stencil=None):
        """The technique's visibility image: an owned R32F texture of ``size`` (width, height)
        and a framebuffer drawing into it, as (texture, framebuffer); :meth:`visibility` reads
        the texture. With ``share_depth_stencil`` (the frame's, lent by
        :meth:`~shadowlab.gpu.frame.Frame.depth_stencil_for`) the framebuffer is a
        :class:`~shadowlab.gpu.targets.ScreenTarget` drawing with that depth-stencil attachment."""
        if share_depth_stencil is None:
            tex, fbo = targets.visibility_target(size)
            self.own(tex)
        else:
            tex = self.own(gl.context().texture(tuple(size), 1, dtype="f4"))
            fbo = targets.ScreenTarget.create(tuple(size), [tex], share_depth_stencil=share_depth_stencil)
        self.own(fbo)
        self._visibility_texture = tex
        return tex, fbo

    @classmethod
    def gbuffer_unit(cls, channel: str) -> int:
        """The texture unit the declared G-buffer ``channel`` is bound on: its place among the
        declared channels (:attr:`READS`) in the frame's channel order
        (:data:`shadowlab.gpu.frame.GBUFFER_CHANNELS`). So the G-buffer takes units 0 ..
        len(READS) − 1 and a technique's own textures start at ``len(READS)``."""
        declared = [c for c in GBUFFER_CHANNELS if c in cls.READS]
        if channel not in declared:
            raise TechniqueError(f"{cls.name}: the G-buffer's {channel} channel is not in its READS "
                                 f"({', '.join(declared) or 'none'})")
        return declared.index(channel)

    def bind_gbuffer(self, program) -> None:
        """Bind the declared G-buffer channels that ``program`` samples, for the pass about to
        draw with it: for each channel ``c`` of :attr:`READS` whose sampler uniform ``u_<c>`` the
        program uses (``gbuffer_fetch.glsl`` declares them; the compiler drops the unused ones),
        the frame's texture on unit :meth:`gbuffer_unit` and the uniform set to that unit. A
        program that samples a channel the technique did not declare is an error (RuntimeError):
        the declaration is the whole of what it reads. Why here: the base binds what a technique
        declares, as a render graph binds a pass's declared inputs, so the declaration cannot
        drift from the binding."""
        for channel in GBUFFER_CHANNELS:
            uniform = f"u_{channel}"
            if uniform not in program:
                continue
            if channel not in self.READS:
                raise RuntimeError(f"{self.name}: a program samples the G-buffer's {channel} channel "
                                   f"({uniform}) but READS declares only {', '.join(sorted(self.READS)) or 'none'}")
            unit = self.gbuffer_unit(channel)
            program[uniform].value = unit
            self.frame.gbuffer_texture(channel).use(unit)

    def fullscreen_quad(self, prog):
        """An owned full-screen quad VertexArray for ``prog`` (:func:`shadowlab.gpu.targets.fullscreen_quad`)."""
        return self.own(targets.fullscreen_quad(prog))

    def release(self) -> None:
        """Free every GL object registered with :meth:`own` (newest first), so a technique can
        be set up again; safe to call twice, and after a setup that failed half-way."""
        owned, self._owned = self._owned, []
        self._visibility_texture = None
        for key in self._programs:
            if _HOLDERS.get(key) is self:
                del _HOLDERS[key]
        self._programs = []
        if owned:
            targets.park()
        for obj in reversed(owned):
            obj.release()
        if not self.keep_across_frames:
            self.forget()


def parse_spec(spec: str) -> tuple[str, dict[str, str]]:
    """Split ``name:key=value,...`` into the name and a dict of raw string values."""
    spec = spec.strip()
    name, _, rest = spec.partition(":")
    name = name.strip()
    if not name:
        raise TechniqueError(f"empty technique name in spec {spec!r}")
    values: dict[str, str] = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, eq, val = item.partition("=")
        if not eq or not key.strip():
            raise TechniqueError(f"{name}: expected key=value, got {item!r}")
        if key.strip() in values:
            raise TechniqueError(f"{name}: parameter {key.strip()!r} given twice")
        values[key.strip()] = val.strip()
    return name, values
