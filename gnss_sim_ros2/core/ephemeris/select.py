"""Choice of the broadcast record used at time t, per satellite (RTKLIB's ``seleph`` layer).

A record may serve t when it is healthy and t lies inside its validity window
toe - before <= t <= toe + after; among those, the record with the nearest
reference time (toe, GLONASS tb) is chosen (equal distance: the later record).
Default windows (``WINDOW_S``; override per system):

- GPS: +- fit interval / 2 (flag 0: 4 h; flag 1: 6-26 h by IODC);
  IS-GPS-200N 20.3.4.4, table 20-XII (RTKLIB MAXDTOE 7200 s).
- QZSS: +- fit interval / 2 (flag 0: 2 h); IS-QZSS-PNT-005 4.1.2.7.
- Galileo: -10 min .. +4 h (a 4 h window); Galileo OS SDD: 4 h validity of a
  data set (RTKLIB MAXDTOE_GAL allows +-4 h).  Measured on OPEC 2022-001
  against the CODE SP3: 0.8-0.9 m 3D RMS for 0-3 h after toe, 2.0 m at 3-4 h,
  but 1.8 m at 20-60 min and 9 m at 1-2 h BEFORE toe (the fit looks forward),
  hence the asymmetric window.
- BeiDou: +- 1 h (toe refreshed hourly, BDS-SIS-ICD-B1I 3.0 5.2.4; RTKLIB
  MAXDTOE_CMP allows 6 h).
- GLONASS: +- 15 min (tb every 30 min); GLONASS ICD 5.1 A.3.1.2 (RTKLIB
  MAXDTOE_GLO allows 30 min); plus 1 s, because two tb 30 min apart in
  GLONASST are 1801 s apart across a leap second (no 1 s hole).
- NavIC: +- 2 h (RTKLIB MAXDTOE_IRN 7200 s).

The choice is precomputed once per record set as piecewise-constant
segments per satellite; a lookup for many satellites is one
``np.searchsorted`` over integer microsecond keys (window edges exact to 1 us;
t is floored to the microsecond).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..time import GnssTime

#: default validity window per system: (before, after) toe [s], toe - before <= t <= toe + after;
#: None = +-half the record's fit interval (GPS, QZSS).  Override with ``windows_s``.
WINDOW_S = {
    "G": None,
    "J": None,
    "E": (600.0, 4 * 3600.0),
    "C": (3600.0, 3600.0),
    "R": (15 * 60.0 + 1.0, 15 * 60.0 + 1.0),   # +1 s: tb 30 min apart are 1801 s apart across a leap second
    "I": (2 * 3600.0, 2 * 3600.0),
}

_US = 1_000_000
_BIG = 1 << 52        # key span per satellite [us] (142 years)
_OFFSET = 1 << 51     # keys are t_us + _OFFSET (t within +-71 years of the reference epoch)


def validity_windows_s(systems: np.ndarray, fit_h: np.ndarray, overrides: dict | None = None):
    """Per-record (before, after) window [s] from the system and (GPS/QZSS) fit interval [h].

    ``overrides``: {system: seconds (symmetric) or (before, after) or None (fit interval)}.
    """
    windows = dict(WINDOW_S)
    if overrides:
        for k, v in overrides.items():
            if k not in windows:
                raise ValueError(f"windows_s: unknown system {k!r} (expected one of {''.join(windows)})")
            if v is not None:
                v = (float(v), float(v)) if np.ndim(v) == 0 else tuple(float(x) for x in v)
                if len(v) != 2 or min(v) < 0 or max(v) <= 0:
                    raise ValueError(f"windows_s[{k!r}]={v}: expected seconds >= 0 (before, after)")
            windows[k] = v
    before = np.empty(len(systems))
    after = np.empty(len(systems))
    for s in np.unique(systems):
        m = systems == s
        win = windows.get(str(s))
        if win is None:
            fh = np.asarray(fit_h, dtype=np.float64)[m]
            default_h = 2.0 if s == "J" else 4.0
            half = np.where(np.isfinite(fh) & (fh > 0), fh, default_h) * 3600.0 / 2.0
            before[m], after[m] = half, half
        else:
            before[m], after[m] = win
    return before, after


class Timeline:
    """Piecewise-constant record choice for many satellites; ``lookup`` is vectorised."""

    def __init__(self, ref_sec: int, start_key, end_key, rec):
        self.ref_sec = int(ref_sec)
        self.start_key = np.asarray(start_key, dtype=np.int64)
        self.end_key = np.asarray(end_key, dtype=np.int64)
        self.rec = np.asarray(rec, dtype=np.int64)

    def t_us(self, sec, frac):
        """Microseconds since the reference epoch (integer, floor), clipped to the key span."""
        us = (np.asarray(sec, dtype=np.int64) - self.ref_sec) * _US + np.floor(np.asarray(frac) * _US).astype(np.int64)
        return np.clip(us, -_OFFSET + 1, _OFFSET - 1)

    def lookup(self, sv_idx, t_us) -> np.ndarray:
        """Record index per (satellite index, time in us); -1 where none serves."""
        key = np.asarray(sv_idx, dtype=np.int64) * _BIG + (np.asarray(t_us, dtype=np.int64) + _OFFSET)
        if not self.end_key.size:
            return np.full(np.shape(key), -1, dtype=np.int64)
        pos = np.searchsorted(self.start_key, key, side="right") - 1
        posc = np.maximum(pos, 0)
        ok = (pos >= 0) & (key < self.end_key[posc])
        return np.where(ok, self.rec[posc], -1)

    def segments_of(self, sv_index: int):
        """(start_us, end_us exclusive, record) of one satellite, for inspection."""
        lo, hi = sv_index * _BIG, (sv_index + 1) * _BIG
        m = (self.start_key >= lo) & (self.start_key < hi)
        return (self.start_key[m] - lo - _OFFSET, self.end_key[m] - lo - _OFFSET, self.rec[m])


def build_timeline(ref_sec: int, sv_idx, toe_sec, toe_frac, before_s, after_s, rec_ids, tiebreak=None) -> Timeline:
    """Segments where each record is the nearest-reference-time record inside its window.

    ``sv_idx`` (n,) satellite index per record; ``toe_*`` reference time (GPS);
    window toe - before_s <= t <= toe + after_s; ``rec_ids`` (n,) the ids returned by lookups;
    ``tiebreak`` (n,) orders records with equal toe (the larger wins, e.g. transmission time).
    """
    sv_idx = np.asarray(sv_idx, dtype=np.int64)
    toe_us = ((np.asarray(toe_sec, dtype=np.int64) - int(ref_sec)) * _US
              + np.round(np.asarray(toe_frac) * _US).astype(np.int64))
    bef_us = np.round(np.broadcast_to(np.asarray(before_s, dtype=np.float64), sv_idx.shape) * _US).astype(np.int64)
    aft_us = np.round(np.broadcast_to(np.asarray(after_s, dtype=np.float64), sv_idx.shape) * _US).astype(np.int64)
    rec_ids = np.asarray(rec_ids, dtype=np.int64)
    tb = np.zeros(len(sv_idx)) if tiebreak is None else np.asarray(tiebreak, dtype=np.float64)
    starts, ends, recs = [], [], []
    order = np.lexsort((tb, toe_us, sv_idx))
    sv_sorted = sv_idx[order]
    bounds = np.flatnonzero(np.diff(sv_sorted)) + 1
    for grp in np.split(order, bounds):
        if grp.size == 0:
            continue
        s = int(sv_idx[grp[0]])
        toe = toe_us[grp]
        # equal toe: keep the last of the group (largest tiebreak)
        keep = np.append(toe[1:] != toe[:-1], True)
        grp, toe = grp[keep], toe[keep]
        lo = toe - bef_us[grp]
        hi = toe + aft_us[grp] + 1          # exclusive end
        br = np.unique(np.concatenate([lo, hi]))
        seg_s, seg_e, seg_r = [], [], []
        for k in range(br.size - 1):
            a, b = int(br[k]), int(br[k + 1])
            valid = np.flatnonzero((lo <= a) & (hi > a))
            if valid.size == 0:
                continue
            vt = toe[valid]  # sorted ascending
            # nearest toe switches from valid[j] to valid[j+1] at ceil((toe_j + toe_j+1) / 2)
            sw = -((-(vt[:-1] + vt[1:])) // 2)
            cur = a
            j = int(np.searchsorted(sw, a, side="right"))
            for q in range(j, valid.size):
                nxt = int(sw[q]) if q < valid.size - 1 else b
                nxt = min(nxt, b)
                if nxt > cur:
                    seg_s.append(cur)
                    seg_e.append(nxt)
                    seg_r.append(int(rec_ids[grp[valid[q]]]))
                cur = max(cur, nxt)
                if cur >= b:
                    break
        # merge contiguous segments of the same record
        for a, b, r in zip(seg_s, seg_e, seg_r):
            if recs and recs[-1] == r and ends[-1] == s * _BIG + a + _OFFSET:
                ends[-1] = s * _BIG + b + _OFFSET
            else:
                starts.append(s * _BIG + a + _OFFSET)
                ends.append(s * _BIG + b + _OFFSET)
                recs.append(r)
    return Timeline(ref_sec, starts, ends, recs)


@dataclass
class EphemerisDiagnostics:
    """Why satellites have (no) state at t.

    ok: a healthy record serves t.  unhealthy: records cover t but all are
    unhealthy.  gap: no record covers t, but the satellite has records later
    (between two records, or before the first).  stale: the newest record is
    older than its validity limit (no later record).  missing: asked for, but
    no ephemeris at all.
    """

    t: GnssTime
    ok: list[str] = field(default_factory=list)
    unhealthy: list[str] = field(default_factory=list)
    gap: list[str] = field(default_factory=list)
    stale: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)
    age_s: dict[str, float] = field(default_factory=dict)

    def status(self, sv: str) -> str:
        for name in ("ok", "unhealthy", "gap", "stale", "missing"):
            if sv in getattr(self, name):
                return name
        return "unknown"

    def __str__(self) -> str:
        lines = [f"ephemeris at {self.t.isoformat()} GPST: {len(self.ok)} ok"]
        for name in ("unhealthy", "gap", "stale", "missing"):
            lst = getattr(self, name)
            if lst:
                lines.append(f"  {name} ({len(lst)}): {' '.join(lst)}")
        return "\n".join(lines)
