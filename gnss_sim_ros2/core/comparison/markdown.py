"""The comparison report's Markdown: one number format (report.py, canyon_report.py); the table layout is
core/markdown_table.py, shared with the calibration report."""
from __future__ import annotations

import math


def fmt(v, digits=3) -> str:
    """A number with ``digits`` decimals ("-" for None / NaN / inf; no "-0.000")."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return f"{0.0 if abs(v) < 0.5 * 10.0**-digits else v:.{digits}f}"
