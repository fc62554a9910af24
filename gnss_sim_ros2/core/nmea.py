"""NMEA 0183 sentences (GGA, RMC, GSA, GSV) of a simulated receiver.

Conventions of NMEA 0183 version 4.10 (and 4.11 for QZSS/NavIC):
- talker ``GP`` when only GPS is used, ``GN`` for a multi-constellation fix
  (GGA, RMC, GSA); GSV is per constellation: GP (GPS, SBAS), GL (GLONASS),
  GA (Galileo), GB (BeiDou), GQ (QZSS), GI (NavIC).
- satellite numbers: GPS 1-32, SBAS 33-64 (PRN - 87), GLONASS 65-96
  (slot + 64), Galileo, BeiDou, QZSS, NavIC: their PRN (1-36, 1-63, 1-10, 1-14).
- GSA carries a system ID field (1 GPS, 2 GLONASS, 3 Galileo, 4 BeiDou,
  5 QZSS, 6 NavIC) with one GSA per system; GSV carries a signal ID field
  (default the L1-band civil signal of each system); RMC carries the
  navigational status field.
- latitude ``ddmm.mmmmm``, longitude ``dddmm.mmmmm`` (5 decimals of minutes =
  1.9 cm), time of day UTC ``hhmmss.ss``, RMC date ``ddmmyy``, checksum = XOR
  of the characters between ``$`` and ``*`` as 2 upper-case hex digits.

Sentences are returned without the trailing CR LF; :func:`join_sentences`
adds it.  GGA altitude is above mean sea level: ``h_ellipsoid - geoid_sep_m``;
no geoid model is applied here (geoid_sep_m defaults to 0, i.e. the altitude
field then holds the ellipsoidal height, and the separation field says 0).
"""
from __future__ import annotations

import datetime as _dt
import functools
import math
import operator
from collections.abc import Sequence

import numpy as np

from .time import GPS_EPOCH, GnssTime

#: GSV talker of each RINEX system letter (NMEA 0183 4.11)
GSV_TALKER = {"G": "GP", "S": "GP", "R": "GL", "E": "GA", "C": "GB", "J": "GQ", "I": "GI"}
#: GSA/GSV system ID (NMEA 0183 4.10 table; QZSS 5 and NavIC 6 from 4.11); SBAS reports under GPS
SYSTEM_ID = {"G": 1, "S": 1, "R": 2, "E": 3, "C": 4, "J": 5, "I": 6}
#: GSV signal ID of the L1-band civil signal (NMEA 0183 4.10/4.11): GPS L1 C/A 1, GLONASS G1 C/A 1,
#: Galileo E1 B/C 7, BeiDou B1I 1, QZSS L1 C/A 1, NavIC L5 SPS 1
DEFAULT_SIGNAL_ID = {"G": 1, "S": 1, "R": 1, "E": 7, "C": 1, "J": 1, "I": 1}
#: GGA fix quality by solution status (NMEA 0183 4.10 GGA field 6)
FIX_QUALITY = {"no_fix": 0, "fix": 1, "single": 1, "dgps": 2, "pps": 3, "rtk_fixed": 4, "rtk_float": 5,
               "dead_reckoning": 6, "manual": 7, "simulation": 8}
#: RMC/GNS mode indicator by GGA fix quality
MODE_INDICATOR = {0: "N", 1: "A", 2: "D", 3: "P", 4: "R", 5: "F", 6: "E", 7: "M", 8: "S"}
#: knots per m/s (1 international nautical mile = 1852 m)
KNOTS_PER_MPS = 3600.0 / 1852.0
#: NMEA 0183 maximum sentence length, "$" to LF inclusive
MAX_SENTENCE_CHARS = 82


def checksum(body: str) -> str:
    """Two hex digits: XOR of the characters of ``body`` (between "$" and "*")."""
    return f"{functools.reduce(operator.xor, body.encode('ascii'), 0):02X}"


def sentence(talker: str, kind: str, fields: Sequence) -> str:
    """``$<talker><kind>,f1,f2,...*hh`` (None fields are empty)."""
    body = ",".join([talker + kind] + ["" if f is None else str(f) for f in fields])
    if "*" in body or "$" in body or "\r" in body or "\n" in body:
        raise ValueError(f"NMEA {kind}: reserved character in fields {fields!r}")
    return f"${body}*{checksum(body)}"


def join_sentences(sentences: Sequence[str]) -> str:
    """Sentences as one string, each ended by CR LF."""
    return "".join(s + "\r\n" for s in sentences)


