"""The receiver's view of one epoch's reflected paths: code and carrier errors and the received amplitude.

Per signal row j (satellite, band) with its chip length, wavelength, the profile's correlator spacing and
front-end bandwidth and its antenna pattern (antenna.py):

- line of sight amplitude a_0 = 10^(-A/20) (A: foliage/diffraction loss) or 0 when blocked;
- reflection i: amplitude a_i = sqrt(|R_co|^2 G_R(el_i) + |R_cross|^2 G_L(el_i)) / sqrt(G_R(el_sat))
  (powers of the co- and cross-polar parts received by the RHCP port, relative to an unobstructed
  line of sight at the satellite's elevation), carrier phase phi_i = arg(R) + 2 pi delta_i / lambda_j
  (R the stronger of the two received parts), code delay delta_i / chip length;
- dll.tracking_error gives the code error (chips -> m), the composite carrier phase and amplitude:
  C/N0 = C/N0(unobstructed) + 20 log10 |R_c(eps)|.
With the line of sight blocked the carrier follows the tracked reflection: its phase error is that
path's excess delay plus the composite phase about it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import antenna, dll


@dataclass
class CompositeErrors:
    code_m: np.ndarray          # (J,) pseudorange error [m]
    phase_m: np.ndarray         # (J,) carrier phase error [m]
    amplitude: np.ndarray       # (J,) composite amplitude relative to an unobstructed LOS
    nlos: np.ndarray            # (J,) bool: line of sight blocked, tracked on a reflection


def reflection_amplitudes(gamma_co, gamma_cross, arrival_el_deg, sat_el_deg, pattern: str):
    """(amplitude, coefficient phase [rad]) of reflected paths (..., K) for satellites at ``sat_el_deg`` (...)."""
    g_r, g_l = antenna.gain_dbic(pattern, np.nan_to_num(arrival_el_deg, nan=0.0))
    g_sat, _ = antenna.gain_dbic(pattern, np.asarray(sat_el_deg, dtype=np.float64)[..., None])
    p_co = np.abs(gamma_co) ** 2 * 10 ** (g_r / 10)
    p_x = np.abs(gamma_cross) ** 2 * 10 ** (g_l / 10)
    amp = np.sqrt((p_co + p_x) / 10 ** (g_sat / 10))
    phase = np.where(p_co >= p_x, np.angle(gamma_co), np.angle(gamma_cross))
    return amp, phase


def composite_errors(los_amp, excess_m, gamma_co, gamma_cross, arrival_el_deg, sat_el_deg, chip_m, lam_m,
                     spacing_chips: float, bandwidth_chips: float, pattern: str, calls=None) -> CompositeErrors:
    """Errors of signal rows (J,) with reflected paths (J, K) (NaN excess: no path); ``calls``: (J,) labels of
    rows computed as separate calls (dll.tracking_error), e.g. the epochs of a block."""
    excess = np.asarray(excess_m, dtype=np.float64)
    valid = np.isfinite(excess)
    amp_r, ph_g = reflection_amplitudes(gamma_co, gamma_cross, arrival_el_deg, sat_el_deg, pattern)
    amp_r = np.where(valid, amp_r, 0.0)
    ex = np.where(valid, excess, 0.0)
    lam = np.asarray(lam_m, dtype=np.float64)[:, None]
    chip = np.asarray(chip_m, dtype=np.float64)
    phase_r = ph_g + 2 * np.pi * ex / lam
    a0 = np.asarray(los_amp, dtype=np.float64)
    amps = np.concatenate([a0[:, None], amp_r], axis=1)
    delays = np.concatenate([np.zeros((len(a0), 1)), ex / chip[:, None]], axis=1)
    phases = np.concatenate([np.zeros((len(a0), 1)), phase_r], axis=1)
    eps, theta, mag = dll.tracking_error(amps, delays, phases, spacing_chips, bandwidth_chips, calls=calls)
    nlos = (a0 <= 0) & np.any(amp_r > 0, axis=1)
    code = np.nan_to_num(eps) * chip
    phase = np.nan_to_num(theta) * lam[:, 0] / (2 * np.pi)
    if np.any(nlos):
        k = np.argmax(amp_r, axis=1)
        r = np.arange(len(a0))
        ref_ex = ex[r, k]
        wrap = np.angle(np.exp(1j * (np.nan_to_num(theta) - 2 * np.pi * ref_ex / lam[:, 0])))
        phase = np.where(nlos, ref_ex + wrap * lam[:, 0] / (2 * np.pi), phase)
    return CompositeErrors(code, phase, mag, nlos)
