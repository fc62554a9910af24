"""Signals of the two receivers matched by band and tracking attribute."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..receiver.profiles import load_profile
from ..rinex.obs_table import ObsTable


@dataclass(frozen=True)
class SignalPair:
    """One signal compared: ``sim_code``/``real_code`` are band + attribute ("1C", "1X")."""

    system: str
    sim_code: str
    real_code: str

    @property
    def band(self) -> str:
        return self.sim_code[0]

    @property
    def label(self) -> str:
        return f"{self.system} {self.sim_code}" + ("" if self.sim_code == self.real_code else f"/{self.real_code}")


def _attributes(tab: ObsTable, system: str) -> list[str]:
    """Band+attribute codes with any observation of ``system``, in the table's order."""
    cols = np.array([s[0] == system for s in tab.sv.tolist()], dtype=bool)
    out = []
    for code, a in tab.values.items():
        if np.isfinite(a[:, cols]).any() and code[1:] not in out:
            out.append(code[1:])
    if tab.kind == "bag":   # a bag has no header order: the simulator's geodetic profile order (first = primary)
        order = list(load_profile("geodetic").signals.get(system, ()))
        out.sort(key=lambda c: order.index(c) if c in order else len(order))
    return out


def pair_signals(sim: ObsTable, real: ObsTable, systems: str) -> list[SignalPair]:
    """Signals of each system matched by band: the same attribute first, else another of the band
    (each real signal used once; real signals with pseudoranges preferred)."""
    pairs = []
    for s in systems:
        a_sim, a_real = _attributes(sim, s), _attributes(real, s)
        svs = [v for v in real.sv.tolist() if v[0] == s]
        used = set()
        match = {}
        for c in a_sim:
            if c in a_real:
                match[c] = c
                used.add(c)
        for c in a_sim:
            if c in match:
                continue
            cands = [r for r in a_real if r[0] == c[0] and r not in used]
            if cands:
                cands.sort(key=lambda r: -int(np.isfinite(real.column("C" + r)[:, np.isin(real.sv, svs)]).sum()))
                match[c] = cands[0]
                used.add(cands[0])
        pairs += [SignalPair(s, c, match[c]) for c in a_sim if c in match]
    return pairs


def unpaired_signals(sim: ObsTable, real: ObsTable, systems: str, pairs: list[SignalPair]) -> dict:
    """Signals (system, band + attribute) of the compared ``systems`` that only one side has, i.e. left out of
    ``pairs``: {"sim": [...], "real": [...]}."""
    out = {"sim": [], "real": []}
    for s in systems:
        used_s = {p.sim_code for p in pairs if p.system == s}
        used_r = {p.real_code for p in pairs if p.system == s}
        out["sim"] += [(s, c) for c in _attributes(sim, s) if c not in used_s]
        out["real"] += [(s, c) for c in _attributes(real, s) if c not in used_r]
    return out
