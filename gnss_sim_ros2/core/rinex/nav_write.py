"""RINEX 3.04 (mixed) navigation file writer.

Format: IGS/RTCM "RINEX The Receiver Independent Exchange Format Version
3.04" (2018), section 5.4 and tables A5 (header), A6 (GPS), A8 (Galileo),
A10 (GLONASS), A12 (QZSS), A14 (BeiDou), A16 (NavIC).  Numbers in D19.12
written with an ``E`` exponent, epoch line ``A1,I2.2,1X,I4,5(1X,I2.2),3D19.12``
then ``4X,4D19.12`` per broadcast orbit line: 7 more lines for the Kepler
systems (G, E, C, J, I), 3 for GLONASS.

Records are dicts keyed with georinex's variable names of each system (see
``FIELDS``), plus ``"sv"`` (``"G05"``) and ``"time"`` (toc as a naive datetime,
or numpy datetime64, in the system's own time scale as RINEX writes it: GPST,
GST, BDT, QZST, IRNT; UTC for GLONASS).  Units are georinex's: seconds, radians,
metres, and GLONASS ``X``..``dZ2`` in m, m/s, m/s^2 (written in km as RINEX
requires).  Missing or NaN fields are written as 0.0, including the spare
fields: a blank field inside a record makes georinex 1.16 discard the whole
record, and zero is what the spare means.

Header dict (all keys optional):
- ``"IONOSPHERIC CORR"``: ``{"GPSA": [a0..a3], "GPSB": [...], "GAL": [ai0, ai1, ai2],
  "BDSA"/"BDSB", "QZSA"/"QZSB", "IRNA"/"IRNB": [...]}`` (georinex ``navheader3``
  layout); georinex dataset attrs ``ionospheric_corr_GPS`` (8 values),
  ``ionospheric_corr_GAL`` (3), ``_BDS``, ``_QZS``, ``_IRN`` are accepted too;
- ``"TIME SYSTEM CORR"``: ``{"GPUT": [a0_s, a1_sps, t_ref_s, week], ...}``;
- ``"LEAP SECONDS"``: int (GPS - UTC) or None;
- ``"program"``, ``"run_by"``, ``"date"`` (datetime or text), ``"comments"``: list of str.
"""
from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

#: RINEX 3.04 record layout: georinex variable names in file order (tables A6-A16), per system.
#: "spare*" are written as 0.0; the fields after the last named one on the last line are omitted.
_KEPLER_HEAD = [
    "SVclockBias", "SVclockDrift", "SVclockDriftRate",
    "{iod}", "Crs", "DeltaN", "M0",
    "Cuc", "Eccentricity", "Cus", "sqrtA",
    "Toe", "Cic", "Omega0", "Cis",
    "Io", "Crc", "omega", "OmegaDot",
]


def _kepler(iod: str, tail: list[str]) -> list[str]:
    return [f.replace("{iod}", iod) for f in _KEPLER_HEAD] + tail


