"""Knife-edge diffraction of blocked satellites over the nearest roof or wall edge (ITU-R P.526).

For a satellite whose line of sight is blocked, the edge that hides it is found by bisection: the
lowest clear elevation at the same azimuth (a roof edge) and the nearest clear azimuth on either side
at the same elevation (a wall corner), each searched within ``max_angle_deg``.  The obstacle's
distance d is the hit distance of a ray just inside the edge; the edge clears the ray by
h = d tan(theta) (theta: the angle from the satellite's direction to the edge), and with the satellite
at infinity the Fresnel-Kirchhoff parameter is  nu = h sqrt(2 / (lambda d))  (ITU-R P.526-15 eq. (26)
with d1 = d, d2 -> infinity).  The loss is the single knife edge of eq. (31),

    J(nu) = 6.9 + 20 log10( sqrt((nu - 0.1)^2 + 1) + nu - 0.1 ) dB    (nu > -0.78; 0 otherwise),

taken over the edge with the smallest nu.  Satellites whose loss exceeds ``max_loss_db`` stay
blocked.  The diffracted path's excess length h^2 / (2 d) (centimetres to a metre) is neglected.
Not modelled: several edges in a row (P.526 Deygout), rounded edges, the polarisation of the edge.
"""
from __future__ import annotations

import numpy as np

#: beyond this loss a diffracted signal is treated as absent [dB]
MAX_LOSS_DB = 40.0


def knife_edge_db(nu):
    """ITU-R P.526-15 eq. (31) single knife-edge loss [dB] of the parameter ``nu`` (array)."""
    v = np.asarray(nu, dtype=np.float64)
    return np.where(v > -0.78, 6.9 + 20.0 * np.log10(np.sqrt((v - 0.1) ** 2 + 1.0) + v - 0.1), 0.0)


def _dirs(az, el):
    ce = np.cos(el)
    return np.column_stack([ce * np.sin(az), ce * np.cos(az), np.sin(el)])


def edge_loss_db(rays, antenna_m, dirs_world, wavelength_m: float, max_angle_deg: float = 15.0,
                 iterations: int = 10):
    """(loss_db (N,), nu (N,), rays cast) of blocked rays from ``antenna_m`` (3,) in unit directions (N, 3)
    (world frame, z up); ``rays``: the scene's RayScene.  NaN loss: no clear edge within ``max_angle_deg``."""
    u = np.asarray(dirs_world, dtype=np.float64).reshape(-1, 3)
    n = len(u)
    if n == 0:
        return np.zeros(0), np.zeros(0), 0
    a = np.asarray(antenna_m, dtype=np.float64)
    az = np.arctan2(u[:, 0], u[:, 1])
    el = np.arcsin(np.clip(u[:, 2], -1.0, 1.0))
    top = np.radians(max_angle_deg)
    best_nu = np.full(n, np.inf)
    cast = 0
    # (direction of the search): elevation up, azimuth left, azimuth right (angle on the cone: cos(el) daz)
    for kind in ("up", "left", "right"):
        def point(theta, kind=kind):
            if kind == "up":
                return _dirs(az, np.minimum(el + theta, np.pi / 2))
            s = 1.0 if kind == "right" else -1.0
            return _dirs(az + s * theta / np.maximum(np.cos(el), 1e-3), el)

        lo, hi = np.zeros(n), np.full(n, top)
        clear_hi = ~rays.occluded(a, point(hi), tnear_m=1e-3)
        cast += n
        if not clear_hi.any():
            continue
        for _ in range(iterations):
            mid = 0.5 * (lo + hi)
            blocked = rays.occluded(a, point(mid), tnear_m=1e-3)
            lo = np.where(blocked, mid, lo)
            hi = np.where(blocked, hi, mid)
        d = rays.hit_distance(a, point(lo), tnear_m=1e-3)
        cast += n * (iterations + 1)
        ok = clear_hi & np.isfinite(d) & (d > 0)
        h = np.where(ok, np.nan_to_num(d, posinf=0.0) * np.tan(hi), np.inf)
        nu = np.where(ok, h * np.sqrt(2.0 / (wavelength_m * np.where(ok, d, 1.0))), np.inf)
        best_nu = np.minimum(best_nu, nu)
    loss = np.where(np.isfinite(best_nu), knife_edge_db(np.where(np.isfinite(best_nu), best_nu, 0.0)), np.nan)
    return loss, best_nu, cast
