"""What the text of every RINEX navigation version shares: number fields, the header's ionospheric
coefficients and leap seconds, the RINEX 3/4 record epoch line, record lengths and message types."""
from __future__ import annotations

import datetime as _dt
import re

#: continuation lines after the epoch line in RINEX 2/3 (RINEX 3.04 A6-A14)
N_CONT = {"G": 7, "E": 7, "C": 7, "J": 7, "I": 7, "R": 3, "S": 3}


def parse_float(s: str) -> float:
    s = s.strip().replace("D", "E").replace("d", "e")
    return float(s) if s else 0.0


def parse_header(lines: list[str], name: str, major: int):
    iono: dict[str, list[float]] = {}
    leap = None
    for i, ln in enumerate(lines):
        label = ln[60:].strip()
        try:
            if label == "IONOSPHERIC CORR":
                kind = ln[:4].strip()
                n = 3 if kind == "GAL" else 4
                iono[kind] = [parse_float(ln[5 + 12 * k: 17 + 12 * k]) for k in range(n)]
            elif label in ("ION ALPHA", "ION BETA"):
                vals = [parse_float(ln[2 + 12 * k: 14 + 12 * k]) for k in range(4)]
                iono["GPSA" if label == "ION ALPHA" else "GPSB"] = vals
            elif label == "LEAP SECONDS":
                leap = int(ln[:6])
        except ValueError as e:
            raise ValueError(f"{name}, line {i + 1}: bad {label} header line ({e})") from None
    return iono, leap


_EPOCH3 = re.compile(r"^([GRECJIS])([ \d]\d) (\d{4}) ([ \d]\d) ([ \d]\d) ([ \d]\d) ([ \d]\d) ([ \d]\d)")


def epoch_line3(line: str):
    m = _EPOCH3.match(line)
    if not m:
        return None
    s, prn, y, mo, d, hh, mm, ss = m.groups()
    try:
        ep = _dt.datetime(int(y), int(mo), int(d), int(hh), int(mm), int(ss))
    except ValueError:
        return None
    return s, f"{s}{int(prn):02d}", ep


def message_type_from_body(sysid: str, sv: str, body: list[str]) -> str:
    src = 0
    if sysid == "E":
        try:
            src = int(parse_float(body[5][4 + 19: 4 + 38]))
        except (ValueError, IndexError):
            src = 0
    return message_type(sysid, sv, src)


def message_type(sysid: str, sv: str, data_src: int = 0) -> str:
    """The message type of a record: Galileo I/NAV or F/NAV by its data source bits (RINEX 3.04 A8),
    BeiDou D2 (GEO) or D1, GLONASS FDMA, LNAV otherwise."""
    if sysid == "E":
        if data_src & 2 and not data_src & 5:
            return "FNAV"
        return "INAV"
    if sysid == "C":
        prn = int(sv[1:])
        return "D2" if (prn <= 5 or prn >= 59) else "D1"
    if sysid == "R":
        return "FDMA"
    return "LNAV"
