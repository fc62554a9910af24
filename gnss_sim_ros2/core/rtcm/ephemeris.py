"""RTCM3 broadcast ephemeris messages from RINEX navigation records (RTCM 10403.3, 3.5.6-3.5.9):
1019 GPS, 1020 GLONASS, 1041 NavIC, 1042 BeiDou, 1044 QZSS, 1045 Galileo F/NAV, 1046 Galileo I/NAV.

Records are the dicts of core/rinex/nav.records_as_dicts (georinex
variable names, RINEX units: seconds, radians, metres; ``"time"`` = toc in the
system's time scale, UTC for GLONASS).  Angles go out in semicircles with the
ICD value of pi; each field is rounded to its RTCM resolution (the scale
factors of the data fields DF071-DF137, DF252-DF317, DF429-DF457, DF488-DF545).
A value that does not fit its field raises :class:`~.frame.RtcmFieldError`.
"""
from __future__ import annotations

import datetime as _dt
import math

from .frame import BitWriter, RtcmFieldError

#: pi for semicircle conversions (IS-GPS-200N 20.3.3.4.3.2; the same value in all Kepler ICDs)
GPS_PI = 3.1415926535898
#: URA upper bounds [m] for the 4-bit accuracy index N (IS-GPS-200N 20.3.3.3.1.3; BDS URAI, NavIC URA)
_URA_BOUNDS_M = (2.4, 3.4, 4.85, 6.85, 9.65, 13.65, 24.0, 48.0, 96.0, 192.0, 384.0, 768.0, 1536.0, 3072.0, 6144.0)
#: the message number of each system's ephemeris (Galileo: 1046 I/NAV, 1045 F/NAV by the data source)
EPHEMERIS_MESSAGE = {"G": 1019, "R": 1020, "I": 1041, "C": 1042, "J": 1044, "E": 1046}


def ura_index(ura_m: float) -> int:
    """4-bit URA index of an accuracy in metres (first bound at or above it; 15 beyond 6144 m)."""
    for i, b in enumerate(_URA_BOUNDS_M):
        if ura_m <= b:
            return i
    return 15


def sisa_index(sisa_m: float) -> int:
    """Galileo SISA index (OS SIS ICD 2.1, 5.1.11): 1 cm steps to 0.49 m, 2 cm to 0.98 m, 4 cm to 1.96 m,
    16 cm to 6 m; 255 (no accuracy prediction available) beyond or for a negative value."""
    s = float(sisa_m)
    if s < 0 or not math.isfinite(s) or s > 6.0:
        return 255
    if s <= 0.49:
        return round(s / 0.01)
    if s <= 0.98:
        return round((s - 0.5) / 0.02) + 50
    if s <= 1.96:
        return round((s - 1.0) / 0.04) + 75
    return round((s - 2.0) / 0.16) + 100


def _q(value: float, lsb: float) -> int:
    return round(float(value) / lsb)


def _sc(rad: float, lsb: float) -> int:
    """Radians (or rad/s) to semicircles in units of ``lsb``."""
    return round(float(rad) / GPS_PI / lsb)


def _tow_s(t: _dt.datetime) -> float:
    """Seconds of the week of a naive datetime in a scale whose weeks start on Sunday 00:00."""
    d = t - _dt.datetime(1980, 1, 6)
    return d.total_seconds() % 604800.0


def _prn(rec: dict) -> int:
    return int(str(rec["sv"])[1:])


def encode_1019(r: dict) -> bytes:
    """GPS LNAV ephemeris (RTCM 10403.3 table 3.5-21)."""
    w = BitWriter()
    w.u(12, 1019, "DF002").u(6, _prn(r), "DF009").u(10, int(r["GPSWeek"]) % 1024, "DF076")
    w.u(4, ura_index(r["SVacc"]), "DF077").u(2, int(r["CodesL2"]) & 3, "DF078")
    w.s(14, _sc(r["IDOT"], 2.0 ** -43), "DF079").u(8, int(r["IODE"]), "DF071")
    w.u(16, round(_tow_s(r["time"]) / 16.0), "DF081")
    w.s(8, _q(r["SVclockDriftRate"], 2.0 ** -55), "DF082").s(16, _q(r["SVclockDrift"], 2.0 ** -43), "DF083")
    w.s(22, _q(r["SVclockBias"], 2.0 ** -31), "DF084").u(10, int(r["IODC"]), "DF085")
    _kepler_body(w, r)
    w.s(8, _q(r["TGD"], 2.0 ** -31), "DF101").u(6, int(r["health"]), "DF102")
    w.u(1, int(r["L2Pflag"]) & 1, "DF103").u(1, _fit_flag(r["FitIntvl"], 4.0), "DF137")
    return w.payload()


