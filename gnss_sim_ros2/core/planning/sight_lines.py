"""Distances and local ENU unit lines of sight of many antennas x satellites, by broadcasting.

A plan's rows repeat each cell's antenna once per time step: what depends on the antenna only (its ECEF point, the
rows of its east / north / up axes in ECEF) is computed once per antenna, what depends on the time only (the
satellites' ECEF positions) once per step, and the (antenna, time, satellite) distances and directions are formed
by broadcasting the two: no per-row geodetic conversion, no sine or cosine per satellite.  The directions are
those the cast's azimuth and elevation describe (the same ENU axes at the antenna's WGS 84 latitude and
longitude, ``frames.enu_rotation``), to rounding; the cast itself (``VisibilityOptions.cast``) still decides the
line-of-sight states.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..frames import ecef_to_geodetic, enu_rotation


@dataclass
class AntennaAxes:
    """Antennas (A,): ECEF points [m] (A, 3) and their local ENU axes as rows in ECEF (A, 3, 3)."""

    ecef_m: np.ndarray
    enu_rows: np.ndarray

    @classmethod
    def of(cls, scene, antenna_world_m) -> AntennaAxes:
        ecef = np.asarray(scene.antenna_ecef(np.asarray(antenna_world_m, float).reshape(-1, 3)), float)
        lat, lon, _ = ecef_to_geodetic(ecef[:, 0], ecef[:, 1], ecef[:, 2])
        return cls(ecef, enu_rotation(np.atleast_1d(lat), np.atleast_1d(lon)).reshape(-1, 3, 3))

    def to_satellites(self, sat_ecef_m, per_time: bool):
        """(range_m, (e, n, u)) of every antenna and satellite, each (A x T, S) rows antenna-major.

        ``per_time``: ``sat_ecef_m`` (T, S, 3) are the satellites of T time steps, seen from every antenna (rows
        antenna * T + time: the planner's grid); else (A, S, 3), one set of satellites per antenna (a path's poses,
        T = 1).  Satellites must be finite (an absent one placed anywhere: its row entries are not used)."""
        sat = np.asarray(sat_ecef_m, float)
        if per_time:          # (A, 1, 1) against (1, T, S): rows antenna * T + time
            rx, rot, sat = self.ecef_m[:, None, None, :], self.enu_rows[:, None, None], sat[None]
        else:                 # (A, 1) against (A, S)
            rx, rot = self.ecef_m[:, None, :], self.enu_rows[:, None]
        shape = np.broadcast_shapes(rx.shape[:-1], sat.shape[:-1])
        # every (A, T, S) array written into one of a few buffers (no temporary per operation; the same arithmetic
        # in the same order, so the same numbers): d, the range, one scratch, the three ENU components
        d = np.empty((3,) + shape)
        for i in range(3):                                          # contiguous components, no (..., 3) array
            np.subtract(sat[..., i], rx[..., i], out=d[i])
        rng, tmp = np.empty(shape), np.empty(shape)
        np.multiply(d[0], d[0], out=rng)
        rng += np.multiply(d[1], d[1], out=tmp)
        rng += np.multiply(d[2], d[2], out=tmp)
        np.sqrt(rng, out=rng)
        np.divide(1.0, rng, out=tmp)
        d *= tmp
        enu = np.empty((3,) + shape)
        for i in range(3):
            acc = np.multiply(d[0], rot[..., i, 0], out=enu[i])
            acc += np.multiply(d[1], rot[..., i, 1], out=tmp)
            acc += np.multiply(d[2], rot[..., i, 2], out=tmp)
        n_s = sat.shape[-2]
        return rng.reshape(-1, n_s), tuple(x.reshape(-1, n_s) for x in enu)
