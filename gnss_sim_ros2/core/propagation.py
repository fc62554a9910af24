"""Signal propagation: light time with Earth rotation, ionosphere, troposphere.

All functions are vectorised over satellites (rows).  Frames: ECEF (WGS 84) at
the *reception* instant unless stated; geodetic latitude/longitude in degrees.

- Light time: the signal leaves the satellite at t_tx = t_rx - tau with
  c * tau = | R3(omega_e tau) r_sat(t_tx) - r_rx(t_rx) |: the satellite
  position of the ECEF frame at t_tx is rotated into the ECEF frame at t_rx
  (IS-GPS-200N 20.3.3.4.3.4, "Earth rotation correction"; the first-order
  form of the same term is the Sagnac correction omega_e (x_s y_r - y_s x_r)/c
  of RTKLIB geodist()).
- Ionosphere: Klobuchar (IS-GPS-200N 20.3.3.5.2.5, figure 20-4) for every
  system, scaled by (f_L1/f)^2 (first-order dispersive delay).  Galileo's
  NeQuick-G and BeiDou's own Klobuchar variant are NOT implemented: the
  simulator uses one ionosphere (the GPS Klobuchar shape) as "truth" for all
  signals; only the receiver-side correction model would differ.
- Troposphere: Saastamoinen zenith delays with a standard atmosphere (as
  RTKLIB tropmodel(): 1013.25 hPa, 15 C at sea level, relative humidity 0.7)
  mapped with the Niell (1996) mapping functions (as RTKLIB nmf()).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from gnss_sim_ros2.core import constants as k
from gnss_sim_ros2.core.time import GnssTime

# =====================================================================================
# Light time and Earth rotation
# =====================================================================================


@dataclass
class LightTimeSolution:
    """Result of :func:`transmit_time_solution` (rows = satellites)."""

    t_tx: object                 #: transmit instants (GnssTime, or float s if t_rx was float; None if no t_rx)
    tau_s: np.ndarray            #: light time t_rx - t_tx [s]
    sat_pos_ecef_m: np.ndarray   #: (N, 3) satellite at t_tx, in the ECEF frame of t_rx
    sat_vel_ecef_mps: np.ndarray  #: (N, 3) satellite ECEF velocity at t_tx, rotated into the frame of t_rx
    range_m: np.ndarray          #: (N,) geometric range = c * tau [m]
    range_rate_mps: np.ndarray   #: (N,) d(range)/d(t_rx) [m/s] (light-time and rotation terms included)
    los_unit_ecef: np.ndarray    #: (N, 3) unit vector receiver -> satellite (ECEF at t_rx)


def _as_rows3(a, name):
    a = np.asarray(a, dtype=np.float64)
    if a.shape[-1:] != (3,):
        raise ValueError(f"propagation: parameter {name!r} must have shape (3,) or (N, 3), got {a.shape}")
    return a


def _n_rows(a, shape):
    """``a`` broadcast to ``shape``: an array of that shape as it is (the receiver's per-row arrays: no
    np.broadcast_to view made per call)."""
    return a if a.shape == shape else np.broadcast_to(a, shape)


def _unpack_state(st, n_expected=None):
    if hasattr(st, "pos_ecef_m"):
        pos, vel = st.pos_ecef_m, st.vel_ecef_mps
    else:
        pos, vel = st[0], st[1]
    pos = np.atleast_2d(np.asarray(pos, dtype=np.float64))
    vel = np.atleast_2d(np.asarray(vel, dtype=np.float64))
    if n_expected is not None and pos.shape[0] != n_expected:
        raise ValueError(
            f"propagation: the states callable returned {pos.shape[0]} rows, expected {n_expected}"
        )
    return pos, vel


def _rotate(theta, a):
    """R3(theta) applied to rows of ``a`` (N, 3): ECEF(t_tx) -> ECEF(t_tx + theta/omega), as _rot_z."""
    c, s = np.cos(theta), np.sin(theta)
    out = np.empty_like(a)
    out[:, 0] = c * a[:, 0] + s * a[:, 1]
    out[:, 1] = c * a[:, 1] - s * a[:, 0]
    out[:, 2] = a[:, 2]
    return out


def _finish(rx, rx_vel, tau, pos, vel, omega):
    theta = omega * tau
    c, s = np.cos(theta), np.sin(theta)
    p = np.empty_like(pos)
    p[:, 0] = c * pos[:, 0] + s * pos[:, 1]
    p[:, 1] = c * pos[:, 1] - s * pos[:, 0]
    p[:, 2] = pos[:, 2]
    v = np.empty_like(vel)
    v[:, 0] = c * vel[:, 0] + s * vel[:, 1]
    v[:, 1] = c * vel[:, 1] - s * vel[:, 0]
    v[:, 2] = vel[:, 2]
    d = p - rx
    rng = np.sqrt(np.einsum("ni,ni->n", d, d))
    u = d / rng[:, None]
    # range rate: rho(t) = |R(w tau) s(t - tau) - r(t)|, tau = rho / c  =>
    # rho_dot = u.(R s_dot - r_dot) / (1 - u.(w R' s - R s_dot) / c),  R' s = (-s x + c y, -c x - s y, 0)
    a = np.einsum("ni,ni->n", u, v - rx_vel)
    drs_x = -s * pos[:, 0] + c * pos[:, 1]
    drs_y = -c * pos[:, 0] - s * pos[:, 1]
    b = u[:, 0] * (omega * drs_x - v[:, 0]) + u[:, 1] * (omega * drs_y - v[:, 1]) - u[:, 2] * v[:, 2]
    rr = a / (1.0 - b / k.C_MPS)
    return p, v, rng, rr, u


def _solve(rx_ecef_m, rx_vel_ecef_mps, state_of_tau, n, iterations, omega_e_radps, pos_at_reception=None):
    """The light-time iterations on ``state_of_tau`` (satellite (pos, vel) at t_rx - tau); ``pos_at_reception``:
    the position state_of_tau(0) gives when known (the first guess without an evaluation)."""
    rx = _n_rows(_as_rows3(rx_ecef_m, "rx_ecef_m"), (n, 3))
    rx_vel = _n_rows(
        _as_rows3(np.zeros(3) if rx_vel_ecef_mps is None else rx_vel_ecef_mps, "rx_vel_ecef_mps"), (n, 3))
    if int(iterations) < 1:
        raise ValueError(f"propagation: parameter 'iterations' = {iterations!r} must be >= 1")
    omega = _n_rows(np.asarray(omega_e_radps, dtype=np.float64), (n,))
    # initial guess: the satellite at the reception instant
    pos = state_of_tau(np.zeros(n))[0] if pos_at_reception is None else pos_at_reception
    tau = _norm_rows(pos - rx) / k.C_MPS
    for _ in range(int(iterations)):
        pos, vel = state_of_tau(tau)
        tau = _norm_rows(_rotate(omega * tau, pos) - rx) / k.C_MPS
    # final evaluation at the converged tau: the returned range is that of the returned t_tx
    pos, vel = state_of_tau(tau)
    p, v, rng, rr, u = _finish(rx, rx_vel, tau, pos, vel, omega)
    return tau, p, v, rng, rr, u


def _norm_rows(d):
    return np.sqrt(np.einsum("ni,ni->n", d, d))


def transmit_time_solution(rx_ecef_m, t_rx, states_at_callable, iterations=2, rx_vel_ecef_mps=None,
                           omega_e_radps=k.OMEGA_E_GPS_RADPS, n_sats=None) -> LightTimeSolution:
    """Light-time solution by re-evaluating the satellite at the transmit time.

    ``states_at_callable(t_tx)`` gets the transmit instants, always an (N,) array
    (GnssTime, or float seconds when ``t_rx`` is float), and returns a
    SatelliteStates-like object (``pos_ecef_m``, ``vel_ecef_mps``) or a tuple
    ``(pos_ecef_m, vel_ecef_mps)`` of shape (N, 3): positions in the ECEF frame
    of the *transmit* instant (as an ephemeris gives them).
    ``rx_ecef_m``: (3,) or (N, 3) receiver position at t_rx; ``rx_vel_ecef_mps``
    optional receiver ECEF velocity (for the range rate).
    ``omega_e_radps``: scalar or (N,) Earth rotation rate of each satellite's system.
    ``n_sats``: N; needed only when ``t_rx`` is scalar and ``rx_ecef_m`` is (3,).
    ``iterations``: light-time updates after the initial guess tau = |r_sat(t_rx) - r_rx|/c
    (error ~3e-7 s); each update multiplies the error by ~1e-5, so 1 -> ~3e-12 s (1 mm),
    2 -> far below 1e-15 s.  The callable is evaluated iterations + 2 times.

    Returns a :class:`LightTimeSolution`; satellite positions rotated into the
    ECEF frame of t_rx (IS-GPS-200N 20.3.3.4.3.4).
    """
    if n_sats is None:
        if isinstance(t_rx, GnssTime) and np.ndim(t_rx.sec) == 1:
            n_sats = np.shape(t_rx.sec)[0]
        elif not isinstance(t_rx, GnssTime) and np.ndim(t_rx) == 1:
            n_sats = np.shape(t_rx)[0]
        elif np.ndim(rx_ecef_m) == 2:
            n_sats = np.shape(rx_ecef_m)[0]
        else:
            raise ValueError("propagation.transmit_time_solution: give 'n_sats' (number of satellites) "
                             "when both t_rx and rx_ecef_m are single values")
    n = int(n_sats)

    def state_of_tau(tau):
        return _unpack_state(states_at_callable(_shift(t_rx, -np.broadcast_to(tau, (n,)))), n)

    tau, p, v, rng, rr, u = _solve(rx_ecef_m, rx_vel_ecef_mps, state_of_tau, n, iterations, omega_e_radps)
    return LightTimeSolution(_shift(t_rx, -tau), tau, p, v, rng, rr, u)


#: light-time updates after one ephemeris evaluation stop when the error left, bounded by the last change
#: of tau times the contraction of the update (|range rate + Earth rotation term| / c < 3e-5 for any
#: GNSS orbit seen from the ground or LEO), is below 1e-15 s (3e-7 m)
_REFINE_TOL_S = 1e-15
_REFINE_CONTRACTION = 3e-5
_REFINE_MAX_UPDATES = 6
#: the satellite is moved along its Taylor series by at most this [s] from the instant the ephemeris was
#: evaluated at (with acceleration: error jerk dt^3 / 6 < 1e-13 m for MEO); further away: evaluate again
_REFINE_TAYLOR_MAX_S = 1e-4


def transmit_time_refined(rx_ecef_m, t_rx, states_at_callable, tau_guess_s, rx_vel_ecef_mps=None,
                          omega_e_radps=k.OMEGA_E_GPS_RADPS, max_evaluations=3) -> LightTimeSolution:
    """Light-time solution with one ephemeris evaluation, from a first guess of the light time.

    The same fixed point as :func:`transmit_time_solution` (c tau = |R3(omega_e tau) r_sat(t_rx - tau)
    - r_rx(t_rx)|, IS-GPS-200N 20.3.3.4.3.4), but the satellite is evaluated once, at
    t_rx - ``tau_guess_s``, and moved from there to t_rx - tau by its second-order Taylor series
    (velocity and acceleration of that evaluation) while tau is iterated.  A guess within
    ~1e-6 s (any guess from the satellite's state at the epoch, even without Earth rotation, is
    within ~5e-7 s) moves the satellite by < 1e-14 m less than a re-evaluation would; a
    guess further than 1e-4 s from the solution triggers another evaluation there (at most
    ``max_evaluations``).  Against transmit_time_solution: ranges within 1e-6 m
    (test_receiver_speed.py).

    ``states_at_callable(t_tx)`` as in :func:`transmit_time_solution`; it may also return
    ``(pos, vel, acc)`` or an object with ``acc_ecef_mps2`` (without an acceleration the series
    is first order: still < 1e-12 m for a guess within 1e-6 s).  ``tau_guess_s``: (N,).
    """
    tau0 = np.atleast_1d(np.asarray(tau_guess_s, dtype=np.float64))
    n = tau0.shape[0]
    rx = _n_rows(_as_rows3(rx_ecef_m, "rx_ecef_m"), (n, 3))
    rx_vel = _n_rows(
        _as_rows3(np.zeros(3) if rx_vel_ecef_mps is None else rx_vel_ecef_mps, "rx_vel_ecef_mps"), (n, 3))
    omega = _n_rows(np.asarray(omega_e_radps, dtype=np.float64), (n,))
    if int(max_evaluations) < 1:
        raise ValueError(f"propagation: parameter 'max_evaluations' = {max_evaluations!r} must be >= 1")
    for _ in range(int(max_evaluations)):
        pos0, vel0, acc0 = _unpack_state_acc(states_at_callable(_shift(t_rx, -tau0)), n)
        tau = tau0
        for j in range(_REFINE_MAX_UPDATES):
            if j == 0:
                p = pos0            # the satellite where it was evaluated
            else:
                dt = (tau - tau0)[:, None]
                p = pos0 - vel0 * dt + 0.5 * acc0 * dt * dt
            new = _norm_rows(_rotate(omega * tau, p) - rx) / k.C_MPS
            change = np.max(np.abs(new - tau), initial=0.0)
            tau = new
            if change * _REFINE_CONTRACTION < _REFINE_TOL_S:
                break
        if np.max(np.abs(tau - tau0), initial=0.0) <= _REFINE_TAYLOR_MAX_S:
            break
        tau0 = tau
    dt = (tau - tau0)[:, None]
    pos = pos0 - vel0 * dt + 0.5 * acc0 * dt * dt
    vel = vel0 - acc0 * dt
    p, v, rng, rr, u = _finish(rx, rx_vel, tau, pos, vel, omega)
    return LightTimeSolution(_shift(t_rx, -tau), tau, p, v, rng, rr, u)


def _unpack_state_acc(st, n):
    """(pos, vel, acc) (N, 3) from a states object or a tuple; acc zero when not given."""
    pos, vel = _unpack_state(st, n)
    if hasattr(st, "acc_ecef_mps2"):
        acc = st.acc_ecef_mps2
    elif not hasattr(st, "pos_ecef_m") and len(st) > 2:
        acc = st[2]
    else:
        acc = None
    acc = np.zeros_like(pos) if acc is None else np.atleast_2d(np.asarray(acc, dtype=np.float64))
    if acc.shape != pos.shape:
        raise ValueError(f"propagation: the states callable returned accelerations of shape {acc.shape}, "
                         f"expected {pos.shape}")
    return pos, vel, acc


def _shift(t, dt_s):
    """t + dt_s for a GnssTime or float t; dt_s an array (N,)."""
    if isinstance(t, GnssTime):
        d = np.asarray(dt_s, dtype=np.float64)
        if np.ndim(t.sec):
            return t + d
        # scalar t: GnssTime.__add__ on t broadcast to the shape of dt_s, without building that broadcast
        whole = np.floor(d)
        return GnssTime(t.sec + whole.astype(np.int64), t.frac + (d - whole))
    return np.asarray(t, dtype=np.float64) + np.asarray(dt_s)


def transmit_time_from_states(rx_ecef_m, pos_ecef_m, vel_ecef_mps, acc_ecef_mps2, t_rx=None, iterations=2,
                              rx_vel_ecef_mps=None, omega_e_radps=k.OMEGA_E_GPS_RADPS) -> LightTimeSolution:
    """Cheap light-time solution from satellite states *at the reception instant*.

    The satellite is moved back to t_rx - tau with a second-order expansion
    r(t_rx - tau) = r - v tau + a tau^2 / 2 (ECEF, so ``acc_ecef_mps2`` must
    be the ECEF acceleration including the frame terms, as SatelliteStates
    carries it).  Over tau ~ 0.07 s the neglected jerk term is below 1e-8 m for
    MEO orbits (see test_propagation).  ``t_rx`` (optional) only fills ``t_tx``.
    """
    pos = np.atleast_2d(_as_rows3(pos_ecef_m, "pos_ecef_m"))
    vel = np.atleast_2d(_as_rows3(vel_ecef_mps, "vel_ecef_mps"))
    acc = np.atleast_2d(_as_rows3(acc_ecef_mps2, "acc_ecef_mps2"))
    n = pos.shape[0]
    if vel.shape != pos.shape or acc.shape != pos.shape:
        raise ValueError(
            f"propagation.transmit_time_from_states: pos/vel/acc shapes differ: {pos.shape}, {vel.shape}, {acc.shape}")

    half_acc = 0.5 * acc

    def state_of_tau(tau):
        t = tau[:, None]
        return pos - vel * t + half_acc * t * t, vel - acc * t

    # at tau = 0 the series is pos itself (pos - v 0 + a 0 0 / 2, the same bits for finite states)
    tau, p, v, rng, rr, u = _solve(rx_ecef_m, rx_vel_ecef_mps, state_of_tau, n, iterations, omega_e_radps, pos)
    t_tx = None if t_rx is None else _shift(t_rx, -tau)
    return LightTimeSolution(t_tx, tau, p, v, rng, rr, u)


def sagnac_correction_m(sat_ecef_m, rx_ecef_m, omega_e_radps=k.OMEGA_E_GPS_RADPS):
    """First-order Earth-rotation (Sagnac) range term omega_e (x_s y_r - y_s x_r) / c [m] (RTKLIB geodist())."""
    s = np.asarray(sat_ecef_m, dtype=np.float64)
    r = np.asarray(rx_ecef_m, dtype=np.float64)
    return omega_e_radps * (s[..., 0] * r[..., 1] - s[..., 1] * r[..., 0]) / k.C_MPS


# =====================================================================================
# Ionosphere
# =====================================================================================
#: Klobuchar night-time constant delay [s] (IS-GPS-200N 20.3.3.5.2.5)
KLOBUCHAR_NIGHT_S = 5.0e-9
#: Klobuchar local time of the maximum [s] (14:00)
KLOBUCHAR_PEAK_S = 50400.0


def _seconds_of_day(t):
    if isinstance(t, GnssTime):
        return np.mod(np.asarray(t.sec, dtype=np.int64), 86400).astype(np.float64) + np.asarray(t.frac)
    return np.mod(np.asarray(t, dtype=np.float64), 86400.0)


def klobuchar_l1_delay_s(t, lat_deg, lon_deg, az_deg, el_deg, alpha, beta):
    """Ionospheric group delay at L1 [s] from the GPS broadcast model (IS-GPS-200N 20.3.3.5.2.5).

    ``t``: GPS time (GnssTime, or float seconds of GPS week/day: only the time
    of day is used); user geodetic ``lat_deg``, ``lon_deg``; satellite
    ``az_deg``, ``el_deg`` (arrays broadcast); ``alpha``, ``beta``: the four
    broadcast coefficients each (s, s/semicircle^n; s, s/semicircle^n).
    """
    alpha = np.asarray(alpha, dtype=np.float64)
    beta = np.asarray(beta, dtype=np.float64)
    if alpha.shape != (4,) or beta.shape != (4,):
        raise ValueError(f"propagation.klobuchar: parameters 'alpha'/'beta' need 4 values each, got "
                         f"{alpha.shape} and {beta.shape}")
    # all angles in semicircles, as in the ICD
    phi_u = np.asarray(lat_deg, dtype=np.float64) / 180.0
    lam_u = np.asarray(lon_deg, dtype=np.float64) / 180.0
    a_rad = np.radians(az_deg)
    e = np.asarray(el_deg, dtype=np.float64) / 180.0
    psi = 0.0137 / (e + 0.11) - 0.022                      # Earth's central angle [semicircles]
    phi_i = np.minimum(np.maximum(phi_u + psi * np.cos(a_rad), -0.416), 0.416)  # sub-ionospheric latitude
    lam_i = lam_u + psi * np.sin(a_rad) / np.cos(phi_i * np.pi)  # sub-ionospheric longitude
    phi_m = phi_i + 0.064 * np.cos((lam_i - 1.617) * np.pi)     # geomagnetic latitude
    tloc = np.mod(4.32e4 * lam_i + _seconds_of_day(t), 86400.0)  # local time [s]
    f = 1.0 + 16.0 * (0.53 - e) ** 3                         # obliquity factor
    amp = np.maximum(alpha[0] + phi_m * (alpha[1] + phi_m * (alpha[2] + phi_m * alpha[3])), 0.0)
    per = np.maximum(beta[0] + phi_m * (beta[1] + phi_m * (beta[2] + phi_m * beta[3])), 72000.0)
    x = 2.0 * np.pi * (tloc - KLOBUCHAR_PEAK_S) / per
    day = np.where(np.abs(x) < 1.57, amp * (1.0 - x**2 / 2.0 + x**4 / 24.0), 0.0)
    return f * (KLOBUCHAR_NIGHT_S + day)


def iono_scale(f_hz):
    """First-order ionospheric scale factor (f_L1 / f)^2 from L1 to frequency ``f_hz``."""
    return (k.F_L1_HZ / np.asarray(f_hz, dtype=np.float64)) ** 2


def iono_code_delay_m(l1_delay_s, f_hz):
    """Group delay on the code (pseudorange) at ``f_hz`` [m] (positive)."""
    return k.C_MPS * np.asarray(l1_delay_s) * iono_scale(f_hz)


def iono_phase_advance_m(l1_delay_s, f_hz):
    """Effect on the carrier phase at ``f_hz`` [m]: the phase advance, -(code delay)."""
    return -iono_code_delay_m(l1_delay_s, f_hz)


# =====================================================================================
# Troposphere
# =====================================================================================
#: RTKLIB tropmodel() default relative humidity [-]
TROPO_HUMIDITY_DEFAULT = 0.7

# Niell (1996, JGR 101(B2):3227) table 3: rows a, b, c at |lat| = 15, 30, 45, 60, 75 deg
_NMF_LAT = np.array([15.0, 30.0, 45.0, 60.0, 75.0])
_NMF_HYD_AVG = np.array([
    [1.2769934e-3, 1.2683230e-3, 1.2465397e-3, 1.2196049e-3, 1.2045996e-3],
    [2.9153695e-3, 2.9152299e-3, 2.9288445e-3, 2.9022565e-3, 2.9024912e-3],
    [62.610505e-3, 62.837393e-3, 63.721774e-3, 63.824265e-3, 64.258455e-3],
])
_NMF_HYD_AMP = np.array([
    [0.0, 1.2709626e-5, 2.6523662e-5, 3.4000452e-5, 4.1202191e-5],
    [0.0, 2.1414979e-5, 3.0160779e-5, 7.2562722e-5, 11.723375e-5],
    [0.0, 9.0128400e-5, 4.3497037e-5, 84.795348e-5, 170.37206e-5],
])
_NMF_WET = np.array([
    [5.8021897e-4, 5.6794847e-4, 5.8118019e-4, 5.9727542e-4, 6.1641693e-4],
    [1.4275268e-3, 1.5138625e-3, 1.4572752e-3, 1.5007428e-3, 1.7599082e-3],
    [4.3472961e-2, 4.6729510e-2, 4.3908931e-2, 4.4626982e-2, 5.4736038e-2],
])
#: Niell hydrostatic height-correction coefficients a, b, c (per km)
_NMF_HT = (2.53e-5, 5.49e-3, 1.14e-3)


def _mapf(sin_el, a, b, c):
    """Marini continued fraction normalised to 1 at zenith (Herring 1992 form used by Niell)."""
    return (1.0 + a / (1.0 + b / (1.0 + c))) / (sin_el + a / (sin_el + b / (sin_el + c)))


def saastamoinen_zenith_m(lat_deg, h_m, humidity=TROPO_HUMIDITY_DEFAULT, temp0_c=15.0, p0_hpa=1013.25):
    """(zenith hydrostatic, zenith wet) delays [m], Saastamoinen with a standard atmosphere.

    As RTKLIB tropmodel(): p = p0 (1 - 2.2557e-5 h)^5.2568 hPa, T = T0 - 6.5e-3 h,
    water vapour e = 6.108 rh exp((17.15 T - 4684)/(T - 38.45)) hPa;
    ZHD = 0.0022768 p / (1 - 0.00266 cos 2 lat - 0.00028 h_km) (Saastamoinen 1972,
    Davis et al. 1985); ZWD = 0.002277 (1255/T + 0.05) e.  Heights below 0 are
    clipped to 0 and above 10 km to 10 km (outside the model's range).
    """
    h = np.clip(np.asarray(h_m, dtype=np.float64), 0.0, 1.0e4)
    if ((humidity < 0 or humidity > 1) if type(humidity) is float
            else ((np.asarray(humidity) < 0) | (np.asarray(humidity) > 1)).any()):
        raise ValueError(f"propagation.saastamoinen: parameter 'humidity' = {humidity!r} must be within 0..1")
    pres = p0_hpa * (1.0 - 2.2557e-5 * h) ** 5.2568
    temp = temp0_c - 6.5e-3 * h + 273.16   # [K] (RTKLIB's 273.16)
    e = 6.108 * humidity * np.exp((17.15 * temp - 4684.0) / (temp - 38.45))
    lat = np.radians(lat_deg)
    zhd = 0.0022768 * pres / (1.0 - 0.00266 * np.cos(2.0 * lat) - 0.00028 * h / 1e3)
    zwd = 0.002277 * (1255.0 / temp + 0.05) * e
    return zhd, zwd


def niell_mapping(el_deg, lat_deg, h_m, doy, epoch_of_row=None):
    """(hydrostatic, wet) Niell mapping functions (Niell 1996; as RTKLIB nmf()).

    ``doy``: day of year (fractional allowed); southern latitudes shift by half a
    year.  ``h_m``: ellipsoidal height (RTKLIB also uses it for the height
    correction).  Elevations below 1 deg are evaluated at 1 deg.  ``epoch_of_row``:
    ``lat_deg``, ``h_m`` and ``doy`` are given per epoch (K,) and ``el_deg`` per row,
    row j at epoch ``epoch_of_row[j]``: the coefficients are computed once per epoch
    (element by element, so the values per row are the same).
    """
    el = np.radians(np.maximum(np.asarray(el_deg, dtype=np.float64), 1.0))
    lat = np.asarray(lat_deg, dtype=np.float64)
    y = (np.asarray(doy, dtype=np.float64) - 28.0) / 365.25 + np.where(lat < 0.0, 0.5, 0.0)
    cosy = np.cos(2.0 * np.pi * y)
    if lat.ndim == 0:      # one receiver position: the latitude interpolation is cached
        avg, amp, wet = _nmf_rows(float(np.abs(lat)))
    else:
        avg, amp, wet = _nmf_interp(np.abs(lat))
    ah = [avg[i] - amp[i] * cosy for i in range(3)]
    aw = list(wet)
    h = np.asarray(h_m, dtype=np.float64)
    if epoch_of_row is not None:
        ah, aw, h = [a[epoch_of_row] for a in ah], [a[epoch_of_row] for a in aw], h[epoch_of_row]
    s = np.sin(el)
    dm = (1.0 / s - _mapf(s, *_NMF_HT)) * h / 1e3
    return _mapf(s, *ah) + dm, _mapf(s, *aw)


def _nmf_interp(alat):
    """Niell table rows interpolated at |latitude| ``alat`` (clamped outside 15..75 like RTKLIB interpc())."""
    return tuple(tuple(np.interp(alat, _NMF_LAT, table[i]) for i in range(3))
                 for table in (_NMF_HYD_AVG, _NMF_HYD_AMP, _NMF_WET))


@functools.lru_cache(maxsize=64)
def _nmf_rows(alat: float):
    return _nmf_interp(np.float64(alat))


def tropo_slant_delay_m(el_deg, lat_deg, h_m, doy, humidity=TROPO_HUMIDITY_DEFAULT, epoch_of_row=None):
    """Slant tropospheric delay [m] (same on code and carrier): ZHD m_h + ZWD m_w.  ``epoch_of_row``:
    ``lat_deg``, ``h_m`` and ``doy`` per epoch, ``el_deg`` per row (niell_mapping): the zenith delays and the
    mapping coefficients once per epoch."""
    return tropo_slant_parts_m(el_deg, lat_deg, h_m, doy, humidity, epoch_of_row)[0]


def tropo_slant_parts_m(el_deg, lat_deg, h_m, doy, humidity=TROPO_HUMIDITY_DEFAULT, epoch_of_row=None):
    """(slant delay ZHD m_h + ZWD m_w, ZWD, m_w) [m, m, -] per row, as :func:`tropo_slant_delay_m`: the
    zenith wet delay and the wet mapping besides the delay, for a wet delay other than the model's
    (receiver/world_errors.py: the true atmosphere's water vapour)."""
    if np.ndim(lat_deg) == 0 and np.ndim(h_m) == 0 and np.ndim(humidity) == 0:   # one receiver: cached
        zhd, zwd = _zenith_cached(float(lat_deg), float(h_m), float(humidity))
    else:
        zhd, zwd = saastamoinen_zenith_m(lat_deg, h_m, humidity)
        if epoch_of_row is not None:
            zhd, zwd = zhd[epoch_of_row], zwd[epoch_of_row]
    mh, mw = niell_mapping(el_deg, lat_deg, h_m, doy, epoch_of_row)
    slant = zhd * mh + zwd * mw
    return slant, _n_rows(np.asarray(zwd), np.shape(slant)), mw


@functools.lru_cache(maxsize=64)
def _zenith_cached(lat_deg: float, h_m: float, humidity: float):
    return saastamoinen_zenith_m(np.float64(lat_deg), np.float64(h_m), humidity)


def day_of_year(t: GnssTime):
    """Fractional day of year (1.0 = Jan 1 00:00) of a GnssTime in GPS time (scalar or array)."""
    import datetime as _dt

    if np.ndim(t.sec) == 0:
        d = t.to_datetime("GPS")
        return (d - _dt.datetime(d.year, 1, 1)).total_seconds() / 86400.0 + 1.0
    return np.array([day_of_year(t[i]) for i in range(len(t))])
