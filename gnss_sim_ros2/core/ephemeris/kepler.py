"""Keplerian broadcast ephemerides: orbit and clock, vectorised over records.

Systems and their algorithms:
- GPS / QZSS: IS-GPS-200N 20.3.3.4.3, table 20-IV (position, and the velocity
  equations of its continuation); IS-QZSS-PNT-005 5.2.4 (same algorithm).
- Galileo: OS SIS ICD 2.1, 5.1.1 table 60 (same algorithm, Galileo GM).
- BeiDou MEO/IGSO: BDS-SIS-ICD-B1I 3.0, 5.2.4.12 (same algorithm, CGCS2000).
  GEO (C01-C05, C59-C62): Omega_k = Omega0 + OmegaDot tk - omega_e toe, then
  [X Y Z] = R_Z(omega_e tk) R_X(-5 deg) [X_GK Y_GK Z_GK].
- NavIC: IRNSS SIS ICD for SPS 1.1, 6.2.1 (same algorithm, WGS 84 constants).
Each system uses its own GM, Earth rotation rate and relativistic F
(core/constants.py).

Velocity: analytic time derivative of the same equations.
Acceleration: analytic two-body + J2 gravity at the computed position and
velocity, expressed in the rotating ECEF frame (Coriolis and centrifugal
terms).  It neglects luni-solar (up to ~7e-6 m/s^2 at GNSS altitude), higher
geopotential terms and solar pressure; against a central difference of the
broadcast velocity it agrees to about 1e-5 m/s^2 (test_ephemeris_broadcast).

Clock (IS-GPS-200N 20.3.3.3.3.1): polynomial af0 + af1 dt + af2 dt^2 with
dt = t - toc (SP3 convention); the periodic relativistic term F e sqrt(A) sin E
is returned separately; the group delay is the record's TGD/BGD (not applied).
"""
from __future__ import annotations

import numpy as np

from .. import constants as K
from ..time import GnssTime

#: system -> (GM [m^3/s^2], Earth rotation rate [rad/s], F [s/m^0.5])
SYSTEM_CONSTANTS = {
    "G": (K.GM_GPS_M3PS2, K.OMEGA_E_GPS_RADPS, K.F_REL_GPS_S_PER_SQRTM),
    "J": (K.GM_QZS_M3PS2, K.OMEGA_E_QZS_RADPS, K.F_REL_QZS_S_PER_SQRTM),
    "E": (K.GM_GAL_M3PS2, K.OMEGA_E_GAL_RADPS, K.F_REL_GAL_S_PER_SQRTM),
    "C": (K.GM_BDS_M3PS2, K.OMEGA_E_BDS_RADPS, K.F_REL_BDS_S_PER_SQRTM),
    "I": (K.GM_IRN_M3PS2, K.OMEGA_E_IRN_RADPS, K.F_REL_IRN_S_PER_SQRTM),
}

# parameter rows of the (NPAR, n) matrix
_NAMES = ("gm", "we", "f", "geo", "a", "n", "e", "sq1me2", "m0", "omega", "cuc", "cus", "crc", "crs",
          "cic", "cis", "i0", "idot", "om_base", "omega_dot_k", "ae", "af0", "af1", "af2", "sqrt_a")
_IX = {name: i for i, name in enumerate(_NAMES)}

_SIN_TILT = np.sin(np.radians(K.BDS_GEO_TILT_DEG))
_COS_TILT = np.cos(np.radians(K.BDS_GEO_TILT_DEG))


def is_bds_geo(sv) -> np.ndarray:
    """True for BeiDou GEO satellites: C01-C05 and C59-C62 (BDS-SIS-ICD-B1I 3.0, 5.2.4.12; as RTKLIB)."""
    sv = np.atleast_1d(np.asarray(sv, dtype="U3"))
    is_c = np.char.startswith(sv, "C")
    prn = np.array([int(s[1:]) if s[1:].isdigit() else 0 for s in sv])
    return is_c & ((prn <= 5) | (prn >= 59))


