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
import io
import logging
import math
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..time import BDT_MINUS_GPST_S, GPS_EPOCH, SECONDS_PER_DAY, SECONDS_PER_WEEK, GnssTime, gps_minus_utc_at_utc

log = logging.getLogger(__name__)


class NavDataWarning(UserWarning):
    """A navigation record dropped or a file's content corrected (the message names file and line)."""


#: systems whose broadcast ephemerides are Keplerian elements
KEPLER_SYSTEMS = "GECJI"
#: systems read by this module (SBAS records are skipped)
SUPPORTED_SYSTEMS = "GRECJI"

#: orbit radius (semi-major axis; GLONASS: position radius) of any GNSS satellite [m]: the lowest is GLONASS
#: at 25,510 km (GLONASS ICD 5.1 3.1), the highest the GEO/IGSO of BeiDou, QZSS and NavIC at 42,164 km;
#: outside 20,000..46,000 km a record is not an orbit of a navigation satellite
ORBIT_RADIUS_RANGE_M = (2.0e7, 4.6e7)
#: the most eccentric GNSS orbits are Galileo E14/E18 (e = 0.16, in the wrong orbit since 2014) and
#: QZSS QZO (0.075); a broadcast eccentricity beyond this is a corrupted record
MAX_ECCENTRICITY = 0.3

#: georinex field names per system (RINEX 3.04 tables A6-A14; same order as georinex nav3)
_GR_FIELDS_KEPLER_COMMON = [
    "SVclockBias", "SVclockDrift", "SVclockDriftRate", "IODE", "Crs", "DeltaN", "M0", "Cuc",
    "Eccentricity", "Cus", "sqrtA", "Toe", "Cic", "Omega0", "Cis", "Io", "Crc", "omega",
    "OmegaDot", "IDOT",
]
GEORINEX_FIELDS = {
    "G": _GR_FIELDS_KEPLER_COMMON + ["CodesL2", "GPSWeek", "L2Pflag", "SVacc", "health", "TGD", "IODC",
                                     "TransTime", "FitIntvl", "spare0", "spare1"],
    "J": _GR_FIELDS_KEPLER_COMMON + ["CodesL2", "GPSWeek", "L2Pflag", "SVacc", "health", "TGD", "IODC",
                                     "TransTime", "FitIntvl", "spare0", "spare1"],
    "E": ["IODnav" if f == "IODE" else f for f in _GR_FIELDS_KEPLER_COMMON]
    + ["DataSrc", "GALWeek", "spare0", "SISA", "health", "BGDe5a", "BGDe5b", "TransTime", "spare1", "spare2",
       "spare3"],
    "C": ["AODE" if f == "IODE" else f for f in _GR_FIELDS_KEPLER_COMMON]
    + ["spare0", "BDTWeek", "spare1", "SVacc", "SatH1", "TGD1", "TGD2", "TransTime", "AODC", "spare2", "spare3"],
    # georinex calls the NavIC week "BDTWeek" (it is the IRN week of RINEX 3.04 A14)
    "I": ["IODEC" if f == "IODE" else f for f in _GR_FIELDS_KEPLER_COMMON]
    + ["spare0", "BDTWeek", "spare1", "URA", "health", "TGD", "spare2", "TransTime", "spare3", "spare4", "spare5"],
    "R": ["SVclockBias", "SVrelFreqBias", "MessageFrameTime", "X", "dX", "dX2", "health", "Y", "dY", "dY2",
          "FreqNum", "Z", "dZ", "dZ2", "AgeOpInfo"],
}
#: continuation lines after the epoch line in RINEX 2/3 (RINEX 3.04 A6-A14)
_N_CONT = {"G": 7, "E": 7, "C": 7, "J": 7, "I": 7, "R": 3, "S": 3}
#: RINEX 4 message types whose body has the RINEX 3 layout
_RINEX4_TYPES = {"G": ("LNAV",), "J": ("LNAV",), "E": ("INAV", "FNAV"), "C": ("D1", "D2"), "I": ("LNAV",),
                 "R": ("FDMA",), "S": ("SBAS",)}