def _angle(value_deg: float, deg_digits: int, decimals: int, pos: str, neg: str) -> tuple[str, str]:
    scale = 10**decimals
    total = round(abs(value_deg) * 60.0 * scale)  # in 10^-decimals arc minutes; rounding may carry to degrees
    deg, rem = divmod(total, 60 * scale)
    minutes, frac = divmod(rem, scale)
    hemi = neg if value_deg < 0 and total != 0 else pos
    text = f"{deg:0{deg_digits}d}{minutes:02d}" + (f".{frac:0{decimals}d}" if decimals else "")
    return text, hemi


def format_lat(lat_deg: float, decimals: int = 5) -> tuple[str, str]:
    """Latitude [deg] -> (``ddmm.mmmmm``, ``N``|``S``)."""
    lat = float(lat_deg)
    if not (math.isfinite(lat) and -90.0 <= lat <= 90.0):
        raise ValueError(f"lat_deg={lat_deg!r} is not a latitude in [-90, 90]")
    return _angle(lat, 2, decimals, "N", "S")


def format_lon(lon_deg: float, decimals: int = 5) -> tuple[str, str]:
    """Longitude [deg] (any value, wrapped to [-180, 180]) -> (``dddmm.mmmmm``, ``E``|``W``)."""
    lon = float(lon_deg)
    if not math.isfinite(lon):
        raise ValueError(f"lon_deg={lon_deg!r} is not finite")
    if not -180.0 <= lon <= 180.0:
        lon = (lon + 180.0) % 360.0 - 180.0
    return _angle(lon, 3, decimals, "E", "W")


#: the last instant utc_time_fields formatted and its fields: GGA and RMC of an epoch, and every robot of a fleet,
#: ask for the same instant
_UTC_LAST: list = [None, None]


def utc_time_fields(t: GnssTime, decimals: int = 2) -> tuple[str, str]:
    """(``hhmmss.ss``, ``ddmmyy``) in UTC of a GPS-time instant, rounded to ``decimals``
    with the carry into the next second, minute, hour and day (the date follows the rounded time).
    During a leap second the time shows 23:59:59."""
    key = (type(t.sec), t.sec, type(t.frac), t.frac, decimals) if np.ndim(t.sec) == 0 == np.ndim(t.frac) else None
    if key is not None and _UTC_LAST[0] == key:
        return _UTC_LAST[1]
    fields = _utc_time_fields(t, decimals)
    _UTC_LAST[:] = key, fields
    return fields


def _utc_time_fields(t: GnssTime, decimals: int) -> tuple[str, str]:
    sec, frac = t.seconds_in("UTC")
    sec = int(sec)
    scale = 10**decimals
    q = round(float(frac) * scale)
    if q >= scale:
        sec, q = sec + 1, q - scale
    d = GPS_EPOCH + _dt.timedelta(seconds=sec)
    hms = d.strftime("%H%M%S") + (f".{q:0{decimals}d}" if decimals else "")
    return hms, d.strftime("%d%m%y")


@functools.lru_cache(maxsize=512)
def nmea_satellite(sv: str) -> tuple[str, int]:
    """(GSV talker, NMEA satellite number) of a RINEX id like ``G05``, ``R07``, ``S20`` (cached: the same
    satellites come back every epoch)."""
    if not isinstance(sv, str) or len(sv) != 3 or sv[0] not in GSV_TALKER or not sv[1:].isdigit():
        raise ValueError(f"satellite id {sv!r} is not a RINEX id like 'G05'")
    s, n = sv[0], int(sv[1:])
    if s == "R":
        return "GL", n + 64  # GLONASS slot + 64
    if s == "S":
        return "GP", n + 100 - 87  # RINEX S20 = PRN 120 -> NMEA 33
    return GSV_TALKER[s], n


def _dop(x) -> str:
    if x is None:
        return ""
    x = float(x)
    return f"{min(x, 99.9):.1f}" if math.isfinite(x) else ""


def _talker(systems) -> str:
    systems = set(systems) - {"S"}
    return "GP" if systems <= {"G"} else "GN"


def gga(t: GnssTime, lat_deg: float, lon_deg: float, h_m: float, fix_quality: int, num_sats: int,
        hdop: float | None, geoid_sep_m: float = 0.0, age_s: float | None = None,
        station_id: int | None = None, talker: str = "GP") -> str:
    """GGA: time, position, fix quality, satellites used, HDOP, altitude above MSL
    (``h_m - geoid_sep_m``, ``h_m`` ellipsoidal), geoid separation, age and station of corrections."""
    if int(fix_quality) not in MODE_INDICATOR:
        raise ValueError(f"GGA fix_quality={fix_quality!r}; expected 0-8")
    hms, _ = utc_time_fields(t)
    if fix_quality == 0:
        lat = lat_h = lon = lon_h = alt = sep = None
    else:
        lat, lat_h = format_lat(lat_deg)
        lon, lon_h = format_lon(lon_deg)
        alt = f"{h_m - geoid_sep_m:.3f}"
        sep = f"{geoid_sep_m:.3f}"
    return sentence(talker, "GGA", [
        hms, lat, lat_h, lon, lon_h, int(fix_quality), f"{min(int(num_sats), 99):02d}", _dop(hdop),
        alt, "M" if alt is not None else None, sep, "M" if sep is not None else None,
        None if age_s is None else f"{age_s:.1f}", None if station_id is None else f"{int(station_id):04d}",
    ])


