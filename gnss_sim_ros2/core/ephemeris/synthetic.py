"""Synthetic multi-GNSS constellation: nominal orbits -> a real RINEX 3.04 navigation file.

For any date without a navigation file at hand: every satellite flies a
nominal orbit of its system's published constellation design, and
broadcast-like records (Keplerian elements; GLONASS state vectors) of that
orbit are written with :func:`write_rinex3_nav` (or taken straight into the
broadcast path with the file's rounding, :meth:`SyntheticConstellation.nav`,
what ``open_ephemeris("synthetic", ...)`` does).  Deterministic: no randomness.

    path = write_synthetic_nav("synthetic.rnx", GnssTime.from_iso("2025-06-01T00:00:00"), 6 * 3600)
    eph = BroadcastEphemeris.from_files([path])
    eph = BroadcastEphemeris(SyntheticConstellation(t0, 6 * 3600).nav())   # the same states, no text

Nominal orbit model (Keplerian systems G, E, C, J, I): a Keplerian ellipse
with constant a, e, i, omega, uniformly advancing mean anomaly (n = sqrt(GM/a^3),
so the broadcast Delta n is 0) and a node regressing at the secular J2 rate
(Omega_dot = -3/2 n J2 (a_e/p)^2 cos i; Vallado, Fundamentals of
Astrodynamics 4th ed., eq. 9-41; 0 for GEO).  The quasi-inertial frame is
the ECEF frame at the reference epoch T_REF (1993-07-01 00:00 GPST) rotated
back by the Greenwich hour angle 18h36m14.4s given for that epoch in the GPS
SPS Performance Standard (2001/2008, table 3-1); Earth rotates uniformly at
each system's ICD rate.  A broadcast record represents this orbit exactly
(harmonic corrections 0), so the records only re-epoch the same orbit.
Repeat-ground-track orbits (GEO, IGSO, QZO) take n = omega_e - Omega_dot and
a = (GM/n^2)^(1/3): their ground track is fixed in ECEF.

GLONASS: the state at the first tb is built from the nominal elements and
integrated numerically (scipy DOP853, rtol 1e-12) with the PZ-90 central
field + J2 in the rotating frame (GLONASS ICD 5.1 A.3.1.2, luni-solar
acceleration 0, as the records state); records give the state at tb every
30 min (hh:15 and hh:45 UTC).

Constellations (counts: GPS 24, Galileo 24, BeiDou 30, GLONASS 24, QZSS 4, NavIC 7):
- GPS: the 24 baseline slots A1..F4 of GPS SPS PS 2001/2008 table 3-1 (RAAN,
  argument of latitude at 1993-07-01 00:00 UTC, taken as GPST: 9 s apart),
  i = 55 deg, a = 26 559.7 km, e = 0; PRNs G01..G24 in slot order (not the real
  PRN-to-slot assignment, which changes with launches).  The 2020 SPS PS
  (5th ed., table 3.2-1) defines an expandable 24-slot layout with a new
  epoch; the 2001 table is used here.
- Galileo: Walker 56 deg: 24/3/1, a = 29 600.318 km (Galileo OS SDD issue 1.1,
  2.1); absolute RAAN/phase at T_REF arbitrary (plane A at 0 deg); E01..E24.
- BeiDou-3 (BDS OS performance standard 3.0, 2021, 2.1): 24 MEO Walker 55 deg:
  24/3/1, a = 27 906.137 km (altitude 21 528 km) as C19-C30, C32-C37, C41-C46;
  3 IGSO at 55 deg on one ground track crossing the equator at 118 E (C38-C40,
  8 h apart); 3 GEO at 140 E (C01), 80 E (C02), 110.5 E (C03); GEO records in
  the BDS GEO convention (BDS-SIS-ICD-B1I 3.0 5.2.4.12: elements in a frame
  tilted by 5 deg).
- GLONASS (GLONASS ICD 5.1, 3.5): 24 slots in 3 planes 120 deg apart at 64.8 deg,
  a = 25 510 km, 45 deg in-plane spacing, 15 deg shift between adjacent planes;
  R01..R24 = slots; frequency channel plan of the ICD/IAC (antipodal slots
  j and j+4 of a plane share k), identical to the broadcast of 2022-01-01.
- QZSS (IS-QZSS-PNT-005 / QZSS orbit overview): 3 QZO (J01-J03) e = 0.075,
  i = 41 deg, omega = 270 deg (apogee north), ascending node at 135 E, 8 h
  apart; 1 GEO at 127 E (J07, QZS-3).
- NavIC (IRNSS SIS ICD 1.1, 1.2): 3 GEO at 32.5 E (I06), 83 E (I03), 129.5 E (I07);
  4 IGSO at 29 deg, ascending nodes at 55 E (I01, I02) and 111.75 E (I04, I05),
  the two of a pair 12 h apart.

Records: clocks zero (af0 = af1 = af2 = 0, GLONASS tau = gamma = 0), all
healthy, group delays 0.  Spacing and fit: GPS every 2 h, fit 4 h; Galileo
and NavIC every 2 h; BeiDou and QZSS every hour (QZSS fit 2 h); GLONASS every
30 min.  The header carries Klobuchar coefficients: RTKLIB's ``ion_default``
(a GPS broadcast of 2004-01-01), typical mid-latitude values, not a forecast.
"""
from __future__ import annotations