#: Keplerian record table (one row per broadcast record)
KEPLER_DTYPE = np.dtype([
    ("sv", "U3"), ("sys", "U1"), ("nav", "U4"),
    ("toc_sec", "i8"), ("toc_frac", "f8"), ("toe_sec", "i8"), ("toe_frac", "f8"),
    ("toe_tow_s", "f8"),      # toe as broadcast: seconds of the system's week (BDT for BeiDou)
    ("week", "i8"),           # continuous week of toe: GPS week (G, J, E, I as RINEX), BDT week (C)
    ("sqrt_a", "f8"), ("e", "f8"), ("i0", "f8"), ("omega0", "f8"), ("omega", "f8"), ("m0", "f8"),
    ("delta_n", "f8"), ("idot", "f8"), ("omega_dot", "f8"),
    ("cuc", "f8"), ("cus", "f8"), ("crc", "f8"), ("crs", "f8"), ("cic", "f8"), ("cis", "f8"),
    ("af0", "f8"), ("af1", "f8"), ("af2", "f8"),
    # group delay of the first frequency for this record's clock: GPS/QZSS TGD, Galileo I/NAV BGD(E1,E5b),
    # F/NAV BGD(E1,E5a), BeiDou TGD1 (B1I, clock refers to B3I), NavIC TGD
    ("tgd_s", "f8"),
    ("tgd2_s", "f8"),         # Galileo: the other BGD; BeiDou TGD2; 0 otherwise
    ("bgd_e1e5a_s", "f8"), ("bgd_e1e5b_s", "f8"),
    ("health", "i8"), ("iode", "i8"), ("iodc", "i8"),
    ("fit_h", "f8"),          # fit interval [h] resolved from the flag/hours field (G, J); NaN otherwise
    ("data_src", "i8"),       # Galileo data source bits (RINEX 3.04 A8); 0 otherwise
    ("ura", "f8"), ("tot_s", "f8"),
])
#: GLONASS record table
GLONASS_DTYPE = np.dtype([
    ("sv", "U3"), ("sys", "U1"), ("nav", "U4"),
    ("toc_sec", "i8"), ("toc_frac", "f8"),        # tb (epoch of the record) as GPS time
    ("toe_sec", "i8"), ("toe_frac", "f8"),        # same instant (reference time for selection)
    ("pos_m", "f8", (3,)), ("vel_mps", "f8", (3,)), ("acc_mps2", "f8", (3,)),  # PZ-90 ECEF
    ("tau_n_s", "f8"),        # tau_n (RINEX writes -tau_n)
    ("gamma_n", "f8"),
    ("tk_s", "f8"),           # message frame time [s of the UTC week] as RINEX
    ("health", "i8"), ("channel", "i8"), ("age_d", "f8"),
    ("iode", "i8"),           # tb index: minutes of GLONASS day / 15 (as RTKLIB)
])


@dataclass
class SystemTable:
    """Records of one system: the record table, georinex's raw values, and the epochs as written."""

    system: str
    rec: np.ndarray                # KEPLER_DTYPE or GLONASS_DTYPE rows
    raw: np.ndarray                # (n, len(fields)) georinex values (GLONASS X.. in m as georinex gives)
    fields: list[str]              # georinex names of raw's columns
    epoch: np.ndarray              # (n,) datetime64[s] record epoch as written (system time; UTC for GLONASS)

    def __len__(self) -> int:
        return len(self.rec)

    def take(self, idx) -> SystemTable:
        return SystemTable(self.system, self.rec[idx], self.raw[idx], list(self.fields), self.epoch[idx])

    @staticmethod
    def concatenate(parts: list[SystemTable]) -> SystemTable:
        parts = [p for p in parts if len(p)]
        if not parts:
            raise ValueError("no records to concatenate")
        return SystemTable(
            parts[0].system,
            np.concatenate([p.rec for p in parts]),
            np.concatenate([p.raw for p in parts]),
            list(parts[0].fields),
            np.concatenate([p.epoch for p in parts]),
        )


@dataclass
class NavData:
    """The content of one or more navigation files."""

    tables: dict[str, SystemTable] = field(default_factory=dict)
    #: header ionospheric coefficients keyed as RINEX 3 IONOSPHERIC CORR: GPSA, GPSB (Klobuchar alpha/beta),
    #: GAL (NeQuick-G ai0..ai2), QZSA, QZSB, BDSA, BDSB, IRNA, IRNB
    iono: dict[str, list[float]] = field(default_factory=dict)
    leap_seconds: int | None = None
    versions: list[float] = field(default_factory=list)
    paths: list[str] = field(default_factory=list)
    #: records not read, by reason (e.g. "RINEX4 G CNAV": 12)
    skipped: dict[str, int] = field(default_factory=dict)
    #: corrections applied to malformed input (also logged as warnings)
    notes: list[str] = field(default_factory=list)
    #: records dropped, one message each ("file:line: G05 2022-01-01 00:00:00 dropped: reason")
    dropped: list[str] = field(default_factory=list)
    #: where each record came from: (sv, nav type, epoch as written) -> "file:line"
    origin: dict[tuple, str] = field(default_factory=dict)

    def merge(self, other: NavData) -> NavData:
        tables = dict(self.tables)
        for s, tab in other.tables.items():
            tables[s] = SystemTable.concatenate([tables[s], tab]) if s in tables else tab
        iono = dict(other.iono)
        iono.update(self.iono)  # the first file's coefficients win
        skipped = dict(self.skipped)
        for k, v in other.skipped.items():
            skipped[k] = skipped.get(k, 0) + v
        return NavData(
            tables=tables,
            iono=iono,
            leap_seconds=self.leap_seconds if self.leap_seconds is not None else other.leap_seconds,
            versions=self.versions + other.versions,
            paths=self.paths + other.paths,
            skipped=skipped,
            notes=self.notes + other.notes,
            dropped=self.dropped + other.dropped,
            origin={**self.origin, **other.origin},
        )

    def drop(self, where: str, sv: str, epoch, reason: str) -> None:
        """Record (and warn) that the record of ``sv`` at ``epoch`` written at ``where`` is not used."""
        msg = f"{where}: {sv} record {str(epoch).replace('T', ' ')[:19]} dropped: {reason}"
        self.dropped.append(msg)
        warnings.warn(msg, NavDataWarning, stacklevel=3)

    def records(self, system: str) -> np.ndarray:
        """Record table of ``system`` (empty table of the right dtype when absent)."""
        if system in self.tables:
            return self.tables[system].rec
        return np.zeros(0, dtype=GLONASS_DTYPE if system == "R" else KEPLER_DTYPE)