class KeplerParams:
    """Per-record constants of Keplerian records, precomputed once.

    ``rec`` is a table with the KEPLER_DTYPE fields of core/rinex/nav/
    (``sys``, ``sv``, ``sqrt_a`` ... ``af2``, ``toe_sec``/``toe_frac``, ``toc_sec``/``toc_frac``).
    """

    def __init__(self, rec: np.ndarray):
        n = len(rec)
        P = np.zeros((len(_NAMES), n))
        sys = np.asarray(rec["sys"])
        for s, (gm, we, f) in SYSTEM_CONSTANTS.items():
            m = sys == s
            P[_IX["gm"], m], P[_IX["we"], m], P[_IX["f"], m] = gm, we, f
        unknown = ~np.isin(sys, list(SYSTEM_CONSTANTS))
        if np.any(unknown):
            raise ValueError(f"record system {sys[unknown][0]!r} has no Keplerian constants")
        P[_IX["geo"]] = is_bds_geo(rec["sv"]) if n else np.zeros(0)
        a = rec["sqrt_a"] ** 2
        P[_IX["a"]] = a
        P[_IX["sqrt_a"]] = rec["sqrt_a"]
        # IS-GPS-200N table 20-IV: n0 = sqrt(GM/A^3), n = n0 + delta_n
        P[_IX["n"]] = np.sqrt(P[_IX["gm"]] / a**3) + rec["delta_n"]
        P[_IX["e"]] = rec["e"]
        P[_IX["sq1me2"]] = np.sqrt(1.0 - rec["e"] ** 2)
        for name in ("m0", "omega", "cuc", "cus", "crc", "crs", "cic", "cis", "i0", "idot", "af0", "af1", "af2"):
            P[_IX[name]] = rec[name]
        # IS-GPS-200N table 20-IV: Omega_k = Omega0 + (OmegaDot - we) tk - we toe;
        # BDS GEO (B1I ICD 5.2.4.12): Omega_k = Omega0 + OmegaDot tk - we toe
        we = P[_IX["we"]]
        P[_IX["om_base"]] = rec["omega0"] - we * rec["toe_tow_s"]
        P[_IX["omega_dot_k"]] = np.where(P[_IX["geo"]] > 0, rec["omega_dot"], rec["omega_dot"] - we)
        P[_IX["ae"]] = a * rec["e"]
        self.P = P
        self.toe_sec = np.asarray(rec["toe_sec"], dtype=np.int64)
        self.toe_frac = np.asarray(rec["toe_frac"], dtype=np.float64)
        self.toc_sec = np.asarray(rec["toc_sec"], dtype=np.int64)
        self.toc_frac = np.asarray(rec["toc_frac"], dtype=np.float64)
        self.any_geo = bool(np.any(P[_IX["geo"]]))

    def __len__(self):
        return self.P.shape[1]

    def evaluate(self, idx, t_sec, t_frac, acceleration: bool = True) -> dict:
        """States of records ``idx`` at GPS time (t_sec, t_frac) (scalars or arrays like idx)."""
        idx = np.asarray(idx, dtype=np.int64)
        tk = (np.asarray(t_sec, dtype=np.int64) - self.toe_sec[idx]).astype(np.float64) + (t_frac - self.toe_frac[idx])
        dtc = (np.asarray(t_sec, dtype=np.int64) - self.toc_sec[idx]).astype(np.float64) + (t_frac - self.toc_frac[idx])
        return kepler_from_params(self.P[:, idx], tk, dtc, self.any_geo, acceleration)


def _solve_kepler(M, e):
    """Eccentric anomaly E from M = E - e sin E (Newton; |dE| < 1e-14 rad)."""
    E = M + e * np.sin(M)
    for _ in range(20):
        dE = (E - e * np.sin(E) - M) / (1.0 - e * np.cos(E))
        E = E - dE
        if np.abs(dE).max(initial=0.0) < 1e-14:     # (NaN never passes, as with np.all)
            break
    return E


