"""GNSS time scales and a time value with sub-nanosecond resolution over decades.

Every instant inside gnss_sim is a :class:`GnssTime`: whole seconds of GPS time
since the GPS epoch (1980-01-06T00:00:00 UTC) as an integer, plus a float64
fraction in [0, 1).  The float fraction resolves about 1e-16 s, the integer
never loses precision, so resolution does not degrade with the distance from
the epoch (a single float64 of seconds would resolve only ~0.1 us in 2050).

The same class holds one instant (Python ints/floats) or many (numpy arrays):
arithmetic broadcasts like numpy.

Time scales (offsets from GPS time, continuous scales have no leap seconds):
- GPST: IS-GPS-200N 3.3.4; epoch 1980-01-06 00:00:00 UTC, weeks of 604800 s,
  broadcast week number modulo 1024 (rollovers 1999-08-22 and 2019-04-07).
- GST (Galileo): Galileo OS SIS ICD 2.1 5.1.2; GST = GPST (the GGTO of a few
  ns is broadcast, ignored here); GST week 0 starts 1999-08-22 (GPS week 1024).
- BDT (BeiDou): BDS-SIS-ICD-B1I 3.0 4.2; epoch 2006-01-01 00:00:00 UTC,
  BDT = GPST - 14 s; BDT week 0 = GPS week 1356.
- QZSST: IS-QZSS-PNT 5.1.1; aligned to GPST.
- IRNSST (NavIC): IRNSS SIS ICD 1.1; epoch 1999-08-22 = GPS week 1024, aligned to GPST.
- GLONASST: GLONASS ICD 5.1 3.3.3; UTC(SU) + 3 h, follows UTC leap seconds.
- UTC: GPST - (GPS-UTC), from the IERS Bulletin C leap second table below.
"""
from __future__ import annotations

import datetime as _dt
import math
import re

import numpy as np

#: seconds in a GNSS week [s]
SECONDS_PER_WEEK = 604800
#: seconds in a day [s]
SECONDS_PER_DAY = 86400
#: GPS epoch as a naive datetime (in GPST, which equals UTC at that instant)
GPS_EPOCH = _dt.datetime(1980, 1, 6)
#: BDT - GPST [s] (BDS-SIS-ICD-B1I 3.0, 4.2)
BDT_MINUS_GPST_S = -14
#: GPS week at which BDT week 0 starts (2006-01-01)
BDT_WEEK0_GPS_WEEK = 1356
#: GPS week at which GST/IRNSST week 0 starts (1999-08-22)
GST_WEEK0_GPS_WEEK = 1024
#: GLONASST - UTC [s] (GLONASS ICD 5.1, 3.3.3)
GLONASST_MINUS_UTC_S = 3 * 3600

#: (UTC instant when it takes effect, GPS - UTC in s after it). IERS Bulletin C 70.
LEAP_SECONDS = (
    (_dt.datetime(1981, 7, 1), 1),
    (_dt.datetime(1982, 7, 1), 2),
    (_dt.datetime(1983, 7, 1), 3),
    (_dt.datetime(1985, 7, 1), 4),
    (_dt.datetime(1988, 1, 1), 5),
    (_dt.datetime(1990, 1, 1), 6),
    (_dt.datetime(1991, 1, 1), 7),
    (_dt.datetime(1992, 7, 1), 8),
    (_dt.datetime(1993, 7, 1), 9),
    (_dt.datetime(1994, 7, 1), 10),
    (_dt.datetime(1996, 1, 1), 11),
    (_dt.datetime(1997, 7, 1), 12),
    (_dt.datetime(1999, 1, 1), 13),
    (_dt.datetime(2006, 1, 1), 14),
    (_dt.datetime(2009, 1, 1), 15),
    (_dt.datetime(2012, 7, 1), 16),
    (_dt.datetime(2015, 7, 1), 17),
    (_dt.datetime(2017, 1, 1), 18),
)

