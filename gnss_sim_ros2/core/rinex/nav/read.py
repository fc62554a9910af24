"""RINEX 2, 3 and 4 broadcast navigation files -> per-system numpy record tables.

The numbers are read by georinex (``georinex.rinexnav``); this module cuts the
file into records first and hands georinex a normalised RINEX 2/3 text, which
works around what georinex 1.16 cannot do by itself:

- RINEX 4 navigation files: georinex reads only versions 2 and 3.  The
  ``> EPH`` records whose body has the RINEX 3 layout (GPS/QZSS LNAV, Galileo
  INAV/FNAV, BeiDou D1/D2, NavIC LNAV, GLONASS FDMA without its 4th orbit line)
  are passed on as RINEX 3.04; CNAV, CNV1/2/3 and other new message types are
  skipped (counted in ``NavData.skipped``).  ``> ION`` records give the
  ionospheric coefficients (Klobuchar, NeQuick-G).
- blank (spare) fields inside a record: georinex turns the whole record into
  NaN (it does so for every BeiDou record of a typical station file) or fails;
  blank fields are filled with 0 before parsing.
- records with the same satellite and epoch: georinex makes copies named
  ``G01_1``... (slow) or, in RINEX 2, drops the satellite entirely.  Duplicates
  are removed here (the last one in the file wins); Galileo I/NAV and F/NAV
  records, which share their epoch, are parsed in separate passes.
- RINEX 3.05/4 GLONASS records with a 4th orbit line: that line is dropped.
- NavIC: georinex names the IRN week ``BDTWeek``; it is read as the IRN week.
- headers: parsed here (IONOSPHERIC CORR, ION ALPHA/BETA, LEAP SECONDS), so a
  malformed TIME SYSTEM CORR line cannot stop georinex.

Compressed input (.gz, .Z, .bz2, .zip, Hatanaka) is opened through georinex's
opener.  Times: every record gets ``toc`` and ``toe`` as GPS time
(``*_sec`` integer GPS seconds + ``*_frac``).  The week of ``toe`` is resolved
from the record epoch (``toe`` is the instant with that time of week nearest
to ``toc``, as RTKLIB's ``adjweek``), so the week fields (continuous GPS week
in RINEX 3, mod 1024 in some writers, GPS-aligned for Galileo, BDT week for
BeiDou) never cause a week error; BeiDou ``toe``/``toc`` are read in BDT and
GLONASS epochs in UTC (RINEX 3 A10) and converted to GPS time with the leap
seconds of core/time.py.
"""
from __future__ import annotations

import datetime as _dt
import warnings
from pathlib import Path

import numpy as np

from ...input_file import not_a_file
from ...time import GnssTime
from ..nav_write import GLONASS_KM_FIELDS, d12, d19, iono_from_header, record_values
from . import v2, v3, v4
from .cache import parse_cached
from .containers import KEPLER_SYSTEMS, SUPPORTED_SYSTEMS, NavData, NavDataWarning, SystemTable, epoch_key
from .georinex_adapter import GEORINEX_FIELDS, fields_in_file_order, georinex_parse, non_numeric_field
from .record_text import message_type, parse_header
from .tables import dedupe, fix_semicircles, record_table