def _kepler_body(w: BitWriter, r: dict, harm_bits: int = 16, r_lsb: float = 2.0 ** -5, c_lsb: float = 2.0 ** -29,
                 toe_bits: int = 16, toe_lsb: float = 16.0) -> None:
    """Crs .. OmegaDot, the run 1019/1044 (DF086-DF100), 1045/1046 (DF297-DF311) and 1042 (DF498-DF512)
    share in this order: radius harmonics (``r_lsb`` m) and angle harmonics (``c_lsb`` rad) of ``harm_bits``,
    32-bit angles and 24-bit node rate in semicircles, toe of ``toe_bits`` in units of ``toe_lsb`` s."""
    w.s(harm_bits, _q(r["Crs"], r_lsb), "Crs").s(16, _sc(r["DeltaN"], 2.0 ** -43), "DeltaN")
    w.s(32, _sc(r["M0"], 2.0 ** -31), "M0").s(harm_bits, _q(r["Cuc"], c_lsb), "Cuc")
    w.u(32, _q(r["Eccentricity"], 2.0 ** -33), "e").s(harm_bits, _q(r["Cus"], c_lsb), "Cus")
    w.u(32, _q(r["sqrtA"], 2.0 ** -19), "sqrtA").u(toe_bits, round(float(r["Toe"]) / toe_lsb), "Toe")
    w.s(harm_bits, _q(r["Cic"], c_lsb), "Cic").s(32, _sc(r["Omega0"], 2.0 ** -31), "Omega0")
    w.s(harm_bits, _q(r["Cis"], c_lsb), "Cis").s(32, _sc(r["Io"], 2.0 ** -31), "i0")
    w.s(harm_bits, _q(r["Crc"], r_lsb), "Crc").s(32, _sc(r["omega"], 2.0 ** -31), "omega")
    w.s(24, _sc(r["OmegaDot"], 2.0 ** -43), "OmegaDot")


def _fit_flag(fit, limit_h: float) -> int:
    """Fit interval flag (DF137/DF457): 0 = the nominal interval, 1 = longer; RINEX writes hours
    (or the flag itself: 0/1)."""
    f = float(fit)
    if f in (0.0, 1.0):
        return int(f)
    return 0 if f <= limit_h else 1


def encode_1044(r: dict) -> bytes:
    """QZSS ephemeris (RTCM 10403.3 table 3.5-29; satellite ID = PRN - 192)."""
    prn = _prn(r)
    if not 1 <= prn <= 10:
        raise RtcmFieldError(f"1044: QZSS satellite {r['sv']} outside J01..J10 (DF429)")
    w = BitWriter()
    w.u(12, 1044, "DF002").u(4, prn, "DF429").u(16, round(_tow_s(r["time"]) / 16.0), "DF430")
    w.s(8, _q(r["SVclockDriftRate"], 2.0 ** -55), "DF431").s(16, _q(r["SVclockDrift"], 2.0 ** -43), "DF432")
    w.s(22, _q(r["SVclockBias"], 2.0 ** -31), "DF433").u(8, int(r["IODE"]), "DF434")
    _kepler_body(w, r)
    w.s(14, _sc(r["IDOT"], 2.0 ** -43), "DF450").u(2, int(r["CodesL2"]) & 3, "DF451")
    w.u(10, int(r["GPSWeek"]) % 1024, "DF452").u(4, ura_index(r["SVacc"]), "DF453")
    w.u(6, int(r["health"]), "DF454").s(8, _q(r["TGD"], 2.0 ** -31), "DF455").u(10, int(r["IODC"]), "DF456")
    w.u(1, _fit_flag(r["FitIntvl"], 2.0), "DF457")
    return w.payload()


def galileo_is_fnav(r: dict) -> bool:
    """F/NAV record: data source bit 1 (E5a-I) set (RINEX 3.04 table A8)."""
    return bool(int(r.get("DataSrc", 0)) & 2)


