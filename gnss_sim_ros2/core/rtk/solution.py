"""rtkrcv solutions read back: llh lines with standard deviations and ENU velocity, ENU baseline
lines (moving baseline: heading), and the NavSatFix status of each quality flag.

Line layout (RTKLIB 2.4.3 solution.c ``outpos`` with the format options of
config.FORMAT_OPTIONS): ``week tow lat_deg lon_deg h_m Q ns sdn sde sdu sdne
sdeu sdun age ratio vn ve vu sdvn sdve sdvu sdvne sdveu sdvun``; the
cross terms are signed square roots of the covariances (``sqvar``: -sqrt(-c)
for a negative c), in metres and m/s, ENU of the solution's position.
Baseline lines (``outenu``, out-solformat enu): ``week tow e n u Q ns sde sdn
sdu sden sdnu sdue age ratio``, the rover minus the base in the base's ENU.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..time import GnssTime

#: RTKLIB solution quality Q (rtklib.h SOLQ_*)
Q_NONE, Q_FIX, Q_FLOAT, Q_SBAS, Q_DGPS, Q_SINGLE, Q_PPP, Q_DR = range(8)
QUALITY_NAMES = {Q_NONE: "none", Q_FIX: "fixed", Q_FLOAT: "float", Q_SBAS: "sbas", Q_DGPS: "dgps",
                 Q_SINGLE: "single", Q_PPP: "ppp", Q_DR: "dead_reckoning"}

#: sensor_msgs/NavSatStatus values
STATUS_NO_FIX, STATUS_FIX, STATUS_SBAS_FIX, STATUS_GBAS_FIX = -1, 0, 1, 2
#: RTKLIB Q -> NavSatStatus.status, as nmea_navsat_driver (ros-drivers, driver.py ``gps_qualities``) maps the
#: GGA quality that RTKLIB writes for each Q (solution.c ``solq_nmea``): RTK fixed (GGA 4) and RTK float
#: (GGA 5) -> STATUS_GBAS_FIX, DGPS (GGA 2) -> STATUS_SBAS_FIX, autonomous (GGA 1) -> STATUS_FIX, none -> NO_FIX.
#: SBAS solutions -> STATUS_SBAS_FIX (what the status means); PPP (GGA 3, not in that table) -> STATUS_FIX
#: (no ground augmentation); dead reckoning (GGA 6, unknown there) -> NO_FIX like the driver's fallback.
#: Fixed and float share GBAS_FIX there: the status topic of the rtk node and the covariance tell them apart.
NAVSAT_STATUS = {Q_NONE: STATUS_NO_FIX, Q_FIX: STATUS_GBAS_FIX, Q_FLOAT: STATUS_GBAS_FIX, Q_SBAS: STATUS_SBAS_FIX,
                 Q_DGPS: STATUS_SBAS_FIX, Q_SINGLE: STATUS_FIX, Q_PPP: STATUS_FIX, Q_DR: STATUS_NO_FIX}


def navsat_status(q: int) -> int:
    """NavSatStatus.status of an RTKLIB quality flag (see NAVSAT_STATUS)."""
    try:
        return NAVSAT_STATUS[int(q)]
    except (KeyError, ValueError, TypeError):
        raise ValueError(f"RTKLIB solution quality {q!r} is not one of {sorted(NAVSAT_STATUS)}") from None


@dataclass
class RtkSolution:
    t: GnssTime                    #: solution time (GPS)
    lat_deg: float
    lon_deg: float
    h_m: float                     #: ellipsoidal height
    q: int                         #: RTKLIB quality (1 fixed, 2 float, 5 single, ...)
    ns: int                        #: satellites used
    cov_enu_m2: np.ndarray         #: (3, 3) position covariance, ENU
    age_s: float                   #: age of the differential (base) data
    ratio: float                   #: ambiguity ratio test value
    vel_enu_mps: np.ndarray        #: (3,) velocity, ENU (zeros when rtkrcv writes none)
    cov_vel_enu_m2ps2: np.ndarray  #: (3, 3)

    @property
    def quality(self) -> str:
        return QUALITY_NAMES.get(self.q, str(self.q))

    @property
    def status(self) -> int:
        return navsat_status(self.q)

    @property
    def sd_enu_m(self) -> np.ndarray:
        return np.sqrt(np.diag(self.cov_enu_m2))


def _cov(sd_n, sd_e, sd_u, q_ne, q_eu, q_un) -> np.ndarray:
    """ENU covariance from RTKLIB's standard deviations and signed square-root cross terms."""
    c_en = q_ne * abs(q_ne)
    c_eu = q_eu * abs(q_eu)
    c_nu = q_un * abs(q_un)
    return np.array([[sd_e ** 2, c_en, c_eu], [c_en, sd_n ** 2, c_nu], [c_eu, c_nu, sd_u ** 2]])


