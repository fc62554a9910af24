"""Observations of one receiver as a table in RINEX terms: epochs (GPS time) x satellites, one array per
RINEX 3 observation code ("C1C", "L1C", "D1C", "S1C"), NaN where absent.  Filled by the RINEX reader
(core/rinex/obs_read.py) and the bag reader (core/bag_obs.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..time import GnssTime

#: the GPS epoch as a numpy datetime64 (RINEX GPS time labels, no leap seconds)
GPS_EPOCH_NP = np.datetime64("1980-01-06T00:00:00", "ns")
#: epochs closer than this are the same epoch [ns]
EPOCH_MATCH_NS = 1_000_000
#: order in which a system becomes the reference of the receiver clock
REFERENCE_ORDER = "GECRJI"


@dataclass
class ObsTable:
    """Observations of one receiver: ``values[code][epoch, sat]`` (NaN = absent)."""

    time: np.ndarray                       #: (E,) datetime64[ns], GPS time labels
    sv: np.ndarray                         #: (S,) str satellite ids ("G05")
    values: dict[str, np.ndarray]          #: obs code "C1C" -> (E, S) float
    source: str = ""                       #: file or bag it came from
    kind: str = "rinex"                    #: "rinex" | "bag"
    approx_pos_ecef_m: np.ndarray | None = None   #: RINEX APPROX POSITION XYZ
    glo_channel: dict[str, int] = field(default_factory=dict)   #: GLONASS slot -> frequency channel
    freq_hz: dict[tuple[str, str], float] = field(default_factory=dict)  #: (sv, "1C") -> carrier (bags)
    #: carrier-phase code "L1C" -> (E, S) int8 loss-of-lock indicator (RINEX 3.05 5.7: bit 0 lost lock, bit 1
    #: half-cycle ambiguity; 0 where blank); RINEX 3/4 files only (empty: the source gives none)
    lli: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def systems(self) -> str:
        """Systems with at least one observation, in REFERENCE_ORDER."""
        have = {s[0] for j, s in enumerate(self.sv.tolist())
                if any(np.isfinite(a[:, j]).any() for a in self.values.values())}
        return "".join(s for s in REFERENCE_ORDER + "S" if s in have)

    def column(self, code: str) -> np.ndarray:
        """(E, S) array of ``code`` (all NaN when the table has no such code)."""
        a = self.values.get(code)
        return a if a is not None else np.full((len(self.time), len(self.sv)), np.nan)

    def has_data(self, code: str, svs=None) -> bool:
        a = self.values.get(code)
        if a is None:
            return False
        if svs is not None:
            a = a[:, np.isin(self.sv, list(svs))]
        return bool(np.isfinite(a).any())

    def frequency_hz(self, sv: str, code: str) -> float:
        """Carrier of ``code`` ("1C") of ``sv``: from the bag, else the signal table (GLONASS: header channel)."""
        f = self.freq_hz.get((sv, code))
        if f is not None and np.isfinite(f) and f > 0:
            return float(f)
        from ..signals import frequency_hz

        if sv[0] == "R":
            ch = self.glo_channel.get(sv)
            if ch is None:
                return math.nan
            return float(frequency_hz("R", code, ch))
        try:
            return float(frequency_hz(sv[0], code))
        except ValueError:
            return math.nan

    def gnss_time(self, i: int) -> GnssTime:
        ns = int((self.time[i] - GPS_EPOCH_NP) / np.timedelta64(1, "ns"))
        return GnssTime(ns // 1_000_000_000, (ns % 1_000_000_000) * 1e-9)

    def subset(self, epochs=None, svs=None) -> ObsTable:
        """A copy restricted to epoch indices and/or satellite ids."""
        e = np.arange(len(self.time)) if epochs is None else np.asarray(epochs)
        cols = np.arange(len(self.sv)) if svs is None else np.array(
            [int(np.flatnonzero(self.sv == s)[0]) for s in svs], dtype=int)
        return ObsTable(self.time[e], self.sv[cols], {c: a[np.ix_(e, cols)] for c, a in self.values.items()},
                        self.source, self.kind, self.approx_pos_ecef_m, dict(self.glo_channel), dict(self.freq_hz),
                        {c: a[np.ix_(e, cols)] for c, a in self.lli.items()})


def match_epochs(t_sim: np.ndarray, t_real: np.ndarray, tol_ns: int = EPOCH_MATCH_NS):
    """Indices (i_sim, i_real) of epochs whose times agree within ``tol_ns``."""
    a = t_sim.astype("datetime64[ns]").astype(np.int64)
    b = t_real.astype("datetime64[ns]").astype(np.int64)
    j = np.searchsorted(b, a)
    i_sim, i_real = [], []
    for i, (x, jj) in enumerate(zip(a, j)):
        best = None
        for c in (jj - 1, jj):
            if 0 <= c < len(b) and abs(int(b[c]) - int(x)) <= tol_ns and (best is None or
                                                                           abs(b[c] - x) < abs(b[best] - x)):
                best = c
        if best is not None:
            i_sim.append(i)
            i_real.append(int(best))
    return np.array(i_sim, dtype=int), np.array(i_real, dtype=int)