FIELDS: dict[str, list[str]] = {
    # GPS LNAV, table A6; QZSS, table A12 (same layout)
    "G": _kepler("IODE", ["IDOT", "CodesL2", "GPSWeek", "L2Pflag",
                          "SVacc", "health", "TGD", "IODC",
                          "TransTime", "FitIntvl"]),
    "J": _kepler("IODE", ["IDOT", "CodesL2", "GPSWeek", "L2Pflag",
                          "SVacc", "health", "TGD", "IODC",
                          "TransTime", "FitIntvl"]),
    # Galileo, table A8 (GAL week aligned to GPS week)
    "E": _kepler("IODnav", ["IDOT", "DataSrc", "GALWeek", "spare0",
                            "SISA", "health", "BGDe5a", "BGDe5b",
                            "TransTime"]),
    # BeiDou, table A14 (BDT week)
    "C": _kepler("AODE", ["IDOT", "spare0", "BDTWeek", "spare1",
                          "SVacc", "SatH1", "TGD1", "TGD2",
                          "TransTime", "AODC"]),
    # NavIC, table A16 (georinex names the IRN week "BDTWeek"; "IRNWeek" is accepted)
    "I": _kepler("IODEC", ["IDOT", "spare0", "BDTWeek", "spare1",
                           "URA", "health", "TGD", "spare2",
                           "TransTime"]),
    # GLONASS, table A10: -TauN, +GammaN, message frame time; X, Xdot, Xacc, health; ...
    "R": ["SVclockBias", "SVrelFreqBias", "MessageFrameTime",
          "X", "dX", "dX2", "health",
          "Y", "dY", "dY2", "FreqNum",
          "Z", "dZ", "dZ2", "AgeOpInfo"],
}
_ALIASES = {("I", "BDTWeek"): ("IRNWeek",)}
#: GLONASS fields RINEX writes in km (georinex gives them in m)
GLONASS_KM_FIELDS = {"X", "dX", "dX2", "Y", "dY", "dY2", "Z", "dZ", "dZ2"}
_SYSTEM_NAMES = {"G": "GPS", "R": "GLONASS", "E": "GALILEO", "C": "BEIDOU", "J": "QZSS", "I": "IRNSS", "M": "MIXED"}
_IONO_ORDER = ("GAL", "GPSA", "GPSB", "QZSA", "QZSB", "BDSA", "BDSB", "IRNA", "IRNB")
_IONO_ATTRS = {"GPS": ("GPSA", "GPSB"), "QZS": ("QZSA", "QZSB"), "BDS": ("BDSA", "BDSB"), "IRN": ("IRNA", "IRNB")}


def d19(value) -> str:
    """One RINEX D19.12 field with an 'E' exponent: ' 5.035293288529E-04' (19 characters)."""
    v = float(value) if value is not None else 0.0
    if not math.isfinite(v) or abs(v) < 1e-99:  # NaN = missing; 3-digit exponents do not fit
        v = 0.0
    s = f"{v:19.12E}"
    if len(s) != 19:
        raise ValueError(f"value {value!r} does not fit the RINEX D19.12 field")
    return s


def d12(value) -> str:
    """One D12.4 field (IONOSPHERIC CORR)."""
    v = float(value)
    s = f"{v:12.4E}"
    if len(s) != 12:
        raise ValueError(f"ionospheric coefficient {value!r} does not fit D12.4")
    return s


def _header_line(content: str, label: str) -> str:
    if len(content) > 60:
        raise ValueError(f"RINEX header line {label!r} content longer than 60 characters: {content!r}")
    return f"{content:<60}{label:<20}".rstrip() + "\n"


def _as_datetime(t, where: str) -> _dt.datetime:
    if isinstance(t, _dt.datetime):
        return t.replace(tzinfo=None)
    if isinstance(t, np.datetime64):
        return t.astype("datetime64[us]").astype(_dt.datetime)
    if hasattr(t, "to_pydatetime"):
        return t.to_pydatetime().replace(tzinfo=None)
    raise ValueError(f"{where}: 'time' must be a datetime or numpy datetime64, got {type(t).__name__}")


def iono_from_header(header: Mapping) -> dict[str, list[float]]:
    out: dict[str, list[float]] = {}
    for kind, vals in dict(header.get("IONOSPHERIC CORR") or {}).items():
        out[str(kind).strip().upper()] = [float(v) for v in vals]
    for sysname, (a, b) in _IONO_ATTRS.items():
        vals = header.get(f"ionospheric_corr_{sysname}")
        if vals is not None:
            vals = [float(v) for v in np.ravel(vals)]
            if len(vals) != 8:
                raise ValueError(f"header ionospheric_corr_{sysname}: expected 8 coefficients, got {len(vals)}")
            out.setdefault(a, vals[:4])
            out.setdefault(b, vals[4:])
    if header.get("ionospheric_corr_GAL") is not None:
        out.setdefault("GAL", [float(v) for v in np.ravel(header["ionospheric_corr_GAL"])])
    for kind, vals in out.items():
        if kind not in _IONO_ORDER:
            raise ValueError(f"header IONOSPHERIC CORR: unknown correction type {kind!r}; "
                             f"expected one of {_IONO_ORDER}")
        n = 3 if kind == "GAL" else 4
        if len(vals) != n:
            raise ValueError(f"header IONOSPHERIC CORR {kind}: expected {n} coefficients, got {len(vals)}")
    return out


