"""RINEX 4 navigation text -> records: ``> EPH`` records of a message type with the RINEX 3 layout
(others counted in ``NavData.skipped``) and ``> ION`` records' ionospheric coefficients."""
from __future__ import annotations

from .containers import NavData
from .record_text import N_CONT, epoch_line3, message_type_from_body, parse_float

#: RINEX 4 message types whose body has the RINEX 3 layout
_RINEX4_TYPES = {"G": ("LNAV",), "J": ("LNAV",), "E": ("INAV", "FNAV"), "C": ("D1", "D2"), "I": ("LNAV",),
                 "R": ("FDMA",), "S": ("SBAS",)}



def split_records(lines, i0, name, nav: NavData):
    out = []
    i = i0
    n = len(lines)
    while i < n:
        ln = lines[i]
        if not ln.startswith(">"):
            if ln.strip():
                raise ValueError(f"{name}, line {i + 1}: expected a '>' record line, got {ln[:40]!r}")
            i += 1
            continue
        parts = ln[1:].split()
        j = i + 1
        while j < n and not lines[j].startswith(">"):
            j += 1
        body = lines[i + 1: j]
        kind = parts[0] if parts else ""
        if kind == "EPH" and len(parts) >= 3:
            sv, msg = parts[1], parts[2]
            sysid = sv[0]
            if msg in _RINEX4_TYPES.get(sysid, ()):
                ep = epoch_line3(body[0]) if body else None
                need = N_CONT[sysid] + 1
                if ep is None or len(body) < need:
                    raise ValueError(f"{name}, line {i + 2}: bad {sv} {msg} record")
                out.append((sysid, ep[1], ep[2], msg if sysid in "EC" else message_type_from_body(sysid, sv, body),
                            body[:need], i + 2))
            else:
                key = f"RINEX4 {sysid} {msg} records (no RINEX 3 layout, not read)"
                nav.skipped[key] = nav.skipped.get(key, 0) + 1
        elif kind == "ION" and len(parts) >= 3 and body:
            _rinex4_ion(parts[1][0], parts[2], body, nav)
        i = j
    return out


def _rinex4_ion(sysid: str, msg: str, body: list[str], nav: NavData):
    vals = []
    for k, ln in enumerate(body):
        start = 23 if k == 0 else 4
        for c in range(start, len(ln.rstrip()), 19):
            try:
                vals.append(parse_float(ln[c: c + 19]))
            except ValueError:
                return
    if msg == "IFNV" and sysid == "E" and len(vals) >= 3:
        nav.iono.setdefault("GAL", vals[:3])
    elif len(vals) >= 8 and msg in ("LNAV", "D1D2"):
        key = {"G": "GPS", "J": "QZS", "C": "BDS", "I": "IRN"}.get(sysid)
        if key:
            nav.iono.setdefault(key + "A", vals[:4])
            nav.iono.setdefault(key + "B", vals[4:8])