def parse_llh_line(line: str) -> RtkSolution | None:
    """One solution line (None for a header/comment or blank line); ValueError naming the line if malformed."""
    s = line.strip()
    if not s or s.startswith("%"):
        return None
    f = s.split()
    if len(f) not in (15, 24):
        raise ValueError(f"rtkrcv solution line has {len(f)} fields (15 or 24 expected: llh with std, "
                         f"optional velocity): {s!r}")
    try:
        week, tow = int(f[0]), float(f[1])
        v = [float(x) for x in f[2:]]
    except ValueError:
        raise ValueError(f"rtkrcv solution line is not numeric: {s!r}") from None
    lat, lon, h, q, ns, sdn, sde, sdu, sdne, sdeu, sdun, age, ratio = v[:13]
    if len(v) == 22:
        vn, ve, vu, sdvn, sdve, sdvu, sdvne, sdveu, sdvun = v[13:]
        vel = np.array([ve, vn, vu])
        cov_v = _cov(sdvn, sdve, sdvu, sdvne, sdveu, sdvun)
    else:
        vel, cov_v = np.zeros(3), np.zeros((3, 3))
    return RtkSolution(GnssTime.from_week_tow(week, tow, "GPS"), lat, lon, h, int(q), int(ns),
                       _cov(sdn, sde, sdu, sdne, sdeu, sdun), age, ratio, vel, cov_v)


@dataclass
class RtkBaseline:
    """Rover minus base in the base's ENU (moving baseline: the second antenna from the first)."""

    t: GnssTime
    enu_m: np.ndarray              #: (3,)
    q: int
    ns: int
    cov_enu_m2: np.ndarray         #: (3, 3)
    age_s: float
    ratio: float

    @property
    def quality(self) -> str:
        return QUALITY_NAMES.get(self.q, str(self.q))

    @property
    def length_m(self) -> float:
        return float(np.linalg.norm(self.enu_m))

    @property
    def heading_deg(self) -> float:
        """Direction of the baseline, clockwise from north, 0..360 deg."""
        e, n = float(self.enu_m[0]), float(self.enu_m[1])
        return float(np.degrees(np.arctan2(e, n)) % 360.0)

    @property
    def heading_sd_deg(self) -> float:
        """Standard deviation of the heading from the horizontal covariance (first-order propagation:
        d heading / d(e, n) = (n, -e) / (e^2 + n^2))."""
        e, n = float(self.enu_m[0]), float(self.enu_m[1])
        h2 = e * e + n * n
        if h2 <= 0.0:
            return float("inf")
        j = np.array([n, -e]) / h2
        return float(np.degrees(np.sqrt(max(j @ self.cov_enu_m2[:2, :2] @ j, 0.0))))

    @property
    def pitch_deg(self) -> float:
        """Elevation of the baseline above the horizontal plane [deg]."""
        return float(np.degrees(np.arctan2(self.enu_m[2], np.hypot(self.enu_m[0], self.enu_m[1]))))


def parse_enu_line(line: str) -> RtkBaseline | None:
    """One baseline line (None for a header/comment or blank line); ValueError naming the line if malformed."""
    s = line.strip()
    if not s or s.startswith("%"):
        return None
    f = s.split()
    if len(f) != 15:
        raise ValueError(f"rtkrcv baseline line has {len(f)} fields (15 expected: week tow e n u Q ns sde sdn sdu "
                         f"sden sdnu sdue age ratio): {s!r}")
    try:
        week, tow = int(f[0]), float(f[1])
        e, n, u, q, ns, sde, sdn, sdu, sden, sdnu, sdue, age, ratio = (float(x) for x in f[2:])
    except ValueError:
        raise ValueError(f"rtkrcv baseline line is not numeric: {s!r}") from None
    return RtkBaseline(GnssTime.from_week_tow(week, tow, "GPS"), np.array([e, n, u]), int(q), int(ns),
                       _cov(sdn, sde, sdu, sden, sdue, sdnu), age, ratio)
