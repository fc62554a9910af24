"""Receiver clock: bias and drift as a two-state random process, with steering.

State x = [bias_s, drift_sps] (seconds, seconds per second).  Continuous model:
bias' = drift + w_f, drift' = w_g, white noises of spectral densities
S_f = h0 / 2 and S_g = 2 pi^2 h_-2 (white and random-walk frequency noise; the
flicker term h_-1 has no finite-state model and is left out).  Exact
discretisation over dt (Brown & Hwang, Introduction to Random Signals and
Applied Kalman Filtering, 4th ed., 9.3):

    Phi = [[1, dt], [0, 1]],
    Q = [[S_f dt + S_g dt^3 / 3, S_g dt^2 / 2], [S_g dt^2 / 2, S_g dt]].

Its Allan variance is sigma_y^2(tau) = h0 / (2 tau) + (2 pi^2 / 3) h_-2 tau.
Typical coefficients (Brown & Hwang, table of Allan-variance parameters for
timing standards): TCXO h0 = 2e-19 s, h_-2 = 2e-20 1/s; OCXO 8e-20, 4e-23;
rubidium 2e-20, 4e-29.

Steering, as receivers do:
- ``"ms_jump"`` (most mass-market and many geodetic receivers): the clock runs
  free and is stepped by exactly 1 ms when |bias| exceeds ``jump_threshold_s``
  (default 1 ms); the pseudoranges jump by 299792.458 m, carrier phases do not
  if the receiver keeps them continuous (reported in ``jumped``).
- ``"continuous"``: the receiver steers its clock frequency to drive the bias
  to zero with time constant ``steer_tau_s``: bias_{k+1} = bias_k (1 - dt/tau)
  + noise; the reported drift is the steered rate.
- ``"none"``: free running.

``noise=False`` gives the deterministic clock: constant drift, linear bias
(and the jumps).  Randomness only from the numpy Generator passed in / seeded.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..memo import BoundedCache

#: Allan-variance coefficients (h0 [s], h_-2 [1/s]) (Brown & Hwang, 4th ed., ch. 9)
OSCILLATORS = {
    "tcxo": (2.0e-19, 2.0e-20),
    "ocxo": (8.0e-20, 4.0e-23),
    "rubidium": (2.0e-20, 4.0e-29),
}
MS_S = 1.0e-3
STEERING_MODES = ("ms_jump", "continuous", "none")


def process_noise(dt_s, h0, h_m2):
    """Discrete process-noise covariance Q (2x2) of [bias_s, drift_sps] over ``dt_s``."""
    sf = h0 / 2.0
    sg = 2.0 * np.pi**2 * h_m2
    dt = float(dt_s)
    return np.array([[sf * dt + sg * dt**3 / 3.0, sg * dt**2 / 2.0], [sg * dt**2 / 2.0, sg * dt]])


@dataclass
class ClockConfig:
    h0: float = OSCILLATORS["tcxo"][0]
    h_m2: float = OSCILLATORS["tcxo"][1]
    initial_bias_s: float = 0.0
    initial_drift_sps: float = 5.0e-7      #: a TCXO within its +-2 ppm tolerance
    steering: str = "ms_jump"
    jump_threshold_s: float = 1.0e-3
    steer_tau_s: float = 10.0
    noise: bool = True

    def __post_init__(self):
        if self.steering not in STEERING_MODES:
            raise ValueError(f"ClockConfig: parameter 'steering' = {self.steering!r} is not one of {STEERING_MODES}")
        if self.h0 < 0 or self.h_m2 < 0:
            raise ValueError(f"ClockConfig: parameters 'h0' = {self.h0}, 'h_m2' = {self.h_m2} must be >= 0")
        if self.jump_threshold_s <= 0 or self.steer_tau_s <= 0:
            raise ValueError("ClockConfig: 'jump_threshold_s' and 'steer_tau_s' must be > 0")


class ReceiverClock:
    """Receiver clock state stepped epoch by epoch (:meth:`step`) or simulated in one go (:meth:`simulate`)."""

    def __init__(self, config: ClockConfig | None = None, rng: np.random.Generator | int | None = 0):
        self.config = config or ClockConfig()
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        self.bias_s = float(self.config.initial_bias_s)
        self.drift_sps = float(self.config.initial_drift_sps)   # oscillator frequency offset
        self.steered_drift_sps = self.drift_sps
        self._chol = BoundedCache(16)

    def _noise(self, dt_s, n):
        c = self.config
        if not c.noise or (c.h0 == 0 and c.h_m2 == 0):
            return np.zeros((n, 2))
        key = (float(dt_s), c.h0, c.h_m2)
        lq = self._chol.get(key)
        if lq is None:     # the factor of one interval, computed once (an epoch grid has one or a few)
            q = process_noise(dt_s, c.h0, c.h_m2)
            lq = np.linalg.cholesky(q + np.diag([1e-300, 1e-300])).T
            self._chol.put(key, lq)
        return self.rng.standard_normal((n, 2)) @ lq

    def step(self, dt_s: float):
        """Advance by ``dt_s`` > 0. Returns (bias_s, drift_sps, jumped_s): jumped_s = step applied (0 or +-1 ms)."""
        if dt_s <= 0:
            raise ValueError(f"ReceiverClock.step: parameter 'dt_s' = {dt_s} must be > 0")
        c = self.config
        w = self._noise(dt_s, 1)[0]
        jumped = 0.0
        if c.steering == "continuous":
            gain = min(dt_s / c.steer_tau_s, 1.0)
            new_bias = self.bias_s * (1.0 - gain) + w[0]
            self.drift_sps += w[1]
            self.steered_drift_sps = (new_bias - self.bias_s) / dt_s
            self.bias_s = new_bias
            return self.bias_s, self.steered_drift_sps, jumped
        self.bias_s += self.drift_sps * dt_s + w[0]
        self.drift_sps += w[1]
        if c.steering == "ms_jump" and abs(self.bias_s) > c.jump_threshold_s:
            jumped = -np.sign(self.bias_s) * MS_S
            self.bias_s += jumped
        self.steered_drift_sps = self.drift_sps
        return self.bias_s, self.drift_sps, jumped

    def simulate(self, n_steps: int, dt_s: float):
        """Run ``n_steps`` steps of ``dt_s`` at once (vectorised). Returns arrays (bias_s, drift_sps, jumped_s).

        Element i is the state after step i+1; the object's state is left at the last one.
        """
        if n_steps < 1 or dt_s <= 0:
            raise ValueError(f"ReceiverClock.simulate: 'n_steps' = {n_steps} must be >= 1, 'dt_s' = {dt_s} > 0")
        c = self.config
        w = self._noise(dt_s, n_steps)
        jumped = np.zeros(n_steps)
        if c.steering == "continuous":
            from scipy.signal import lfilter

            a = 1.0 - min(dt_s / c.steer_tau_s, 1.0)
            bias, _ = lfilter([1.0], [1.0, -a], w[:, 0], zi=[a * self.bias_s])
            prev = np.concatenate([[self.bias_s], bias[:-1]])
            drift = (bias - prev) / dt_s
            self.drift_sps += w[:, 1].sum()
        else:
            drift_osc = self.drift_sps + np.cumsum(w[:, 1])
            drift_before = np.concatenate([[self.drift_sps], drift_osc[:-1]])
            bias = self.bias_s + np.cumsum(drift_before * dt_s + w[:, 0])
            drift = drift_osc
            if c.steering == "ms_jump":
                offset = 0.0
                i = 0
                while True:
                    over = np.nonzero(np.abs(bias[i:] + offset) > c.jump_threshold_s)[0]
                    if over.size == 0:
                        break
                    i += int(over[0])
                    step = -np.sign(bias[i] + offset) * MS_S
                    jumped[i] = step
                    offset += step
                    i += 1
                bias = bias + np.cumsum(jumped)
            self.drift_sps = float(drift_osc[-1])
        self.bias_s = float(bias[-1])
        self.steered_drift_sps = float(drift[-1])
        return bias, drift, jumped
