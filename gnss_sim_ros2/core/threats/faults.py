"""Receiver faults of a scenario (scenario.FAULT_KINDS), each applied at its stage of the chain:

- on the receiver clock (before the observables): ``clock_jump_s`` -- the receiver's clock bias is off by
  ``jump_s`` while the fault is active (every pseudorange and phase, the epoch's true reception time and the
  reported clock bias follow, as after a real clock jump);
- on the ranges (after the observables, before the fix and the files): ``satellite_clock_step_m`` (the
  satellite's clock off by ``step_m`` metres of range, on code and phase alike, as a real clock anomaly;
  the broadcast clock does not know), ``satellite_ramp_mps`` (off by ``ramp_mps`` (t - start_s)),
  ``bad_ephemeris`` (the broadcast orbit the receiver solves with is off by ``error_m`` radially; the
  measured ranges are true);
- on the outputs: ``off`` (no observation, no fix), ``stuck`` (the last output before the fault repeated:
  observations at the new epoch tag and the fix frozen), ``position_offset`` (the fix displaced by
  ``offset_enu_m``); off and stuck act on the observations before the fix (so NMEA, RINEX and the published
  messages agree), the receiver's own state (its prior position) is kept from the true fix.
"""
from __future__ import annotations

import copy
import dataclasses

import numpy as np

from ..constants import C_MPS
from ..frames import ecef_to_geodetic, enu_rotation
from ..receiver.observations import untracked_epoch

RANGE_KINDS = ("satellite_clock_step_m", "satellite_ramp_mps", "bad_ephemeris")
OUTPUT_KINDS = ("off", "stuck", "position_offset")


def clock_offset_s(faults, t_rel_s) -> np.ndarray | None:
    """The receiver clock's extra bias [s] at run times ``t_rel_s`` (K,), or None when no clock fault is active."""
    t = np.asarray(t_rel_s, dtype=float)
    out, any_active = np.zeros(t.shape), False
    for f in faults:
        if f.kind == "clock_jump_s":
            on = f.active(t)
            if on.any():
                out = out + np.where(on, f.jump_s, 0.0)
                any_active = True
    return out if any_active else None


def on_ranges(faults, t_rel_s: float, obs):
    """The observations with the active satellite faults applied (a copy; ``obs`` itself if none is active)."""
    active = [f for f in faults if f.kind in RANGE_KINDS and f.active(t_rel_s)]
    if not active or len(obs.sv) == 0:
        return obs
    out = copy.copy(obs)
    sv = np.asarray(obs.sv)
    pr, phase, pos = obs.pseudorange_m.copy(), obs.carrier_phase_cyc.copy(), obs.sat_pos_ecef_m.copy()
    lam = C_MPS / np.asarray(obs.frequency_hz, dtype=float)
    for f in active:
        rows = sv == f.satellite
        if not rows.any():
            continue
        if f.kind == "bad_ephemeris":
            p = pos[rows]
            pos[rows] = p + f.error_m * p / np.linalg.norm(p, axis=1, keepdims=True)
            continue
        d_m = f.step_m if f.kind == "satellite_clock_step_m" else f.ramp_mps * (t_rel_s - f.start_s)
        pr[rows] += d_m
        phase[rows] += d_m / lam[rows]
    out.pseudorange_m, out.carrier_phase_cyc, out.sat_pos_ecef_m = pr, phase, pos
    return out


class OutputFaults:
    """The output faults of one run: the observations (:meth:`observations`, before the fix, so the fix, NMEA and
    files agree with them) and the fix (:meth:`solution`); remembers the last output for ``stuck``."""

    def __init__(self, faults):
        self.faults = [f for f in faults if f.kind in OUTPUT_KINDS]
        self._last_obs = None
        self._last_sol = None

    def _active(self, t_rel_s: float) -> dict:
        return {f.kind: f for f in self.faults if f.active(t_rel_s)}

    def observations(self, t_rel_s: float, obs):
        """The observations the receiver outputs: none (off), the last ones again at this epoch's tag (stuck)."""
        active = self._active(t_rel_s)
        if "off" in active or ("stuck" in active and self._last_obs is None):
            return untracked_epoch(obs.t, obs.clock_bias_s, obs.clock_drift_sps, obs.sat_sv, obs.sat_az_deg,
                                   obs.sat_el_deg, obs.sat_vis_state, obs.sat_attenuation_db)
        if "stuck" in active:
            frozen = copy.copy(self._last_obs)
            frozen.t = obs.t
            return frozen
        self._last_obs = obs
        return obs

    def solution(self, t_rel_s: float, sol):
        """The fix the receiver outputs: none (off), the last one (stuck), displaced (position_offset)."""
        active = self._active(t_rel_s)
        if "off" in active:
            return _no_fix(sol, "off")
        if "stuck" in active:
            return self._last_sol if self._last_sol is not None else _no_fix(sol, "stuck")
        offsets = [f.offset_enu_m for f in self.faults if f.kind == "position_offset" and f.active(t_rel_s)]
        if offsets and sol.is_fix:
            sol = _moved(sol, np.sum(offsets, axis=0))
        self._last_sol = sol
        return sol


def _no_fix(sol, why: str):
    nan3 = np.full(3, np.nan)
    return dataclasses.replace(sol, status="no_fix", reason=f"fault {why}", pos_ecef_m=nan3, lat_deg=np.nan,
                               lon_deg=np.nan, h_m=np.nan, n_used=0, used=np.zeros(len(sol.sv), bool),
                               vel_ecef_mps=nan3.copy(), vel_enu_mps=nan3.copy(), vel_status="none")


def _moved(sol, offset_enu_m):
    rot = enu_rotation(sol.lat_deg, sol.lon_deg)          # rows E, N, U in ECEF
    pos = np.asarray(sol.pos_ecef_m, dtype=float) + rot.T @ np.asarray(offset_enu_m, dtype=float)
    lat, lon, h = ecef_to_geodetic(*pos)
    return dataclasses.replace(sol, pos_ecef_m=pos, lat_deg=float(lat), lon_deg=float(lon), h_m=float(h))
