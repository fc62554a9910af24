"""Where a receiver starts and ends its tracks: the C/N0 at each track start and end of a signal, and whether it
lies at a rise / set (the horizon's geometry) or away from it (the receiver's own acquisition / loss of lock).

In an open sky a satellite's first and last epochs are set by the horizon or the elevation mask, not by the
receiver: the C/N0 there is the C/N0 of the horizon (ESBC PolaRx5: GPS L1 arcs end at 0.8 deg elevation at a
median 22.5 dB-Hz).  What the receiver decides is seen where a track starts after a gap while the satellite is up
(a reacquisition) and where it ends while the satellite stays up (a loss of lock).

A satellite's *pass* is a run of epochs with an observation on any of its signals, split at gaps over
``PASS_GAP_S``.  A pass that begins after the span's first epoch rises there; one that ends before the span's
last epoch sets there.  A track start counts as *at the rise* when it lies within ``HORIZON_MARGIN_DEG`` of the
elevation at its pass's rise (and a track end at the set likewise); a pass already up at the span's start (a
geostationary satellite) has no rise, so all its track starts are the receiver's.  A track start or end at the
span's first / last epoch is no event.

The thresholds (threshold_from_events): the ``TAIL_PERCENT`` percentile of the C/N0 at the events away from rise
/ set (the receiver's low tail: below it, it does not start / keep a track); ``lowest_held_dbhz`` (the
``HELD_PERCENT`` percentile over the tracks of each track's lowest C/N0) is the fallback where a span has too few
such events: in an open sky the low tail of where its tracks bottom out, at rise and set included.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .arcs import arc_ends, arc_ids

#: an absence longer than this ends a satellite's pass (a set; the next observation is a rise) [s]
PASS_GAP_S = 1800.0
#: a track start / end within this of its pass's rise / set elevation is the horizon's, not the receiver's [deg]
HORIZON_MARGIN_DEG = 3.0
#: the thresholds are this percentile of the C/N0 at track starts / ends away from rise and set [%]
TAIL_PERCENT = 5.0
#: without enough such events: the lowest C/N0 the receiver holds, this percentile over its tracks of each
#: track's lowest C/N0 [%] (of all samples instead, the sky's high satellites would set it: ESBC 26-27.5 dB-Hz)
HELD_PERCENT = 5.0


@dataclass
class TrackEvents:
    """C/N0 [dB-Hz] at a signal's track starts and ends (finite C/N0 only), and whether each is at a rise / set."""

    start_cn0_dbhz: np.ndarray
    start_at_horizon: np.ndarray        #: bool: at its pass's rise (within HORIZON_MARGIN_DEG)
    end_cn0_dbhz: np.ndarray
    end_at_horizon: np.ndarray          #: bool: at its pass's set
    #: HELD_PERCENT percentile over the tracks of each track's lowest C/N0 (NaN: none) [dB-Hz]
    lowest_held_dbhz: float = float("nan")

    def to_json(self) -> dict:
        def tail(v):
            return round(float(np.percentile(v, TAIL_PERCENT)), 2) if v.size else None

        return {"starts": int(self.start_cn0_dbhz.size), "starts_at_rise": int(self.start_at_horizon.sum()),
                "ends": int(self.end_cn0_dbhz.size), "ends_at_set": int(self.end_at_horizon.sum()),
                f"acquisitions_p{TAIL_PERCENT:g}_dbhz": tail(self.acquisitions_dbhz),
                f"losses_p{TAIL_PERCENT:g}_dbhz": tail(self.losses_dbhz),
                f"held_p{HELD_PERCENT:g}_dbhz": None if not np.isfinite(self.lowest_held_dbhz)
                else round(self.lowest_held_dbhz, 2)}

    @property
    def acquisitions_dbhz(self) -> np.ndarray:
        """C/N0 at the track starts away from a rise (reacquisitions)."""
        return self.start_cn0_dbhz[~self.start_at_horizon]

    @property
    def losses_dbhz(self) -> np.ndarray:
        """C/N0 at the track ends away from a set (losses of lock)."""
        return self.end_cn0_dbhz[~self.end_at_horizon]


