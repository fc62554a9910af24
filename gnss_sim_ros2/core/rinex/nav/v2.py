"""RINEX 2 navigation text -> records (one file per system; two-digit years, PRN-only epoch lines)."""
from __future__ import annotations

import datetime as _dt
import re

from .record_text import N_CONT, message_type_from_body

_EPOCH2 = re.compile(r"^([ \d]\d) ([ \d]\d) ([ \d]\d) ([ \d]\d) ([ \d]\d) ([ \d]\d) ([ \d]\d\.\d)")


def split_records(lines, i0, sysid, name):
    out = []
    i = i0
    n = len(lines)
    need = N_CONT[sysid] + 1
    while i < n:
        ln = lines[i]
        if not ln.strip():
            i += 1
            continue
        m = _EPOCH2.match(ln)
        if not m:
            raise ValueError(f"{name}, line {i + 1}: expected a RINEX 2 record epoch line, got {ln[:40]!r}")
        prn, yy, mo, d, hh, mm, ss = m.groups()
        y = int(yy)
        y += 1900 if y >= 80 else 2000
        sec = float(ss)
        try:
            epoch = _dt.datetime(y, int(mo), int(d), int(hh), int(mm), int(sec))
        except ValueError:
            raise ValueError(f"{name}, line {i + 1}: bad epoch {ln[3:22]!r}") from None
        body = lines[i: i + need]
        if len(body) < need or any(b[:3].strip() for b in body[1:]):
            raise ValueError(f"{name}, line {i + 1}: record of PRN {prn.strip()} has fewer than {need} lines")
        sv = f"{sysid}{int(prn):02d}"
        out.append((sysid, sv, epoch, message_type_from_body(sysid, sv, [""] * 6) if sysid != "E" else "INAV",
                    body, i + 1))
        i += need
    return out