def encode_galileo(r: dict) -> bytes:
    """1045 (F/NAV, table 3.5-30) or 1046 (I/NAV, table 3.5-31) by the record's data source."""
    fnav = galileo_is_fnav(r)
    h = int(r["health"])
    w = BitWriter()
    w.u(12, 1045 if fnav else 1046, "DF002").u(6, _prn(r), "DF252")
    w.u(12, (int(r["GALWeek"]) - 1024) % 4096, "DF289").u(10, int(r["IODnav"]), "DF290")
    w.u(8, sisa_index(r["SISA"]), "DF291/DF286").s(14, _sc(r["IDOT"], 2.0 ** -43), "DF292")
    w.u(14, round(_tow_s(r["time"]) / 60.0), "DF293")
    w.s(6, _q(r["SVclockDriftRate"], 2.0 ** -59), "DF294").s(21, _q(r["SVclockDrift"], 2.0 ** -46), "DF295")
    w.s(31, _q(r["SVclockBias"], 2.0 ** -34), "DF296")
    _kepler_body(w, r, toe_bits=14, toe_lsb=60.0)
    w.s(10, _q(r["BGDe5a"], 2.0 ** -32), "DF312")
    # health bits (RINEX 3.04 A8): 0 E1-B DVS, 1-2 E1-B HS, 3 E5a DVS, 4-5 E5a HS, 6 E5b DVS, 7-8 E5b HS
    if fnav:
        w.u(2, (h >> 4) & 3, "DF314").u(1, (h >> 3) & 1, "DF315").u(7, 0, "DF001")
    else:
        w.s(10, _q(r["BGDe5b"], 2.0 ** -32), "DF313")
        w.u(2, (h >> 7) & 3, "DF316").u(1, (h >> 6) & 1, "DF317")
        w.u(2, (h >> 1) & 3, "DF287").u(1, h & 1, "DF288").u(2, 0, "DF001")
    return w.payload()


def encode_1042(r: dict) -> bytes:
    """BeiDou D1/D2 ephemeris (RTCM 10403.3 table 3.5-32; times in BDT)."""
    aode, aodc = int(r["AODE"]), int(r["AODC"])
    if not (0 <= aode < 32 and 0 <= aodc < 32):
        raise RtcmFieldError(f"1042: {r['sv']} AODE {aode} / AODC {aodc} do not fit 5 bits (DF492/DF497)")
    w = BitWriter()
    w.u(12, 1042, "DF002").u(6, _prn(r), "DF488").u(13, int(r["BDTWeek"]) % 8192, "DF489")
    w.u(4, ura_index(r["SVacc"]), "DF490").s(14, _sc(r["IDOT"], 2.0 ** -43), "DF491").u(5, aode, "DF492")
    w.u(17, round(_tow_s(r["time"]) / 8.0), "DF493")
    w.s(11, _q(r["SVclockDriftRate"], 2.0 ** -66), "DF494").s(22, _q(r["SVclockDrift"], 2.0 ** -50), "DF495")
    w.s(24, _q(r["SVclockBias"], 2.0 ** -33), "DF496").u(5, aodc, "DF497")
    _kepler_body(w, r, harm_bits=18, r_lsb=2.0 ** -6, c_lsb=2.0 ** -31, toe_bits=17, toe_lsb=8.0)
    w.s(10, _q(r["TGD1"], 1e-10), "DF513").s(10, _q(r["TGD2"], 1e-10), "DF514")
    w.u(1, int(r["SatH1"]) & 1, "DF515")
    return w.payload()


def encode_1041(r: dict) -> bytes:
    """NavIC ephemeris (RTCM 10403.3 Amendment 1, table 3.5-32.1)."""
    w = BitWriter()
    w.u(12, 1041, "DF002").u(6, _prn(r), "DF516").u(10, int(r["BDTWeek"]) % 1024, "DF517")
    w.s(22, _q(r["SVclockBias"], 2.0 ** -31), "DF518").s(16, _q(r["SVclockDrift"], 2.0 ** -43), "DF519")
    w.s(8, _q(r["SVclockDriftRate"], 2.0 ** -55), "DF520").u(4, ura_index(r["URA"]), "DF521")
    w.u(16, round(_tow_s(r["time"]) / 16.0), "DF522").s(8, _q(r["TGD"], 2.0 ** -31), "DF523")
    w.s(22, _sc(r["DeltaN"], 2.0 ** -41), "DF524").u(8, int(r["IODEC"]), "DF525").u(10, 0, "DF526")
    h = int(r["health"])
    w.u(1, (h >> 1) & 1, "DF527").u(1, h & 1, "DF528")
    for name, df in (("Cuc", "DF529"), ("Cus", "DF530"), ("Cic", "DF531"), ("Cis", "DF532")):
        w.s(15, _q(r[name], 2.0 ** -28), df)
    w.s(15, _q(r["Crc"], 2.0 ** -4), "DF533").s(15, _q(r["Crs"], 2.0 ** -4), "DF534")
    w.s(14, _sc(r["IDOT"], 2.0 ** -43), "DF535").s(32, _sc(r["M0"], 2.0 ** -31), "DF536")
    w.u(16, round(float(r["Toe"]) / 16.0), "DF537").u(32, _q(r["Eccentricity"], 2.0 ** -33), "DF538")
    w.u(32, _q(r["sqrtA"], 2.0 ** -19), "DF539").s(32, _sc(r["Omega0"], 2.0 ** -31), "DF540")
    w.s(32, _sc(r["omega"], 2.0 ** -31), "DF541").s(22, _sc(r["OmegaDot"], 2.0 ** -41), "DF542")
    w.s(32, _sc(r["Io"], 2.0 ** -31), "DF543").u(2, 0, "DF544").u(2, 0, "DF545")
    return w.payload()


