"""The RTK availability indicator of the planner: a proxy from geometry, not a simulated RTK solution.

Rule (per cell and time step): RTK is counted available when at least ``min_sats`` satellites tracked on two
frequencies are in line of sight (not blocked, not through foliage, not reflected-only) above the
ambiguity-resolution elevation mask ``ar_mask_deg`` and were so at the previous time step too (continuously
visible: a carrier-phase arc without a break over the step), and the PDOP of those satellites is below
``max_pdop``.

Sources: RTKLIB (demo5 b34) holds an integer fix only with at least ``pos2-minholdsats`` = 5 satellites and
fixes with at least ``pos2-minfixsats`` = 4 (its default configuration; a satellite enters ambiguity resolution
after ``pos2-arlockcnt`` epochs of continuous lock) and uses an AR elevation mask ``pos2-arelmask``
(15 deg in common configurations); PDOP < 6 is the usual survey-planning limit of DOP for precise work
(e.g. the planning tools of survey receivers). The 5-satellite + continuity + PDOP form is what the
issue asks for as a published rule of thumb; it is a proxy: it does not model cycle slips, the baseline,
the base station, the ratio test or multipath on carrier phase, and it is not yet validated against the
simulator's own rtk node (docs/PLANNING.md says so).  A single-frequency profile counts its single-frequency
satellites instead (single-frequency RTK exists but needs more time and geometry: read its share as optimistic).
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class RtkRule:
    min_sats: int = 5            # RTKLIB pos2-minholdsats
    ar_mask_deg: float = 15.0    # RTKLIB pos2-arelmask as commonly set
    max_pdop: float = 6.0

    def describe(self) -> str:
        return (f">= {self.min_sats} dual-frequency satellites in line of sight above {self.ar_mask_deg:g} deg at "
                f"this and the previous time step, PDOP < {self.max_pdop:g} (RTKLIB minholdsats/arelmask; a proxy)")