def toe_time(rec: np.ndarray) -> GnssTime:
    """Reference time (toe, GLONASS tb) of record rows as GPS time."""
    return GnssTime(rec["toe_sec"], rec["toe_frac"])


def toc_time(rec: np.ndarray) -> GnssTime:
    """Clock reference time (toc, GLONASS tb) of record rows as GPS time."""
    return GnssTime(rec["toc_sec"], rec["toc_frac"])


# ----------------------------------------------------------------------------------------------
# reading
# ----------------------------------------------------------------------------------------------
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
        out.tables[s] = _dedupe(out.tables[s])
    return out


def read_nav_file(path, start: GnssTime | None = None, end: GnssTime | None = None,
                  systems: str = SUPPORTED_SYSTEMS, margin_s: float = 6 * 3600.0) -> NavData:
    """Read one RINEX 2/3/4 navigation file (plain or compressed)."""
    from georinex.rio import opener  # local import: georinex pulls in xarray

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"navigation file {path} does not exist")
    try:
        with opener(path) as f:
            text = f.read()
    except (OSError, EOFError, ValueError) as e:
        raise ValueError(f"{path}: cannot open as a RINEX navigation file ({e})") from e
    return parse_nav_text(text, name=str(path), start=start, end=end, systems=systems, margin_s=margin_s)


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
    iono, leap = _parse_header(lines[: hdr_end + 1], name, major)
    nav = NavData(iono=iono, leap_seconds=leap, versions=[version], paths=[name])

    if major == 2:
        file_sys = {"N": "G", "G": "R", "E": "E", "H": "S", "J": "J", "C": "C", "I": "I"}.get(first[20:21])
        if file_sys is None:
            raise ValueError(f"{name}, line 1: RINEX 2 navigation file type {first[20:21]!r} is not supported")
        records = _split_rinex2(lines, hdr_end + 1, file_sys, name)
    elif major == 3:
        records = _split_rinex3(lines, hdr_end + 1, name, version)
    else:
        records = _split_rinex4(lines, hdr_end + 1, name, nav)

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
        bad = _non_numeric_field(body, 22 if major == 2 else 23, 3 if major == 2 else 4)
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
        tab = _georinex_parse(sysid, nav_type, list(recs.values()), major, first, name, nav)
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
            _fix_semicircles(tab, name, nav)
    return nav


def nav_from_records(records_by_system: dict, header: dict | None = None, name: str = "<records>") -> NavData:
    """The NavData that reading the file ``write_rinex3_nav(path, records_by_system, header)`` gives,
    without writing or parsing text: every value rounded to the file's D19.12 (GLONASS in km, as written
    and read back), the epochs to the second, the ionospheric coefficients to D12.4, so the satellite
    states equal those of the round trip.  ``name`` stands for the file in messages."""
    from .nav_write import GLONASS_KM_FIELDS, d12, d19, iono_from_header, record_values

    header = dict(header or {})
    iono = {kind: [float(d12(v)) for v in vals] for kind, vals in iono_from_header(header).items()}
    leap = header.get("LEAP SECONDS")
    nav = NavData(iono=iono, leap_seconds=None if leap is None else int(leap), versions=[3.04], paths=[name])
    for sysid in SUPPORTED_SYSTEMS:
        recs = records_by_system.get(sysid) or []
        groups: dict[str, dict] = {}
        file_fields = _file_fields(sysid)
        for k, rec in enumerate(recs):
            sv, t, vals = record_values(sysid, rec, f"{name} record {k}")
            vals = [float(d19(v)) * (1000.0 if sysid == "R" and f in GLONASS_KM_FIELDS else 1.0)
                    for f, v in zip(file_fields, vals)]
            row = dict(zip(file_fields, vals))
            nav_type = _nav_type(sysid, sv, int(row.get("DataSrc", 0)))
            epoch = np.datetime64(t, "s")
            groups.setdefault(nav_type, {})[(sv, epoch)] = row    # the last of a repeated record wins
            nav.origin[(sv, nav_type, epoch_key(epoch))] = f"{name}:{sv}"
        for nav_type, rows in sorted(groups.items()):
            fields = GEORINEX_FIELDS[sysid]
            raw = np.array([[row.get(f, 0.0) for f in fields] for row in rows.values()], dtype=np.float64)
            sv = np.array([key[0] for key in rows], dtype="U3")
            epoch = np.array([key[1] for key in rows], dtype="datetime64[s]")
            tab = _table(sysid, nav_type, sv, epoch, raw, fields, name, nav)
            if len(tab):
                nav.tables[sysid] = SystemTable.concatenate([nav.tables[sysid], tab]) if sysid in nav.tables else tab
    for sysid, tab in list(nav.tables.items()):
        if sysid in KEPLER_SYSTEMS:
            _fix_semicircles(tab, name, nav)
        nav.tables[sysid] = _dedupe(tab)
    return nav


