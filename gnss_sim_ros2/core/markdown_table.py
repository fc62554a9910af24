"""One Markdown table layout for the reports (comparison, calibration): header, rule, rows, a blank line."""
from __future__ import annotations


def md_table(header: list[str], rows: list[list]) -> list[str]:
    """Lines of a Markdown table (header, separator, rows) and a blank line."""
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return out + [""]
