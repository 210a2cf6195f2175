"""The parameters a tune searches: one :class:`Dimension` per ``--param`` of ``shadowlab tune``.

A dimension is a numeric range — linear, or geometric (``log``) for parameters whose effect
scales with their order of magnitude (a depth bias, a variance floor) — or a list of values
(a parameter's choices, a bool, or any list given on the command line). Where ``--param NAME``
gives no range, the technique's declared one is used: ``Param(..., tune=TuneRange(lo, hi, log))``
in the technique's ``PARAMS`` (:class:`shadowlab.techniques.base.TuneRange`), the values worth
trying for that parameter, always inside its ``min``/``max``.

``--param`` forms (:func:`parse_params`):

- ``NAME``: the declared range (numeric), the choices (choice parameters) or false, true (bool);
- ``NAME=LO:HI`` or ``NAME=LO:HI:log``: a numeric range, linear or geometric;
- ``NAME=a,b,c``: exactly these values, for a parameter of any type.

Every bound and listed value is checked as the technique would check it in a spec — by
:meth:`Param.parse <shadowlab.techniques.base.Param.parse>` and then by building the technique
with it, so that rules between parameters (an odd blur kernel, an exponent that overflows the
chosen storage) are caught here, before anything renders. Errors are :class:`TuneError`: one line
naming the technique and the ``--param`` (the command's exit status 2).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

from ..techniques.base import Param, Technique, TechniqueError, format_value, parse_spec
from ..util.validation import did_you_mean

KINDS = ("float", "int", "choice")
#: Significant digits of the float grid points (so that candidate specs read ``bias=0.00111803``,
#: not 17 digits); ample for the search's smallest window, 1e-3 of a range across a few points.
FLOAT_DIGITS = 6


class TuneError(ValueError):
    """A ``--param``, ``--objective`` or other tune setting is wrong: one line naming the
    technique and the setting, for exit status 2 (like :class:`~shadowlab.techniques.TechniqueError`)."""


def _is_power_of_two(x: float) -> bool:
    return x >= 1 and float(x).is_integer() and (int(x) & (int(x) - 1)) == 0


def _round_int(x: float) -> int:
    """Round half up (Python's round() rounds half to even: 4.5 → 4 but 5.5 → 6)."""
    return int(math.floor(x + 0.5))


@dataclass(frozen=True)
class Dimension:
    """One searched parameter: ``kind`` "float" or "int" over [``lo``, ``hi``] (geometric when
    ``log``), or "choice" over ``choices``. An "int" dimension with ``log`` whose bounds are
    powers of two (a map resolution) takes only powers of two (:attr:`powers_of_two`)."""

    name: str
    kind: str
    lo: float | None = None
    hi: float | None = None
    log: bool = False
    choices: tuple | None = None

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"{self.name}: kind must be one of {KINDS}, got {self.kind!r}")
        if self.kind == "choice":
            if not self.choices:
                raise ValueError(f"{self.name}: a choice dimension needs choices")
            return
        if self.lo is None or self.hi is None or not self.lo < self.hi:
            raise ValueError(f"{self.name}: needs lo < hi, got [{self.lo}, {self.hi}]")
        if self.log and self.lo <= 0:
            raise ValueError(f"{self.name}: a log range needs lo > 0, got {self.lo}")

    # -- the search coordinate ------------------------------------------------------
    @property
    def powers_of_two(self) -> bool:
        """An int log range between powers of two: its values are the powers of two in it."""
        return self.kind == "int" and self.log and _is_power_of_two(self.lo) and _is_power_of_two(self.hi)

    def coordinate(self, value: float) -> float:
        """Where ``value`` lies on the axis the search spaces points evenly along: the value
        itself, its natural log (``log``) or its base-2 log (powers of two)."""
        if self.powers_of_two:
            return math.log2(value)
        return math.log(value) if self.log else float(value)

    def value_at(self, u: float) -> float:
        """The inverse of :meth:`coordinate` (unrounded)."""
        if self.powers_of_two:
            return 2.0 ** u
        return math.exp(u) if self.log else float(u)

    @property
    def span(self) -> float:
        """The whole range's length in :meth:`coordinate` units (0 for a choice dimension)."""
        if self.kind == "choice":
            return 0.0
        return self.coordinate(self.hi) - self.coordinate(self.lo)

    # -- values ---------------------------------------------------------------------
    def grid(self, n: int, lo: float | None = None, hi: float | None = None) -> list:
        """``n`` values evenly spaced (in :meth:`coordinate`: geometric when ``log``) across
        [``lo``, ``hi``] ∩ the dimension's range (default: the whole range), both ends
        included (``n`` = 1: the middle). Floats are rounded to :data:`FLOAT_DIGITS` significant
        digits; ints rounded and deduplicated (in order), powers-of-two ranges give only powers
        of two; a choice dimension gives all its choices whatever ``n``."""
        if self.kind == "choice":
            return list(self.choices)
        if n < 1:
            raise ValueError(f"{self.name}: grid needs n >= 1, got {n}")
        lo = self.lo if lo is None else min(max(lo, self.lo), self.hi)
        hi = self.hi if hi is None else min(max(hi, self.lo), self.hi)
        if hi < lo:
            lo, hi = hi, lo
        ua, ub = self.coordinate(lo), self.coordinate(hi)
        us = [(ua + ub) / 2] if n == 1 else [ua + (ub - ua) * i / (n - 1) for i in range(n)]
        if self.powers_of_two:
            first, last = math.ceil(ua - 1e-9), math.floor(ub + 1e-9)
            exps = [min(max(_round_int(u), first), last) for u in us] if first <= last \
                else [_round_int((ua + ub) / 2)]
            return list(dict.fromkeys(int(self.clip(2 ** e)) for e in exps))
        values = [self.value_at(u) for u in us]
        values[0] = lo if n > 1 else values[0]   # the ends exactly, not exp(log(x))
        values[-1] = hi if n > 1 else values[-1]
        if self.kind == "int":
            first, last = math.ceil(lo - 1e-9), math.floor(hi + 1e-9)
            if first > last:
                return [self.clip(_round_int((lo + hi) / 2))]
            return list(dict.fromkeys(min(max(_round_int(v), first), last) for v in values))
        return list(dict.fromkeys(self.clip(float(f"{v:.{FLOAT_DIGITS}g}")) for v in values))

    def clip(self, value: Any) -> Any:
        """``value`` moved into the dimension: bounded to [lo, hi] (ints rounded); for a choice
        dimension the value itself if it is a choice, else the nearest numeric choice, else the
        first choice."""
        if self.kind == "choice":
            same = [c for c in self.choices if c == value]
            if same:  # the choice itself (1024 for 1024.0; False for 0 only when no 0 is listed)
                return next((c for c in same if type(c) is type(value)), same[0])
            numeric = [c for c in self.choices if isinstance(c, (int, float)) and not isinstance(c, bool)]
            if numeric and isinstance(value, (int, float)) and not isinstance(value, bool) \
                    and len(numeric) == len(self.choices):
                return min(numeric, key=lambda c: abs(c - value))
            return self.choices[0]
        v = min(max(float(value), self.lo), self.hi)
        return _round_int(v) if self.kind == "int" else v

    def describe(self) -> str:
        """The dimension in words: ``bias in [1e-05, 0.05], log``, ``resolution in [256, 4096],
        powers of two``, ``filter in {nearest, pcf3, pcf5}``."""
        if self.kind == "choice":
            return f"{self.name} in {{{', '.join(format_value(c) for c in self.choices)}}}"
        lo, hi = (f"{int(v)}" if self.kind == "int" else f"{v:g}" for v in (self.lo, self.hi))
        scale = ", powers of two" if self.powers_of_two else (", log" if self.log else "")
        return f"{self.name} in [{lo}, {hi}]{scale}"


