"""The reports' Markdown (comparison, calibration): one table layout (header, rule, rows, a blank line) and one
number format for its cells."""
from __future__ import annotations

import math


def md_table(header: list[str], rows: list[list]) -> list[str]:
    """Lines of a Markdown table (header, separator, rows) and a blank line."""
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return out + [""]


def fmt(v, digits=3) -> str:
    """A number with ``digits`` decimals ("-" for None / NaN / inf, numpy scalars included; no "-0.000")."""
    if v is None or not math.isfinite(v):
        return "-"
    return f"{0.0 if abs(v) < 0.5 * 10.0**-digits else v:.{digits}f}"