def read_nav_files(paths, start: GnssTime | None = None, end: GnssTime | None = None,
                   systems: str = SUPPORTED_SYSTEMS, margin_s: float = 6 * 3600.0) -> NavData:
    """Read several navigation files into one :class:`NavData` (duplicates removed).

    ``start``/``end`` (GPS time) keep only records whose epoch lies within
    [start - margin_s, end + margin_s]; the margin covers the validity windows.
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    paths = list(paths)
    if not paths:
        raise ValueError("no navigation file given")
    out = NavData()
    for p in paths:
        out = out.merge(read_nav_file(p, start, end, systems, margin_s))
    for s in list(out.tables):
        out.tables[s] = dedupe(out.tables[s])
    return out


def read_nav_file(path, start: GnssTime | None = None, end: GnssTime | None = None,
                  systems: str = SUPPORTED_SYSTEMS, margin_s: float = 6 * 3600.0) -> NavData:
    """Read one RINEX 2/3/4 navigation file (plain or compressed)."""
    path = Path(path)
    if (why := not_a_file(path)) is not None:      # /dev/null was said "does not exist"
        raise ValueError(f"navigation file {path}: {why}")

    def parse() -> NavData:
        from georinex.rio import opener  # local import: georinex pulls in xarray

        try:
            with opener(path) as f:
                text = f.read()
        except (OSError, EOFError, ValueError) as e:
            raise ValueError(f"{path}: cannot open as a RINEX navigation file ({e})") from e
        return parse_nav_text(text, name=str(path), start=start, end=end, systems=systems, margin_s=margin_s)

    # a second run on the same file: the records of the first (cache.py), without georinex
    window = [None if t is None else [int(t.sec), float(t.frac)] for t in (start, end)] + [systems, float(margin_s)]
    return parse_cached(path, tuple(window), parse)


def parse_nav_text(text: str, name: str = "<text>", start: GnssTime | None = None, end: GnssTime | None = None,
                   systems: str = SUPPORTED_SYSTEMS, margin_s: float = 6 * 3600.0) -> NavData:
    """Parse the text of a navigation file (see module doc)."""
    lines = text.splitlines()
    if not lines:
        raise ValueError(f"{name}: empty file")
    first = lines[0]
    try:
        version = float(first[:9])
    except ValueError:
        raise ValueError(f"{name}, line 1: no RINEX version in {first[:20]!r}") from None
    if "RINEX VERSION" not in first or first[20:21] not in ("N", "G", "E", "H", "J", "C", "I", "L"):
        if "NAV" not in first[20:60].upper():
            raise ValueError(f"{name}, line 1: not a RINEX navigation file ({first[20:60].strip()!r})")
    major = int(version)
    if major not in (2, 3, 4):
        raise ValueError(f"{name}: RINEX navigation version {version} is not supported (2, 3 and 4 are)")
    hdr_end = next((i for i, ln in enumerate(lines) if "END OF HEADER" in ln[60:]), None)
    if hdr_end is None:
        raise ValueError(f"{name}: no END OF HEADER line")
    iono, leap = parse_header(lines[: hdr_end + 1], name, major)
    nav = NavData(iono=iono, leap_seconds=leap, versions=[version], paths=[name])

    if major == 2:
        file_sys = {"N": "G", "G": "R", "E": "E", "H": "S", "J": "J", "C": "C", "I": "I"}.get(first[20:21])
        if file_sys is None:
            raise ValueError(f"{name}, line 1: RINEX 2 navigation file type {first[20:21]!r} is not supported")
        records = v2.split_records(lines, hdr_end + 1, file_sys, name)
    elif major == 3:
        records = v3.split_records(lines, hdr_end + 1, name, version)
    else:
        records = v4.split_records(lines, hdr_end + 1, name, nav)

    # time window on the epoch as written (a few seconds off GPS time: inside the margin)
    lo = hi = None
    if start is not None:
        lo = start.to_datetime("GPS") - _dt.timedelta(seconds=margin_s)
    if end is not None:
        hi = end.to_datetime("GPS") + _dt.timedelta(seconds=margin_s)

    if not records and not nav.skipped:
        raise ValueError(f"{name}: no navigation records after the header (a blank file)")
    groups: dict[tuple[str, str], dict[tuple[str, _dt.datetime], list[str]]] = {}
    n_sbas = 0
    for sysid, sv, epoch, nav_type, body, lineno in records:
        if sysid == "S":
            n_sbas += 1
            continue
        if sysid not in systems:
            continue
        if (lo is not None and epoch < lo) or (hi is not None and epoch > hi):
            continue
        bad = non_numeric_field(body, 22 if major == 2 else 23, 3 if major == 2 else 4)
        if bad is not None:
            k, text = bad
            nav.drop(f"{name}:{lineno + k}", sv, epoch, f"field {text.strip()!r} is not a number")
            continue
        # duplicates (same satellite, epoch and message type): the last in the file wins
        groups.setdefault((sysid, nav_type), {})[(sv, epoch)] = body
        nav.origin[(sv, nav_type, epoch_key(epoch))] = f"{name}:{lineno}"
    if n_sbas:
        key = "SBAS records (SBAS is not simulated)"
        nav.skipped[key] = nav.skipped.get(key, 0) + n_sbas
        msg = f"{name}: {n_sbas} SBAS record{'s' if n_sbas > 1 else ''} skipped (SBAS is not simulated)"
        nav.notes.append(msg)
        warnings.warn(msg, NavDataWarning, stacklevel=2)

    for (sysid, nav_type), recs in sorted(groups.items()):
        n_dropped = len(nav.dropped)
        tab = georinex_parse(sysid, nav_type, list(recs.values()), major, first, name, nav)
        have = set() if tab is None else {(str(a), epoch_key(b)) for a, b in zip(tab.rec["sv"], tab.epoch)}
        if len(have) + len(nav.dropped) - n_dropped < len(recs):
            gone = {m.split(": ", 1)[0] for m in nav.dropped[n_dropped:]}
            for sv, epoch in recs:
                where = nav.origin[(sv, nav_type, epoch_key(epoch))]
                if (sv, epoch_key(epoch)) not in have and where not in gone:
                    nav.drop(where, sv, epoch, "georinex could not read it")
        if tab is not None and len(tab):
            nav.tables[sysid] = SystemTable.concatenate([nav.tables[sysid], tab]) if sysid in nav.tables else tab
    for sysid, tab in nav.tables.items():
        if sysid in KEPLER_SYSTEMS:
            fix_semicircles(tab, name, nav)
    return nav


def nav_from_records(records_by_system: dict, header: dict | None = None, name: str = "<records>") -> NavData:
    """The NavData that reading the file ``write_rinex3_nav(path, records_by_system, header)`` gives,
    without writing or parsing text: every value rounded to the file's D19.12 (GLONASS in km, as written
    and read back), the epochs to the second, the ionospheric coefficients to D12.4, so the satellite
    states equal those of the round trip.  ``name`` stands for the file in messages."""
    header = dict(header or {})
    iono = {kind: [float(d12(v)) for v in vals] for kind, vals in iono_from_header(header).items()}
    leap = header.get("LEAP SECONDS")
    nav = NavData(iono=iono, leap_seconds=None if leap is None else int(leap), versions=[3.04], paths=[name])
    for sysid in SUPPORTED_SYSTEMS:
        recs = records_by_system.get(sysid) or []
        groups: dict[str, dict] = {}
        file_fields = fields_in_file_order(sysid)
        for k, rec in enumerate(recs):
            sv, t, vals = record_values(sysid, rec, f"{name} record {k}")
            vals = [float(d19(v)) * (1000.0 if sysid == "R" and f in GLONASS_KM_FIELDS else 1.0)
                    for f, v in zip(file_fields, vals)]
            row = dict(zip(file_fields, vals))
            nav_type = message_type(sysid, sv, int(row.get("DataSrc", 0)))
            epoch = np.datetime64(t, "s")
            groups.setdefault(nav_type, {})[(sv, epoch)] = row    # the last of a repeated record wins
            nav.origin[(sv, nav_type, epoch_key(epoch))] = f"{name}:{sv}"
        for nav_type, rows in sorted(groups.items()):
            fields = GEORINEX_FIELDS[sysid]
            raw = np.array([[row.get(f, 0.0) for f in fields] for row in rows.values()], dtype=np.float64)
            sv = np.array([key[0] for key in rows], dtype="U3")
            epoch = np.array([key[1] for key in rows], dtype="datetime64[s]")
            tab = record_table(sysid, nav_type, sv, epoch, raw, fields, name, nav)
            if len(tab):
                nav.tables[sysid] = SystemTable.concatenate([nav.tables[sysid], tab]) if sysid in nav.tables else tab
    for sysid, tab in list(nav.tables.items()):
        if sysid in KEPLER_SYSTEMS:
            fix_semicircles(tab, name, nav)
        nav.tables[sysid] = dedupe(tab)
    return nav
