"""The simulated world's smooth error processes: the ionosphere model's own error g(t), the true zenith wet
delay's departure from the standard atmosphere's w(t), and each satellite's broadcast orbit and clock error
S_s(t) (engine module doc).

They belong to the world, not to one receiver: smooth functions of GPS time (sums of sinusoids, periods of
hours, random phases from ``world_seed``), so every receiver of one world (a base and a rover) sees the same
values at any epoch rate.

The time scales are the real atmosphere's.  Ionosphere: the model's error is mostly the diurnal shape of TEC
that Klobuchar's half cosine and NeQuick's monthly median miss (day-to-day variability), so periods of hours.
Measured with the geometry-free phase L1-L2 (the 30 s change of the slant L1 delay, RMS per elevation bin,
GPS L1C-L2W): ESBC 2020-177 0-8 h (PolaRx5) 14.6 / 9.6 / 6.1 / 3.4 mm at 10-20 / 20-30 / 30-45 / 45-90 deg;
the simulator with periods of 20 min to 4 h gave 44.9 / 38.2 / 32.3 / 21.0 mm (3-6x), its deterministic part
alone (the slant geometry of NeQuick-G, noise off) 8.9 / 7.3 / 5.2 / 2.7 mm; the band below brings the change
to the real one's (13.5 / 10.7 / 7.1 / 4.4 mm; on OPEC 2022-001, not used to choose it: real 15.5 / 8.5 /
6.6 / 4.0 mm, simulated 27.3 / 21.0 / 15.2 / 12.1 before, 14.2 / 7.1 / 4.9 / 3.1 mm after; test_world_errors).
Troposphere: water vapour changes with the weather, over half a day
to days as weather systems pass; a random walk of about 1 cm/sqrt(h) in the zenith wet delay is what PPP filters
assume (from memory, check against e.g. Kouba & Heroux 2001, GPS Solutions 5(2)).
"""
from __future__ import annotations

import numpy as np

from ..time import GnssTime

#: period bands [s] of the world's smooth error processes (module doc): ionosphere residual 2 h to 24 h
#: (large-scale disturbances to the diurnal shape errors of the model), zenith wet delay residual 12 h to
#: 4 days (weather systems: 1.3 cm in an hour, 0.1 mm in 30 s for 5 cm RMS), satellite orbit/clock error
#: 2 h to 12 h (clock wander to the once-per-revolution orbit error of MEO satellites)
WORLD_PERIODS_S = {"iono": (7200.0, 86400.0), "tropo": (43200.0, 345600.0), "sat": (7200.0, 43200.0)}
WORLD_TERMS = 6
#: RMS [m] of the true zenith wet delay about the receiver's standard-atmosphere model (Saastamoinen, 15 C,
#: 1013.25 hPa, 70 % humidity, as RTKLIB's tropmodel): the zenith delay residuals of blind models against
#: ray tracing / IGS zenith delays are about 5 cm RMS (UNB3m, Leandro, Santos & Langley, ION NTM 2006; from
#: memory, check against the document), nearly all of it water vapour
ZWD_RESIDUAL_SIGMA_M = 0.05


class WorldErrorTerms:
    """The terms (periods, phases) of the world's processes, drawn once per key from ``world_seed``."""

    def __init__(self, world_seed: int):
        self.world_seed = world_seed
        self._terms: dict = {}

    def stacked(self, keys):
        """(periods (K, 6) int, phases (K, 6)) of the processes of ``keys`` (("iono",), ("tropo",), ("sat", "G05"))."""
        per, pha = [], []
        for key in keys:
            terms = self._terms.get(key)
            if terms is None:
                lo, hi = WORLD_PERIODS_S[key[0] if key[0] in WORLD_PERIODS_S else "sat"]
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