import datetime as _dt
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import constants as K
from ..rinex.nav_write import write_rinex3_nav
from ..time import GPS_EPOCH, SYSTEM_SCALE, GnssTime, gps_minus_utc_at_gps

#: reference epoch of the nominal elements: GPS SPS PS table 3-1 epoch (1993-07-01 00:00, read as GPST)
T_REF = GnssTime.from_iso("1993-07-01T00:00:00", "GPS")
#: Greenwich hour angle at T_REF [rad] (GPS SPS PS 2001 table 3-1: 18 h 36 min 14.4 s)
THETA_REF_RAD = (18 + 36 / 60 + 14.4 / 3600) / 24 * 2 * math.pi

#: Klobuchar alpha/beta: RTKLIB ion_default (GPS broadcast of 2004-01-01), "typical" values
KLOBUCHAR_TYPICAL = {
    "GPSA": [0.1118e-07, -0.7451e-08, -0.5961e-07, 0.1192e-06],
    "GPSB": [0.1167e06, -0.2294e06, -0.1311e06, 0.1049e07],
}

#: system -> (GM [m^3/s^2], Earth rotation rate [rad/s]) of its ICD (as kepler.py)
_SYS_CONST = {
    "G": (K.GM_GPS_M3PS2, K.OMEGA_E_GPS_RADPS),
    "J": (K.GM_QZS_M3PS2, K.OMEGA_E_QZS_RADPS),
    "E": (K.GM_GAL_M3PS2, K.OMEGA_E_GAL_RADPS),
    "C": (K.GM_BDS_M3PS2, K.OMEGA_E_BDS_RADPS),
    "I": (K.GM_IRN_M3PS2, K.OMEGA_E_IRN_RADPS),
    "R": (K.GM_GLO_M3PS2, K.OMEGA_E_GLO_RADPS),
}
#: record spacing [s] and fit interval [h] (0: not written) per system
_SPACING_S = {"G": 7200, "E": 7200, "C": 3600, "J": 3600, "I": 7200, "R": 1800}
_FIT_H = {"G": 4.0, "J": 2.0}

