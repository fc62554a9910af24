"""Earth frames: ECEF (WGS 84), geodetic (WGS 84), local ENU at a stated origin.

Thin wrappers over pymap3d (one function for a scalar or an array) so that the
rest of gnss_sim names frames and units the same way everywhere, except the
ECEF -> geodetic conversion, which the receiver, the solver and the visibility
step call several times per epoch: it is computed here in closed form (Bowring
1976, two iterations: round-off accurate from 300 km below the surface to
beyond GNSS orbits, see test_frames.py), with pymap3d only for points deep
inside the Earth.  Angles are
degrees in names ending ``_deg``; ENU vectors are "east, north, up" at the
geodetic origin (lat0_deg, lon0_deg, h0_m), up along the ellipsoid normal.
"""
from __future__ import annotations

import math

import numpy as np

from .constants import WGS84_A_M, WGS84_F

# WGS 84 derived quantities (NIMA TR8350.2, 3rd ed., table 3.3)
_B_M = WGS84_A_M * (1.0 - WGS84_F)          # semi-minor axis b [m]
_E2 = WGS84_F * (2.0 - WGS84_F)             # first eccentricity squared e^2
_EP2 = _E2 / (1.0 - _E2)                    # second eccentricity squared e'^2
_ONE_M_F = 1.0 - WGS84_F
#: closer to the Earth centre than this [m], ecef_to_geodetic hands over to pymap3d (the fast
#: iteration is verified from 300 km below the surface outwards; such points are no antenna)
_FAST_MIN_RADIUS_M = 5.0e6


def geodetic_to_ecef(lat_deg, lon_deg, h_m):
    """Geodetic (WGS 84) -> ECEF [m]; scalars or arrays. Returns (x_m, y_m, z_m)."""
    import pymap3d  # imported where used (start-up of a run that never needs it)

    return pymap3d.geodetic2ecef(lat_deg, lon_deg, h_m)


def ecef_to_geodetic(x_m, y_m, z_m):
    """ECEF [m] -> geodetic (WGS 84). Returns (lat_deg, lon_deg, h_m); lon in (-180, 180].

    Scalars give numpy float64 scalars, arrays (broadcast) give arrays.  Bowring's
    (1976, Survey Review 23:323) iteration on the reduced latitude beta, started at
    tan beta = a z / (b p), p = hypot(x, y):
    tan lat = (z + e'^2 b sin^3 beta) / (p - e^2 a cos^3 beta), tan beta = (1 - f) tan lat,
    two iterations; h = p cos lat + z sin lat - a sqrt(1 - e^2 sin^2 lat) (no loss of
    precision at the poles).  Against pymap3d's geodetic2ecef round trip: latitude and
    height within 1e-7 m from -300 km to 40 000 km height (test_frames.py).
    """
    if np.ndim(x_m) == 0 and np.ndim(y_m) == 0 and np.ndim(z_m) == 0:
        x, y, z = float(x_m), float(y_m), float(z_m)
        p = math.hypot(x, y)
        if math.hypot(p, z) < _FAST_MIN_RADIUS_M or not math.isfinite(p + z):
            import pymap3d

            return pymap3d.ecef2geodetic(x, y, z)
        lat, h = _bowring(p, z, math.sin, math.cos, math.atan2, math.sqrt)
        return np.float64(math.degrees(lat)), np.float64(math.degrees(math.atan2(y, x))), np.float64(h)
    x, y, z = np.broadcast_arrays(np.asarray(x_m, dtype=np.float64), np.asarray(y_m, dtype=np.float64),
                                  np.asarray(z_m, dtype=np.float64))
    p = np.hypot(x, y)
    r = np.hypot(p, z)
    if not np.all(r >= _FAST_MIN_RADIUS_M):     # deep inside the Earth, or NaN: pymap3d's own handling
        import pymap3d

        return pymap3d.ecef2geodetic(x, y, z)
    beta = np.arctan2(z, _ONE_M_F * p)
    for _ in range(2):
        sb, cb = np.sin(beta), np.cos(beta)
        lat = np.arctan2(z + _EP2 * _B_M * sb**3, p - _E2 * WGS84_A_M * cb**3)
        beta = np.arctan2(_ONE_M_F * np.sin(lat), np.cos(lat))
    sl, cl = np.sin(lat), np.cos(lat)
    h = p * cl + z * sl - WGS84_A_M * np.sqrt(1.0 - _E2 * sl * sl)
    return np.degrees(lat), np.degrees(np.arctan2(y, x)), h