SCALES = ("GPS", "GST", "BDT", "QZS", "IRN", "GLO", "UTC")
#: RINEX system letter -> time scale of its broadcast ephemerides
SYSTEM_SCALE = {"G": "GPS", "E": "GST", "C": "BDT", "J": "QZS", "I": "IRN", "R": "GLO", "S": "GPS"}


def _utc_seconds(dt_utc: _dt.datetime) -> int:
    return int((dt_utc - GPS_EPOCH).total_seconds())


# GPS-second instants (in GPS time) at which each leap second takes effect.
_LEAP_GPS_SEC = np.array([_utc_seconds(d) + n for d, n in LEAP_SECONDS], dtype=np.int64)
_LEAP_UTC_SEC = np.array([_utc_seconds(d) for d, _ in LEAP_SECONDS], dtype=np.int64)
_LEAP_VALUES = np.array([n for _, n in LEAP_SECONDS], dtype=np.int64)


def gps_minus_utc_at_gps(sec_gps):
    """GPS - UTC [s] at GPS-time seconds since the GPS epoch (scalar or array)."""
    idx = np.searchsorted(_LEAP_GPS_SEC, np.asarray(sec_gps, dtype=np.int64), side="right")
    out = np.where(idx > 0, _LEAP_VALUES[np.maximum(idx - 1, 0)], 0)
    return int(out) if np.ndim(out) == 0 else out


def gps_minus_utc_at_utc(sec_utc):
    """GPS - UTC [s] at UTC seconds since 1980-01-06 (scalar or array)."""
    idx = np.searchsorted(_LEAP_UTC_SEC, np.asarray(sec_utc, dtype=np.int64), side="right")
    out = np.where(idx > 0, _LEAP_VALUES[np.maximum(idx - 1, 0)], 0)
    return int(out) if np.ndim(out) == 0 else out


def _scale_offset_from_gps(scale: str, sec_gps):
    """(scale time) - (GPS time) in whole seconds at the given GPS seconds."""
    if scale in ("GPS", "GST", "QZS", "IRN"):
        return 0
    if scale == "BDT":
        return BDT_MINUS_GPST_S
    if scale == "UTC":
        return -gps_minus_utc_at_gps(sec_gps)
    if scale == "GLO":
        return GLONASST_MINUS_UTC_S - gps_minus_utc_at_gps(sec_gps)
    raise ValueError(f"unknown time scale {scale!r}; expected one of {SCALES}")


def _scale_offset_from_scale(scale: str, sec_scale):
    """(GPS time) - (scale time) in whole seconds, given seconds counted in that scale."""
    if scale in ("GPS", "GST", "QZS", "IRN"):
        return 0
    if scale == "BDT":
        return -BDT_MINUS_GPST_S
    if scale == "UTC":
        return gps_minus_utc_at_utc(sec_scale)
    if scale == "GLO":
        return gps_minus_utc_at_utc(np.asarray(sec_scale) - GLONASST_MINUS_UTC_S) - GLONASST_MINUS_UTC_S
    raise ValueError(f"unknown time scale {scale!r}; expected one of {SCALES}")


