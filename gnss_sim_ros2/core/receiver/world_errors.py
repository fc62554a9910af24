"""The simulated world's smooth error processes: the ionosphere model's own error g(t) and each satellite's
broadcast orbit and clock error S_s(t) (engine module doc).

They belong to the world, not to one receiver: smooth functions of GPS time (sums of sinusoids, periods 20 min
to 12 h, random phases from ``world_seed``), so every receiver of one world (a base and a rover) sees the same
values at any epoch rate.
"""
from __future__ import annotations

import numpy as np

from ..time import GnssTime

#: period bands [s] of the world's smooth error processes: ionosphere residual 20 min to 4 h
#: (travelling disturbances to diurnal shape errors), satellite orbit/clock error 2 h to 12 h
#: (clock wander to the once-per-revolution orbit error of MEO satellites)
WORLD_PERIODS_S = {"iono": (1200.0, 14400.0), "sat": (7200.0, 43200.0)}
WORLD_TERMS = 6


class WorldErrorTerms:
    """The terms (periods, phases) of the world's processes, drawn once per key from ``world_seed``."""

    def __init__(self, world_seed: int):
        self.world_seed = world_seed
        self._terms: dict = {}

    def stacked(self, keys):
        """(periods (K, 6) int, phases (K, 6)) of the processes of ``keys`` (("iono",), ("sat", "G05"))."""
        per, pha = [], []
        for key in keys:
            terms = self._terms.get(key)
            if terms is None:
                lo, hi = WORLD_PERIODS_S["iono" if key[0] == "iono" else "sat"]
                words = [int(self.world_seed)] + [int.from_bytes(str(x).encode(), "big") for x in key]
                g = np.random.default_rng(words)
                terms = (np.round(np.exp(g.uniform(np.log(lo), np.log(hi), WORLD_TERMS))).astype(np.int64),
                         g.uniform(0.0, 2.0 * np.pi, WORLD_TERMS))
                self._terms[key] = terms
            per.append(terms[0])
            pha.append(terms[1])
        return np.array(per), np.array(pha)


def world_process(t: GnssTime, terms) -> np.ndarray:
    """Smooth zero-mean unit-variance processes of GPS time, one per row of ``terms``
    (WorldErrorTerms.stacked); ``t`` scalar (every row at t) or (K,) (row k at t[k]; ``terms`` of one row
    serve every t).

    x(t) = sqrt(2/K) sum_k sin(2 pi t / P_k + phi_k), K = 6 terms, integer periods
    P_k log-uniform in the key's band, phases uniform: the same values at any
    epoch rate and for every receiver with the same ``world_seed``.
    """
    sec = np.asarray(t.sec, dtype=np.int64)[..., None]      # t scalar: (1,); t (K,): (K, 1), one per row
    frac = np.asarray(t.frac, dtype=np.float64)[..., None]
    per, pha = terms
    arg = 2.0 * np.pi * ((sec % per) + frac) / per + pha
    return np.sqrt(2.0 / WORLD_TERMS) * np.sin(arg).sum(axis=-1)
