"""Satellite states: the contract between ephemeris providers, visibility and receiver.

See docs/DEVELOPING.md ("Satellite states").  Rows are satellites (or
satellite-instants); every array has the same first dimension N.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..time import GnssTime

#: the per-row array fields of SatelliteStates (everything except t and source)
ROW_FIELDS = (
    "sv",
    "pos_ecef_m",
    "vel_ecef_mps",
    "acc_ecef_mps2",
    "clock_bias_s",
    "clock_drift_sps",
    "relativistic_s",
    "tgd_s",
    "health",
    "iode",
    "age_s",
    "glo_channel",
)


@dataclass
class SatelliteStates:
    t: GnssTime              # instants (scalar, or one per row), GPS time
    sv: np.ndarray           # (N,) str, "G05"
    pos_ecef_m: np.ndarray   # (N, 3) ECEF of the ephemeris source (no light time)
    vel_ecef_mps: np.ndarray  # (N, 3)
    acc_ecef_mps2: np.ndarray  # (N, 3)
    clock_bias_s: np.ndarray  # (N,) SP3 convention: clock polynomial only
    clock_drift_sps: np.ndarray  # (N,) s/s
    relativistic_s: np.ndarray   # (N,) periodic relativistic term (IS-GPS-200 20.3.3.3.3.1); 0 for SP3
    tgd_s: np.ndarray        # (N,) broadcast group delay (GPS TGD, Galileo BGD, BeiDou TGD1); 0 if none
    health: np.ndarray       # (N,) int, 0 = healthy
    iode: np.ndarray         # (N,) int issue of data (-1 if none)
    age_s: np.ndarray        # (N,) t - reference time of the record used
    glo_channel: np.ndarray  # (N,) int GLONASS frequency channel k (0 for others)
    source: str              # "broadcast" | "sp3" | "synthetic"

    def __len__(self) -> int:
        return int(np.shape(self.sv)[0])

    @property
    def t_per_row(self) -> GnssTime:
        """The instants as one GnssTime per row (broadcasts a scalar ``t``)."""
        n = len(self)
        if np.ndim(self.t.sec) == 0:
            return GnssTime(np.full(n, self.t.sec, dtype=np.int64), np.full(n, self.t.frac))
        return GnssTime(np.asarray(self.t.sec, dtype=np.int64), np.asarray(self.t.frac))

    def select(self, idx) -> SatelliteStates:
        """Rows chosen by a boolean mask or an index array (the instants follow)."""
        idx = np.asarray(idx)
        t = self.t if np.ndim(self.t.sec) == 0 else GnssTime(np.asarray(self.t.sec)[idx], np.asarray(self.t.frac)[idx])
        if idx.ndim == 1 and idx.dtype.kind in "iu":      # take: the rows of fancy indexing, faster on (N, 3)
            kw = {name: np.asarray(getattr(self, name)).take(idx, axis=0) for name in ROW_FIELDS}
        else:
            kw = {name: np.asarray(getattr(self, name))[idx] for name in ROW_FIELDS}
        return SatelliteStates(t=t, source=self.source, **kw)

    def by_sv(self, sv: str) -> SatelliteStates:
        """Rows of one satellite."""
        return self.select(np.asarray(self.sv) == sv)

    def index_of(self, sv: str) -> int:
        """Row of ``sv`` (first match); ValueError when absent."""
        hits = np.flatnonzero(np.asarray(self.sv) == sv)
        if hits.size == 0:
            raise ValueError(f"satellite {sv!r} has no row in these states")
        return int(hits[0])

    @staticmethod
    def empty(t: GnssTime, source: str) -> SatelliteStates:
        """No rows."""
        return SatelliteStates(
            t=t,
            sv=np.zeros(0, dtype="<U3"),
            pos_ecef_m=np.zeros((0, 3)),
            vel_ecef_mps=np.zeros((0, 3)),
            acc_ecef_mps2=np.zeros((0, 3)),
            clock_bias_s=np.zeros(0),
            clock_drift_sps=np.zeros(0),
            relativistic_s=np.zeros(0),
            tgd_s=np.zeros(0),
            health=np.zeros(0, dtype=np.int64),
            iode=np.zeros(0, dtype=np.int64),
            age_s=np.zeros(0),
            glo_channel=np.zeros(0, dtype=np.int64),
            source=source,
        )

    @staticmethod
    def concatenate(parts: list[SatelliteStates]) -> SatelliteStates:
        """Rows of several states one after another (instants become per row)."""
        parts = [p for p in parts if p is not None]
        if not parts:
            raise ValueError("concatenate needs at least one SatelliteStates")
        sources = {p.source for p in parts}
        source = parts[0].source if len(sources) == 1 else "+".join(sorted(sources))
        t = GnssTime.stack([p.t_per_row for p in parts]) if any(len(p) for p in parts) else parts[0].t
        kw = {name: np.concatenate([np.asarray(getattr(p, name)) for p in parts]) for name in ROW_FIELDS}
        return SatelliteStates(t=t, source=source, **kw)

    def as_dict(self) -> dict:
        """Plain dict of the fields (for debugging and serialisation)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}