# GPS SPS PS 2001 / 2008 table 3-1: slot -> (RAAN deg, argument of latitude deg) at T_REF
GPS_SLOTS = {
    "A1": (272.847, 268.126), "A2": (272.847, 161.786), "A3": (272.847, 11.676), "A4": (272.847, 41.806),
    "B1": (332.847, 80.956), "B2": (332.847, 173.336), "B3": (332.847, 309.976), "B4": (332.847, 204.376),
    "C1": (32.847, 111.876), "C2": (32.847, 11.796), "C3": (32.847, 339.666), "C4": (32.847, 241.556),
    "D1": (92.847, 135.226), "D2": (92.847, 265.446), "D3": (92.847, 35.156), "D4": (92.847, 167.356),
    "E1": (152.847, 197.046), "E2": (152.847, 302.596), "E3": (152.847, 66.066), "E4": (152.847, 333.686),
    "F1": (212.847, 238.886), "F2": (212.847, 345.226), "F3": (212.847, 105.206), "F4": (212.847, 135.346),
}
#: GLONASS frequency channel k per orbital slot (GLONASS ICD 5.1 3.3.1.1 / IAC plan since 2005:
#: antipodal slots share k); equal to the broadcast FreqNum of 2022-01-01 (OPEC navigation file)
GLONASS_CHANNELS = {
    1: 1, 2: -4, 3: 5, 4: 6, 5: 1, 6: -4, 7: 5, 8: 6,
    9: -2, 10: -7, 11: 0, 12: -1, 13: -2, 14: -7, 15: 0, 16: -1,
    17: 4, 18: -3, 19: 3, 20: 2, 21: 4, 22: -3, 23: 3, 24: 2,
}
BDS_MEO_PRNS = list(range(19, 31)) + list(range(32, 38)) + list(range(41, 47))

_A_GPS_M = 26559.7e3          # GPS SPS PS 2001 table 3-1
_A_GAL_M = 29600.318e3        # Galileo OS SDD 1.1, 2.1
_A_BDS_MEO_M = 27906.137e3    # BDS OS PS 3.0: altitude 21 528 km + WGS 84 a
_A_GLO_M = 25510.0e3          # GLONASS ICD 5.1 3.5
_D = math.pi / 180.0


@dataclass(frozen=True)
class NominalSatellite:
    """Nominal orbit of one satellite (angles in rad, at T_REF, in the quasi-inertial frame)."""

    sv: str
    kind: str                 # MEO, IGSO, GEO, QZO
    a_m: float
    e: float
    i_rad: float
    argp_rad: float           # argument of perigee omega
    raan_ref_rad: float       # right ascension of the ascending node at T_REF
    m_ref_rad: float          # mean anomaly at T_REF
    raan_rate_radps: float    # secular nodal rate (J2)
    n_radps: float            # mean motion
    slot: str = ""
    glo_channel: int = 0

    @property
    def system(self) -> str:
        return self.sv[0]

    @property
    def bds_geo(self) -> bool:
        return self.system == "C" and self.kind == "GEO"


def _j2_node_rate(gm: float, a_m: float, e: float, i_rad: float) -> float:
    """Secular nodal regression [rad/s] (Vallado 4th ed. eq. 9-41), WGS 84 J2 and a_e."""
    n = math.sqrt(gm / a_m**3)
    p = a_m * (1 - e * e)
    return -1.5 * n * K.J2_WGS84 * (K.WGS84_A_M / p) ** 2 * math.cos(i_rad)


def _mean_from_true(nu: float, e: float) -> float:
    ecc_anom = 2 * math.atan2(math.sqrt(1 - e) * math.sin(nu / 2), math.sqrt(1 + e) * math.cos(nu / 2))
    return ecc_anom - e * math.sin(ecc_anom)


def _walker(system, prns, a_m, i_deg, t, p, f, raan0_deg=0.0, u0_deg=0.0, names=None):
    """Walker i:t/p/f constellation: planes 360/p apart, in-plane 360 p/t, phase f*360/t per plane."""
    gm, _ = _SYS_CONST[system]
    i = i_deg * _D
    n = math.sqrt(gm / a_m**3)
    rate = _j2_node_rate(gm, a_m, 0.0, i)
    per_plane = t // p
    out = []
    for k, prn in enumerate(prns):
        plane, s = divmod(k, per_plane)
        raan = (raan0_deg + 360.0 * plane / p) * _D
        u = (u0_deg + 360.0 * s / per_plane + f * 360.0 * plane / t) * _D
        slot = names[k] if names else f"{'ABC'[plane]}{s + 1}"
        out.append(NominalSatellite(f"{system}{prn:02d}", "MEO", a_m, 0.0, i, 0.0, raan, u, rate, n, slot))
    return out


