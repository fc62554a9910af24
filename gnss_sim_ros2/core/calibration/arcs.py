"""Continuous arcs of a receiver's samples (epochs x signals columns): which arc each sample belongs to and where each
arc starts and ends.  The code-noise and C/N0 statistics (signal_stats.py) and the tracking thresholds
(track_events.py) both cut a file's samples into arcs this way."""
from __future__ import annotations

import numpy as np


def arc_ids(valid: np.ndarray, t_s: np.ndarray, max_gap_s: float, breaks: np.ndarray | None = None) -> np.ndarray:
    """(E, S) int: the continuous arc of each valid sample (-1 where not valid).  A new arc starts at a column's
    first valid sample, after a gap over ``max_gap_s`` and where ``breaks`` is True."""
    out = np.full(valid.shape, -1, dtype=np.int64)
    cols, rows = np.nonzero(valid.T)            # sorted by column, then epoch
    if not len(rows):
        return out
    new = np.ones(len(rows), dtype=bool)
    same = cols[1:] == cols[:-1]
    new[1:] = ~same | (t_s[rows[1:]] - t_s[rows[:-1]] > max_gap_s)
    if breaks is not None:
        new |= breaks[rows, cols]
    out[rows, cols] = np.cumsum(new) - 1
    return out


def arc_ends(arcs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(first, last) (epoch, column) of every arc id 0..N-1 ((N, 2) each)."""
    r, c = np.nonzero(arcs >= 0)
    a = arcs[r, c]
    n = int(a.max()) + 1 if a.size else 0
    first = np.zeros((n, 2), dtype=np.int64)
    last = np.zeros((n, 2), dtype=np.int64)
    if n:
        order = np.lexsort((r, a))
        a_s, r_s, c_s = a[order], r[order], c[order]
        start = np.flatnonzero(np.r_[True, a_s[1:] != a_s[:-1]])
        end = np.r_[start[1:] - 1, len(a_s) - 1]
        first[a_s[start]] = np.stack([r_s[start], c_s[start]], axis=1)
        last[a_s[end]] = np.stack([r_s[end], c_s[end]], axis=1)
    return first, last