def _header(systems: str, header: Mapping) -> list[str]:
    sysletter = systems if len(systems) == 1 else "M"
    lines = [_header_line(f"{3.04:9.2f}{'':11s}N: GNSS NAV DATA    {sysletter}: {_SYSTEM_NAMES[sysletter]:<17s}",
                          "RINEX VERSION / TYPE")]
    date = header.get("date") or _dt.datetime.now(_dt.timezone.utc).replace(tzinfo=None)
    if isinstance(date, _dt.datetime):
        date = date.strftime("%Y%m%d %H%M%S") + " UTC"
    lines.append(_header_line(f"{str(header.get('program', 'gnss_sim'))[:20]:<20}"
                              f"{str(header.get('run_by', ''))[:20]:<20}{str(date)[:20]:<20}",
                              "PGM / RUN BY / DATE"))
    for c in header.get("comments", ()) or ():
        for k in range(0, max(len(c), 1), 60):
            lines.append(_header_line(c[k:k + 60], "COMMENT"))
    iono = iono_from_header(header)
    for kind in _IONO_ORDER:
        if kind in iono:
            vals = list(iono[kind]) + ([0.0] if kind == "GAL" else [])
            # A4,1X,4D12.4 (RINEX 3.04 table A5); time mark / SV id left blank
            lines.append(_header_line(f"{kind:<4} " + "".join(d12(v) for v in vals), "IONOSPHERIC CORR"))
    for kind, vals in dict(header.get("TIME SYSTEM CORR") or {}).items():
        try:
            a0, a1, tref, week = vals[:4]
        except (TypeError, ValueError) as exc:
            raise ValueError(f"header TIME SYSTEM CORR {kind}: expected [a0, a1, t_ref, week], got {vals!r}") from exc
        # A4,1X,D17.10,D16.9,1X,I6,1X,I4 (table A5)
        a0s, a1s = f"{float(a0):17.10E}", f"{float(a1):16.9E}"
        lines.append(_header_line(f"{kind:<4} {a0s}{a1s} {int(tref):6d} {int(week):4d}", "TIME SYSTEM CORR"))
    leap = header.get("LEAP SECONDS", header.get("leap_seconds"))
    if leap is not None:
        if isinstance(leap, (list, tuple)):
            leap = leap[0]
        lines.append(_header_line(f"{int(leap):6d}", "LEAP SECONDS"))
    lines.append(_header_line("", "END OF HEADER"))
    return lines


def _value(rec: Mapping, sysid: str, name: str):
    if name.startswith("spare"):
        return float(rec.get(name, 0.0) or 0.0)
    if name in rec:
        return rec[name]
    for alias in _ALIASES.get((sysid, name), ()):
        if alias in rec:
            return rec[alias]
    return 0.0


