"""georinex reads the numbers: records handed to it as a normalised RINEX 2/3 text (blank fields zero),
its dataset turned into record tables, and back to georinex-named dicts (for nav_write.write_rinex3_nav)."""
from __future__ import annotations

import datetime as _dt
import io
import math
import re
import warnings

import numpy as np

from ..nav_write import FIELDS
from .containers import SUPPORTED_SYSTEMS, NavData, SystemTable
from .tables import record_table

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


def fields_in_file_order(sysid: str) -> list[str]:
    """The georinex names of the fields of a record in file order (nav_write.FIELDS, spares as written)."""
    spares = iter(f for f in GEORINEX_FIELDS[sysid] if f.startswith("spare"))
    return [next(spares) if f.startswith("spare") else f for f in FIELDS[sysid]]


_ZERO_FIELD = " 0.000000000000E+00"
#: a Fortran real: mantissa, then an exponent with its letter, or without it when Fortran drops the letter of a
#: 3-digit exponent ("0.499063314480-269", seen in IGS brdc files of 2012)
_NUMBER = re.compile(r"^\s*[-+]?(\d+\.?\d*|\.\d+)([EeDd][-+]?\d+|[-+]\d{3})?\s*$")


def non_numeric_field(body: list[str], first_col: int, cont_col: int):
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


def georinex_parse(sysid, nav_type, bodies, major, first_line, name, nav: NavData) -> SystemTable | None:
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
    return record_table(sysid, nav_type, sv, times[ti], raw, fields, name, nav)


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
