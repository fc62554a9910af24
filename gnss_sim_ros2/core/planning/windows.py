"""The best time windows of a plan: the longest runs of time steps where a share of the area meets a threshold.

A window of consecutive steps i..j (share[k] >= threshold for every k in it) spans from step i's time to step
j's time plus one step (each step stands for the interval up to the next), the plan's last step standing for
itself alone (the window ends there).  Windows are listed longest first,
ties by start.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Window:
    start_s: float            # from the plan's first step
    end_s: float
    min_share: float          # the lowest area share inside the window
    mean_share: float


def best_windows(share, step_s: float, threshold: float, t0_s: float = 0.0, limit: int = 3) -> list[Window]:
    """Longest windows of ``share`` (T,) (fractions in [0, 1], NaN counts as below) >= ``threshold``."""
    s = np.asarray(share, float)
    ok = np.nan_to_num(s, nan=-1.0) >= threshold
    if not ok.any():
        return []
    edges = np.diff(np.concatenate([[0], ok.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)     # [start, end)
    runs = sorted(zip(starts.tolist(), ends.tolist()), key=lambda r: (-(r[1] - r[0]), r[0]))[:limit]
    last = len(s) - 1
    return [Window(t0_s + a * step_s, t0_s + min(b, last) * step_s, float(s[a:b].min()), float(s[a:b].mean()))
            for a, b in runs]