class GnssTime:
    """GPS time as integer seconds since the GPS epoch plus a fraction in [0, 1).

    Scalars or numpy arrays (broadcasting).  ``t2 - t1`` between two GnssTime
    gives float seconds computed without loss (the integer parts subtract
    exactly); ``t + dt_s`` shifts by float seconds.
    """

    __slots__ = ("sec", "frac")

    def __init__(self, sec, frac=0.0):
        if type(sec) is int and type(frac) is float and 0.0 <= frac < 1.0:    # normalised scalars already
            self.sec, self.frac = sec, frac
            return
        sec_is_scalar = np.ndim(sec) == 0 and np.ndim(frac) == 0
        if sec_is_scalar and isinstance(sec, float):
            whole = math.floor(sec)
            frac = frac + (sec - whole)
            sec = int(whole)
        fl = np.floor(frac)
        if sec_is_scalar:
            self.sec = int(sec) + int(fl)
            self.frac = float(frac - fl)
        else:
            self.sec = np.asarray(sec, dtype=np.int64) + fl.astype(np.int64)
            self.frac = np.asarray(frac - fl, dtype=np.float64)

    # ----- construction -------------------------------------------------
    @classmethod
    def from_week_tow(cls, week, tow_s, scale: str = "GPS"):
        """From a continuous (not modulo) week number and time of week of ``scale``.

        GST and IRNSST weeks count from 1999-08-22, BDT weeks from 2006-01-01.
        """
        week = np.asarray(week)
        base_week = {"GST": GST_WEEK0_GPS_WEEK, "IRN": GST_WEEK0_GPS_WEEK, "BDT": BDT_WEEK0_GPS_WEEK}.get(scale, 0)
        tow = np.asarray(tow_s, dtype=np.float64)
        whole = np.floor(tow)
        if scale in ("UTC", "GLO"):
            raise ValueError("UTC and GLONASS time have no week numbers")
        # seconds counted in the scale from its own week 0, shifted to GPS seconds
        sec = (week.astype(np.int64) + base_week) * SECONDS_PER_WEEK + whole.astype(np.int64)
        sec = sec - _scale_offset_from_gps(scale, sec)
        out = cls(sec, tow - whole)
        return out._squeeze()

    @classmethod
    def from_datetime(cls, dt, scale: str = "GPS"):
        """From a naive datetime (or an ISO 8601 string) read in ``scale``.

        Timezone-aware datetimes are converted to UTC first and read as UTC.
        Resolution of datetime is 1 us; use ``+ seconds`` for finer offsets.
        """
        if isinstance(dt, str):
            return cls.from_iso(dt, scale)
        if dt.tzinfo is not None:
            dt = dt.astimezone(_dt.timezone.utc).replace(tzinfo=None)
            scale = "UTC"
        delta = dt - GPS_EPOCH
        sec_scale = delta.days * SECONDS_PER_DAY + delta.seconds
        frac = delta.microseconds * 1e-6
        sec = sec_scale + _scale_offset_from_scale(scale, sec_scale)
        return cls(int(sec), frac)

    @classmethod
    def from_iso(cls, text: str, scale: str = "GPS"):
        """Parse ``YYYY-MM-DD[T ]hh:mm:ss[.fffffffff...]`` in ``scale`` (fraction to any digits)."""
        m = re.fullmatch(r"\s*(\d{4})-(\d{2})-(\d{2})(?:[T ](\d{2}):(\d{2})(?::(\d{2})(\.\d+)?)?)?\s*(Z)?\s*", text)
        if not m:
            raise ValueError(f"not an ISO 8601 date-time: {text!r} (expected e.g. 2022-01-01T00:05:00)")
        y, mo, d, hh, mm, ss, fr, _z = m.groups()
        base = _dt.datetime(int(y), int(mo), int(d), int(hh or 0), int(mm or 0), int(ss or 0))
        t = cls.from_datetime(base, scale)
        return t + float(fr) if fr else t

    @classmethod
    def from_gps_seconds(cls, seconds):
        """From float seconds of GPS time since the GPS epoch (loses precision: tests only)."""
        s = np.asarray(seconds, dtype=np.float64)
        whole = np.floor(s)
        return cls(whole.astype(np.int64), s - whole)._squeeze()

    # ----- conversion ---------------------------------------------------
    def week_tow(self, scale: str = "GPS"):
        """(continuous week, time of week in s) in ``scale`` (GPS, GST, BDT, QZS, IRN)."""
        if scale in ("UTC", "GLO"):
            raise ValueError("UTC and GLONASS time have no week numbers")
        sec = np.asarray(self.sec, dtype=np.int64) + _scale_offset_from_gps(scale, self.sec)
        base_week = {"GST": GST_WEEK0_GPS_WEEK, "IRN": GST_WEEK0_GPS_WEEK, "BDT": BDT_WEEK0_GPS_WEEK}.get(scale, 0)
        week = sec // SECONDS_PER_WEEK
        tow = (sec - week * SECONDS_PER_WEEK) + np.asarray(self.frac)
        week = week - base_week
        if np.ndim(week) == 0:
            return int(week), float(tow)
        return week, tow

    def seconds_in(self, scale: str):
        """(integer seconds, fraction) of this instant counted in ``scale`` from 1980-01-06 00:00:00."""
        return np.asarray(self.sec) + _scale_offset_from_gps(scale, self.sec), self.frac

    def to_datetime(self, scale: str = "GPS") -> _dt.datetime:
        """Naive datetime in ``scale`` (scalar only; fraction rounded to 1 us).

        During a leap second (23:59:60 UTC) the datetime shows 23:59:59.
        """
        if np.ndim(self.sec) != 0:
            raise TypeError("to_datetime works on a scalar GnssTime; iterate for arrays")
        sec = self.sec + _scale_offset_from_gps(scale, self.sec)
        us = round(self.frac * 1e6)
        return GPS_EPOCH + _dt.timedelta(seconds=int(sec), microseconds=us)

    def isoformat(self, scale: str = "GPS", digits: int = 0) -> str:
        """``YYYY-MM-DDThh:mm:ss`` (with ``digits`` decimals) in ``scale``; scalar only."""
        sec = int(self.sec + _scale_offset_from_gps(scale, self.sec))
        frac = self.frac
        if digits:
            q = round(frac * 10**digits)
            if q >= 10**digits:
                sec, q = sec + 1, 0
            tail = f".{q:0{digits}d}"
        else:
            if frac >= 0.5:
                sec += 1
            tail = ""
        base = GPS_EPOCH + _dt.timedelta(seconds=sec)
        return base.isoformat(timespec="seconds") + tail     # YYYY-MM-DDThh:mm:ss (naive: no offset)

    def to_gps_seconds(self):
        """Float seconds since the GPS epoch (loses precision below ~0.1 us: display only)."""
        return np.asarray(self.sec, dtype=np.float64) + self.frac

    # ----- arithmetic ---------------------------------------------------
    def __add__(self, dt_s):
        if isinstance(dt_s, GnssTime):
            raise TypeError("cannot add two instants")
        if type(self.sec) is int and np.ndim(dt_s) == 0:
            # a scalar instant and a finite scalar offset: the same doubles as the array path below, in
            # Python numbers (integer parts exact, the fractions the same IEEE operations)
            d = float(dt_s)
            if math.isfinite(d):
                whole = math.floor(d)
                f = self.frac + (d - whole)
                fl = math.floor(f)
                return GnssTime(self.sec + whole + fl, f - fl)
        d = np.asarray(dt_s, dtype=np.float64)
        whole = np.floor(d)
        sec = np.asarray(self.sec) + whole.astype(np.int64)
        out = GnssTime(sec, np.asarray(self.frac) + (d - whole))
        return out._squeeze()

    __radd__ = __add__

    def __sub__(self, other):
        if isinstance(other, GnssTime):
            if type(self.sec) is int and type(other.sec) is int:     # two scalars: the same double, less overhead
                return float(self.sec - other.sec) + (self.frac - other.frac)
            ds = np.asarray(self.sec, dtype=np.int64) - np.asarray(other.sec, dtype=np.int64)
            out = ds.astype(np.float64) + (np.asarray(self.frac) - np.asarray(other.frac))
            return float(out) if np.ndim(out) == 0 else out
        return self + (-np.asarray(other, dtype=np.float64))

    def _cmp_key(self, other):
        d = self - other
        return d

    def __lt__(self, other):
        return self._cmp_key(other) < 0

    def __le__(self, other):
        return self._cmp_key(other) <= 0

    def __gt__(self, other):
        return self._cmp_key(other) > 0

    def __ge__(self, other):
        return self._cmp_key(other) >= 0

    def __eq__(self, other):
        if not isinstance(other, GnssTime):
            return NotImplemented
        return self._cmp_key(other) == 0

    def __hash__(self):
        if np.ndim(self.sec) != 0:
            raise TypeError("array GnssTime is not hashable")
        return hash((self.sec, self.frac))

    def __len__(self):
        return len(np.atleast_1d(self.sec))

    def __getitem__(self, idx):
        return GnssTime(np.atleast_1d(self.sec)[idx], np.atleast_1d(self.frac)[idx])._squeeze()

    def __repr__(self):
        if np.ndim(self.sec) == 0:
            return f"GnssTime({self.isoformat(digits=9)} GPST)"
        return f"GnssTime(array of {np.size(self.sec)})"

    def _squeeze(self):
        if np.ndim(self.sec) == 0 and not isinstance(self.sec, int):
            self.sec = int(self.sec)
            self.frac = float(self.frac)
        return self

    @staticmethod
    def stack(times):
        """One array GnssTime from a sequence of GnssTime."""
        return GnssTime(
            np.concatenate([np.atleast_1d(t.sec) for t in times]).astype(np.int64),
            np.concatenate([np.atleast_1d(t.frac) for t in times]),
        )

    @staticmethod
    def arange(start: GnssTime, stop: GnssTime, step_s: float):
        """Instants start, start+step, ... strictly before ``stop`` (step may be fractional)."""
        n = int(math.floor((stop - start) / step_s - 1e-9)) + 1
        k = np.arange(max(n, 0), dtype=np.float64)
        offs = k * step_s
        whole = np.floor(offs)
        return GnssTime(np.asarray(start.sec, dtype=np.int64) + whole.astype(np.int64), start.frac + (offs - whole))


