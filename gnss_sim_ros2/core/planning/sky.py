"""The satellites of every time step of a plan: one ``provider.states`` call per step (rows only for satellites
with a valid, healthy record), gathered on the union of their ids; NaN where a satellite has no record."""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ..time import GnssTime


@dataclass
class PlanSky:
    sv: np.ndarray            # (S,) str, "G05"
    pos_ecef_m: np.ndarray    # (T, S, 3), NaN where absent
    times: GnssTime           # (T,)
    t_s: np.ndarray           # (T,) seconds from the first step

    @property
    def system(self) -> np.ndarray:
        return np.array([s[0] for s in self.sv.tolist()])


def time_steps(start: GnssTime, hours: float, every_min: float) -> GnssTime:
    """Steps from ``start`` over ``hours`` every ``every_min`` minutes (both > 0: ValueError naming the option)."""
    if not (np.isfinite(hours) and hours > 0):
        raise ValueError(f"option --hours is {hours}: a time window > 0 h is needed")
    if not (np.isfinite(every_min) and every_min > 0):
        raise ValueError(f"option --every-min is {every_min}: a time step > 0 min is needed")
    n = int(np.floor(hours * 60.0 / every_min + 1e-9)) + 1
    return GnssTime.stack([start + k * every_min * 60.0 for k in range(n)])


def plan_sky(provider, times: GnssTime, systems: str, excluded_svs: str = "") -> PlanSky:
    """The satellites of ``systems`` at each of ``times`` (profile's ``excluded_svs`` regular expression left out)."""
    per = []
    for k in range(len(np.atleast_1d(times.sec))):
        st = provider.states(times[k], systems=systems)
        per.append((np.asarray(st.sv), np.asarray(st.pos_ecef_m, float)))
    excl = re.compile(excluded_svs) if excluded_svs else None
    svs = sorted({s for sv, _ in per for s in sv.tolist() if excl is None or not excl.fullmatch(s)})
    if not svs:
        raise ValueError(f"no satellite of systems {systems!r} has a valid navigation record in the time window")
    col = {s: j for j, s in enumerate(svs)}
    pos = np.full((len(per), len(svs), 3), np.nan)
    for k, (sv, p) in enumerate(per):
        for i, s in enumerate(sv.tolist()):
            j = col.get(s)
            if j is not None:
                pos[k, j] = p[i]
    t_s = np.array([times[k] - times[0] for k in range(len(per))])
    return PlanSky(np.array(svs), pos, times, t_s)
