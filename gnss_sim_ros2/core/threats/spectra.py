"""Normalised power spectral densities of the GNSS signals and the spectral separation coefficient of an
interferer on a signal.

PSDs (unit power over all frequencies, f relative to the carrier; Betz, "Binary offset carrier
modulations for radionavigation", Navigation 48(4), 2001, eq. 5-6; Kaplan & Hegarty, Understanding GPS/GNSS
3rd ed., ch. 9):

    BPSK(fc):         G(f) = (1 / fc) sinc^2(f / fc),  sinc(x) = sin(pi x) / (pi x)
    sine BOC(fs, fc): G(f) = fc [sin(pi f / fc) tan(pi f / (2 fs)) / (pi f)]^2   (2 fs / fc even)
                      G(f) = fc [cos(pi f / fc) tan(pi f / (2 fs)) / (pi f)]^2   (2 fs / fc odd)

Composite signals as power-weighted sums: GPS/QZSS L1C (TMBOC), Galileo E1 OS (CBOC(6,1,1/11)) and BeiDou
B1C (QMBOC) are 10/11 BOC(1,1) + 1/11 BOC(6,1) over data and pilot (IS-GPS-800J 3.2.2; OS SIS ICD 2.1
2.3.3; BDS-SIS-ICD-B1C 1.0 4.3); Galileo E5 AltBOC(15,10) is taken as sine BOC(15,10) (the same main lobes at
+-15.345 MHz: a stated approximation); every other signal BPSK at its chip rate (core/signals.py).

Spectral separation coefficient of an interferer on a signal, both normalised to unit power, the signal over
the receiver's front-end band B_fe (double-sided, ReceiverConfig.frontend_bandwidth_hz) around its carrier
(Betz, "Effect of partial-band interference on receiver estimation of C/N0", ION NTM 2001):

    kappa = int_{-B_fe/2}^{B_fe/2} G_s(f) G_j(f) df   [1/Hz]
    CW tone at offset df:                 kappa = G_s(df)        (0 outside the front end)
    white noise of bandwidth B at df:     kappa = (1 / B) int_{band within the front end} G_s(f) df
"""
from __future__ import annotations

import functools

import numpy as np

from .. import signals as sig

#: (system, signal name) -> components (power weight, subcarrier fs [Hz] (0: BPSK), chip rate fc [Hz])
_F0 = 1.023e6
_MBOC = ((10.0 / 11.0, _F0, _F0), (1.0 / 11.0, 6 * _F0, _F0))
COMPOSITE = {("G", "L1C"): _MBOC, ("J", "L1C"): _MBOC, ("E", "E1 OS"): _MBOC, ("C", "B1C"): _MBOC,
             ("E", "E5 AltBOC"): ((1.0, 15 * _F0, 10 * _F0),)}
#: frequency step of the numerical integrals [Hz] (the PSDs' finest structure, BOC(6,1)'s lobes, is 1 MHz wide)
_DF_HZ = 2.0e3


def components(system: str, code: str) -> tuple:
    """The PSD components of signal ``(system, code)`` (module doc)."""
    s = sig.signal(system, code)
    return COMPOSITE.get((system, s.name), ((1.0, 0.0, s.chip_rate_cps),))


def psd_per_hz(comps: tuple, f_hz) -> np.ndarray:
    """Unit-power PSD [1/Hz] of the components at offsets ``f_hz`` from the carrier."""
    f = np.asarray(f_hz, dtype=float)
    f = np.where(np.abs(f) < 1e-6, 1e-6, f)          # the limits at 0 and at tan's poles are removable
    out = np.zeros_like(f)
    for w, fs, fc in comps:
        if fs == 0.0:
            out += w * np.sinc(f / fc) ** 2 / fc
            continue
        k = int(round(2.0 * fs / fc))
        a = np.pi * f / (2.0 * fs)
        num = np.sin(np.pi * f / fc) if k % 2 == 0 else np.cos(np.pi * f / fc)
        c = np.cos(a)
        c = np.where(np.abs(c) < 1e-9, 1e-9, c)
        out += w * fc * (num * np.sin(a) / (c * np.pi * f)) ** 2
    return out


def _integral(comps: tuple, lo_hz: float, hi_hz: float) -> float:
    if hi_hz <= lo_hz:
        return 0.0
    n = max(64, int(np.ceil((hi_hz - lo_hz) / _DF_HZ)))
    f = np.linspace(lo_hz, hi_hz, n + 1)
    return float(np.trapezoid(psd_per_hz(comps, f), f))


@functools.lru_cache(maxsize=4096)
def kappa_per_hz(comps: tuple, frontend_bw_hz: float, offset_hz: float, bandwidth_hz: float) -> float:
    """Spectral separation coefficient [1/Hz] of an interferer centred ``offset_hz`` from the signal's carrier
    with ``bandwidth_hz`` (0: a CW tone) on the signal of PSD ``comps``, front end ``frontend_bw_hz`` wide."""
    half = 0.5 * frontend_bw_hz
    in_band = _integral(comps, -half, half)               # the signal's power the front end passes
    if bandwidth_hz <= 0.0:
        if abs(offset_hz) > half:
            return 0.0
        return float(psd_per_hz(comps, offset_hz)) / in_band
    lo, hi = max(offset_hz - 0.5 * bandwidth_hz, -half), min(offset_hz + 0.5 * bandwidth_hz, half)
    return _integral(comps, lo, hi) / bandwidth_hz / in_band


@functools.lru_cache(maxsize=256)
def matched_kappa_per_hz(comps: tuple, frontend_bw_hz: float) -> float:
    """Spectral separation coefficient [1/Hz] of an interferer with the signal's own spectrum (a spoofer's
    counterfeit of the same signal): int G_s^2 df / (int G_s df)^2 over the front end (Betz 2001)."""
    half = 0.5 * frontend_bw_hz
    n = max(64, int(np.ceil(frontend_bw_hz / _DF_HZ)))
    f = np.linspace(-half, half, n + 1)
    g = psd_per_hz(comps, f)
    return float(np.trapezoid(g * g, f)) / float(np.trapezoid(g, f)) ** 2