def _repeat_track(sv, kind, i_deg, e, argp_deg, node_lon_deg, delay_frac, glo=0):
    """GEO / IGSO / QZO: ground track fixed in ECEF.  The satellite crosses its ascending node at
    ECEF longitude ``node_lon_deg`` at T_REF + delay_frac * (repeat period); GEO: stays at that longitude."""
    system = sv[0]
    gm, we = _SYS_CONST[system]
    i, w = i_deg * _D, argp_deg * _D
    if kind == "GEO":
        rate = 0.0
        n = we
    else:
        a = (gm / we**2) ** (1 / 3)
        for _ in range(5):  # n = we - Omega_dot(a), a = (GM/n^2)^(1/3)
            rate = _j2_node_rate(gm, a, e, i)
            n = we - rate
            a = (gm / n**2) ** (1 / 3)
    a = (gm / n**2) ** (1 / 3)
    tau = delay_frac * 2 * math.pi / n  # time after T_REF of the node crossing
    m_node = _mean_from_true(-w, e)     # true anomaly at the node: nu = -omega
    m_ref = m_node - n * tau
    # at T_REF + tau: RAAN - theta = node_lon  ->  RAAN_ref = node_lon + theta(T_REF + tau) - rate tau
    raan_ref = node_lon_deg * _D + THETA_REF_RAD + we * tau - rate * tau
    return NominalSatellite(sv, kind, a, e, i, w, raan_ref, m_ref, rate, n, kind, glo)


def nominal_constellation(systems: str = "GRECJI") -> list[NominalSatellite]:
    """The nominal satellites of ``systems`` (see the module docstring for sources)."""
    sats: list[NominalSatellite] = []
    bad = set(systems) - set("GRECJI")
    if bad:
        raise ValueError(f"systems={systems!r}: unknown letters {''.join(sorted(bad))} (expected letters of GRECJI)")
    if "G" in systems:
        gm, _ = _SYS_CONST["G"]
        n = math.sqrt(gm / _A_GPS_M**3)
        rate = _j2_node_rate(gm, _A_GPS_M, 0.0, 55 * _D)
        for k, (slot, (raan, u)) in enumerate(GPS_SLOTS.items()):
            sats.append(NominalSatellite(f"G{k + 1:02d}", "MEO", _A_GPS_M, 0.0, 55 * _D, 0.0, raan * _D, u * _D,
                                         rate, n, slot))
    if "R" in systems:
        gm, _ = _SYS_CONST["R"]
        i = 64.8 * _D
        n = math.sqrt(gm / _A_GLO_M**3)
        rate = _j2_node_rate(gm, _A_GLO_M, 0.0, i)
        for slot in range(1, 25):
            plane, j = divmod(slot - 1, 8)
            raan = 120.0 * plane * _D
            u = (-45.0 * j + 15.0 * plane) * _D  # ICD 5.1 3.5: 45 deg in plane, 15 deg between planes
            sats.append(NominalSatellite(f"R{slot:02d}", "MEO", _A_GLO_M, 0.0, i, 0.0, raan, u, rate, n,
                                         f"{slot}", GLONASS_CHANNELS[slot]))
    if "E" in systems:
        sats += _walker("E", range(1, 25), _A_GAL_M, 56.0, 24, 3, 1)
    if "C" in systems:
        sats += [_repeat_track("C01", "GEO", 0.0, 0.0, 0.0, 140.0, 0.0),
                 _repeat_track("C02", "GEO", 0.0, 0.0, 0.0, 80.0, 0.0),
                 _repeat_track("C03", "GEO", 0.0, 0.0, 0.0, 110.5, 0.0)]
        sats += _walker("C", BDS_MEO_PRNS, _A_BDS_MEO_M, 55.0, 24, 3, 1)
        sats += [_repeat_track(f"C{38 + k}", "IGSO", 55.0, 0.0, 0.0, 118.0, k / 3) for k in range(3)]
    if "J" in systems:
        sats += [_repeat_track(f"J{1 + k:02d}", "QZO", 41.0, 0.075, 270.0, 135.0, k / 3) for k in range(3)]
        sats.append(_repeat_track("J07", "GEO", 0.0, 0.0, 0.0, 127.0, 0.0))
    if "I" in systems:
        sats += [_repeat_track("I01", "IGSO", 29.0, 0.0, 0.0, 55.0, 0.0),
                 _repeat_track("I02", "IGSO", 29.0, 0.0, 0.0, 55.0, 0.5),
                 _repeat_track("I03", "GEO", 0.0, 0.0, 0.0, 83.0, 0.0),
                 _repeat_track("I04", "IGSO", 29.0, 0.0, 0.0, 111.75, 0.0),
                 _repeat_track("I05", "IGSO", 29.0, 0.0, 0.0, 111.75, 0.5),
                 _repeat_track("I06", "GEO", 0.0, 0.0, 0.0, 32.5, 0.0),
                 _repeat_track("I07", "GEO", 0.0, 0.0, 0.0, 129.5, 0.0)]
    order = {s: k for k, s in enumerate("GRECJI")}
    return sorted(sats, key=lambda s: (order[s.system], s.sv))