def rmc(t: GnssTime, lat_deg: float, lon_deg: float, speed_mps: float | None, course_deg: float | None,
        fix_quality: int, talker: str = "GP", mag_var_deg: float | None = None) -> str:
    """RMC: time, status (A valid / V invalid), position, speed over ground [knots],
    course over ground [deg true], date, magnetic variation, mode indicator, navigational status."""
    hms, date = utc_time_fields(t)
    valid = fix_quality != 0
    if valid:
        lat, lat_h = format_lat(lat_deg)
        lon, lon_h = format_lon(lon_deg)
    else:
        lat = lat_h = lon = lon_h = None
    spd = None if (speed_mps is None or not valid) else f"{speed_mps * KNOTS_PER_MPS:.3f}"
    cog = None if (course_deg is None or not valid) else f"{float(course_deg) % 360.0:.2f}"
    mv = mv_h = None
    if mag_var_deg is not None:
        mv, mv_h = f"{abs(mag_var_deg):.1f}", ("W" if mag_var_deg < 0 else "E")
    return sentence(talker, "RMC", [hms, "A" if valid else "V", lat, lat_h, lon, lon_h, spd, cog, date, mv, mv_h,
                                    MODE_INDICATOR[int(fix_quality)], "V"])


def gsa(sat_numbers: Sequence[int], fix_type: int, pdop: float | None, hdop: float | None, vdop: float | None,
        system_id: int | None = None, talker: str = "GP", mode: str = "A") -> list[str]:
    """GSA: fix type (1 none, 2 2D, 3 3D), satellites used (12 per sentence; more give
    several sentences), PDOP, HDOP, VDOP, and (NMEA 4.10) the system ID."""
    if fix_type not in (1, 2, 3):
        raise ValueError(f"GSA fix_type={fix_type!r}; expected 1, 2 or 3")
    nums = [int(n) for n in sat_numbers]
    out = []
    for k in range(0, max(len(nums), 1), 12):
        chunk = nums[k:k + 12]
        fields = [mode, fix_type] + [f"{n:02d}" for n in chunk] + [None] * (12 - len(chunk))
        fields += [_dop(pdop), _dop(hdop), _dop(vdop)]
        if system_id is not None:
            fields.append(f"{int(system_id):X}")
        out.append(sentence(talker, "GSA", fields))
    return out


_DIGITS2 = tuple(f"{i:02d}" for i in range(100))
_DIGITS3 = tuple(f"{i:03d}" for i in range(360))


def gsv(talker: str, satellites: Sequence[tuple[int, float, float, float | None]],
        signal_id: int | None = None) -> list[str]:
    """GSV messages of one talker: (satellite number, elevation [deg], azimuth [deg],
    C/N0 [dB-Hz] or None when not tracked), 4 per sentence; (NMEA 4.10) signal ID last."""
    sats = list(satellites)
    n_msg = max(1, math.ceil(len(sats) / 4))
    # each satellite's four fields (number, elevation, azimuth, C/N0 or empty) as one piece of the sentence;
    # the zero-padded numbers from tables (_DIGITS2: 0-99, _DIGITS3: 0-359)
    blocks = []
    d2, d3 = _DIGITS2, _DIGITS3
    for num, el, az, snr in sats:
        el_i = max(min(int(round(float(el))), 90), 0)
        az_i = int(round(float(az))) % 360
        snr_s = "" if snr is None or not math.isfinite(snr) else d2[int(round(min(max(snr, 0), 99)))]
        num = int(num)
        blocks.append(f"{d2[num] if 0 <= num < 100 else f'{num:02d}'},{d2[el_i]},{d3[az_i]},{snr_s}")
    out = []
    for m in range(n_msg):
        fields = [n_msg, m + 1, f"{len(sats):02d}"] + blocks[4 * m:4 * m + 4]
        if signal_id is not None:
            fields.append(f"{int(signal_id):X}")
        out.append(sentence(talker, "GSV", fields))
    return out


