"""Earth frames: ECEF (WGS 84), geodetic (WGS 84), local ENU at a stated origin.

Thin wrappers over pymap3d (one function for a scalar or an array) so that the
rest of gnss_sim names frames and units the same way everywhere.  Angles are
degrees in names ending ``_deg``; ENU vectors are "east, north, up" at the
geodetic origin (lat0_deg, lon0_deg, h0_m), up along the ellipsoid normal.
"""
from __future__ import annotations

import numpy as np
import pymap3d


def geodetic_to_ecef(lat_deg, lon_deg, h_m):
    """Geodetic (WGS 84) -> ECEF [m]; scalars or arrays. Returns (x_m, y_m, z_m)."""
    return pymap3d.geodetic2ecef(lat_deg, lon_deg, h_m)


def ecef_to_geodetic(x_m, y_m, z_m):
    """ECEF [m] -> geodetic (WGS 84). Returns (lat_deg, lon_deg, h_m); lon in (-180, 180]."""
    return pymap3d.ecef2geodetic(x_m, y_m, z_m)


def enu_rotation(lat0_deg, lon0_deg) -> np.ndarray:
    """3x3 matrix R whose rows are the east, north, up unit vectors in ECEF: enu = R @ d_ecef."""
    lat = np.radians(lat0_deg)
    lon = np.radians(lon0_deg)
    sl, cl = np.sin(lat), np.cos(lat)
    so, co = np.sin(lon), np.cos(lon)
    return np.array([
        [-so, co, 0.0],
        [-sl * co, -sl * so, cl],
        [cl * co, cl * so, sl],
    ])


def ecef_to_enu(pos_ecef_m, lat0_deg, lon0_deg, h0_m):
    """ECEF points [..., 3] -> ENU [..., 3] at the geodetic origin (float64 throughout)."""
    origin = np.array(geodetic_to_ecef(lat0_deg, lon0_deg, h0_m))
    return (np.asarray(pos_ecef_m, dtype=np.float64) - origin) @ enu_rotation(lat0_deg, lon0_deg).T


def enu_to_ecef(pos_enu_m, lat0_deg, lon0_deg, h0_m):
    """ENU points [..., 3] at the geodetic origin -> ECEF [..., 3]."""
    origin = np.array(geodetic_to_ecef(lat0_deg, lon0_deg, h0_m))
    return np.asarray(pos_enu_m, dtype=np.float64) @ enu_rotation(lat0_deg, lon0_deg) + origin


def az_el_from_ecef(rx_ecef_m, sat_ecef_m):
    """Azimuth (from north, clockwise) and elevation [deg] of satellites seen from a receiver.

    ``rx_ecef_m``: [3] or [..., 3]; ``sat_ecef_m``: [..., 3] (broadcasts).  The
    local frame is ENU at the receiver's own geodetic position (geodetic up).
    Returns (az_deg in [0, 360), el_deg in [-90, 90], range_m).
    """
    rx = np.asarray(rx_ecef_m, dtype=np.float64)
    sat = np.asarray(sat_ecef_m, dtype=np.float64)
    lat, lon, _ = ecef_to_geodetic(rx[..., 0], rx[..., 1], rx[..., 2])
    d = sat - rx
    lat_r, lon_r = np.radians(lat), np.radians(lon)
    sl, cl, so, co = np.sin(lat_r), np.cos(lat_r), np.sin(lon_r), np.cos(lon_r)
    e = -so * d[..., 0] + co * d[..., 1]
    n = -sl * co * d[..., 0] - sl * so * d[..., 1] + cl * d[..., 2]
    u = cl * co * d[..., 0] + cl * so * d[..., 1] + sl * d[..., 2]
    rng = np.sqrt(e * e + n * n + u * u)
    az = np.degrees(np.arctan2(e, n)) % 360.0
    el = np.degrees(np.arcsin(np.clip(u / rng, -1.0, 1.0)))
    return az, el, rng


def enu_unit_from_az_el(az_deg, el_deg):
    """Unit direction vectors [..., 3] in ENU from azimuth/elevation [deg]."""
    az = np.radians(az_deg)
    el = np.radians(el_deg)
    ce = np.cos(el)
    return np.stack([ce * np.sin(az), ce * np.cos(az), np.sin(el)], axis=-1)
