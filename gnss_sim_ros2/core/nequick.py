"""NeQuick-G ionosphere (Galileo's broadcast model) through the EC JRC reference library.

The electron density model is the JRC implementation of "Ionospheric
Correction Algorithm for Galileo Single Frequency Users" 1.2 (European GNSS
(Galileo) Open Service, 2016), wrapped by the ``nequick`` package (PyPI,
MIT).  It is driven by the three effective ionisation coefficients a0, a1, a2
of the Galileo navigation message (RINEX "GAL" IONOSPHERIC CORR).

The simulator uses it as the *true* ionosphere where those coefficients are
present, so that a receiver correcting with Klobuchar keeps a residual with
the spatial structure of a real one (larger delays towards the geomagnetic
equator, none of Klobuchar's constant night-time floor).

Slant delay: a stated approximation of the library's slant integration
(0.2 ms per ray): the model's vertical TEC (0.012 ms) at the ionospheric
pierce point of a thin shell at ``SHELL_HEIGHT_M`` times the single-layer
mapping function (IONEX 1.0 single-layer model); within 5 % of the slant
integration on the ICA validation rows (test/test_nequick.py).  Vertical TEC is
interpolated (trilinear, continuous: no jumps in carrier phase) between model
values on nodes ``UPDATE_S`` apart in time and ``CELL_DEG`` apart in latitude
and longitude, each computed once: a pierce point moves about 0.1 deg per
minute, so an epoch needs a new node now and then, not a model call per ray.
"""
from __future__ import annotations

import datetime as _dt

import numpy as np

from . import constants as k
from .memo import BoundedCache

#: thin-shell height [m] of the pierce point (IONEX 1.0 and IGS maps use 450 km)
SHELL_HEIGHT_M = 450e3
#: mean Earth radius [m] of the single-layer model (IONEX 1.0 BASE RADIUS 6371 km)
EARTH_RADIUS_M = 6371e3
#: TEC to L1 group delay: 40.3e16 / f^2 [m per TECU] (first-order ionosphere, IERS Conventions 2010 eq. 9.22)
TECU_TO_M_L1 = 40.3e16 / k.F_L1_HZ**2
#: cache of vertical TEC: time step [s] and pierce-point cell [deg]
UPDATE_S = 60.0
CELL_DEG = 0.25


def available() -> bool:
    """True when the ``nequick`` package (the JRC library) can be imported."""
    try:
        import nequick  # noqa: F401
    except ImportError:
        return False
    return True


def pierce_point_deg(lat_deg, lon_deg, az_deg, el_deg, shell_height_m: float = SHELL_HEIGHT_M):
    """(lat, lon) [deg] of the ionospheric pierce point of rays (az, el) from (lat, lon) on a sphere.

    Spherical single-layer geometry (IONEX 1.0 / Schaer 1999, eq. 2.9); arrays broadcast.
    """
    phi = np.radians(np.asarray(lat_deg, dtype=float))
    lam = np.radians(np.asarray(lon_deg, dtype=float))
    a = np.radians(np.asarray(az_deg, dtype=float))
    e = np.radians(np.asarray(el_deg, dtype=float))
    z_ipp = np.arcsin(EARTH_RADIUS_M / (EARTH_RADIUS_M + shell_height_m) * np.cos(e))   # zenith angle at the IPP
    psi = np.pi / 2 - e - z_ipp                                                       # Earth central angle
    phi_i = np.arcsin(np.clip(np.sin(phi) * np.cos(psi) + np.cos(phi) * np.sin(psi) * np.cos(a), -1.0, 1.0))
    lam_i = lam + np.arcsin(np.clip(np.sin(psi) * np.sin(a) / np.cos(phi_i), -1.0, 1.0))
    lon_i = (np.degrees(lam_i) + 180.0) % 360.0 - 180.0
    return np.degrees(phi_i), lon_i


def mapping_function(el_deg, shell_height_m: float = SHELL_HEIGHT_M):
    """Single-layer mapping function 1 / cos z' (IONEX 1.0 "COSZ"); slant = M * vertical."""
    e = np.radians(np.asarray(el_deg, dtype=float))
    s = EARTH_RADIUS_M / (EARTH_RADIUS_M + shell_height_m) * np.cos(e)
    return 1.0 / np.sqrt(1.0 - s * s)


class NeQuickG:
    """NeQuick-G for one set of broadcast coefficients (a0 [sfu], a1 [sfu/deg], a2 [sfu/deg^2])."""

    def __init__(self, coefficients):
        c = [float(v) for v in coefficients]
        if len(c) != 3 or not all(np.isfinite(c)):
            raise ValueError(f"nequick: parameter 'coefficients' needs 3 finite values (a0, a1, a2), "
                             f"got {coefficients!r}")
        try:
            from nequick import NeQuick
        except ImportError as exc:   # declared dependency (requirements/python.txt); named when missing
            raise ValueError("nequick: the 'nequick' package (the JRC NeQuick-G library) is not installed; "
                             "run scripts/setup_env.sh or set the receiver's ionosphere to 'klobuchar'") from exc
        self.coefficients = tuple(c)
        self._model = NeQuick(*c)
        self._cache = BoundedCache(50000)

    def vtec_tecu(self, t_utc, lat_deg, lon_deg) -> np.ndarray:
        """Vertical TEC [TECU] at (lat, lon) arrays at ``t_utc`` (a datetime in UTC; the model depends on the
        month and the UT hour): trilinear interpolation between model values on nodes UPDATE_S apart in
        time and CELL_DEG apart in latitude and longitude (module doc), each node computed once."""
        lat = np.atleast_1d(np.asarray(lat_deg, dtype=float))
        lon = np.atleast_1d(np.asarray(lon_deg, dtype=float))
        day = _dt.datetime(t_utc.year, t_utc.month, t_utc.day)
        tod = (t_utc - day).total_seconds() / UPDATE_S
        k0 = int(np.floor(tod))
        ft = tod - k0
        x, y = lat / CELL_DEG, lon / CELL_DEG
        i0, j0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
        fi, fj = x - i0, y - j0
        out = np.zeros(lat.shape)
        for dk, wt in ((0, 1.0 - ft), (1, ft)):
            if wt == 0.0:
                continue
            for di in (0, 1):
                wi = fi if di else 1.0 - fi
                for dj in (0, 1):
                    wj = fj if dj else 1.0 - fj
                    vals = np.array([self._node(day, k0 + dk, i, j)
                                     for i, j in zip((i0 + di).tolist(), (j0 + dj).tolist())])
                    out += wt * wi * wj * vals
        return out

    def _node(self, day, kt: int, i: int, j: int) -> float:
        key = (day, kt, i, j)
        v = self._cache.get(key)
        if v is None:
            epoch = day + _dt.timedelta(seconds=kt * UPDATE_S)
            lon = (j * CELL_DEG + 180.0) % 360.0 - 180.0
            v = self._cache.put(key, float(self._model.compute_vtec(epoch, lon, float(np.clip(i * CELL_DEG, -90, 90)))))
        return v

    def l1_delay_s(self, t_utc, lat_deg, lon_deg, az_deg, el_deg) -> np.ndarray:
        """Slant ionospheric group delay at L1 [s] of rays (az, el) from the user at (lat, lon)."""
        lat_i, lon_i = pierce_point_deg(lat_deg, lon_deg, az_deg, el_deg)
        vtec = self.vtec_tecu(t_utc, lat_i, lon_i)
        return TECU_TO_M_L1 * vtec * mapping_function(el_deg) / k.C_MPS
