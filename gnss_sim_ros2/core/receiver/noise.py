"""Thermal-noise standard deviations of code, carrier phase and Doppler from C/N0.

Formulas (C/N0 as a ratio c = 10^(cn0_dbhz/10) Hz; all functions broadcast):

- DLL, noncoherent early-minus-late power discriminator, BPSK code, wide
  front end (Kaplan & Hegarty, Understanding GPS, 2nd ed., 5.6.2, eq. 5.23 in
  the project notes' numbering):
  sigma = sqrt( B_n D / (2 c) * (1 + 2 / (T c (2 - D))) ) chips.
  With a finite double-sided front-end bandwidth B_fe (b = B_fe T_c, in chip rates) a correlator spacing
  below pi / b gains less than D suggests (Kaplan & Hegarty, 3rd ed. 2017, ch. 8, the noncoherent EMLP
  variance for band-limited BPSK after Betz & Kolodziejski 2009; from memory, check):
  D >= pi / b: the wide-band form above; 1 / b < D < pi / b: D -> 1/b + b / (pi - 1) (D - 1/b)^2;
  D <= 1 / b: D -> 1 / b and the squaring-loss term 1 + 1 / (T c).
- BOC signals (Galileo E1, E5 AltBOC, GPS/QZSS L1C, BeiDou B1C): the BPSK formula of the same chip rate
  times signals.Signal.dll_noise_factor (1/sqrt(3) for BOC(1,1)-family, 1/sqrt(5) for AltBOC(15,10): the
  steeper correlation peak, Betz 2001); the front-end term is the BPSK one (a stated approximation).
- PLL thermal jitter, Costas loop (Kaplan eq. 5.6):
  sigma = sqrt( B_n / c * (1 + 1 / (2 T c)) ) rad.
- FLL thermal frequency jitter (Kaplan eq. 5.12):
  sigma = 1 / (2 pi T) sqrt( 4 F B_n / c * (1 + 1 / (T c)) ) Hz, F = 1 near
  full strength, 2 near the tracking threshold.
- Doppler from the PLL "as the receiver does": the carrier phase differenced
  over ``interval_s`` longer than the loop's memory (1/B_n), so two independent
  phase errors: sigma_f = sqrt(2) sigma_phi / (2 pi interval).
- Mean time to cycle slip of a first-order loop (Viterbi, Principles of
  Coherent Communication, 1966): T = pi^2 rho I0(rho)^2 / (2 B_n), loop SNR
  rho = c / B_n; for a Costas (data-tolerant) loop rho -> rho S_L / 4 with the
  squaring loss S_L = 1 / (1 + 1/(2 T c)) (Holmes, Coherent Spread Spectrum
  Systems, 1982).  Used by tracking.py for random cycle slips.

Defaults: DLL B_n = 1 Hz, D = 0.5 chip, T = 20 ms, infinite front end; PLL B_n = 15 Hz, T = 1 ms
(the figures of /work/shared/notes/physics-anchors.md); FLL B_n = 2 Hz, T = 20 ms.  The receiver takes
its profile's loop parameters (ReceiverConfig dll_bn_hz, dll_spacing_chips, dll_t_int_s,
frontend_bandwidth_hz; TrackingConfig pll_bn_hz, pll_t_int_s, also for the cycle slips).
"""
from __future__ import annotations

import numpy as np

from gnss_sim_ros2.core import signals as _signals
from gnss_sim_ros2.core.bessel import i0e
from gnss_sim_ros2.core.memo import BoundedCache, read_only
from gnss_sim_ros2.core.receiver.signal_rows import array_key


def _ratio(cn0_dbhz):
    return 10.0 ** (np.asarray(cn0_dbhz, dtype=np.float64) / 10.0)


def _positive(name, v):
    if type(v) is float or type(v) is int:      # the common scalar case without numpy's overhead
        if not v > 0:
            raise ValueError(f"receiver.noise: parameter {name!r} = {v!r} must be > 0")
        return
    if (np.asarray(v) <= 0).any():
        raise ValueError(f"receiver.noise: parameter {name!r} = {v!r} must be > 0")


