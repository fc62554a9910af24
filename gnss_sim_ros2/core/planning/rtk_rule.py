"""The RTK availability indicator of the planner: a proxy from geometry and predicted signal strength, not a simulated
RTK solution.

Rule (per cell or path pose, step after step):

- candidates: satellites tracked on two frequencies above the ambiguity-resolution elevation mask ``ar_mask_deg``
  that the receiver tracks: in line of sight, or through foliage / a soft edge (attenuated) with a C/N0 predicted
  from the profile's link budget (predicted_cn0.py) at or above the profile's loss-of-lock threshold
  (``tracking_cn0_dbhz``) when ``count_attenuated`` (RTKLIB uses every satellite the receiver delivers: the rtk
  node leaves ``pos1-snrmask`` off); never a reflected-only satellite;
- an arc is unbroken when the satellite was a candidate at the previous step too, or within ``max_outage_s`` before
  (RTKLIB ``pos2-maxout`` = 5 epochs, its default and the rtk node's, at 1 Hz: a satellite's ambiguity state
  survives an outage that short and is reset after it);
- a fix is gained with at least ``min_sats`` unbroken candidates whose geometry gives a position (finite PDOP, below
  ``max_pdop`` when one is set), and held while at least ``min_hold_sats`` continue (a hysteresis: RTKLIB demo5 b34
  resolves and validates ambiguities with as few as ``pos2-minfixsats`` = 4 satellites, 3 double differences, its
  default; the rule asks ``pos2-minholdsats`` = 5 to gain a fix, one satellite of redundancy, and 4 to keep it
  while the filter's ambiguities are converged).

Sources: RTKLIB 2.4.3 b34 / demo5 b34 option defaults (rtkrcv.conf, the rtk node's config.py): ``pos1-elmask``
15 deg by default with ``pos2-arelmask`` 0 (ambiguity resolution over every satellite above the elevation mask),
and no DOP gate on a fix, so ``max_pdop`` is off by default (inf; PDOP < 6, a survey-planning limit of DOP for
precise work, made the rule far more cautious than the rtk node: docs/PLANNING.md).  It remains a proxy:
no cycle slips, baseline, base station, ratio test or carrier multipath; validated against the simulator's own rtk
node in docs/PLANNING.md.  A single-frequency profile counts its single-frequency satellites instead
(single-frequency RTK exists but needs more time and geometry: read its share as optimistic).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RtkRule:
    min_sats: int = 5            # to gain a fix (RTKLIB demo5 pos2-minholdsats: one more than to keep it)
    min_hold_sats: int = 4       # to keep it (RTKLIB demo5 pos2-minfixsats; 4 satellites for a position)
    ar_mask_deg: float = 15.0    # RTKLIB pos1-elmask default (pos2-arelmask 0: AR above the elevation mask)
    max_pdop: float = float("inf")   # RTKLIB has no DOP gate on a fix; a survey DOP limit if set
    max_outage_s: float = 5.0    # RTKLIB pos2-maxout: 5 epochs at 1 Hz
    count_attenuated: bool = True

    def describe(self) -> str:
        att = "line of sight or tracked through foliage" if self.count_attenuated else "line of sight"
        dop = f", PDOP < {self.max_pdop:g}" if self.max_pdop < float("inf") else ""
        return (f">= {self.min_sats} dual-frequency satellites ({att}) above {self.ar_mask_deg:g} deg with "
                f"unbroken arcs (outages <= {self.max_outage_s:g} s){dop}; held while >= "
                f"{self.min_hold_sats} continue (RTKLIB minholdsats/minfixsats/maxout/arelmask; a proxy)")


class RtkArcs:
    """Per row (cell or path) from step to step: when each satellite was last a candidate, whether the row is fixed."""

    def __init__(self, rule: RtkRule, n_rows: int, n_sats: int):
        self.rule = rule
        self.last_s = np.full((n_rows, n_sats), -np.inf)
        self.fixed = np.zeros(n_rows, bool)
        self.t_prev = None

    def unbroken(self, cand, t_s: float, max_outage_s: float | None = None, cols=None) -> np.ndarray:
        """(rows, S) candidates ``cand`` at time ``t_s`` whose arc is unbroken (module doc; the first step: all).
        ``cols``: the satellites (S') ``cand`` (rows, S') holds, the others not candidates at this step."""
        gap = self.rule.max_outage_s if max_outage_s is None else max_outage_s
        cand = np.asarray(cand, bool)
        last = self.last_s if cols is None else self.last_s[:, cols]
        if self.t_prev is None:
            cont = cand.copy()
        else:
            cont = cand & ((last >= self.t_prev) | (t_s - last <= gap))
        if cols is None:
            self.last_s = np.where(cand, t_s, last)
        else:
            self.last_s[:, cols] = np.where(cand, t_s, last)
        self.t_prev = t_s
        return cont

    def fix(self, n_rtk, pdop) -> np.ndarray:
        """(rows,) fixed at this step from the unbroken candidates' count and PDOP (gain / hold, module doc)."""
        ok = np.asarray(pdop) < self.rule.max_pdop
        n = np.asarray(n_rtk)
        self.fixed = ok & ((n >= self.rule.min_sats) | (self.fixed & (n >= self.rule.min_hold_sats)))
        return self.fixed.copy()
