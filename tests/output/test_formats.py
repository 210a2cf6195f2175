"""The numbers and notes every page shows (shadowlab.util.format): percentages and fixed decimals
that never round a nonzero figure to zero, and notes repeated over frames written once with the
frames as ranges (shadowlab issue 38)."""
import math

import pytest

from shadowlab.util.format import fmt_fixed, fmt_pct, fmt_ranges, fmt_table_pct, format_column, group_notes


@pytest.mark.parametrize("rate, shown", [
    (0.0, "0.00 %"),             # zero only when exactly zero
    (3.5e-6, "0.00035 %"),       # one wrong pixel in 286k: not "0.00 %"
    (1 / 300_000, "0.00033 %"),
    (4.8e-7, "0.000048 %"),      # one pixel of 1920×1080: no exponent notation
    (5e-5, "0.005 %"),
    (0.000999, "0.1 %"),         # two significant digits below 0.1 %
    (0.001, "0.10 %"),           # two decimals from 0.1 % on, as before
    (0.0012345, "0.12 %"),
    (0.5, "50.00 %"),
    (1.0, "100.00 %"),
    (None, ""),
    (math.nan, ""),
])
def test_pct_keeps_two_significant_digits(rate, shown):
    assert fmt_pct(rate) == shown


def test_pct_never_reads_zero_for_a_nonzero_rate():
    for exp in range(-12, 0):
        for mantissa in (1.0, 3.5, 9.99):
            rate = mantissa * 10.0 ** exp
            text = fmt_pct(rate)
            assert float(text.rstrip(" %")) > 0 and "e" not in text, (rate, text)
            assert float(text.rstrip(" %")) == pytest.approx(100 * rate, rel=0.06), (rate, text)


@pytest.mark.parametrize("rate, shown", [
    (0.0, "0.000 %"), (3.5e-6, "0.00035 %"), (1e-6, "0.0001 %"), (4.8e-7, "0.000048 %"), (0.00123, "0.123 %"),
])
def test_metrics_table_percent_without_exponent(rate, shown):
    assert format_column(rate, "percent") == shown == fmt_table_pct(rate)


@pytest.mark.parametrize("value, shown", [
    (0.0, "0.0000"), (0.0123, "0.0123"), (0.5, "0.5000"), (4e-5, "0.00004"), (2.5e-6, "0.0000025"),
    (None, ""), (math.nan, ""),
])
def test_fixed_decimals_keep_a_small_value(value, shown):
    assert fmt_fixed(value, 4) == shown


@pytest.mark.parametrize("indices, shown", [
    (range(24), "0–23"),
    ([3, 7, 8, 9], "3, 7–9"),
    ([5], "5"),
    ([9, 8, 7, 3, 3], "3, 7–9"),
    ([0, 1, 3, 4, 6], "0–1, 3–4, 6"),
    ([], ""),
])
def test_ranges(indices, shown):
    assert fmt_ranges(indices) == shown


def test_notes_repeated_over_frames_are_grouped():
    floor = "shadow_volume: object 'floor': 4 boundary edges"
    items = [(k, floor) for k in range(24)] + [(3, "b"), (7, "b"), (8, "b"), (9, "b"), (5, "c")]
    assert group_notes(items) == ["frames 0–23: " + floor, "frames 3, 7–9: b", "frame 5: c"]
    assert group_notes([(2, "x"), (0, "y"), (0, "x")], unit="light") == ["lights 0, 2: x", "light 0: y"]
    assert group_notes([]) == []