def resolve_week(week_mod: int, near: GnssTime, modulus: int = 1024, scale: str = "GPS") -> int:
    """Continuous week from a broadcast week number modulo ``modulus`` (1024 for GPS
    LNAV, 8192 for CNAV, 4096 for GST, 8192 for BDT) nearest to the instant ``near``."""
    w_near, _ = near.week_tow(scale)
    k = round((w_near - week_mod) / modulus)
    return int(week_mod + k * modulus)


def ros_time_to_gnss(sec: int, nanosec: int, offset: GnssTime | None = None, ros_is_utc: bool = True) -> GnssTime:
    """Map a ROS stamp (sec, nanosec) to GNSS time.

    With ``offset`` the ROS clock counts seconds since that GNSS instant
    (simulated time starting at 0); otherwise the ROS stamp is taken as UNIX
    time in UTC (``ros_is_utc``) or already in GPS time.
    """
    if offset is not None:
        return GnssTime(offset.sec + int(sec), offset.frac + nanosec * 1e-9)
    unix_to_gps = _utc_seconds(_dt.datetime(1970, 1, 1))  # negative: 1970 is before 1980
    sec_since = int(sec) + unix_to_gps
    if ros_is_utc:
        sec_since += gps_minus_utc_at_utc(sec_since)
    return GnssTime(sec_since, nanosec * 1e-9)


def gnss_to_ros_time(t: GnssTime, offset: GnssTime | None = None, ros_is_utc: bool = True) -> tuple[int, int]:
    """Inverse of :func:`ros_time_to_gnss`: (sec, nanosec) of a ROS stamp."""
    if offset is not None:
        d_sec = int(t.sec - offset.sec)
        frac = t.frac - offset.frac
    else:
        d_sec = int(t.sec) - _utc_seconds(_dt.datetime(1970, 1, 1))
        if ros_is_utc:
            d_sec -= gps_minus_utc_at_gps(t.sec)
        frac = t.frac
    ns = int(round(frac * 1e9))
    d_sec += ns // 1_000_000_000
    ns %= 1_000_000_000
    return d_sec, ns
