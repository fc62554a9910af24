"""GLONASS FDMA broadcast ephemerides: numerical integration of the PZ-90 state.

GLONASS ICD 5.1 (2008), A.3.1.2 ("simplified algorithm"): the broadcast
position, velocity and luni-solar acceleration at tb are integrated in the
rotating PZ-90 frame with the central field, the J2 (C20) zonal term and the
broadcast luni-solar acceleration held constant:

    dv/dt = -GM r/r^3 - 3/2 J2 GM a_e^2 / r^5 (x (1-5z^2/r^2), y (1-5z^2/r^2), z (3-5z^2/r^2))
            + w^2 (x, y, 0) + 2 w (vy, -vx, 0) + a_ls

with 4th-order Runge-Kutta steps of ``STEP_S`` (<= 60 s, ICD A.3.1.2).
Each record is integrated once over its whole validity window (backwards and
forwards from tb) and the nodes are kept; states between nodes come from the
quintic Hermite interpolant of position, velocity and acceleration at the two
nodes around t (precomputed as polynomial coefficients per interval;
interpolation error far below the RK4 error: the test against an independent
DOP853 integration agrees to 1 cm), so a call never re-integrates from tb.

Time: the records' tb is converted from UTC (RINEX) to GPS time by core/time.py;
t - tb is then elapsed GPS seconds, which across a leap second equals elapsed
GLONASST (UTC(SU) + 3 h) seconds: the leap second is accounted for.
Clock (ICD 5.1, 3.3.3): t_sv - t_GLONASS = -tau_n + gamma_n (t - tb); as in SP3
it refers to GLONASST (the GLONASS - GPS time offset, a few tens of ns, is
common to all GLONASS satellites).  No relativistic term is returned (the
GLONASS broadcast clock contains it).
PZ-90.11 vs ITRF: the transformation is a few millimetres (IERS / GLONASS ICD
2016 edition) and is neglected: positions are PZ-90.11 taken as ITRF.
"""
from __future__ import annotations

import numpy as np

from .. import constants as K
from .kepler import gravity_j2_ecef

#: RK4 step [s] (GLONASS ICD 5.1 A.3.1.2 asks for <= 60 s; RTKLIB uses 60 s)
STEP_S = 30.0


def glonass_acceleration(pos_m, vel_mps, acc_ls_mps2):
    """Right-hand side of GLONASS ICD 5.1 A.3.1.2 in PZ-90 ECEF [m/s^2] (arrays (..., 3)):
    two-body + J2 in the rotating frame with the PZ-90 constants, plus the broadcast luni-solar terms."""
    return gravity_j2_ecef(pos_m, vel_mps, K.GM_GLO_M3PS2, K.OMEGA_E_GLO_RADPS, K.A_E_GLO_M, K.J2_GLO) + acc_ls_mps2


def rk4_step(pos, vel, acc_ls, h):
    """One RK4 step of length h [s] (negative to go backwards)."""
    def f(p, v):
        return v, glonass_acceleration(p, v, acc_ls)

    k1p, k1v = f(pos, vel)
    k2p, k2v = f(pos + 0.5 * h * k1p, vel + 0.5 * h * k1v)
    k3p, k3v = f(pos + 0.5 * h * k2p, vel + 0.5 * h * k2v)
    k4p, k4v = f(pos + h * k3p, vel + h * k3v)
    return (pos + h / 6.0 * (k1p + 2 * k2p + 2 * k3p + k4p),
            vel + h / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v))


def integrate(pos0_m, vel0_mps, acc_ls_mps2, dt_s, step_s: float = STEP_S):
    """Integrate states (N, 3) from tb to tb + dt_s (scalar or (N,)) with RK4 steps <= step_s.

    Direct integration (used by tests and for one-off states); the provider
    uses :class:`GlonassOrbits` instead.
    """
    pos = np.array(pos0_m, dtype=np.float64, ndmin=2)
    vel = np.array(vel0_mps, dtype=np.float64, ndmin=2)
    acc = np.array(acc_ls_mps2, dtype=np.float64, ndmin=2)
    dt = np.broadcast_to(np.asarray(dt_s, dtype=np.float64), pos.shape[:1]).copy()
    nsteps = np.ceil(np.abs(dt) / step_s).astype(np.int64)
    h_all = np.where(nsteps > 0, dt / np.maximum(nsteps, 1), 0.0)
    for k in range(int(nsteps.max(initial=0))):
        active = k < nsteps
        h = np.where(active, h_all, 0.0)[:, None]
        p1, v1 = rk4_step(pos, vel, acc, h)
        pos, vel = np.where(active[:, None], p1, pos), np.where(active[:, None], v1, vel)
    return pos, vel, glonass_acceleration(pos, vel, acc)


