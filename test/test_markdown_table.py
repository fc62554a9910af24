"""The reports' Markdown (core/markdown_table.py): the table layout and the cells' number format."""
from __future__ import annotations

import math

import numpy as np

from gnss_sim_ros2.core.markdown_table import fmt, md_table


def test_fmt_rounds_to_digits_and_never_writes_minus_zero():
    assert fmt(1.23456) == "1.235"
    assert fmt(1.23456, 1) == "1.2"
    assert fmt(-2.5, 2) == "-2.50"
    assert fmt(-0.0004) == "0.000"
    assert fmt(-0.04, 1) == "0.0"
    assert fmt(7) == "7.000"


def test_fmt_writes_a_dash_for_missing_or_non_finite_values_numpy_scalars_included():
    for v in (None, math.nan, math.inf, -math.inf, np.float32("nan"), np.float64("inf")):
        assert fmt(v) == "-", v
    assert fmt(np.float32(0.5), 1) == "0.5"


def test_md_table_has_header_rule_rows_and_a_blank_line():
    assert md_table(["a", "b"], [[1, "x"], [2.5, None]]) == [
        "| a | b |", "|---|---|", "| 1 | x |", "| 2.5 | None |", ""]