def _arc_first_last(ids: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(first epoch, last epoch, column) of each arc id 0..N-1 of ``ids`` ((E, S), -1 outside arcs)."""
    ends = arc_ends(ids)
    return ends[0][:, 0], ends[1][:, 0], ends[0][:, 1]


def _pass_edges_el(seen: np.ndarray, el: np.ndarray, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(E, S) elevation at the rise / set of the pass each epoch belongs to (NaN: the pass has no rise / set in the
    span, or outside passes)."""
    n_e = seen.shape[0]
    passes = arc_ids(seen, t_s, PASS_GAP_S)
    rise = np.full(seen.shape, np.nan)
    set_ = np.full(seen.shape, np.nan)
    r, c = np.nonzero(passes >= 0)
    if not r.size:
        return rise, set_
    p = passes[r, c]
    first, last, col = _arc_first_last(passes)
    el_rise = np.where(first > 0, el[first, col], np.nan)
    el_set = np.where(last < n_e - 1, el[last, col], np.nan)
    rise[r, c], set_[r, c] = el_rise[p], el_set[p]
    return rise, set_


def track_events(tracked: np.ndarray, cn0: np.ndarray, el: np.ndarray, t_s: np.ndarray, max_gap_s: float,
                 seen: np.ndarray | None = None, sel: np.ndarray | None = None) -> TrackEvents:
    """Track starts / ends of one signal over (E, S) arrays: ``tracked`` (the signal observed), its ``cn0``
    [dB-Hz], the satellites' elevation ``el`` [deg] (NaN unknown: no event), ``t_s`` (E,) [s]; a gap over
    ``max_gap_s`` ends a track.  ``seen``: the satellite observed on any signal (its passes; default ``tracked``).
    ``sel``: line-of-sight selection (None: all); an event then counts only with the satellite in the line of
    sight at it and at the epoch before a start / after an end (a track that starts as the satellite clears a
    building is the scene's doing)."""
    tracked = np.asarray(tracked, bool)
    n_e = tracked.shape[0]
    rise_el, set_el = _pass_edges_el(tracked if seen is None else np.asarray(seen, bool), el, t_s)
    arcs = arc_ids(tracked, t_s, max_gap_s)
    first, last, col = _arc_first_last(arcs)
    n = first.size

    def events(rows, ok, edge_el, neighbour):
        ok = ok & np.isfinite(cn0[rows, col]) & np.isfinite(el[rows, col])
        if sel is not None:
            ok &= sel[rows, col] & sel[np.clip(neighbour, 0, n_e - 1), col]
        rows_, col_ = rows[ok], col[ok]
        e_el = edge_el[rows_, col_]
        at = np.isfinite(e_el) & (el[rows_, col_] <= e_el + HORIZON_MARGIN_DEG)
        return cn0[rows_, col_].astype(float), at

    s_cn0, s_at = events(first, first > 0, rise_el, first - 1)
    e_cn0, e_at = events(last, last < n_e - 1, set_el, last + 1)
    held = (arcs >= 0) & np.isfinite(cn0) & (True if sel is None else sel)
    track_min = np.full(n, np.inf)
    np.minimum.at(track_min, arcs[held], cn0[held])
    track_min = track_min[np.isfinite(track_min)]
    low = float(np.percentile(track_min, HELD_PERCENT)) if track_min.size else float("nan")
    return TrackEvents(s_cn0, s_at, e_cn0, e_at, low)


def threshold_from_events(cn0_dbhz: np.ndarray, min_events: int) -> float:
    """The TAIL_PERCENT percentile of ``cn0_dbhz`` [dB-Hz]; NaN with fewer than ``min_events`` values."""
    v = np.asarray(cn0_dbhz, float)
    v = v[np.isfinite(v)]
    return float(np.percentile(v, TAIL_PERCENT)) if v.size >= min_events else float("nan")