# --------------------------------------------------------------------------- parsing --param

def tunable(tech: Technique) -> list[str]:
    """The parameters of ``tech`` that ``--param NAME`` takes without a range: those with a
    declared ``tune`` range, choices, or a bool type."""
    return [k for k, p in tech.PARAMS.items()
            if p.tune is not None or p.choices is not None or type(p.default) is bool]


def _reason(tech: Technique, exc: TechniqueError) -> str:
    """A TechniqueError's message without the technique's name in front."""
    msg, prefix = str(exc), f"{tech.name}: "
    return msg[len(prefix):] if msg.startswith(prefix) else msg


def _param_error(tech: Technique, arg: str, exc: TechniqueError) -> TuneError:
    """A TechniqueError about one value, as the TuneError of the ``--param`` that gave it."""
    return TuneError(f"{tech.name}: --param {arg}: {_reason(tech, exc)}")


def _checked(tech: Technique, arg: str, key: str, param: Param, raw: Any) -> Any:
    """``raw`` parsed as ``key``'s value, and accepted by the technique built with it."""
    try:
        value = param.parse(tech.name, key, raw)
        with_params(tech, {key: value})
    except TechniqueError as exc:
        raise _param_error(tech, arg, exc) from None
    return value


def _dimension(tech: Technique, arg: str) -> Dimension:
    """The dimension of one ``--param`` argument (see :func:`parse_params`)."""
    name, eq, rng = (s.strip() for s in arg.partition("="))
    params = tech.PARAMS
    if name not in params:
        raise TuneError(f"{tech.name}: --param {arg}: unknown parameter '{name}'{did_you_mean(name, params)} "
                        f"(known: {', '.join(params) or 'none'})")
    p = params[name]
    kind = type(p.default)
    numeric = kind in (int, float) and p.choices is None
    if not eq:
        if p.choices is not None:
            return Dimension(name, "choice", choices=tuple(p.choices))
        if kind is bool:
            return Dimension(name, "choice", choices=(False, True))
        if not numeric:
            raise TuneError(f"{tech.name}: --param {name}: give a list of values: --param {name}=a,b")
        if p.tune is None:
            raise TuneError(f"{tech.name}: --param {name}: {tech.name} declares no tuning range for {name}; "
                            f"give a range: --param {name}=LO:HI (or LO:HI:log)")
        t = p.tune
        try:
            for bound in (t.lo, t.hi):
                with_params(tech, {name: kind(bound)})
        except TechniqueError as exc:
            raise TuneError(f"{tech.name}: --param {name}: the declared range [{t.lo:g}, {t.hi:g}] does not fit "
                            f"this configuration ({_reason(tech, exc)}); "
                            f"give a range: --param {name}=LO:HI") from None
        return Dimension(name, "int" if kind is int else "float", kind(t.lo), kind(t.hi), t.log)
    if not rng:
        raise TuneError(f"{tech.name}: --param {arg}: nothing after '='; give LO:HI, LO:HI:log or a list a,b,c")
    if "," in rng:
        raw = [s.strip() for s in rng.split(",")]
        if any(not s for s in raw):
            raise TuneError(f"{tech.name}: --param {arg}: an empty value in the list")
        values = list(dict.fromkeys(_checked(tech, arg, name, p, s) for s in raw))
        if len(values) < 2:
            raise TuneError(f"{tech.name}: --param {arg}: a list needs two or more different values")
        return Dimension(name, "choice", choices=tuple(values))
    if ":" in rng:
        parts = [s.strip() for s in rng.split(":")]
        if not numeric:
            what = f"one of {', '.join(map(format_value, p.choices))}" if p.choices is not None else kind.__name__
            raise TuneError(f"{tech.name}: --param {arg}: {name} takes {what}, not a range; give a list: "
                            f"--param {name}=a,b")
        if len(parts) not in (2, 3) or (len(parts) == 3 and parts[2].lower() != "log"):
            raise TuneError(f"{tech.name}: --param {arg}: expected LO:HI or LO:HI:log")
        log = len(parts) == 3
        lo, hi = (_checked(tech, arg, name, p, s) for s in parts[:2])
        if not lo < hi:
            raise TuneError(f"{tech.name}: --param {arg}: LO must be below HI, got {format_value(lo)} >= "
                            f"{format_value(hi)}")
        if log and lo <= 0:
            raise TuneError(f"{tech.name}: --param {arg}: a log range needs LO > 0, got {format_value(lo)}")
        return Dimension(name, "int" if kind is int else "float", lo, hi, log)
    raise TuneError(f"{tech.name}: --param {arg}: expected {name}, {name}=LO:HI, {name}=LO:HI:log or "
                    f"{name}=a,b,c")