def _bowring(p, z, sin, cos, atan2, sqrt):
    """(latitude [rad], height [m]) of ecef_to_geodetic from p = hypot(x, y) and z: the arithmetic of its scalar
    path, written once (ecef_to_geodetic, ecef_to_geodetic_pointwise)."""
    beta = atan2(z, _ONE_M_F * p)
    for _ in range(2):
        sb, cb = sin(beta), cos(beta)
        lat = atan2(z + _EP2 * _B_M * sb * sb * sb, p - _E2 * WGS84_A_M * cb * cb * cb)
        beta = atan2(_ONE_M_F * sin(lat), cos(lat))
    sl, cl = sin(lat), cos(lat)
    return lat, p * cl + z * sl - WGS84_A_M * sqrt(1.0 - _E2 * sl * sl)


def ecef_to_geodetic_pointwise(x_m, y_m, z_m):
    """ecef_to_geodetic of 1-D arrays, each point's (lat_deg, lon_deg, h_m) bit for bit those of its own scalar
    call however many points are converted together (numpy's arctan2 and hypot differ from math's in the last
    bit): the scalar path point by point on Python floats.  For results that must not depend on the batch (the
    solver's fixes of one epoch or of several robots' or epochs')."""
    out = []
    sin, cos, atan2, sqrt, hypot, degrees = math.sin, math.cos, math.atan2, math.sqrt, math.hypot, math.degrees
    for x, y, z in zip(*(np.asarray(v, dtype=np.float64).reshape(-1).tolist() for v in (x_m, y_m, z_m))):
        p = hypot(x, y)
        if hypot(p, z) < _FAST_MIN_RADIUS_M or not math.isfinite(p + z):
            out.append(tuple(float(v) for v in ecef_to_geodetic(x, y, z)))
            continue
        lat, h = _bowring(p, z, sin, cos, atan2, sqrt)
        out.append((degrees(lat), degrees(atan2(y, x)), h))
    lla = np.array(out, dtype=np.float64).reshape(-1, 3)
    return lla[:, 0], lla[:, 1], lla[:, 2]


def enu_rotation(lat0_deg, lon0_deg) -> np.ndarray:
    """3x3 matrix R whose rows are the east, north, up unit vectors in ECEF: enu = R @ d_ecef; for arrays of
    K origins, the (K, 3, 3) stack of them."""
    lat = np.radians(lat0_deg)
    lon = np.radians(lon0_deg)
    sl, cl = np.sin(lat), np.cos(lat)
    so, co = np.sin(lon), np.cos(lon)
    zero = 0.0 if np.ndim(sl) == 0 else np.zeros_like(sl)
    r = np.array([
        [-so, co, zero],
        [-sl * co, -sl * so, cl],
        [cl * co, cl * so, sl],
    ])
    return r if r.ndim == 2 else np.moveaxis(r, (0, 1), (-2, -1))


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
    lat, lon, _ = ecef_to_geodetic(rx[..., 0], rx[..., 1], rx[..., 2])
    return az_el_at(rx, lat, lon, sat_ecef_m)


def az_el_at(rx_ecef_m, lat_deg, lon_deg, sat_ecef_m):
    """:func:`az_el_from_ecef` with the receiver's geodetic latitude/longitude already known.

    ``rx_ecef_m`` [3] or [..., 3]; ``lat_deg``/``lon_deg`` its geodetic position (broadcast
    like ``rx_ecef_m[..., 0]``); ``sat_ecef_m`` [..., 3].  Returns (az_deg, el_deg, range_m)
    in the ENU frame at (lat_deg, lon_deg).
    """
    rx = np.asarray(rx_ecef_m, dtype=np.float64)
    sat = np.asarray(sat_ecef_m, dtype=np.float64)
    d = sat - rx
    if np.ndim(lat_deg) == 0 and np.ndim(lon_deg) == 0:
        lat_r, lon_r = math.radians(lat_deg), math.radians(lon_deg)
        sl, cl, so, co = math.sin(lat_r), math.cos(lat_r), math.sin(lon_r), math.cos(lon_r)
    else:
        lat_r, lon_r = np.radians(lat_deg), np.radians(lon_deg)
        sl, cl, so, co = np.sin(lat_r), np.cos(lat_r), np.sin(lon_r), np.cos(lon_r)
    e = -so * d[..., 0] + co * d[..., 1]
    n = -sl * co * d[..., 0] - sl * so * d[..., 1] + cl * d[..., 2]
    u = cl * co * d[..., 0] + cl * so * d[..., 1] + sl * d[..., 2]
    rng = np.sqrt(e * e + n * n + u * u)
    az = np.degrees(np.arctan2(e, n)) % 360.0
    az = az - 360.0 * (az >= 360.0)  # (-tiny) % 360 rounds to 360.0; keeps scalars scalar
    el = np.degrees(np.arcsin(np.minimum(np.maximum(u / rng, -1.0), 1.0)))   # np.clip, cheaper
    return az, el, rng


