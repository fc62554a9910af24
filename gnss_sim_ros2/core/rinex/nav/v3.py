"""RINEX 3 navigation text -> records (mixed files, an epoch line naming the satellite)."""
from __future__ import annotations

from .record_text import N_CONT, epoch_line3, message_type_from_body


def split_records(lines, i0, name, version):
    """(sys, sv, epoch, nav type, body lines, line number) of each RINEX 3 record."""
    out = []
    i = i0
    n = len(lines)
    while i < n:
        ln = lines[i]
        if not ln.strip():
            i += 1
            continue
        ep = epoch_line3(ln)
        if ep is None:
            raise ValueError(f"{name}, line {i + 1}: expected a record epoch line, got {ln[:40]!r}")
        sysid, sv, epoch = ep
        j = i + 1
        while j < n and lines[j][:1] == " " and lines[j].strip():
            j += 1
        body = [ln] + lines[i + 1: j]
        need = N_CONT[sysid] + 1
        if len(body) < need:
            raise ValueError(f"{name}, line {i + 1}: record of {sv} has {len(body)} lines, expected {need}")
        out.append((sysid, sv, epoch, message_type_from_body(sysid, sv, body), body[:need], i + 1))
        i = j
    return out