class GlonassOrbits:
    """Dense orbits of GLONASS records: RK4 nodes every ``step_s`` over [tb - span, tb + span].

    ``pos0``, ``vel0``, ``acc_ls`` are (N, 3) arrays of the records at tb;
    ``span_s`` (scalar or (N,)) is how far from tb states are wanted.
    """

    def __init__(self, pos0_m, vel0_mps, acc_ls_mps2, span_s, step_s: float = STEP_S):
        if not 0 < step_s <= 60.0:
            raise ValueError(f"GLONASS integration step_s={step_s} must be in (0, 60] s (ICD 5.1 A.3.1.2)")
        pos0 = np.array(pos0_m, dtype=np.float64, ndmin=2)
        vel0 = np.array(vel0_mps, dtype=np.float64, ndmin=2)
        acc_ls = np.array(acc_ls_mps2, dtype=np.float64, ndmin=2)
        n = pos0.shape[0]
        span = float(np.max(span_s, initial=0.0))
        self.step_s = float(step_s)
        self.k_half = int(np.ceil(span / step_s)) + 1   # nodes on each side of tb
        nn = 2 * self.k_half + 1
        P = np.empty((n, nn, 3))
        V = np.empty((n, nn, 3))
        A = np.empty((n, nn, 3))
        c = self.k_half
        P[:, c], V[:, c] = pos0, vel0
        A[:, c] = glonass_acceleration(pos0, vel0, acc_ls)
        for direction in (1, -1):
            p, v = pos0, vel0
            for k in range(1, self.k_half + 1):
                p, v = rk4_step(p, v, acc_ls, direction * step_s)
                j = c + direction * k
                P[:, j], V[:, j] = p, v
                A[:, j] = glonass_acceleration(p, v, acc_ls)
        # quintic Hermite polynomial of each node interval, in powers of s = (t - t_j) / h
        h = self.step_s
        data = np.stack([P[:, :-1], V[:, :-1] * h, A[:, :-1] * (h * h), P[:, 1:], V[:, 1:] * h, A[:, 1:] * (h * h)],
                        axis=2)                                    # (n, intervals, 6 data, 3)
        self.C = np.einsum("bk,njbd->njkd", _HERMITE5, data)       # (n, intervals, 6 powers, 3)
        self.n = n

    def evaluate(self, idx, dt_s):
        """(pos, vel, acc) of records ``idx`` at dt_s = t - tb [s] (arrays like idx)."""
        idx = np.asarray(idx, dtype=np.int64)
        h = self.step_s
        x = np.asarray(dt_s, dtype=np.float64) / h + self.k_half
        j = np.clip(np.floor(x).astype(np.int64), 0, 2 * self.k_half - 1)
        s = (x - j)[:, None]
        c = self.C[idx, j]                                          # (m, 6, 3)
        S = s ** _POW                                               # (m, 6): 1, s, .., s^5
        pos = np.matmul(S[:, None, :], c)[:, 0]
        vel = np.matmul((S[:, :5] * _D1)[:, None, :], c[:, 1:])[:, 0] / h
        acc = np.matmul((S[:, :4] * _D2)[:, None, :], c[:, 2:])[:, 0] / (h * h)
        return pos, vel, acc


#: quintic Hermite basis (rows: p0, h v0, h^2 a0, p1, h v1, h^2 a1) in powers s^0..s^5
_HERMITE5 = np.array([
    [1, 0, 0, -10, 15, -6],
    [0, 1, 0, -6, 8, -3],
    [0, 0, 0.5, -1.5, 1.5, -0.5],
    [0, 0, 0, 10, -15, 6],
    [0, 0, 0, -4, 7, -3],
    [0, 0, 0, 0.5, -1, 0.5],
], dtype=np.float64)
_POW = np.arange(6, dtype=np.float64)
_D1 = np.arange(1, 6, dtype=np.float64)                  # d/ds s^k = k s^(k-1)
_D2 = np.array([2, 6, 12, 20], dtype=np.float64)         # d2/ds2 s^k = k (k-1) s^(k-2)


def glonass_clock(tau_n_s, gamma_n, dt_s):
    """(bias, drift) of the satellite clock: -tau_n + gamma_n (t - tb) (GLONASS ICD 5.1, 3.3.3)."""
    return -tau_n_s + gamma_n * dt_s, gamma_n + 0.0 * dt_s