def kepler_from_params(P: np.ndarray, tk, dtc, any_geo: bool = True, acceleration: bool = True) -> dict:
    """Orbit and clock from a parameter matrix (rows as ``_NAMES``), tk = t - toe, dtc = t - toc [s]."""
    (gm, we, f, geo, a, n, e, sq1me2, m0, omega, cuc, cus, crc, crs, cic, cis, i0, idot, om_base,
     omega_dot_k, ae, af0, af1, af2, sqrt_a) = P
    tk = np.asarray(tk, dtype=np.float64)
    # IS-GPS-200N table 20-IV
    M = m0 + n * tk
    E = _solve_kepler(M, e)
    sinE, cosE = np.sin(E), np.cos(E)
    one_m_ecosE = 1.0 - e * cosE
    nu = np.arctan2(sq1me2 * sinE, cosE - e)
    phi = nu + omega
    s2, c2 = np.sin(2 * phi), np.cos(2 * phi)
    u = phi + cus * s2 + cuc * c2
    r = a * one_m_ecosE + crs * s2 + crc * c2
    inc = i0 + idot * tk + cis * s2 + cic * c2
    # derivatives (IS-GPS-200N table 20-IV continued)
    Edot = n / one_m_ecosE
    nudot = Edot * sq1me2 / one_m_ecosE
    udot = nudot * (1.0 + 2.0 * (cus * c2 - cuc * s2))
    rdot = ae * sinE * Edot + 2.0 * nudot * (crs * c2 - crc * s2)
    idot_k = idot + 2.0 * nudot * (cis * c2 - cic * s2)
    cu, su = np.cos(u), np.sin(u)
    xp, yp = r * cu, r * su
    xpdot = rdot * cu - yp * udot
    ypdot = rdot * su + xp * udot
    # longitude of the ascending node: MEO/IGSO in ECEF; GEO in the inertial-like GK frame
    Om = om_base + omega_dot_k * tk
    cO, sO = np.cos(Om), np.sin(Om)
    ci, si = np.cos(inc), np.sin(inc)
    x = xp * cO - yp * ci * sO
    y = xp * sO + yp * ci * cO
    z = yp * si
    vx = xpdot * cO - ypdot * ci * sO + yp * si * idot_k * sO - y * omega_dot_k
    vy = xpdot * sO + ypdot * ci * cO - yp * si * idot_k * cO + x * omega_dot_k
    vz = ypdot * si + yp * ci * idot_k
    if any_geo and np.any(geo > 0):
        g = geo > 0
        # BDS-SIS-ICD-B1I 3.0 5.2.4.12: R_X(-5 deg) then R_Z(omega_e tk)
        x1, y1, z1 = x[g], y[g] * _COS_TILT + z[g] * _SIN_TILT, -y[g] * _SIN_TILT + z[g] * _COS_TILT
        vx1, vy1, vz1 = vx[g], vy[g] * _COS_TILT + vz[g] * _SIN_TILT, -vy[g] * _SIN_TILT + vz[g] * _COS_TILT
        wg = we[g]
        ang = wg * tk[g] if np.ndim(tk) else wg * tk
        ca, sa = np.cos(ang), np.sin(ang)
        x[g] = ca * x1 + sa * y1
        y[g] = -sa * x1 + ca * y1
        z[g] = z1
        # d/dt of R_Z(w tk) r1 = R_Z v1 + w dR_Z/d(ang) r1
        vx[g] = ca * vx1 + sa * vy1 + wg * (-sa * x1 + ca * y1)
        vy[g] = -sa * vx1 + ca * vy1 + wg * (-ca * x1 - sa * y1)
        vz[g] = vz1
    pos = _rows3(x, y, z)
    vel = _rows3(vx, vy, vz)
    out = {"pos_ecef_m": pos, "vel_ecef_mps": vel, "E": E}
    if acceleration:
        out["acc_ecef_mps2"] = gravity_j2_ecef(pos, vel, gm, we)
    dtc = np.asarray(dtc, dtype=np.float64)
    out["clock_bias_s"] = af0 + (af1 + af2 * dtc) * dtc
    out["clock_drift_sps"] = af1 + 2.0 * af2 * dtc
    # IS-GPS-200N 20.3.3.3.3.1: delta t_r = F e sqrt(A) sin E_k
    out["relativistic_s"] = f * e * sqrt_a * sinE
    return out


def gravity_j2_ecef(pos_ecef_m, vel_ecef_mps, gm, we, a_e_m=K.WGS84_A_M, j2=K.J2_WGS84):
    """Two-body + J2 acceleration in a frame rotating at ``we`` about Z [m/s^2].

    a = -GM r/|r|^3 (1 + 3/2 J2 (a_e/r)^2 (1 - 5 z^2/r^2)) (z: 3 - 5 z^2/r^2)
        - 2 w x v - w x (w x r)   (as GLONASS ICD 5.1 A.3.1.2 writes it for PZ-90)
    """
    x, y, z = pos_ecef_m[..., 0], pos_ecef_m[..., 1], pos_ecef_m[..., 2]
    r2 = x * x + y * y + z * z
    r = np.sqrt(r2)
    mu_r3 = gm / (r2 * r)
    k = 1.5 * j2 * a_e_m * a_e_m / r2
    zz = 5.0 * z * z / r2
    ax = -mu_r3 * x * (1.0 + k * (1.0 - zz)) + we * we * x + 2.0 * we * vel_ecef_mps[..., 1]
    ay = -mu_r3 * y * (1.0 + k * (1.0 - zz)) + we * we * y - 2.0 * we * vel_ecef_mps[..., 0]
    az = -mu_r3 * z * (1.0 + k * (3.0 - zz))
    return _rows3(ax, ay, az)


def _rows3(x, y, z):
    """(N, 3) array from three (N,) columns (np.stack(..., axis=-1) without its overhead)."""
    x = np.asarray(x)
    out = np.empty(np.shape(x) + (3,))
    out[..., 0], out[..., 1], out[..., 2] = x, y, z
    return out


def kepler_states(rec: np.ndarray, t: GnssTime, acceleration: bool = True) -> dict:
    """Evaluate every row of a Keplerian record table at ``t`` (scalar or one per row).

    Returns a dict of arrays: pos_ecef_m (N,3), vel_ecef_mps, acc_ecef_mps2,
    clock_bias_s, clock_drift_sps, relativistic_s, E (eccentric anomaly).
    No validity check: that is select.py's job.
    """
    params = KeplerParams(rec)
    idx = np.arange(len(rec))
    return params.evaluate(idx, t.sec, t.frac, acceleration)
