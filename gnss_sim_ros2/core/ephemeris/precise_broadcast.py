"""SP3 orbits and clocks as the truth, with the broadcast message's group delays, clock reference and
health: what a receiver that uses the broadcast navigation sees when the satellites follow the precise
orbits (the ``sp3`` ephemeris source with navigation files; the accurate preset)."""
from __future__ import annotations

import numpy as np

from .broadcast import precise_to_broadcast_clock_s


class PreciseWithBroadcastGroupDelay:
    """SP3 orbits and clocks with the broadcast group delays (TGD/BGD) and navigation header.

    SP3 clocks refer to the ionosphere-free combination (no group delay), while a
    receiver's single-frequency code carries the broadcast TGD/BGD (IS-GPS-200N
    20.3.3.3.3.2; Galileo OS SIS ICD 5.1.5): without it each satellite's code
    would be off by its c * TGD (up to ~3 m).  The group delay of each satellite
    is taken once from the broadcast record valid at ``t_ref`` (it changes on
    the scale of months).  ``nav``/``iono`` come from the navigation files, so
    the written navigation file and the Klobuchar coefficients are the real ones.

    Precise clocks refer to ionosphere-free combinations, broadcast ones to the
    record's signal (BeiDou B3I, Galileo I/NAV E1/E5b): each satellite's precise
    clock is moved to its broadcast record's reference
    (ephemeris.broadcast.precise_to_broadcast_clock_s, + 2.944 TGD1 for
    BeiDou), so that the receiver's group delay convention (TGD1 on B1I,
    nothing on B3I; BGD on E1) holds for both sources.  Without it BeiDou codes
    were off by up to 22 m and RTKLIB solved 61 of 440 OPEC epochs.
    """

    def __init__(self, precise, broadcast, t_ref, span_s: float = 0.0):
        self.precise, self.broadcast = precise, broadcast
        self.source = "sp3"
        self.nav = getattr(broadcast, "nav", None)
        #: per satellite (group delay [s], precise-to-broadcast clock shift [s]) of its first broadcast record;
        #: its keys are the satellites served: SP3 files carry no health flags, so only those the broadcast
        #: message declares healthy at some time of the span (sampled hourly; station navigation files have
        #: gaps of hours)
        self._broadcast_terms: dict[str, tuple[float, float]] = {}
        for k in range(int(np.ceil(max(span_s, 0.0) / 3600.0)) + 1):
            st = broadcast.states(t_ref + min(3600.0 * k, max(span_s, 0.0)))
            shift = precise_to_broadcast_clock_s(broadcast, st)
            for sv, tgd, dt_s in zip(np.asarray(st.sv).tolist(), np.asarray(st.tgd_s, dtype=float).tolist(),
                                     shift.tolist()):
                self._broadcast_terms.setdefault(sv, (tgd, dt_s))

    @property
    def iono(self):
        return getattr(self.broadcast, "iono", None)

    def svs(self, systems: str = "GRECJI"):
        return [sv for sv in self.precise.svs(systems) if sv in self._broadcast_terms]

    def _with_tgd(self, st):
        names = np.asarray(st.sv).tolist()
        keep = np.array([sv in self._broadcast_terms for sv in names], dtype=bool)
        if not keep.all():
            st = st.select(keep)
            names = np.asarray(st.sv).tolist()
        terms = np.array([self._broadcast_terms[sv] for sv in names], dtype=float).reshape(-1, 2)
        st.tgd_s = terms[:, 0]
        st.clock_bias_s = st.clock_bias_s + terms[:, 1]
        return st

    def states(self, t, svs=None, systems: str = "GRECJI"):
        return self._with_tgd(self.precise.states(t, svs=svs, systems=systems))

    def states_at(self, svs, t):
        return self._with_tgd(self.precise.states_at(svs, t))