def enu_unit_from_az_el(az_deg, el_deg):
    """Unit direction vectors [..., 3] in ENU from azimuth/elevation [deg]."""
    az = np.radians(az_deg)
    el = np.radians(el_deg)
    ce = np.cos(el)
    return np.stack([ce * np.sin(az), ce * np.cos(az), np.sin(el)], axis=-1)


# ---------------------------------------------------------------------------- the receivers this simulator models
#: latitude [deg] (geodetic, WGS 84): the poles are the ends; 91 would wrap over the pole
LATITUDE_SPAN_DEG = (-90.0, 90.0)
#: longitude [deg], east: -180..180 and the 0..360 some tools write
LONGITUDE_SPAN_DEG = (-180.0, 360.0)
#: ellipsoidal height [m] of an antenna this simulator models: a terrestrial or low-altitude receiver.  Below:
#: the Dead Sea shore (-430 m, the lowest dry land).  Above: 10 km, the range of the troposphere model
#: (Saastamoinen with a standard atmosphere, core/propagation.py; RTKLIB's tropmodel() refuses heights above
#: 1e4 m too).  Higher receivers need a partial atmosphere and see satellites below the horizon (aircraft above
#: 10 km, balloons, spacecraft): out of scope.
HEIGHT_SPAN_M = (-500.0, 10_000.0)
#: an ECEF point's height is compared with HEIGHT_SPAN_M within this [m]: the round-off of geodetic -> ECEF ->
#: geodetic (~4e-9 m, test_frames.py), so a bound given in ECEF is the bound
_ROUND_OFF_M = 1e-6


def check_receiver_position(pos, frame: str, where: str, labels=None) -> np.ndarray:
    """``pos`` (3,) or (N, 3) of a receiver antenna in ``frame``: ``geodetic``/``llh`` (lat_deg, lon_deg, h_m)
    or ``ecef`` (x_m, y_m, z_m, WGS 84), finite and within LATITUDE_SPAN_DEG, LONGITUDE_SPAN_DEG and
    HEIGHT_SPAN_M (an ECEF point through its geodetic height: the Earth's centre is refused).  Bounds
    inclusive.  Returns ``pos`` as a float array of its own shape; else ValueError naming ``where`` and, for the
    first bad row i, ``labels[i]`` or ``labels(i)`` (e.g. ``:12``, the line of a file)."""
    try:
        a = np.asarray(pos, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: {pos!r} is not 3 numbers") from None
    if a.shape[-1:] != (3,) or a.ndim > 2:
        raise ValueError(f"{where}: needs 3 numbers per position ({frame}), got shape {a.shape}")
    rows = a.reshape(-1, 3)

    def fail(i, text):
        if labels is None:
            label = "" if a.ndim == 1 else f" (row {i + 1})"
        else:
            label = labels(i) if callable(labels) else labels[i]
        raise ValueError(f"{where}{label}: {text}")

    finite = np.isfinite(rows).all(axis=1)
    if not finite.all():
        i = int(np.flatnonzero(~finite)[0])
        fail(i, f"{rows[i].tolist()} is not 3 finite numbers")
    h_lo, h_hi = HEIGHT_SPAN_M
    span = (f"{h_lo:g}..{h_hi:g} m (ellipsoidal; the simulator models terrestrial and low-altitude receivers, "
            f"within the troposphere model's range)")
    if frame in ("geodetic", "llh"):
        lat, lon, h = rows[:, 0], rows[:, 1], rows[:, 2]
        for values, (lo, hi), what in ((lat, LATITUDE_SPAN_DEG, "latitude"), (lon, LONGITUDE_SPAN_DEG, "longitude"),
                                       (h, HEIGHT_SPAN_M, "height")):
            bad = (values < lo) | (values > hi)
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                fail(i, f"height {values[i]:g} m is outside {span}" if what == "height" else
                     f"{what} {values[i]:g} deg is outside {lo:g}..{hi:g} deg")
    elif frame == "ecef":
        r = np.linalg.norm(rows, axis=1)
        h = np.full(len(rows), -np.inf)
        near = r >= _FAST_MIN_RADIUS_M
        if near.any():
            h[near] = ecef_to_geodetic(rows[near, 0], rows[near, 1], rows[near, 2])[2]
        bad = (h < h_lo - _ROUND_OFF_M) | (h > h_hi + _ROUND_OFF_M)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            at = f"a geodetic height of {h[i]:.0f} m" if np.isfinite(h[i]) else "deep inside the Earth"
            xyz = [round(v, 1) for v in rows[i].tolist()]
            fail(i, f"ECEF {xyz} m is {r[i]:.0f} m from the Earth's centre, {at}; the antenna must be at a height "
                    f"of {span}")
    else:
        raise ValueError(f"{where}: unknown position frame {frame!r} (geodetic, llh or ecef)")
    return a