def _file_fields(sysid: str) -> list[str]:
    """The georinex names of the fields of a record in file order (nav_write.FIELDS, spares as written)."""
    from .nav_write import FIELDS

    spares = iter(f for f in GEORINEX_FIELDS[sysid] if f.startswith("spare"))
    return [next(spares) if f.startswith("spare") else f for f in FIELDS[sysid]]


def epoch_key(epoch) -> str:
    """A record epoch (datetime or datetime64) as 'YYYY-MM-DD HH:MM:SS' (dictionary key)."""
    return str(np.datetime64(epoch, "s")).replace("T", " ")


def _parse_float(s: str) -> float:
    s = s.strip().replace("D", "E").replace("d", "e")
    return float(s) if s else 0.0


def _parse_header(lines: list[str], name: str, major: int):
    iono: dict[str, list[float]] = {}
    leap = None
    for i, ln in enumerate(lines):
        label = ln[60:].strip()
        try:
            if label == "IONOSPHERIC CORR":
                kind = ln[:4].strip()
                n = 3 if kind == "GAL" else 4
                iono[kind] = [_parse_float(ln[5 + 12 * k: 17 + 12 * k]) for k in range(n)]
            elif label in ("ION ALPHA", "ION BETA"):
                vals = [_parse_float(ln[2 + 12 * k: 14 + 12 * k]) for k in range(4)]
                iono["GPSA" if label == "ION ALPHA" else "GPSB"] = vals
            elif label == "LEAP SECONDS":
                leap = int(ln[:6])
        except ValueError as e:
            raise ValueError(f"{name}, line {i + 1}: bad {label} header line ({e})") from None
    return iono, leap


_EPOCH3 = re.compile(r"^([GRECJIS])([ \d]\d) (\d{4}) ([ \d]\d) ([ \d]\d) ([ \d]\d) ([ \d]\d) ([ \d]\d)")


def _epoch3(line: str):
    m = _EPOCH3.match(line)
    if not m:
        return None
    s, prn, y, mo, d, hh, mm, ss = m.groups()
    try:
        ep = _dt.datetime(int(y), int(mo), int(d), int(hh), int(mm), int(ss))
    except ValueError:
        return None
    return s, f"{s}{int(prn):02d}", ep


def _nav_type_from_body(sysid: str, sv: str, body: list[str]) -> str:
    src = 0
    if sysid == "E":
        try:
            src = int(_parse_float(body[5][4 + 19: 4 + 38]))
        except (ValueError, IndexError):
            src = 0
    return _nav_type(sysid, sv, src)


def _nav_type(sysid: str, sv: str, data_src: int = 0) -> str:
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


def _split_rinex3(lines, i0, name, version):
    """(sys, sv, epoch, nav type, body lines, line number) of each RINEX 3 record."""
    out = []
    i = i0
    n = len(lines)
    while i < n:
        ln = lines[i]
        if not ln.strip():
            i += 1
            continue
        ep = _epoch3(ln)
        if ep is None:
            raise ValueError(f"{name}, line {i + 1}: expected a record epoch line, got {ln[:40]!r}")
        sysid, sv, epoch = ep
        j = i + 1
        while j < n and lines[j][:1] == " " and lines[j].strip():
            j += 1
        body = [ln] + lines[i + 1: j]
        need = _N_CONT[sysid] + 1
        if len(body) < need:
            raise ValueError(f"{name}, line {i + 1}: record of {sv} has {len(body)} lines, expected {need}")
        out.append((sysid, sv, epoch, _nav_type_from_body(sysid, sv, body), body[:need], i + 1))
        i = j
    return out


