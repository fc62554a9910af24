"""RINEX headers: the observation-header fields georinex does not give (any compression georinex opens)."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np


def _three_f14(line: str, path, n: int, label: str) -> np.ndarray:
    """The three 3F14.4 numbers of a header line (APPROX POSITION XYZ, ANTENNA: DELTA H/E/N; RINEX 3.05 table A2);
    ValueError naming the file, line and label."""
    try:
        return np.array([float(line[i:i + 14]) for i in (0, 14, 28)])
    except ValueError:
        raise ValueError(f"{path}, line {n}: unreadable {label} {line[:42]!r}") from None


def read_obs_header(path: Path) -> dict:
    """Fields georinex does not give: ``version``, ``approx`` (APPROX POSITION XYZ, None when absent or 0),
    ``glo`` (GLONASS SLOT / FRQ #: slot -> channel), ``first_obs`` (TIME OF FIRST OBS to the minute)."""
    from georinex.rio import opener  # plain, .gz, .Z, .bz2, .zip and Hatanaka (CRINEX, with the hatanaka package)

    try:
        with opener(Path(path)) as f:
            return parse_obs_header(f, path)
    except (OSError, EOFError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot open as a RINEX observation file ({exc})") from None


def parse_obs_header(f, path) -> dict:
    """The fields of :func:`read_obs_header` from an open text stream ``f`` (``path`` names it in errors), and
    ``receiver_type`` / ``antenna_type`` (REC # / TYPE / VERS, ANT # / TYPE), ``delta_hen_m`` (ANTENNA: DELTA H/E/N,
    (3,) or None), ``interval_s`` (INTERVAL or None)."""
    out = {"approx": None, "glo": {}, "version": None, "first_obs": None, "receiver_type": "",
           "antenna_type": "", "delta_hen_m": None, "interval_s": None}
    first = f.readline()
    if not first.strip():
        raise ValueError(f"{path}: empty file (no RINEX VERSION / TYPE line)")
    if "OBSERVATION DATA" not in first[20:60] or not first[:9].strip():
        raise ValueError(f"{path}, line 1: not a RINEX observation file (RINEX VERSION / TYPE is {first!r:.90})")
    try:
        version = float(first[:9])
    except ValueError:
        raise ValueError(f"{path}, line 1: unreadable RINEX version {first[:9]!r}") from None
    if not 2 <= version < 5:
        raise ValueError(f"{path}, line 1: RINEX {version} observation files are not supported (versions 2 to 4)")
    out["version"] = version
    for n, line in enumerate(f, start=2):
        label = line[60:].strip()
        if label == "END OF HEADER":
            break
        if label == "APPROX POSITION XYZ":
            out["approx"] = _three_f14(line, path, n, label)
        elif label == "REC # / TYPE / VERS":
            out["receiver_type"] = line[20:40].strip()
        elif label == "ANT # / TYPE":
            out["antenna_type"] = line[20:40].rstrip()
        elif label == "ANTENNA: DELTA H/E/N":
            out["delta_hen_m"] = _three_f14(line, path, n, label)
        elif label == "INTERVAL":
            try:
                out["interval_s"] = float(line[:10])
            except ValueError:
                raise ValueError(f"{path}, line {n}: unreadable INTERVAL {line[:10]!r}") from None
        elif label == "TIME OF FIRST OBS":
            try:
                y, mo, d, h, mi = (int(x) for x in line[:30].split())
                out["first_obs"] = np.datetime64(f"{y:04d}-{mo:02d}-{d:02d}T{h:02d}:{mi:02d}", "s")
            except ValueError:
                raise ValueError(f"{path}, line {n}: unreadable TIME OF FIRST OBS {line[:43]!r}") from None
        elif label == "GLONASS SLOT / FRQ #":
            for m in re.finditer(r"(R\s?\d{1,2})\s+(-?\d+)", line[4:60]):
                sv = "R" + f"{int(m.group(1)[1:]):02d}"
                out["glo"][sv] = int(m.group(2))
    else:
        raise ValueError(f"{path}: no END OF HEADER")
    if out["approx"] is not None and not np.any(out["approx"]):
        out["approx"] = None
    return out
