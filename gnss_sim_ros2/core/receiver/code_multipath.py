"""The receiver's code multipath/residual m_j (engine module doc): per (satellite, signal) a unit-variance
first-order Gauss-Markov state (correlation time ``mp_tau_s``) times sigma(el) = mp_zenith_m + mp_low_m
exp(-el / 15 deg) (a stated approximation), drawn from the receiver's own random stream."""
from __future__ import annotations

import numpy as np


class CodeMultipath:
    """The Gauss-Markov states, one slot per (sv, code) kept for the receiver's lifetime (NaN until first seen)."""

    def __init__(self, config, rng: np.random.Generator):
        self.cfg = config            # ReceiverConfig: mp_zenith_m, mp_low_m, mp_tau_s
        self.rng = rng
        self._index: dict[tuple[str, str], int] = {}
        self._x = np.full(256, np.nan)

    def slots(self, sv_j, codes) -> np.ndarray:
        """The state slot of each signal (sv_j, codes), new ones added."""
        idx = np.empty(len(sv_j), dtype=np.int64)
        for j, key in enumerate(zip(np.asarray(sv_j).tolist(), np.asarray(codes).tolist())):
            i = self._index.get(key)
            if i is None:
                i = self._index[key] = len(self._index)
            idx[j] = i
        if len(self._index) > self._x.size:
            grown = np.full(max(2 * self._x.size, len(self._index)), np.nan)
            grown[: self._x.size] = self._x
            self._x = grown
        return idx

    def sigma_m(self, el_deg):
        cfg = self.cfg
        return cfg.mp_zenith_m + cfg.mp_low_m * np.exp(-np.maximum(el_deg, 0.0) / 15.0)

    def state(self, idx, dt_s, w=None):
        """Unit-variance Gauss-Markov states of the slots ``idx`` advanced by ``dt_s`` (one draw each: ``w``, or
        drawn now)."""
        phi = np.exp(-dt_s / self.cfg.mp_tau_s) if dt_s > 0 else 0.0
        if w is None:
            w = self.rng.standard_normal(len(idx))
        prev = self._x[idx]
        x = np.where(np.isnan(prev), w, phi * prev + np.sqrt(1 - phi * phi) * w)
        self._x[idx] = x
        return x

    def values_m(self, sv_j, codes, el_deg, dt_s):
        """Code multipath [m] of signals (sv_j, codes) at elevations ``el_deg``, ``dt_s`` after the last step."""
        return self.sigma_m(el_deg) * self.state(self.slots(sv_j, codes), dt_s)
