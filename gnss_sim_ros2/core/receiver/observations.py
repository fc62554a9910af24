"""What the receiver produced at one epoch (``EpochObservations``: satellites above the horizon, tracked
signals' observables and what a receiver needs for its own solution)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..time import GnssTime


@dataclass
class EpochObservations:
    """Everything the receiver produced at one epoch (rows = signals, sat_* rows = satellites)."""

    t: GnssTime                   # epoch tag (receiver time = GPS time + clock bias)
    clock_bias_s: float           # receiver clock offset dt_r
    clock_drift_sps: float
    # satellites above the horizon
    sat_sv: np.ndarray
    sat_az_deg: np.ndarray
    sat_el_deg: np.ndarray
    sat_vis_state: np.ndarray
    sat_attenuation_db: np.ndarray
    # signals (tracked ones only)
    sv: np.ndarray
    code: np.ndarray              # RINEX band+attribute, "1C"
    frequency_hz: np.ndarray
    pseudorange_m: np.ndarray
    carrier_phase_cyc: np.ndarray
    doppler_hz: np.ndarray
    cn0_dbhz: np.ndarray
    lli: np.ndarray
    lock_time_s: np.ndarray
    # what a receiver needs for its own solution, per signal row
    sat_pos_ecef_m: np.ndarray    # at transmit time, in the ECEF frame of reception
    sat_vel_ecef_mps: np.ndarray
    sat_clock_s: np.ndarray       # dt_s,j (incl. relativistic, group delay) as the broadcast gives it
    sat_clock_drift_sps: np.ndarray
    iono_model_m: np.ndarray      # the broadcast model's delay for this signal (what a receiver would remove)
    tropo_model_m: np.ndarray
    el_deg: np.ndarray
    true_range_m: np.ndarray

    @property
    def n_tracked_sats(self) -> int:
        return len(set(np.asarray(self.sv).tolist()))


def untracked_epoch(t, bias, drift, svs, az, el, vis, att) -> EpochObservations:
    """An epoch without any signal tracked (satellites above the horizon listed)."""
    z = np.zeros(0)
    return EpochObservations(t, bias, drift, svs, az, el, vis, att, np.zeros(0, "<U3"), np.zeros(0, "<U2"),
                             z, z, z, z, z, np.zeros(0, np.int8), z, np.zeros((0, 3)), np.zeros((0, 3)), z, z, z,
                             z, z, z)