def encode_1020(r: dict) -> bytes:
    """GLONASS ephemeris (RTCM 10403.3 table 3.5-24): PZ-90 state in km, km/s, km/s^2 (sign-magnitude),
    times in GLONASS time (UTC + 3 h)."""
    toc_glo = r["time"] + _dt.timedelta(hours=3)          # RINEX: toc (tb) in UTC
    tod_tb = toc_glo.hour * 3600 + toc_glo.minute * 60 + toc_glo.second
    tk_tod = (float(r["MessageFrameTime"]) + 10800.0) % 86400.0   # RINEX: tk in seconds of the UTC week
    tk_h, rem = divmod(int(round(tk_tod)), 3600)
    tk_m, tk_s = divmod(rem, 60)
    leap_year = toc_glo.year - toc_glo.year % 4
    nt = (toc_glo.date() - _dt.date(leap_year, 1, 1)).days + 1
    ch = int(r["FreqNum"])
    if not -7 <= ch <= 24:
        raise RtcmFieldError(f"1020: {r['sv']} frequency channel {ch} outside -7..24 (DF040)")
    w = BitWriter()
    w.u(12, 1020, "DF002").u(6, _prn(r), "DF038").u(5, ch + 7, "DF040")
    w.u(1, 0, "DF104").u(1, 0, "DF105").u(2, 0, "DF106")
    w.u(5, tk_h % 24, "DF107 h").u(6, tk_m, "DF107 min").u(1, 1 if tk_s >= 30 else 0, "DF107 30 s")
    w.u(1, 1 if int(r["health"]) else 0, "DF108").u(1, 0, "DF109").u(7, round(tod_tb / 900.0), "DF110")
    for axis in "XYZ":
        w.sm(24, _q(float(r["d" + axis]) / 1e3, 2.0 ** -20), f"DF111 d{axis}")
        w.sm(27, _q(float(r[axis]) / 1e3, 2.0 ** -11), f"DF112 {axis}")
        w.sm(5, _q(float(r["d" + axis + "2"]) / 1e3, 2.0 ** -30), f"DF113 d{axis}2")
    w.u(1, 0, "DF120").sm(11, _q(r["SVrelFreqBias"], 2.0 ** -40), "DF121").u(2, 0, "DF122").u(1, 0, "DF123")
    w.sm(22, _q(-float(r["SVclockBias"]), 2.0 ** -30), "DF124 tau_n")    # RINEX writes -tau_n
    w.sm(5, 0, "DF125").u(5, int(r.get("AgeOpInfo", 0)) & 31, "DF126").u(1, 0, "DF127").u(4, 0, "DF128")
    w.u(11, nt, "DF129").u(2, 0, "DF130").u(1, 0, "DF131").u(11, 0, "DF132").sm(32, 0, "DF133")
    w.u(5, 0, "DF134").sm(22, 0, "DF135").u(1, 0, "DF136").u(7, 0, "DF001")
    return w.payload()


def encode_record(system: str, r: dict) -> bytes:
    """The ephemeris message of one record of ``system``."""
    enc = {"G": encode_1019, "R": encode_1020, "E": encode_galileo, "C": encode_1042, "J": encode_1044,
           "I": encode_1041}.get(system)
    if enc is None:
        raise ValueError(f"RTCM ephemeris: system {system!r} has no message (known: GRECJI)")
    try:
        return enc(r)
    except KeyError as exc:
        raise ValueError(f"RTCM ephemeris {system} record {r.get('sv')}: field {exc} missing") from None
