"""RINEX headers: the observation-header fields georinex does not give."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np


def read_obs_header(path: Path) -> dict:
    """Fields georinex does not give: APPROX POSITION XYZ and the GLONASS SLOT / FRQ # table."""
    out = {"approx": None, "glo": {}}
    with open(path, errors="replace") as f:
        first = f.readline()
        if "OBSERVATION DATA" not in first[20:60] or not first[:9].strip():
            raise ValueError(f"{path}, line 1: not a RINEX observation file (RINEX VERSION / TYPE is {first!r:.90})")
        try:
            version = float(first[:9])
        except ValueError:
            raise ValueError(f"{path}, line 1: unreadable RINEX version {first[:9]!r}") from None
        if version < 3:
            raise ValueError(f"{path}, line 1: RINEX {version} observation files are not supported (RINEX 3 only)")
        for n, line in enumerate(f, start=2):
            label = line[60:].strip()
            if label == "END OF HEADER":
                break
            if label == "APPROX POSITION XYZ":
                try:
                    out["approx"] = np.array([float(line[i:i + 14]) for i in (0, 14, 28)])
                except ValueError:
                    raise ValueError(f"{path}, line {n}: unreadable APPROX POSITION XYZ {line[:42]!r}") from None
            elif label == "GLONASS SLOT / FRQ #":
                for m in re.finditer(r"(R\s?\d{1,2})\s+(-?\d+)", line[4:60]):
                    sv = "R" + f"{int(m.group(1)[1:]):02d}"
                    out["glo"][sv] = int(m.group(2))
        else:
            raise ValueError(f"{path}: no END OF HEADER")
    if out["approx"] is not None and not np.any(out["approx"]):
        out["approx"] = None
    return out
