"""What every shadow technique is: declared parameters, and a visibility image per light.

A technique is built from a spec string ``name`` or ``name:key=value,...``. Its parameters are
declared (:class:`Param`) with defaults; an unknown or ill-typed parameter is an error (pbrt's
unused-parameter report), and :meth:`Technique.spec` round-trips: ``from_spec(t.spec())``
rebuilds ``t``. The pipeline (:mod:`shadowlab.pipeline`) calls, per (frame, light):
:meth:`setup` once (untimed allocation and fitting), :meth:`render` repeatedly (the timed
passes), then :meth:`visibility`, :meth:`stats` and :meth:`release`.

Inputs and outputs (the stage contract of DESIGN §2): a technique reads the frame (G-buffer
textures, vertex buffers, exact points, evaluated masks, the scene) and writes only its own GL
objects and its visibility image. The one shared resource it may overwrite is the G-buffer's
depth-stencil attachment, and only if it says so in :attr:`Technique.MODIFIES_FRAME` (see
:meth:`shadowlab.frame.Frame.depth_stencil_for`). Its notes (fallbacks, skipped objects) go
to :attr:`Technique.notes`, which the run reports.

Soft shadows from hard techniques: a class that sets ``LIGHT_SAMPLED = True`` gets the shared
parameter ``light_samples`` (:data:`LIGHT_SAMPLES`), and the pipeline measures it on an area
light as the average of that many hard measurements from points of the light
(:mod:`shadowlab.light_sampling`); the technique itself only ever sees point lights.
"""
from __future__ import annotations

import contextlib
from dataclasses import dataclass
from typing import Any

import numpy as np


class TechniqueError(ValueError):
    """A technique spec names an unknown technique, an unknown parameter or a bad value,
    or a technique cannot handle the scene it was given."""


_TRUE, _FALSE = {"1", "true", "yes", "on"}, {"0", "false", "no", "off"}


@dataclass(frozen=True)
class Param:
    """One declared parameter: default (its type is the parameter's type), doc, and limits."""

    default: Any
    doc: str
    choices: tuple | None = None
    min: float | None = None
    max: float | None = None
    min_open: bool = False  # the lower bound itself is excluded

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
            raise TechniqueError(f"{owner}: {key} must be one of {', '.join(map(str, self.choices))}, got {value!r}")
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
#: (:mod:`shadowlab.light_sampling`).
LIGHT_SAMPLES = Param(1, "area lights: hard renders averaged, one from each of N stratified points of the "
                         "light (1 = its centre); ignored, with a note, on other lights", min=1, max=4096)


class Technique:
    """Base class. Subclasses set ``name``, ``PARAMS`` and implement setup/render/visibility.

    A subclass that sets ``LIGHT_SAMPLED = True`` gets the shared parameter ``light_samples``
    (:data:`LIGHT_SAMPLES`) appended to its ``PARAMS`` when the class is made, so it parses,
    round-trips in :meth:`spec` and becomes a ``param_light_samples`` column like a declared one;
    the pipeline then averages the technique over that many points of an area light."""

    name = "technique"
    summary = ""
    PARAMS: dict[str, Param] = {}
    #: True for a hard technique that the pipeline may average over points of an area light
    #: (Heckbert & Herf 1997): it then has the ``light_samples`` parameter.
    LIGHT_SAMPLED = False
    #: True when the work is on the CPU (no GL finish needed around it when timing).
    cpu = False
    #: Shared frame resources this technique overwrites: empty, or {"depth_stencil"}.
    MODIFIES_FRAME: frozenset[str] = frozenset()
    #: The passes :meth:`render` names with :meth:`timed_pass`, in drawing order.
    PASSES: tuple[str, ...] = ()
    #: True for a technique that only makes sense on an area light (it raises TechniqueError on
    #: another light): suites and tests give it soft-shadow scenes.
    NEEDS_AREA_LIGHT = False
    #: True for a technique that only handles directional lights (cascades, LiSPSM: they fit
    #: the map to the camera's view along a light at infinity; TechniqueError on another light).
    NEEDS_DIRECTIONAL_LIGHT = False
    #: Set by the pipeline while it times passes (a :class:`shadowlab.timing.PassTimer`).
    pass_timer = None

    def __init_subclass__(cls, **kwargs):
        """Merge the shared ``light_samples`` parameter into an opted-in class's ``PARAMS`` (last,
        so declared parameters keep their order), and drop it from a class that opts out again
        while inheriting a parent's ``PARAMS``."""
        super().__init_subclass__(**kwargs)
        declared = {k: p for k, p in cls.PARAMS.items() if k != "light_samples" or p is not LIGHT_SAMPLES}
        if "light_samples" in declared:
            raise TypeError(f"{cls.__name__}: 'light_samples' is the shared parameter of light-sampled "
                            f"techniques; set LIGHT_SAMPLED = True instead of declaring it")
        cls.PARAMS = {**declared, "light_samples": LIGHT_SAMPLES} if cls.LIGHT_SAMPLED else declared

    def __init__(self, **params):
        unknown = sorted(set(params) - set(self.PARAMS))
        if unknown:
            known = ", ".join(self.PARAMS) or "none"
            raise TechniqueError(f"{self.name}: unknown parameter '{unknown[0]}' (known: {known})")
        self._params = {k: p.parse(self.name, k, params.get(k, p.default)) for k, p in self.PARAMS.items()}
        self.notes: list[str] = []

    def __getattr__(self, key):
        params = self.__dict__.get("_params")
        if params is not None and key in params:
            return params[key]
        raise AttributeError(key)

    def params(self) -> dict:
        """Every parameter's value (defaults included), in declaration order."""
        return dict(self._params)

    def params_string(self) -> str:
        """``key=value,...`` for every parameter (the metrics.csv ``params`` column)."""
        return ",".join(f"{k}={format_value(v)}" for k, v in self._params.items())

    def spec(self) -> str:
        """The full spec ``name:key=value,...``; ``from_spec(spec())`` rebuilds this technique."""
        ps = self.params_string()
        return f"{self.name}:{ps}" if ps else self.name

    def short_label(self) -> str:
        """The name and the parameters that differ from their defaults (for legends and headings)."""
        diff = [f"{k}={format_value(v)}" for k, v in self._params.items() if v != self.PARAMS[k].default]
        return f"{self.name}:{','.join(diff)}" if diff else self.name

    def __repr__(self) -> str:
        return f"<{self.spec()}>"

    # -- the per-light protocol -------------------------------------------------
    def setup(self, frame, light_index: int) -> None:
        """Untimed preparation for one light of ``frame`` (allocate, fit frusta)."""

    def render(self) -> None:
        """The technique's own passes for the light given to :meth:`setup` (timed)."""
        raise NotImplementedError

    def visibility(self) -> np.ndarray:
        """Visibility in [0, 1], float32 (height, width), row 0 = top; 1 = lit."""
        raise NotImplementedError

    def timed_pass(self, name: str, cpu: bool = False):
        """Context manager around one pass of :meth:`render` (``name`` from :attr:`PASSES`;
        ``cpu`` for work on the CPU): timed only while the pipeline asks for per-pass times."""
        if self.pass_timer is None:
            return contextlib.nullcontext()
        return self.pass_timer.measure(name, cpu)

    def stats(self) -> dict:
        """Cost figures beside time (memory, passes ...), as extra metrics.csv columns."""
        return {}

    def release(self) -> None:
        """Free GL resources made by :meth:`setup`."""


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