# ------------------------------------------------------------------------------------------
# nominal states
# ------------------------------------------------------------------------------------------
def _kepler_E(m, e):
    ecc = np.array(m, dtype=np.float64, copy=True)
    for _ in range(30):
        d = (ecc - e * np.sin(ecc) - m) / (1 - e * np.cos(ecc))
        ecc -= d
        if np.all(np.abs(d) < 1e-15):
            break
    return ecc


def _angles(sat: NominalSatellite, dt_ref_s):
    """(mean anomaly, RAAN - theta (ECEF node longitude), its rate) at T_REF + dt_ref_s."""
    _, we = _SYS_CONST[sat.system]
    dt = np.asarray(dt_ref_s, dtype=np.float64)
    m = np.mod(sat.m_ref_rad + sat.n_radps * dt, 2 * np.pi)
    lam = np.mod(sat.raan_ref_rad + sat.raan_rate_radps * dt - THETA_REF_RAD - we * dt, 2 * np.pi)
    return m, lam, sat.raan_rate_radps - we


def _kepler_state_ecef(sat: NominalSatellite, dt_ref_s):
    """Closed-form ECEF position [m] and velocity [m/s] of a Keplerian nominal orbit."""
    m, lam, lam_dot = _angles(sat, dt_ref_s)
    e, a = sat.e, sat.a_m
    ecc = _kepler_E(m, e)
    r = a * (1 - e * np.cos(ecc))
    nu = np.arctan2(np.sqrt(1 - e * e) * np.sin(ecc), np.cos(ecc) - e)
    u = nu + sat.argp_rad
    e_dot = sat.n_radps / (1 - e * np.cos(ecc))
    r_dot = a * e * np.sin(ecc) * e_dot
    u_dot = np.sqrt(1 - e * e) * e_dot / (1 - e * np.cos(ecc))
    # q: position in the orbital plane (x along the node); R1(-i) then R3(-lambda)
    ci, si = math.cos(sat.i_rad), math.sin(sat.i_rad)
    cu, su = np.cos(u), np.sin(u)
    xq, yq = r * cu, r * su
    xq_dot = r_dot * cu - r * u_dot * su
    yq_dot = r_dot * su + r * u_dot * cu
    cl, sl = np.cos(lam), np.sin(lam)
    x = xq * cl - yq * ci * sl
    y = xq * sl + yq * ci * cl
    z = yq * si
    vx = xq_dot * cl - yq_dot * ci * sl + lam_dot * (-xq * sl - yq * ci * cl)
    vy = xq_dot * sl + yq_dot * ci * cl + lam_dot * (xq * cl - yq * ci * sl)
    vz = yq_dot * si
    return np.stack([x, y, z], axis=-1), np.stack([vx, vy, vz], axis=-1)


