"""Numbers as the lab shows them, one set of formatters for every table, page and line: the
metrics table's formats (:func:`format_column`: reports, the CLI summary, the study's verdicts)
and the pages' shorter ones (:func:`fmt_pct`, :func:`fmt_ms`, :func:`fmt_num`: Jinja2 filters
``pct``, ``ms``, ``num``). Missing values (None, NaN: :func:`is_missing`) are shown as ''.
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


def format_column(value, fmt: str) -> str:
    """``value`` in a metrics column's format ``fmt`` (:class:`shadowlab.evaluation.metrics.Column`:
    'percent', 'px', 'ms', 'count', 'value' or 'text'), as the report and the CLI show it; ''
    for None or a float NaN."""
    if value is None or (isinstance(value, float) and np.isnan(value)):
        return ""
    if fmt == "percent":
        # three decimals, but never "0.000 %" for a rate that is not zero (one wrong pixel
        # in 300k is 0.0003 %): small rates keep two significant digits
        pct = 100 * value
        return f"{pct:.3f} %" if pct == 0 or abs(pct) >= 0.1 else f"{pct:.2g} %"
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
    """A rate in [0, 1] as a percentage ("0.12 %"); '' when missing."""
    return "" if is_missing(rate) else f"{100.0 * float(rate):.{digits}f} %"


def fmt_ms(value) -> str:
    """Milliseconds with sensible precision ("0.31", "12.4", "1250"); '' when missing."""
    if is_missing(value):
        return ""
    v = float(value)
    return f"{v:.2f}" if v < 10 else f"{v:.1f}" if v < 100 else f"{v:.0f}"


def fmt_num(value, digits: int = 3) -> str:
    """A number to ``digits`` significant digits; '' when missing."""
    return "" if is_missing(value) else f"{float(value):.{digits}g}"


def fmt_whole_pct(x: float) -> str:
    """A fraction as a whole percentage ("12 %"; "n/a" when missing)."""
    return "n/a" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{100 * x:.0f} %"