def parse_params(tech: Technique, args: Sequence[str]) -> list[Dimension]:
    """The dimensions of ``--param`` arguments (``NAME``, ``NAME=LO:HI[:log]``, ``NAME=a,b,c``)
    for the technique ``tech`` (built from the tune's spec), in the order given. Names are the
    keys of ``tech.PARAMS`` (``light_samples`` included for light-sampled techniques).

    TuneError (one line naming the technique and the ``--param``) for: no ``--param`` at all, an
    unknown name (with the closest as a hint), a name given twice, a numeric parameter without a
    declared range and none given, LO >= HI, a log range from LO <= 0, a bound or listed value
    the parameter or the technique rejects, or a range for a choice or bool parameter."""
    if not args:
        raise TuneError(f"{tech.name}: nothing to tune: give --param NAME "
                        f"(by name alone: {', '.join(tunable(tech)) or 'none'})")
    dims: list[Dimension] = []
    for arg in args:
        dim = _dimension(tech, str(arg).strip())
        if any(d.name == dim.name for d in dims):
            raise TuneError(f"{tech.name}: --param {dim.name} given twice")
        dims.append(dim)
    return dims


def with_params(tech: Technique, values: dict) -> str:
    """The full spec of ``tech`` with ``values`` (parameter → value) replacing its own, checked
    as a spec would be (TechniqueError for an unknown key or a bad value); ``from_spec`` of the
    result rebuilds the technique with those values."""
    # from the spec, not params(): a spec with an engine preset leaves out the keys the preset
    # fills in per light type (shadowlab/techniques/maps/presets.py), and they must stay so
    name, given = parse_spec(tech.spec())
    return type(tech)(**{**given, **values}).spec()