def _glonass_rhs(_t, y):
    """GLONASS ICD 5.1 A.3.1.2 equations of motion in PZ-90 (rotating), luni-solar terms 0."""
    gm, ae, j2, w = K.GM_GLO_M3PS2, K.A_E_GLO_M, K.J2_GLO, K.OMEGA_E_GLO_RADPS
    s = y.reshape(-1, 6)
    x, yy, z, vx, vy, vz = s.T
    r2 = x * x + yy * yy + z * z
    r = np.sqrt(r2)
    g = -gm / (r2 * r)
    c = -1.5 * j2 * gm * ae * ae / (r2 * r2 * r)
    zr = 5 * z * z / r2
    ax = g * x + c * x * (1 - zr) + w * w * x + 2 * w * vy
    ay = g * yy + c * yy * (1 - zr) + w * w * yy - 2 * w * vx
    az = g * z + c * z * (3 - zr)
    return np.stack([vx, vy, vz, ax, ay, az], axis=1).ravel()


class SyntheticConstellation:
    """Nominal orbits of ``systems`` over [start, start + duration_s] and their broadcast records."""

    def __init__(self, start: GnssTime, duration_s: float, systems: str = "GRECJI"):
        if not duration_s > 0:
            raise ValueError(f"duration_s must be positive, got {duration_s}")
        if np.ndim(start.sec) != 0:
            raise ValueError("start must be a scalar GnssTime")
        self.start = start
        self.end = start + float(duration_s)
        self.systems = systems
        self.satellites = nominal_constellation(systems)
        self._by_sv = {s.sv: s for s in self.satellites}
        self._glo_sol = None
        glo = [s for s in self.satellites if s.system == "R"]
        if glo:
            self._init_glonass(glo)

    # ----- record epochs --------------------------------------------------------------
    def record_epochs(self, system: str) -> GnssTime:
        """Reference times (toe/tb) of the records of ``system``, covering [start, end], as GPS time."""
        step = _SPACING_S[system]
        scale = "UTC" if system == "R" else SYSTEM_SCALE[system]
        offset = 900 if system == "R" else 0  # GLONASS tb at hh:15 and hh:45
        s0, _ = self.start.seconds_in(scale)
        s1, f1 = self.end.seconds_in(scale)
        first = (int(s0) - offset) // step * step + offset
        last = -((-(int(s1) + (1 if f1 > 0 else 0) - offset)) // step) * step + offset
        k = np.arange(first, last + 1, step, dtype=np.int64)
        # seconds counted in the scale -> GPS time (leap seconds for UTC, 14 s for BDT)
        times = [GnssTime.from_datetime(GPS_EPOCH + _dt.timedelta(seconds=int(x)), scale) for x in k]
        return GnssTime.stack(times)

    # ----- GLONASS ----------------------------------------------------------------------
    def _init_glonass(self, glo):
        from scipy.integrate import solve_ivp

        tb = self.record_epochs("R")
        self._glo_t0 = tb[0]
        span = (tb[-1] - tb[0]) + 1200.0
        y0 = []
        for s in glo:
            pos, vel = _kepler_state_ecef(s, tb[0] - T_REF)
            y0.append(np.concatenate([pos, vel]))
        y0 = np.concatenate(y0)
        kw = dict(method="DOP853", rtol=1e-12, atol=1e-7, dense_output=True)
        fwd = solve_ivp(_glonass_rhs, (0.0, span), y0, **kw)
        bwd = solve_ivp(_glonass_rhs, (0.0, -1200.0), y0, **kw)
        if not (fwd.success and bwd.success):
            raise RuntimeError(f"GLONASS nominal orbit integration failed: {fwd.message} {bwd.message}")
        self._glo_sol = (fwd.sol, bwd.sol, span)
        self._glo_index = {s.sv: k for k, s in enumerate(glo)}

    def _glonass_state(self, sv: str, dt0):
        fwd, bwd, span = self._glo_sol
        dt0 = np.atleast_1d(np.asarray(dt0, dtype=np.float64))
        if np.any(dt0 < -1200.0) or np.any(dt0 > span):
            raise ValueError(f"{sv}: instant outside the synthetic span")
        k = self._glo_index[sv]
        out = np.empty((len(dt0), 6))
        neg = dt0 < 0
        if np.any(~neg):
            out[~neg] = fwd(dt0[~neg])[6 * k:6 * k + 6].T
        if np.any(neg):
            out[neg] = bwd(dt0[neg])[6 * k:6 * k + 6].T
        return out[:, :3], out[:, 3:]

    # ----- nominal states ---------------------------------------------------------------
    def nominal_state(self, sv: str, t: GnssTime):
        """ECEF position [m] and velocity [m/s] of the nominal orbit of ``sv`` at ``t`` (scalar or array)."""
        if sv not in self._by_sv:
            raise ValueError(f"satellite {sv!r} is not in the synthetic constellation ({self.systems})")
        sat = self._by_sv[sv]
        if sat.system == "R":
            return self._glonass_state(sv, t - self._glo_t0)
        return _kepler_state_ecef(sat, t - T_REF)

    # ----- records -------------------------------------------------------------------------
    def records(self) -> dict[str, list[dict]]:
        """Broadcast records for :func:`write_rinex3_nav` (georinex field names)."""
        out: dict[str, list[dict]] = {}
        for sat in self.satellites:
            s = sat.system
            lst = out.setdefault(s, [])
            for toe in self.record_epochs(s):
                lst.append(self._glonass_record(sat, toe) if s == "R" else self._kepler_record(sat, toe))
        return out

    def _kepler_record(self, sat: NominalSatellite, toe: GnssTime) -> dict:
        s = sat.system
        gm, we = _SYS_CONST[s]
        scale = SYSTEM_SCALE[s]
        week, toe_tow = toe.week_tow(scale)
        gps_week, _ = toe.week_tow("GPS")
        m, lam, _ = _angles(sat, toe - T_REF)
        m, lam = float(m), float(lam)
        i, argp, raan_rate = sat.i_rad, sat.argp_rad, sat.raan_rate_radps
        if sat.bds_geo:
            i, argp, m, lam, raan_rate = _bds_geo_elements(sat, toe - T_REF, gm, we)
        # Omega_k = Omega0 + (Omega_dot - we) tk - we toe (IS-GPS-200N table 20-IV): node longitude at toe
        omega0 = _wrap(lam + we * toe_tow)
        step = _SPACING_S[s]
        idx = int(toe.sec // step)
        rec = {
            "sv": sat.sv, "time": toe.to_datetime(scale),
            "SVclockBias": 0.0, "SVclockDrift": 0.0, "SVclockDriftRate": 0.0,
            "Crs": 0.0, "DeltaN": 0.0, "M0": _wrap(m), "Cuc": 0.0, "Eccentricity": sat.e, "Cus": 0.0,
            "sqrtA": math.sqrt(sat.a_m), "Toe": toe_tow, "Cic": 0.0, "Omega0": omega0, "Cis": 0.0,
            "Io": i, "Crc": 0.0, "omega": _wrap(argp), "OmegaDot": raan_rate, "IDOT": 0.0,
            "health": 0.0, "TransTime": max(toe_tow - step / 2, 0.0),
        }
        if s in "GJ":
            rec.update(IODE=idx % 256, IODC=idx % 256, CodesL2=1.0, GPSWeek=gps_week, L2Pflag=0.0, SVacc=2.0,
                       TGD=0.0, FitIntvl=_FIT_H[s])
        elif s == "E":
            # DataSrc 517: I/NAV E1-B + E5b, clock for E5b/E1 (RINEX 3.04 A8)
            rec.update(IODnav=idx % 1024, DataSrc=517.0, GALWeek=gps_week, SISA=3.12, BGDe5a=0.0, BGDe5b=0.0)
        elif s == "C":
            rec.update(AODE=1.0, AODC=1.0, BDTWeek=week, SVacc=2.0, SatH1=0.0, TGD1=0.0, TGD2=0.0)
            rec.pop("health")
        elif s == "I":
            rec.update(IODEC=idx % 256, BDTWeek=gps_week, URA=2.0, TGD=0.0)
        return rec

    def _glonass_record(self, sat: NominalSatellite, tb: GnssTime) -> dict:
        pos, vel = self._glonass_state(sat.sv, tb - self._glo_t0)
        utc = tb.to_datetime("UTC")
        tk = tb - 900.0
        tk_utc_sow = int(tk.seconds_in("UTC")[0]) % 604800  # UTC seconds of week (1980-01-06 was a Sunday)
        return {
            "sv": sat.sv, "time": utc, "SVclockBias": 0.0, "SVrelFreqBias": 0.0,
            "MessageFrameTime": float(tk_utc_sow),
            "X": pos[0, 0], "dX": vel[0, 0], "dX2": 0.0, "health": 0.0,
            "Y": pos[0, 1], "dY": vel[0, 1], "dY2": 0.0, "FreqNum": float(sat.glo_channel),
            "Z": pos[0, 2], "dZ": vel[0, 2], "dZ2": 0.0, "AgeOpInfo": 0.0,
        }

    def header(self) -> dict:
        return {"IONOSPHERIC CORR": KLOBUCHAR_TYPICAL, "LEAP SECONDS": gps_minus_utc_at_gps(self.start.sec),
                "program": "gnss_sim synthetic", "run_by": "gnss_sim",
                # the creation date field holds the span start: the same request gives the same file
                "date": self.start.to_datetime("UTC").strftime("%Y%m%d %H%M%S") + " UTC",
                "comments": ["Synthetic nominal constellation, no real satellite data:",
                             "gnss_sim core/ephemeris/synthetic.py; clocks zero",
                             "Klobuchar: RTKLIB ion_default, typical values only"]}

    def write(self, path) -> Path:
        return write_rinex3_nav(path, self.records(), self.header())

    def nav(self):
        """The records as reading the file :meth:`write` writes gives them (rinex.nav.NavData), without
        the text: the same values to the last bit (rinex.nav.nav_from_records)."""
        from ..rinex.nav import nav_from_records

        return nav_from_records(self.records(), self.header(), name=f"synthetic constellation {self.systems}")


def _wrap(x: float) -> float:
    """Angle in (-pi, pi]."""
    y = math.fmod(x + math.pi, 2 * math.pi)
    if y <= 0:
        y += 2 * math.pi
    return y - math.pi


def _bds_geo_elements(sat: NominalSatellite, dt_ref_s: float, gm: float, we: float):
    """Elements of a BeiDou GEO record (BDS-SIS-ICD-B1I 3.0 5.2.4.12).

    The ICD rotates [X Y Z]_GK by R_X(-5 deg) then R_Z(we tk): the GK frame is
    the ECEF frame at toe tilted by 5 deg, fixed in inertial space.  The orbit's
    state at toe (inertial velocity in ECEF axes) is taken into GK and turned
    into Keplerian elements there.  Returns (i, omega, M, node angle in GK, Omega_dot = 0).
    """
    pos, vel = _kepler_state_ecef(sat, dt_ref_s)
    r_f = np.asarray(pos, dtype=np.float64).reshape(3)
    v_f = np.asarray(vel, dtype=np.float64).reshape(3) + np.cross([0.0, 0.0, we], r_f)
    phi = math.radians(K.BDS_GEO_TILT_DEG)  # R_X(phi) of the ICD: [[1,0,0],[0,c,s],[0,-s,c]]
    c, s = math.cos(phi), math.sin(phi)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]])
    r_gk, v_gk = rx.T @ r_f, rx.T @ v_f  # [X Y Z]_F = R_X(phi) [X Y Z]_GK
    h = np.cross(r_gk, v_gk)
    i = math.acos(h[2] / np.linalg.norm(h))
    node = np.cross([0.0, 0.0, 1.0], h)
    raan = math.atan2(node[1], node[0])
    nn = node / np.linalg.norm(node)
    w_dir = np.cross(h / np.linalg.norm(h), nn)
    u = math.atan2(float(r_gk @ w_dir), float(r_gk @ nn))
    # circular orbit (e = 0): omega = 0, M = u
    return i, 0.0, u, raan, 0.0


def write_synthetic_nav(path, start: GnssTime, duration_s: float, systems: str = "GRECJI") -> Path:
    """Write a RINEX 3.04 navigation file of the synthetic constellation covering
    [start, start + duration_s] (GPS time); returns the path."""
    return SyntheticConstellation(start, duration_s, systems).write(path)