def dll_sigma_chips(cn0_dbhz, bn_hz=1.0, spacing_chips=0.5, t_int_s=0.02, frontend_bw_chips=None):
    """DLL thermal code noise [chips], noncoherent early-minus-late power (Kaplan eq. 5.23; module doc);
    ``frontend_bw_chips``: double-sided front-end bandwidth in chip rates b = B_fe T_c (None: infinite)."""
    _positive("bn_hz", bn_hz)
    _positive("t_int_s", t_int_s)
    d = np.asarray(spacing_chips, dtype=np.float64)
    if (spacing_chips <= 0 or spacing_chips > 1) if type(spacing_chips) is float else ((d <= 0) | (d > 1)).any():
        raise ValueError(f"receiver.noise: parameter 'spacing_chips' = {spacing_chips!r} must be in (0, 1]")
    c = _ratio(cn0_dbhz)
    squaring = 1.0 + 2.0 / (t_int_s * c * (2.0 - d))
    if frontend_bw_chips is None:
        return np.sqrt(bn_hz * d / (2.0 * c) * squaring)
    d_eff, wide = _front_end(d, np.asarray(frontend_bw_chips, dtype=np.float64))
    squaring = np.where(wide, squaring, 1.0 + 1.0 / (t_int_s * c))
    return np.sqrt(bn_hz * d_eff / (2.0 * c) * squaring)


#: _front_end's values by its arguments' contents: a receiver's signals come back epoch after epoch
_FRONT_END = BoundedCache(16)


def _front_end(d, b):
    """(effective spacing D' [chips], where D > 1/b) of the correlator spacing ``d`` [chips] with the front-end
    bandwidths ``b`` in chip rates (dll_sigma_chips, module doc); cached by the contents of both."""
    key = (d.shape, b.shape, array_key(d), array_key(b))    # the shapes too: array_key holds a scalar as one value
    hit = _FRONT_END.get(key)
    if hit is None:
        _positive("frontend_bw_chips", b)
        d_eff = np.where(d >= np.pi / b, d, np.where(d > 1.0 / b, 1.0 / b + b / (np.pi - 1.0) * (d - 1.0 / b) ** 2,
                                                     1.0 / b))
        hit = _FRONT_END.put(key, read_only((d_eff, d > 1.0 / b)))
    return hit


def dll_sigma_m(cn0_dbhz, chip_length_m, bn_hz=1.0, spacing_chips=0.5, t_int_s=0.02, frontend_bw_chips=None):
    """DLL thermal code noise [m] for a code of chip length ``chip_length_m`` (293.05 m for C/A)."""
    _positive("chip_length_m", chip_length_m)
    return dll_sigma_chips(cn0_dbhz, bn_hz, spacing_chips, t_int_s, frontend_bw_chips) * np.asarray(chip_length_m)


def pll_sigma_rad(cn0_dbhz, bn_hz=15.0, t_int_s=0.001):
    """PLL (Costas) thermal phase jitter [rad] (Kaplan eq. 5.6)."""
    _positive("bn_hz", bn_hz)
    _positive("t_int_s", t_int_s)
    c = _ratio(cn0_dbhz)
    return np.sqrt(bn_hz / c * (1.0 + 1.0 / (2.0 * t_int_s * c)))


def pll_sigma_m(cn0_dbhz, wavelength_m, bn_hz=15.0, t_int_s=0.001):
    """PLL thermal carrier-phase noise [m] = lambda / (2 pi) * sigma_rad."""
    _positive("wavelength_m", wavelength_m)
    return pll_sigma_rad(cn0_dbhz, bn_hz, t_int_s) * np.asarray(wavelength_m) / (2.0 * np.pi)


def fll_sigma_hz(cn0_dbhz, bn_hz=2.0, t_int_s=0.02, f_factor=1.0):
    """FLL thermal frequency jitter [Hz] (Kaplan eq. 5.12); ``f_factor`` F = 1 (strong) or 2 (near threshold)."""
    _positive("bn_hz", bn_hz)
    _positive("t_int_s", t_int_s)
    c = _ratio(cn0_dbhz)
    return np.sqrt(4.0 * f_factor * bn_hz / c * (1.0 + 1.0 / (t_int_s * c))) / (2.0 * np.pi * t_int_s)


