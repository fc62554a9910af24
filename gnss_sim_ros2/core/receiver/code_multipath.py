"""The receiver's code multipath/residual m_j (engine module doc): per (satellite, signal) a unit-variance
first-order Gauss-Markov state (correlation time ``mp_tau_s``) times sigma(el), drawn from the receiver's own
random stream.  sigma(el), per signal:

- the profile's ``code_multipath_m`` table of that signal ("G1C": {el_deg, sigma_m}, linear interpolation,
  receiver/signal_tables.py), e.g. fitted by ``gnss-sim calibrate`` from a real recording; else
- mp_zenith_m + mp_low_m exp(-el / 15 deg) (a stated approximation of the open-sky multipath envelope), with
  the profile's values or, where it gives none, its antenna class's (OPEN_SKY_MP_M).

Open-sky code multipath per antenna class, without the DLL thermal noise (receiver/noise.py adds that):
published multipath-combination RMS (teqc MP1/MP2) of IGS choke-ring stations with modern narrow-correlator
receivers is 0.2-0.4 m over all elevations above 10 deg and under 0.1-0.2 m above 40 deg (Estey & Meertens,
"TEQC: the multi-purpose toolkit for GPS/GLONASS data", GPS Solutions 3(1), 1999; IGS station quality
summaries; from memory, check); a choke ring suppresses ground reflections 10-20 dB better than a flat patch
(antenna.py), so the patch's residual is about three times larger (0.15 m + 1.2 m exp(-el/15): 0.65 m RMS
of a satellite's code residual about its mean on OPEC 2022-001 against 0.47-0.69 m for the real NETR9,
test_receiver_acceptance); the helix lies between.
"""
from __future__ import annotations

import numpy as np

from . import signal_tables

#: antenna class -> (sigma at zenith [m], low-elevation amplitude [m]) of the open-sky code multipath (module doc)
OPEN_SKY_MP_M = {"choke_ring": (0.05, 0.45), "helical": (0.10, 0.8), "patch": (0.15, 1.2)}


def check_table(table):
    """A profile's ``code_multipath_m`` checked (ValueError naming the key); returned as given."""
    signal_tables.validate(table, "code_multipath_m", "sigma_m", nonnegative=True)
    return table


def _advanced(prev, phi, w):
    """Unit-variance Gauss-Markov states ``prev`` (NaN: not seen yet) advanced with correlation ``phi`` (scalar or
    per state) and unit draws ``w``."""
    return np.where(np.isnan(prev), w, phi * prev + np.sqrt(1 - phi * phi) * w)


def advance_states(models, slots, dt_s, w):
    """``models[i].state(slots[i], dt_s[i], w_i)`` for every i at once (several receivers' one epoch each,
    core/receiver/batch_observe.py): ``w`` the draws of every part one after another; each model's own states
    read and written.  The bits of the separate calls (the same operations per element)."""
    n = [len(i) for i in slots]
    prev = np.concatenate([mdl._x[i] for mdl, i in zip(models, slots)])
    phi = np.repeat(np.array([mdl._phi(dt) for mdl, dt in zip(models, dt_s)], dtype=float), n)
    x = _advanced(prev, phi, w)
    j = 0
    for mdl, i, k in zip(models, slots, n):
        mdl._x[i] = x[j:j + k]
        j += k
    return x


class CodeMultipath:
    """The Gauss-Markov states, one slot per (sv, code) kept for the receiver's lifetime (NaN until first seen)."""

    def __init__(self, config, rng: np.random.Generator):
        self.cfg = config            # ReceiverConfig: mp_zenith_m, mp_low_m, mp_tau_s, code_multipath_m, antenna
        self.zenith_m, self.low_m = config.mp_zenith_m, config.mp_low_m     # resolved by ReceiverConfig
        self.table = signal_tables.validate(config.code_multipath_m, "code_multipath_m", "sigma_m", nonnegative=True)
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

    def sigma_m(self, el_deg, signal_keys=None):
        """sigma [m] at ``el_deg``; ``signal_keys`` ("G1C" per row): the profile's table where it has the signal."""
        s = self.zenith_m + self.low_m * np.exp(-np.maximum(el_deg, 0.0) / 15.0)
        if self.table and signal_keys is not None:
            tab = signal_tables.lookup(self.table, signal_keys, el_deg)
            s = np.where(np.isnan(tab), s, tab)
        return s

    def fading_scale(self, el_deg):
        """The open-sky multipath envelope at ``el_deg`` relative to the zenith's (>= 1): the reflected-to-direct
        amplitude ratio that moves the code also fades C/N0 (20 log10(1 + a cos phi) dB), so the receiver's C/N0
        scatter grows towards the horizon by this factor (ESBC 2020-177, PolaRx5 with a choke ring, 30 s
        epoch-to-epoch: 0.12-0.2 dB above 40 deg, 0.6-0.7 dB at 10-20 deg, 0.9-1.7 dB below 10 deg; the choke
        ring's factor: 4.2 at 15 deg, 7.3 at 5 deg)."""
        zen = self.zenith_m + self.low_m * np.exp(-6.0)
        if zen <= 0:
            return np.ones(np.shape(el_deg))
        return (self.zenith_m + self.low_m * np.exp(-np.maximum(el_deg, 0.0) / 15.0)) / zen

    def state(self, idx, dt_s, w=None):
        """Unit-variance Gauss-Markov states of the slots ``idx`` advanced by ``dt_s`` (one draw each: ``w``, or
        drawn now)."""
        if w is None:
            w = self.rng.standard_normal(len(idx))
        x = _advanced(self._x[idx], self._phi(dt_s), w)
        self._x[idx] = x
        return x

    def _phi(self, dt_s):
        """The states' correlation over ``dt_s`` (0 when no time passed: a fresh draw)."""
        return np.exp(-dt_s / self.cfg.mp_tau_s) if dt_s > 0 else 0.0

    def values_m(self, sv_j, codes, el_deg, dt_s):
        """Code multipath [m] of signals (sv_j, codes) at elevations ``el_deg``, ``dt_s`` after the last step."""
        keys = signal_tables.signal_keys(sv_j, codes)        # "G05" -> system letter "G"
        return self.sigma_m(el_deg, keys) * self.state(self.slots(sv_j, codes), dt_s)