def epoch_sentences(t: GnssTime, *, lat_deg: float, lon_deg: float, h_m: float, fix_quality: int,
                    sv_used: Sequence[str], pdop: float | None, hdop: float | None, vdop: float | None,
                    sv_in_view: Sequence[str] = (), el_deg: Sequence[float] = (), az_deg: Sequence[float] = (),
                    cn0_dbhz: Sequence[float] | None = None, vel_enu_mps: Sequence[float] | None = None,
                    geoid_sep_m: float = 0.0, signal_id: dict[str, int] | None = None) -> list[str]:
    """GGA, RMC, GSA (one per used system) and GSV (per constellation) of one epoch.

    ``sv_in_view`` with ``el_deg``/``az_deg``/``cn0_dbhz`` (same order) feed GSV;
    satellites below the horizon are left out.  Speed and course come from
    ``vel_enu_mps`` (ENU at the receiver).
    """
    used_sys = sorted({sv[0] for sv in sv_used}, key="GRECJIS".index)
    talker = _talker(used_sys or {sv[0] for sv in sv_in_view})
    speed = course = None
    if vel_enu_mps is not None:
        ve, vn = float(vel_enu_mps[0]), float(vel_enu_mps[1])
        if math.isfinite(ve) and math.isfinite(vn):
            speed = math.hypot(ve, vn)
            course = math.degrees(math.atan2(ve, vn)) % 360.0
    out = [gga(t, lat_deg, lon_deg, h_m, fix_quality, len(sv_used), hdop, geoid_sep_m, talker=talker),
           rmc(t, lat_deg, lon_deg, speed, course, fix_quality, talker=talker)]
    fix_type = 1 if fix_quality == 0 else 3
    if talker == "GP":
        out += gsa([nmea_satellite(sv)[1] for sv in sv_used], fix_type, pdop, hdop, vdop, system_id=1, talker="GP")
    else:
        for s in used_sys or ["G"]:
            nums = [nmea_satellite(sv)[1] for sv in sv_used if sv[0] == s]
            out += gsa(nums, fix_type, pdop, hdop, vdop, system_id=SYSTEM_ID[s], talker="GN")
    sig = dict(DEFAULT_SIGNAL_ID, **(signal_id or {}))
    by_talker: dict[str, list] = {}
    first_sys: dict[str, str] = {}
    # Python numbers (the same values) instead of numpy scalars, element by element
    el_l, az_l = _as_list(el_deg), _as_list(az_deg)
    cn0_l = None if cn0_dbhz is None else _as_list(cn0_dbhz)
    for i, sv in enumerate(_as_list(sv_in_view)):
        el = el_l[i]
        if not math.isfinite(el) or el < 0:
            continue
        tk, num = nmea_satellite(sv)
        c = None if cn0_l is None else cn0_l[i]
        by_talker.setdefault(tk, []).append((num, el, az_l[i], c))
        first_sys.setdefault(tk, sv[0])
    for tk in ("GP", "GL", "GA", "GB", "GQ", "GI"):
        if tk in by_talker:
            out += gsv(tk, sorted(by_talker[tk]), signal_id=sig[first_sys[tk]])
    return out


def _as_list(x) -> list:
    """A sequence's elements as Python objects (numpy arrays through ``tolist``: the same values)."""
    return x.tolist() if isinstance(x, np.ndarray) else list(x)


def sentences_from_solution(t: GnssTime, sol, cn0_dbhz: Sequence[float] | None = None,
                            geoid_sep_m: float = 0.0, fix_status: str | None = None) -> list[str]:
    """NMEA sentences of a :class:`gnss_sim_ros2.core.solver.PvtSolution` (duck-typed).

    GSV lists every satellite given to the solver (``sol.sv`` with its
    ``el_deg``/``az_deg``) above the horizon; ``cn0_dbhz`` in the same order.
    ``fix_status`` overrides the GGA quality key (default: "fix" or "no_fix").
    """
    quality = FIX_QUALITY[fix_status or ("fix" if sol.status == "fix" else "no_fix")]
    sv = _as_list(sol.sv)
    used = [s for s, u in zip(sv, _as_list(sol.used)) if u]
    lat, lon, h = (sol.lat_deg, sol.lon_deg, sol.h_m) if quality else (0.0, 0.0, 0.0)
    return epoch_sentences(
        t, lat_deg=lat, lon_deg=lon, h_m=h, fix_quality=quality, sv_used=used,
        pdop=sol.pdop, hdop=sol.hdop, vdop=sol.vdop, sv_in_view=sv, el_deg=sol.el_deg, az_deg=sol.az_deg,
        cn0_dbhz=cn0_dbhz, vel_enu_mps=getattr(sol, "vel_enu_mps", None), geoid_sep_m=geoid_sep_m)