def doppler_sigma_hz(cn0_dbhz, method="fll", bn_hz=None, t_int_s=None, interval_s=1.0):
    """Doppler measurement noise [Hz].

    ``method="fll"``: FLL jitter (defaults B_n = 2 Hz, T = 20 ms);
    ``method="pll"``: carrier phase differenced over ``interval_s`` (defaults
    B_n = 15 Hz, T = 1 ms), sqrt(2) sigma_phi / (2 pi interval).
    """
    if method == "fll":
        return fll_sigma_hz(cn0_dbhz, 2.0 if bn_hz is None else bn_hz, 0.02 if t_int_s is None else t_int_s)
    if method == "pll":
        _positive("interval_s", interval_s)
        bn = 15.0 if bn_hz is None else bn_hz
        if interval_s * bn < 1.0:
            raise ValueError(f"receiver.noise: parameter 'interval_s' = {interval_s} is shorter than the loop "
                             f"memory 1/B_n = {1.0 / bn:.3g} s: the phase errors are correlated")
        sig = pll_sigma_rad(cn0_dbhz, bn, 0.001 if t_int_s is None else t_int_s)
        return np.sqrt(2.0) * sig / (2.0 * np.pi * interval_s)
    raise ValueError(f"receiver.noise: parameter 'method' = {method!r} is not 'fll' or 'pll'")


def mean_time_to_slip_s(cn0_dbhz, bn_hz=15.0, t_int_s=0.001, costas=True):
    """Mean time between cycle slips [s] of a first-order loop (Viterbi 1966), Costas-adjusted."""
    _positive("bn_hz", bn_hz)
    c = _ratio(cn0_dbhz)
    rho = c / bn_hz
    if costas:
        rho = rho / (1.0 + 1.0 / (2.0 * t_int_s * c)) / 4.0
    # I0(rho)^2 = (i0e(rho) e^rho)^2; evaluated in logs to avoid overflow
    log_t = np.log(np.pi**2 * rho / (2.0 * bn_hz)) + 2.0 * np.log(i0e(rho)) + 2.0 * rho
    return np.exp(np.minimum(log_t, 700.0))


def slip_probability(cn0_dbhz, dt_s, bn_hz=15.0, t_int_s=0.001):
    """Probability of a cycle slip within ``dt_s`` > 0 (scalar or per row): 1 - exp(-dt / T),
    T = :func:`mean_time_to_slip_s` (Costas loop).  Rows whose probability is 0 in double precision
    whatever I0 is are not evaluated: with I0(rho) e^-rho >= 1 / sqrt(2 pi rho) for rho >= 1/2,
    log T >= L = log(pi^2 rho / (2 B_n)) - log(2 pi rho) + 2 rho, and dt / T < 2^-54 (L > log dt + 38)
    makes exp(-dt / T) round to 1 exactly (I0 is only evaluated for weak signals)."""
    _positive("bn_hz", bn_hz)
    c = _ratio(cn0_dbhz)
    rho = c / bn_hz / (1.0 + 1.0 / (2.0 * t_int_s * c)) / 4.0
    rho_b = np.maximum(rho, 0.5)
    bound = np.minimum(np.log(np.pi**2 * rho_b / (2.0 * bn_hz)) - np.log(2.0 * np.pi * rho_b) + 2.0 * rho_b, 700.0)
    dt = np.asarray(dt_s, dtype=np.float64)
    if dt.shape != c.shape:
        dt = np.broadcast_to(dt, c.shape)
    maybe = (rho < 0.5) | (bound <= np.log(dt) + 38.0)
    p = np.zeros(np.shape(c))
    if maybe.any():
        p[maybe] = 1.0 - np.exp(-dt[maybe] / mean_time_to_slip_s(np.asarray(cn0_dbhz)[maybe], bn_hz, t_int_s))
    return p


# ---- helpers from the signal table -----------------------------------------------------
def code_sigma_m(system: str, code: str, cn0_dbhz, bn_hz=1.0, spacing_chips=0.5, t_int_s=0.02, frontend_bw_hz=None):
    """DLL code noise [m] of signal ``(system, code)`` (chip length and BOC factor from core/signals.py);
    ``frontend_bw_hz``: double-sided front-end bandwidth [Hz] (None: infinite)."""
    s = _signals.signal(system, code)
    b = None if frontend_bw_hz is None else frontend_bw_hz / s.chip_rate_cps
    return dll_sigma_m(cn0_dbhz, s.chip_length_m, bn_hz, spacing_chips, t_int_s, b) * s.dll_noise_factor


def phase_sigma_m(system: str, code: str, cn0_dbhz, glo_channel=0, bn_hz=15.0, t_int_s=0.001):
    """PLL carrier-phase noise [m] of signal ``(system, code)``."""
    return pll_sigma_m(cn0_dbhz, _signals.wavelength_m(system, code, glo_channel), bn_hz, t_int_s)