def record_values(sysid: str, rec: Mapping, where: str = "record") -> tuple[str, _dt.datetime, list[float]]:
    """(sv, epoch, field values) of one record as the file writes them: the epoch rounded to the second
    (RINEX 3 nav has I2.2 seconds), the values in FIELDS order and RINEX units (GLONASS km), not yet
    rounded to D19.12."""
    if sysid not in FIELDS:
        raise ValueError(f"{where}: system {sysid!r} not supported (expected one of {''.join(FIELDS)})")
    sv = str(rec.get("sv", ""))
    if len(sv) != 3 or sv[0] != sysid or not sv[1:].isdigit():
        raise ValueError(f"{where}: sv {sv!r} is not a {sysid} satellite id like {sysid}05")
    t = _as_datetime(rec.get("time"), f"{where} ({sv})")
    vals = []
    for name in FIELDS[sysid]:
        v = _value(rec, sysid, name)
        try:
            v = float(v)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{where} ({sv}): field {name!r} is not a number: {v!r}") from exc
        if not math.isfinite(v):
            v = 0.0
        if sysid == "R" and name in GLONASS_KM_FIELDS:
            v = v / 1000.0  # georinex units (m) -> RINEX km
        vals.append(v)
    # integer-second epochs only in RINEX 3 nav (I2.2 seconds)
    sec = t.second + (1 if t.microsecond >= 500000 else 0)
    t = t.replace(second=0, microsecond=0) + _dt.timedelta(seconds=sec)
    return sv, t, vals


def format_record(sysid: str, rec: Mapping, where: str = "record") -> str:
    """Text (8 or 4 lines) of one navigation record of system ``sysid``."""
    sv, t, vals = record_values(sysid, rec, where)
    out = [f"{sv} {t.year:4d} {t.month:02d} {t.day:02d} {t.hour:02d} {t.minute:02d} {t.second:02d}"
           + "".join(d19(v) for v in vals[:3])]
    rest = vals[3:]
    for k in range(0, len(rest), 4):
        out.append("    " + "".join(d19(v) for v in rest[k:k + 4]))
    return "\n".join(out) + "\n"


def write_rinex3_nav(path, records_by_system: Mapping[str, Sequence[Mapping]], header: Mapping | None = None) -> Path:
    """Write a RINEX 3.04 navigation file (mixed when several systems have records).

    ``records_by_system``: ``{"G": [record dict, ...], "R": [...], ...}``;
    records are written sorted by epoch, then satellite.  Returns the path.
    """
    header = dict(header or {})
    path = Path(path)
    systems = "".join(s for s in "GRECJI" if records_by_system.get(s))
    unknown = set(records_by_system) - set(FIELDS)
    if unknown:
        raise ValueError(f"records_by_system: unsupported system(s) {sorted(unknown)}; expected keys among GRECJI")
    if not systems:
        raise ValueError("records_by_system has no records to write")
    items = []
    for s in systems:
        for k, rec in enumerate(records_by_system[s]):
            where = f"records_by_system[{s!r}][{k}]"
            text = format_record(s, rec, where)
            items.append((_as_datetime(rec.get("time"), where), str(rec["sv"]), text))
    items.sort(key=lambda x: (x[0], "GRECJI".index(x[1][0]), x[1]))
    lines = _header(systems, header)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", encoding="ascii", newline="\n") as f:
        f.writelines(lines)
        for _, _, text in items:
            f.write(text)
    return path


def records_from_georinex(ds) -> dict[str, list[dict]]:
    """Records of a georinex navigation Dataset as ``{system: [dict]}`` for :func:`write_rinex3_nav`.

    Satellites named ``G01_1`` (georinex's copies of repeated epochs) keep
    their real id; all-NaN (absent) records are skipped.
    """
    out: dict[str, list[dict]] = {}
    names = [str(v) for v in ds.data_vars]
    times = ds["time"].values
    arrays = {n: ds[n].values for n in names}
    for j, svname in enumerate(ds["sv"].values):
        sv = str(svname).split("_")[0]
        s = sv[0]
        if s not in FIELDS:
            continue
        for i, t in enumerate(times):
            row = {n: float(arrays[n][i, j]) for n in names if arrays[n].ndim == 2}
            if all(not math.isfinite(v) for v in row.values()):
                continue
            row = {n: (v if math.isfinite(v) else 0.0) for n, v in row.items()}
            row["sv"] = sv
            row["time"] = np.datetime64(t, "us").astype(_dt.datetime)
            out.setdefault(s, []).append(row)
    return out
