"""Jamming physics: the jammer's power at the receiver and its effect on each signal's C/N0.

Received jammer power at the antenna output [dBW] (Friis; Kaplan & Hegarty 3rd ed. ch. 9):

    J = EIRP - 20 log10(4 pi d f / c) + G_ant(el_jammer, f) - L_scene

with the antenna class's RHCP gain toward the jammer (core/multipath/antenna.py, the table the C/N0 link budget
uses, at the jammer's elevation seen from the antenna: a jammer on the ground arrives near or below the horizon)
and the scene's loss on the segment jammer -> antenna (runtime.py: opaque -> blocked, foliage / penetrable
materials in dB/m along the segment, the satellites' material table).  EIRP is that of the polarisation the
antenna receives (no polarisation mismatch added).

Effective C/N0 of a signal (Betz, ION NTM 2001; Kaplan & Hegarty eq. 9.17):

    (C/N0)_eff = C / (N0 + J kappa) = 1 / (1 / (C/N0) + kappa J / C)

with kappa the jammer's spectral separation coefficient on the signal (spectra.py) and N0 = k T_sys of the
receiver's link budget (receiver/cn0.py).  Loss of lock and reacquisition follow from the tracking thresholds
(receiver/tracking.py) on this C/N0.

Receiver status figures per band (what u-blox UBX-MON-HW / MON-RF report as jamInd and the AGC):
- ``jamming_indicator`` 0-255: 255 / 60 per dB of the in-band jammer-to-noise ratio J/N = J - (N0 + 10 log10
  B_fe), clipped: 0 at J/N <= 0 dB (no jammer above the thermal noise), 255 at J/N >= 60 dB (this
  simulator's documented mapping; u-blox does not publish its own);
- ``agc_db``: the gain reduction an AGC holding the front end's output power constant applies,
  10 log10(1 + J/N) [dB].
"""
from __future__ import annotations

import numpy as np

from ..constants import C_MPS

#: J/N [dB] at which the jamming indicator reaches 255
JAM_INDICATOR_FULL_SCALE_DB = 60.0


def free_space_loss_db(distance_m, frequency_hz):
    """20 log10(4 pi d f / c) [dB] (Friis)."""
    return 20.0 * np.log10(4.0 * np.pi * np.maximum(np.asarray(distance_m, dtype=float), 1e-3)
                           * np.asarray(frequency_hz, dtype=float) / C_MPS)


def received_power_dbw(eirp_dbw, distance_m, frequency_hz, antenna_gain_dbi, scene_loss_db=0.0):
    """The jammer's power at the antenna output [dBW] (module doc); -inf where the scene blocks it."""
    return (np.asarray(eirp_dbw, dtype=float) - free_space_loss_db(distance_m, frequency_hz)
            + np.asarray(antenna_gain_dbi, dtype=float) - np.asarray(scene_loss_db, dtype=float))


def cn0_drop_db(j_kappa_w_per_hz, n0_dbwhz):
    """10 log10(1 + kappa J / N0) [dB]: how far the effective C/N0 lies below the jammer-free one, for the sum of
    kappa J [W/Hz] over the jammers (independent interferers add)."""
    return 10.0 * np.log10(1.0 + np.asarray(j_kappa_w_per_hz, dtype=float) / 10.0 ** (n0_dbwhz / 10.0))


def effective_cn0_dbhz(cn0_dbhz, j_kappa_w_per_hz, n0_dbwhz):
    """(C/N0)_eff = C / (N0 + kappa J) [dB-Hz] of signals of C/N0 ``cn0_dbhz``."""
    return np.asarray(cn0_dbhz, dtype=float) - cn0_drop_db(j_kappa_w_per_hz, n0_dbwhz)


def jam_to_noise_db(j_in_band_w, n0_dbwhz, frontend_bw_hz):
    """J/N [dB] in the front end's band (N = N0 B_fe)."""
    n_w = 10.0 ** (n0_dbwhz / 10.0) * frontend_bw_hz
    return 10.0 * np.log10(np.maximum(np.asarray(j_in_band_w, dtype=float), 1e-300) / n_w)


def jamming_indicator(j_to_n_db):
    """0-255 (module doc): 255 / JAM_INDICATOR_FULL_SCALE_DB per dB of J/N above 0 dB, clipped."""
    x = np.asarray(j_to_n_db, dtype=float) * (255.0 / JAM_INDICATOR_FULL_SCALE_DB)
    return np.clip(np.round(x), 0, 255).astype(np.int64)


def agc_db(j_to_n_db):
    """Gain reduction of the AGC [dB]: 10 log10(1 + J/N)."""
    return 10.0 * np.log10(1.0 + 10.0 ** (np.asarray(j_to_n_db, dtype=float) / 10.0))