def _split_rinex4(lines, i0, name, nav: NavData):
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
                ep = _epoch3(body[0]) if body else None
                need = _N_CONT[sysid] + 1
                if ep is None or len(body) < need:
                    raise ValueError(f"{name}, line {i + 2}: bad {sv} {msg} record")
                out.append((sysid, ep[1], ep[2], msg if sysid in "EC" else _nav_type_from_body(sysid, sv, body),
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
                vals.append(_parse_float(ln[c: c + 19]))
            except ValueError:
                return
    if msg == "IFNV" and sysid == "E" and len(vals) >= 3:
        nav.iono.setdefault("GAL", vals[:3])
    elif len(vals) >= 8 and msg in ("LNAV", "D1D2"):
        key = {"G": "GPS", "J": "QZS", "C": "BDS", "I": "IRN"}.get(sysid)
        if key:
            nav.iono.setdefault(key + "A", vals[:4])
            nav.iono.setdefault(key + "B", vals[4:8])


_EPOCH2 = re.compile(r"^([ \d]\d) ([ \d]\d) ([ \d]\d) ([ \d]\d) ([ \d]\d) ([ \d]\d) ([ \d]\d\.\d)")


def _split_rinex2(lines, i0, sysid, name):
    out = []
    i = i0
    n = len(lines)
    need = _N_CONT[sysid] + 1
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
        out.append((sysid, sv, epoch, _nav_type_from_body(sysid, sv, [""] * 6) if sysid != "E" else "INAV",
                    body, i + 1))
        i += need
    return out


_ZERO_FIELD = " 0.000000000000E+00"
#: a Fortran real: mantissa, then an exponent with its letter, or without it when Fortran drops the letter of a
#: 3-digit exponent ("0.499063314480-269", seen in IGS brdc files of 2012)
_NUMBER = re.compile(r"^\s*[-+]?(\d+\.?\d*|\.\d+)([EeDd][-+]?\d+|[-+]\d{3})?\s*$")


def _non_numeric_field(body: list[str], first_col: int, cont_col: int):
    """(line offset in the record, field text) of the first 19-column field that is neither blank nor a
    number (RINEX D19.12 / E19.12 fields); None when every field reads."""
    for k, ln in enumerate(body):
        c0 = first_col if k == 0 else cont_col
        rest = ln.rstrip("\r\n")[c0:]
        for q in range(3 if k == 0 else 4):
            f = rest[19 * q: 19 * (q + 1)]
            if f.strip() and not _NUMBER.match(f):
                return k, f
    return None


def _normalise_body(body: list[str], first_col: int, cont_col: int) -> list[str]:
    """Pad lines to 80 columns and fill every blank 19-column field with zero."""
    out = []
    for k, ln in enumerate(body):
        ln = ln.rstrip("\n").ljust(80)
        c0 = first_col if k == 0 else cont_col
        nfield = 3 if k == 0 else 4
        head, rest = ln[:c0], ln[c0:]
        slots = [rest[19 * q: 19 * (q + 1)] for q in range(nfield)]
        slots = [s if s.strip() else _ZERO_FIELD for s in slots]
        out.append(head + "".join(slots))
    return out


def _georinex_parse(sysid, nav_type, bodies, major, first_line, name, nav: NavData) -> SystemTable | None:
    import georinex

    if major == 2:
        header = first_line[:60].ljust(60) + "RINEX VERSION / TYPE"
        norm = [ln for b in bodies for ln in _normalise_body(b, 22, 3)]
    else:
        header = "     3.04           N: GNSS NAV DATA    M: MIXED            RINEX VERSION / TYPE"
        norm = [ln for b in bodies for ln in _normalise_body(b, 23, 4)]
    text = "\n".join([header, " " * 60 + "END OF HEADER"] + norm) + "\n"
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ds = georinex.rinexnav(io.StringIO(text))
    except Exception as e:  # georinex raises assorted types on malformed records
        raise ValueError(f"{name}: georinex could not read the {sysid} {nav_type} records ({type(e).__name__}: {e})"
                         ) from e
    return _dataset_to_table(ds, sysid, nav_type, name, nav)


def _dataset_to_table(ds, sysid, nav_type, name, nav: NavData) -> SystemTable | None:
    fields = [f for f in GEORINEX_FIELDS[sysid] if f in ds.data_vars]
    key = "X" if sysid == "R" else "sqrtA"
    if key not in ds.data_vars:
        return None
    times = ds["time"].values.astype("datetime64[s]")
    svs = ds["sv"].values
    valid = ds[key].values  # (time, sv)
    ti, si = np.nonzero(np.isfinite(valid))
    if ti.size == 0:
        return None
    raw = np.stack([ds[f].values[ti, si] for f in fields], axis=1).astype(np.float64)
    sv = np.array([str(s)[:3] for s in svs[si]])
    return _table(sysid, nav_type, sv, times[ti], raw, fields, name, nav)


def _table(sysid, nav_type, sv, epoch, raw, fields, name, nav: NavData) -> SystemTable:
    """The SystemTable of records (sv, epoch as written, georinex values ``raw`` (n, fields)); records that
    cannot be orbits are dropped (nav.drop)."""
    if sysid == "R":
        rec, why = _glonass_table(sv, epoch, raw, fields, name)
    else:
        rec, why = _kepler_table(sysid, nav_type, sv, epoch, raw, fields, name)
    keep = np.ones(len(rec), dtype=bool)
    for k, reason in why.items():
        keep[k] = False
        nav.drop(nav.origin.get((str(sv[k]), nav_type, epoch_key(epoch[k])), name), str(sv[k]), epoch[k], reason)
    rec, raw, epoch = rec[keep], raw[keep], epoch[keep]
    order = np.lexsort((rec["toe_sec"], rec["sv"]))
    return SystemTable(sysid, rec[order], raw[order], fields, epoch[order])


#: nominal inclination [rad] of the non-GEO orbits per system (GPS 55, Galileo 56, BeiDou MEO/IGSO 55,
#: QZSS IGSO/QZO 41, NavIC GSO 29 deg): tells radians from semicircles
_NOMINAL_INCLINATION_RAD = {"G": 0.96, "E": 0.98, "C": 0.96, "J": 0.72, "I": 0.51}
_ANGLE_FIELDS = ("m0", "omega0", "i0", "omega", "delta_n", "omega_dot", "idot")
_ANGLE_RAW = ("M0", "Omega0", "Io", "omega", "DeltaN", "OmegaDot", "IDOT")


def _fix_semicircles(tab: SystemTable, name: str, nav: NavData) -> None:
    """Some writers put angles in semicircles instead of radians (seen: BeiDou records of
    gl_Rinex/NMA station files, 2022).  Detected from the inclinations of the non-GEO
    records (median nearer nominal/pi than nominal) and converted in place."""
    inc = np.abs(tab.rec["i0"])
    nongeo = inc > 0.1
    if not np.any(nongeo):
        return
    nominal = _NOMINAL_INCLINATION_RAD[tab.system]
    med = float(np.median(inc[nongeo]))
    if abs(med - nominal / np.pi) < abs(med - nominal):
        for f in _ANGLE_FIELDS:
            tab.rec[f] *= np.pi
        for f in _ANGLE_RAW:
            if f in tab.fields:
                tab.raw[:, tab.fields.index(f)] *= np.pi
        msg = (f"{name}: {tab.system} angles are in semicircles, not radians as RINEX requires "
               f"(median inclination {med:.3f}); multiplied by pi")
        log.warning(msg)
        nav.notes.append(msg)


def _epoch_gps_seconds(epoch: np.ndarray, scale: str) -> np.ndarray:
    """Integer GPS seconds of naive epochs (datetime64[s]) read in ``scale``."""
    sec = (epoch - np.datetime64(GPS_EPOCH, "s")).astype(np.int64)
    if scale == "BDT":
        return sec - BDT_MINUS_GPST_S
    if scale == "UTC":
        return sec + np.asarray(gps_minus_utc_at_utc(sec), dtype=np.int64)
    return sec


def _col(raw, fields, name, default=0.0):
    if name in fields:
        v = raw[:, fields.index(name)]
        return np.where(np.isfinite(v), v, default)
    return np.full(raw.shape[0], default, dtype=np.float64)


def _gps_fit_hours(value: np.ndarray, iodc: np.ndarray, sysid: str) -> np.ndarray:
    """Fit interval [h] from RINEX's field: hours (RINEX 3) or a 0/1 flag (some writers, RINEX 3 QZSS).

    GPS flag 0 -> 4 h; flag 1 -> by IODC, IS-GPS-200N 20.3.4.4 table 20-XII
    (240-247: 8 h, 248-255 and 496: 14 h, 497-503 and 1021-1023: 26 h, else 6 h).
    QZSS flag 0 -> 2 h, 1 -> 4 h (IS-QZSS-PNT-005 4.1.2.7 / RINEX 3.04 A7).
    """
    v = np.asarray(value, dtype=np.float64)
    if sysid == "J":
        return np.where(v >= 2, v, np.where(v == 1, 4.0, 2.0))
    flag1 = np.select(
        [(iodc >= 240) & (iodc <= 247), ((iodc >= 248) & (iodc <= 255)) | (iodc == 496),
         ((iodc >= 497) & (iodc <= 503)) | ((iodc >= 1021) & (iodc <= 1023))],
        [8.0, 14.0, 26.0], default=6.0)
    return np.where(v >= 2, v, np.where(v == 1, flag1, 4.0))


def _kepler_table(sysid, nav_type, sv, epoch, raw, fields, name) -> np.ndarray:
    n = len(sv)
    rec = np.zeros(n, dtype=KEPLER_DTYPE)
    rec["sv"] = sv
    rec["sys"] = sysid
    rec["nav"] = nav_type
    scale = "BDT" if sysid == "C" else "GPS"  # GST, QZST, IRNT count like GPST
    toc = _epoch_gps_seconds(epoch, scale)
    rec["toc_sec"] = toc
    # toe: the instant with broadcast time of week Toe nearest to toc (weeks of the system's scale)
    toe_tow = _col(raw, fields, "Toe")
    why: dict[int, str] = {}
    bad_toe = ~np.isfinite(toe_tow) | (toe_tow < 0) | (toe_tow > SECONDS_PER_WEEK)
    for k in np.flatnonzero(bad_toe).tolist():
        why[k] = f"Toe {toe_tow[k]} s is outside 0..604800 s"
    toe_tow = np.where(bad_toe, 0.0, toe_tow)
    toc_scale = toc + (BDT_MINUS_GPST_S if scale == "BDT" else 0)
    week = np.floor_divide(toc_scale, SECONDS_PER_WEEK)
    tow_toc = toc_scale - week * SECONDS_PER_WEEK
    week = week + np.where(toe_tow - tow_toc > SECONDS_PER_WEEK / 2, -1, 0) \
        + np.where(toe_tow - tow_toc < -SECONDS_PER_WEEK / 2, 1, 0)
    toe_whole = np.floor(toe_tow)
    toe_scale = week * SECONDS_PER_WEEK + toe_whole.astype(np.int64)
    rec["toe_sec"] = toe_scale - (BDT_MINUS_GPST_S if scale == "BDT" else 0)
    rec["toe_frac"] = toe_tow - toe_whole
    rec["toe_tow_s"] = toe_tow
    rec["week"] = week - (1356 if scale == "BDT" else 0)  # BDT week 0 = GPS week 1356
    for mine, theirs in (("sqrt_a", "sqrtA"), ("e", "Eccentricity"), ("i0", "Io"), ("omega0", "Omega0"),
                         ("omega", "omega"), ("m0", "M0"), ("delta_n", "DeltaN"), ("idot", "IDOT"),
                         ("omega_dot", "OmegaDot"), ("cuc", "Cuc"), ("cus", "Cus"), ("crc", "Crc"),
                         ("crs", "Crs"), ("cic", "Cic"), ("cis", "Cis"), ("af0", "SVclockBias"),
                         ("af1", "SVclockDrift"), ("af2", "SVclockDriftRate"), ("tot_s", "TransTime")):
        rec[mine] = _col(raw, fields, theirs)
    if sysid in "GJ":
        rec["tgd_s"] = _col(raw, fields, "TGD")
        rec["health"] = _col(raw, fields, "health").astype(np.int64)
        rec["iode"] = _col(raw, fields, "IODE", -1).astype(np.int64)
        rec["iodc"] = _col(raw, fields, "IODC", -1).astype(np.int64)
        rec["fit_h"] = _gps_fit_hours(_col(raw, fields, "FitIntvl"), rec["iodc"], sysid)
        rec["ura"] = _col(raw, fields, "SVacc")
    elif sysid == "E":
        e5a, e5b = _col(raw, fields, "BGDe5a"), _col(raw, fields, "BGDe5b")
        rec["bgd_e1e5a_s"], rec["bgd_e1e5b_s"] = e5a, e5b
        fnav = nav_type == "FNAV"
        rec["tgd_s"] = e5a if fnav else e5b
        rec["tgd2_s"] = e5b if fnav else e5a
        rec["health"] = _col(raw, fields, "health").astype(np.int64)
        rec["iode"] = _col(raw, fields, "IODnav", -1).astype(np.int64)
        rec["iodc"] = -1
        rec["fit_h"] = np.nan
        rec["data_src"] = _col(raw, fields, "DataSrc").astype(np.int64)
        rec["ura"] = _col(raw, fields, "SISA")
    elif sysid == "C":
        rec["tgd_s"] = _col(raw, fields, "TGD1")
        rec["tgd2_s"] = _col(raw, fields, "TGD2")
        rec["health"] = _col(raw, fields, "SatH1").astype(np.int64)
        rec["iode"] = _col(raw, fields, "AODE", -1).astype(np.int64)
        rec["iodc"] = _col(raw, fields, "AODC", -1).astype(np.int64)
        rec["fit_h"] = np.nan
        rec["ura"] = _col(raw, fields, "SVacc")
    elif sysid == "I":
        rec["tgd_s"] = _col(raw, fields, "TGD")
        rec["health"] = _col(raw, fields, "health").astype(np.int64)
        rec["iode"] = _col(raw, fields, "IODEC", -1).astype(np.int64)
        rec["iodc"] = -1
        rec["fit_h"] = np.nan
        rec["ura"] = _col(raw, fields, "URA")
    a_m = rec["sqrt_a"] ** 2
    bad = ~((a_m >= ORBIT_RADIUS_RANGE_M[0]) & (a_m <= ORBIT_RADIUS_RANGE_M[1]) & (rec["e"] >= 0)
            & (rec["e"] < MAX_ECCENTRICITY))
    for k in np.flatnonzero(bad).tolist():
        why.setdefault(k, f"impossible orbit for a GNSS satellite (sqrtA {rec['sqrt_a'][k]:.6g} m^0.5, "
                          f"e {rec['e'][k]:.6g})")
    return rec, why


def _glonass_table(sv, epoch, raw, fields, name) -> np.ndarray:
    n = len(sv)
    rec = np.zeros(n, dtype=GLONASS_DTYPE)
    rec["sv"] = sv
    rec["sys"] = "R"
    rec["nav"] = "FDMA"
    # RINEX 3.04 A10: epoch (tb) in UTC
    t_gps = _epoch_gps_seconds(epoch, "UTC")
    rec["toc_sec"] = t_gps
    rec["toe_sec"] = t_gps
    rec["pos_m"] = np.stack([_col(raw, fields, k) for k in ("X", "Y", "Z")], axis=1)  # georinex: km -> m
    rec["vel_mps"] = np.stack([_col(raw, fields, k) for k in ("dX", "dY", "dZ")], axis=1)
    rec["acc_mps2"] = np.stack([_col(raw, fields, k) for k in ("dX2", "dY2", "dZ2")], axis=1)
    rec["tau_n_s"] = -_col(raw, fields, "SVclockBias")   # RINEX writes -TauN
    rec["gamma_n"] = _col(raw, fields, "SVrelFreqBias")
    rec["tk_s"] = _col(raw, fields, "MessageFrameTime")
    rec["health"] = _col(raw, fields, "health").astype(np.int64)
    rec["channel"] = _col(raw, fields, "FreqNum").astype(np.int64)
    rec["age_d"] = _col(raw, fields, "AgeOpInfo")
    sec_utc = (epoch - np.datetime64(GPS_EPOCH, "s")).astype(np.int64)
    rec["iode"] = ((sec_utc + 3 * 3600) % SECONDS_PER_DAY) // 900  # tb index in GLONASS day
    r = np.linalg.norm(rec["pos_m"], axis=1)
    bad = ~((r >= ORBIT_RADIUS_RANGE_M[0]) & (r <= ORBIT_RADIUS_RANGE_M[1]))
    why = {k: f"impossible orbit for a GNSS satellite (position radius {r[k]:.6g} m)"
           for k in np.flatnonzero(bad).tolist()}
    return rec, why


def _dedupe(tab: SystemTable) -> SystemTable:
    """Drop repeated records (same sv, message type, reference time and issue of data) across files."""
    rec = tab.rec
    if len(rec) < 2:
        return tab
    keys = np.rec.fromarrays([rec["sv"], rec["nav"], rec["toe_sec"], rec["iode"]])
    _, first = np.unique(keys, return_index=True)
    first = np.sort(first)
    out = tab.take(first)
    order = np.lexsort((out.rec["toe_sec"], out.rec["sv"]))
    return out.take(order)


# ----------------------------------------------------------------------------------------------
# back to georinex-named dicts (for core/rinex/nav_write.write_rinex3_nav)
# ----------------------------------------------------------------------------------------------
def records_as_dicts(nav: NavData, systems: str = SUPPORTED_SYSTEMS) -> dict[str, list[dict]]:
    """Records as ``{system letter: [dict, ...]}`` for ``write_rinex3_nav``.

    Each dict has ``"sv"`` (``"G05"``), ``"time"`` (the record epoch toc as a
    naive ``datetime`` in the system's time scale as RINEX 3 writes it: GPST,
    GST, BDT, QZST, IRNT; UTC for GLONASS) and every georinex variable of that
    system (``GEORINEX_FIELDS``) with georinex's value and unit: GLONASS
    ``X``..``dZ2`` in metres, m/s, m/s^2 (the writer divides by 1000).
    """
    out: dict[str, list[dict]] = {}
    for s, tab in nav.tables.items():
        if s not in systems:
            continue
        lst = []
        for k in range(len(tab)):
            d = {"sv": str(tab.rec["sv"][k]), "time": tab.epoch[k].astype("datetime64[s]").astype(_dt.datetime)}
            for j, f in enumerate(tab.fields):
                v = float(tab.raw[k, j])
                d[f] = 0.0 if not math.isfinite(v) else v
            lst.append(d)
        out[s] = lst
    return out


def header_dict(nav: NavData) -> dict:
    """Header content keyed as georinex's navheader3: ``"IONOSPHERIC CORR"`` (dict kind -> values),
    ``"LEAP SECONDS"`` (int or None), ``"version"`` (3.04)."""
    return {"IONOSPHERIC CORR": {k: list(v) for k, v in nav.iono.items()},
            "LEAP SECONDS": nav.leap_seconds, "version": 3.04}
