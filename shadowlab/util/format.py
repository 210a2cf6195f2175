"""Numbers as the lab shows them, one set of formatters for every table, page and line: the
metrics table's formats (:func:`format_column`: reports, the CLI summary, the study's verdicts)
and the pages' shorter ones (:func:`fmt_pct`, :func:`fmt_ms`, :func:`fmt_num`, :func:`fmt_fixed`:
Jinja2 filters ``pct``, ``ms``, ``num``, ``fixed``). Missing values (None, NaN: :func:`is_missing`)
are shown as ''. No format rounds a value that is not zero to zero: fixed decimals give way to
:data:`SMALL_DIGITS` significant digits where they would (:func:`_decimals`). Notes repeated over
frames or lights are written once, with the indices they occurred on as ranges
(:func:`group_notes`, :func:`fmt_ranges`).
"""
from __future__ import annotations

import math

import numpy as np


def is_missing(value) -> bool:
    """Whether a table cell holds nothing: None or NaN (other values, lists included, do not)."""
    if value is None:
        return True
    import pandas as pd  # here, not at import: the metrics' formats need no pandas

    try:
        return bool(pd.isna(value))
    except (TypeError, ValueError):
        return False


#: Significant digits a small nonzero figure keeps where its fixed decimals would show fewer
#: (one wrong pixel in 300k is 0.00033 %, not "0.00 %").
SMALL_DIGITS = 2


def _significant(value: float) -> str:
    """``value`` to :data:`SMALL_DIGITS` significant digits as ``:.2g`` writes it (trailing zeros
    dropped), but never in exponent notation: 3.5e-4 → "0.00035", 4.8e-5 → "0.000048"."""
    text = f"{value:.{SMALL_DIGITS}g}"
    if "e" not in text:
        return text
    leading = math.floor(math.log10(abs(value)))  # the first significant digit's place
    text = f"{value:.{SMALL_DIGITS - 1 - leading}f}"
    return text.rstrip("0").rstrip(".") if "." in text else text


def _decimals(value: float, decimals: int) -> str:
    """``value`` with ``decimals`` decimals ("0.00" when exactly zero), or, for a nonzero value
    those would show with fewer than :data:`SMALL_DIGITS` significant digits, those digits
    (:func:`_significant`): ``_decimals(3.5e-4, 2)`` is "0.00035", never "0.00"."""
    if value != 0 and math.isfinite(value) and abs(value) < 10.0 ** (SMALL_DIGITS - 1 - decimals):
        return _significant(value)
    return f"{value:.{decimals}f}"


def format_column(value, fmt: str) -> str:
    """``value`` in a metrics column's format ``fmt`` (:class:`shadowlab.evaluation.metrics.Column`:
    'percent', 'px', 'ms', 'count', 'value' or 'text'), as the report and the CLI show it; ''
    for None or a float NaN."""
    if value is None or (isinstance(value, float) and np.isnan(value)):
        return ""
    if fmt == "percent":
        # three decimals, but never "0.000 %" for a rate that is not zero (one wrong pixel
        # in 300k is 0.00033 %): small rates keep two significant digits
        pct = 100 * value
        return f"{pct:.3f} %" if pct == 0 or abs(pct) >= 0.1 else f"{_significant(pct)} %"
    if fmt in ("px", "ms"):
        return f"{value:.3f}"
    if fmt == "count":
        return f"{int(value)}"
    if fmt == "value" and isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def fmt_table_pct(rate) -> str:
    """A rate in [0, 1] as the metrics table shows error_rate ("0.123 %", small rates to two
    significant digits); '' when missing."""
    return format_column(None if is_missing(rate) else float(rate), "percent")


def fmt_table_ms(value) -> str:
    """Milliseconds as the metrics table shows time_ms_median (three decimals); '' when missing."""
    return format_column(None if is_missing(value) else float(value), "ms")


def fmt_pct(rate, digits: int = 2) -> str:
    """A rate in [0, 1] as a percentage with ``digits`` decimals ("0.12 %", "0.00 %" only when
    exactly zero), more where a small nonzero rate needs them for two significant digits
    (3.5e-6 → "0.00035 %"); '' when missing."""
    return "" if is_missing(rate) else f"{_decimals(100.0 * float(rate), digits)} %"


def fmt_ms(value) -> str:
    """Milliseconds with sensible precision ("0.31", "12.4", "1250"); '' when missing."""
    if is_missing(value):
        return ""
    v = float(value)
    return f"{v:.2f}" if v < 10 else f"{v:.1f}" if v < 100 else f"{v:.0f}"


def fmt_fixed(value, decimals: int = 4) -> str:
    """A number with ``decimals`` decimals ("0.0123"), more where a small nonzero value needs them
    for two significant digits (2e-6 → "0.000002"); '' when missing."""
    return "" if is_missing(value) else _decimals(float(value), decimals)


def fmt_num(value, digits: int = 3) -> str:
    """A number to ``digits`` significant digits; '' when missing."""
    return "" if is_missing(value) else f"{float(value):.{digits}g}"


def fmt_whole_pct(x: float) -> str:
    """A fraction as a whole percentage ("12 %"; "n/a" when missing)."""
    return "n/a" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{100 * x:.0f} %"


def fmt_ranges(indices) -> str:
    """Integers as sorted runs, each run of consecutive ones as "first–last" (an en dash):
    [0, 1, …, 23] → "0–23", [3, 7, 8, 9] → "3, 7–9", [5] → "5"; duplicates count once."""
    values = sorted({int(i) for i in indices})
    runs: list[list[int]] = []
    for v in values:
        if runs and v == runs[-1][1] + 1:
            runs[-1][1] = v
        else:
            runs.append([v, v])
    return ", ".join(str(a) if a == b else f"{a}–{b}" for a, b in runs)


def group_notes(items, unit: str = "frame") -> list[str]:
    """Notes that recur over frames (or lights, …) once each: ``items`` are (index, text) pairs;
    the result has one line per distinct text, in the order texts first occur, prefixed with the
    indices it occurred on (:func:`fmt_ranges`) and ``unit``, plural for more than one index:
    [(0, "a"), (1, "a"), (2, "b")] → ["frames 0–1: a", "frame 2: b"]."""
    where: dict[str, set[int]] = {}
    for index, text in items:
        where.setdefault(str(text), set()).add(int(index))
    return [f"{unit}{'s' if len(ix) > 1 else ''} {fmt_ranges(ix)}: {text}" for text, ix in where.items()]
