"""Record tables from georinex's values: toc/toe as GPS time (weeks resolved from the record epoch),
our field names and units, records that cannot be orbits dropped, angles in semicircles corrected, repeats
across files removed."""
from __future__ import annotations

import logging

import numpy as np

from ...time import BDT_MINUS_GPST_S, GPS_EPOCH, SECONDS_PER_DAY, SECONDS_PER_WEEK, gps_minus_utc_at_utc
from .containers import GLONASS_DTYPE, KEPLER_DTYPE, NavData, SystemTable, epoch_key

log = logging.getLogger(__name__)

#: orbit radius (semi-major axis; GLONASS: position radius) of any GNSS satellite [m]: the lowest is GLONASS
#: at 25,510 km (GLONASS ICD 5.1 3.1), the highest the GEO/IGSO of BeiDou, QZSS and NavIC at 42,164 km;
#: outside 20,000..46,000 km a record is not an orbit of a navigation satellite
ORBIT_RADIUS_RANGE_M = (2.0e7, 4.6e7)


#: the most eccentric GNSS orbits are Galileo E14/E18 (e = 0.16, in the wrong orbit since 2014) and
#: QZSS QZO (0.075); a broadcast eccentricity beyond this is a corrupted record
MAX_ECCENTRICITY = 0.3


def record_table(sysid, nav_type, sv, epoch, raw, fields, name, nav: NavData) -> SystemTable:
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


def fix_semicircles(tab: SystemTable, name: str, nav: NavData) -> None:
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


def dedupe(tab: SystemTable) -> SystemTable:
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
