"""Tracking state per (satellite, signal): acquisition, loss of lock, ambiguities, RINEX LLI flags.

Rules (per key ``(sv, code)``, e.g. ``("G05", "1C")``):

- acquired when the line of sight is usable (``visible``) and C/N0 >=
  ``acquisition_cn0_dbhz`` (default 33 dB-Hz) continuously for
  ``acquisition_time_s`` (default 0: at the first such epoch);
- kept while visible and C/N0 >= ``tracking_cn0_dbhz`` (default 28 dB-Hz):
  the gap between the two thresholds is the hysteresis real receivers have
  (acquisition needs more signal than tracking; cf. RTKLIB's simulator, which
  flags loss of lock below 35 dB-Hz);
- lost when blocked, below the tracking threshold, or absent from an epoch;
- every new continuous track draws a new integer carrier-phase ambiguity
  (uniform in +-``ambiguity_max_cyc``, from the seeded Generator);
- random cycle slips with the mean time between slips of the PLL
  (receiver/noise.py mean_time_to_slip_s: negligible above ~30 dB-Hz, frequent
  near 25 dB-Hz), or forced by the caller (``force_slip``): the ambiguity
  changes by +-1 cycle and the lock time restarts;
- RINEX 3.04 LLI (5.3, table A2): bit 0 (value 1) on the first epoch of a new
  track and on an epoch with a cycle slip; bit 1 (value 2) "half-cycle
  ambiguity possible" until the Costas loop's half-cycle is resolved, on a
  data-modulated signal: the loop locks with a 180 deg ambiguity that the
  polarity of the navigation message's frame sync word removes, so the flag
  lasts from acquisition to the end of the first sync word received, the wait
  for the next frame start (uniform over the frame period: the acquisition
  instant is unrelated to the data frame) plus the word itself
  (:data:`HALF_CYCLE_SYNC`: GPS/QZSS LNAV subframe 6 s with its 0.6 s
  telemetry word, IS-GPS-200N 20.3.2/20.3.3.1; GLONASS string 2 s with its
  0.3 s time mark, GLONASS ICD 5.1 4.3; BeiDou D1 6 s / GEO D2 0.6 s with a
  30-bit first word, BDS-SIS-ICD-B1I 3.0 5.2/5.3; Galileo I/NAV page part
  1 s, F/NAV page 10 s, C/NAV page 1 s, OS SIS ICD 2.1 4.3; NavIC subframe
  12 s with a 16-symbol sync word, IRNSS SPS ICD 1.1 5.1); or a fixed
  ``half_cycle_time_s`` when one is set.  Signals tracked on a dataless
  pilot (L1C-P, L2C-L, L5-Q, E1-C, E5a/b-Q, B1C/B2a-P, ...) never get bit 1.
- ``lock_time_s``: time since acquisition or the last slip (0 when not tracked).

Start of a run (``start``): "warm" (default) -- a recording that starts while the receiver has long been
running, as a station's daily file or a logger switched on mid-pass: at the first epoch every key that is
visible and at or above the tracking threshold is tracked as locked long ago (no LLI bit, lock time
:data:`WARM_LOCK_TIME_S`, half-cycle resolved); "cold" -- a receiver switched on at the first epoch:
every track is acquired then (thresholds and ``acquisition_time_s`` above) with the flags of a new track.
Measured on the real files: ESBC 2020-177 (Septentrio PolaRx5, a daily file) has no LLI on any track at
its first epoch, OPEC 2022-001 (Trimble NetR9) bit 0 on every track at its first epoch (its logging
session starts there) and bit 0 on 1 of 16 arcs of rising satellites later.

``aided_cn0_dbhz`` (default None: every signal on the two thresholds): a multi-frequency receiver acquires a
satellite on its first signal (the profile lists it first: GPS L1 C/A, Galileo E1, BeiDou B1I) and tracks
the others aided by it (semi-codeless L2 P(Y), L2C, L5, E5 ... from the first signal's code and carrier):
with a value, a satellite's other signals are tracked while its first one is and their own C/N0 is at or
above it.  On ESBC 2020-177 0-8 h the other signals start within a few tenths of a degree of the first
(rise median: L1 C/A 2.6 deg, L2C 2.6, L2 P(Y) 2.8 at 13 dB-Hz as the PolaRx5 reports it, L5 2.4; E1 3.8,
E5b 3.8) and end at their own C/N0 (set: L2C 25.5, L5 24.2, E5a 25.0, E5b 25.2 dB-Hz, median).

``half_cycle_flags`` (default True): whether this receiver class reports LLI bit 1 at all.  Geodetic
receivers resolve the half cycle before they output a phase: no bit 1 in 24 h of ESBC (PolaRx5, every
signal) nor in 3.7 h of OPEC (NetR9); a u-blox M8T (Hong Kong drive 2019-118, RINEX by RTKLIB convbin)
sets it at the start of every arc, for 6 epochs (GPS L1, 1 Hz) to 10 (BeiDou B1I) on average.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from gnss_sim_ros2.core.memo import BoundedCache
from gnss_sim_ros2.core.receiver.noise import slip_probability
from gnss_sim_ros2.core.signals import BEIDOU_GEO_PATTERN
from gnss_sim_ros2.core.time import GnssTime
from gnss_sim_ros2.core.vocabulary import TRACKING_STARTS

LLI_LOSS_OF_LOCK = 1
LLI_HALF_CYCLE = 2
#: lock time [s] of a track a warm start finds locked: beyond the largest lock time RTCM MSM4 distinguishes
#: (DF402 indicator 15: >= 524.288 s, RTCM 10403.3 table 3.5-74, rtcm/msm.py), so a consumer takes the track
#: as long established; the true time since the satellite rose is not known
WARM_LOCK_TIME_S = 1000.0

#: (system, code) tracked on a dataless pilot component: no half-cycle ambiguity
PILOT_CODES = frozenset(
    [("G", c) for c in ("1L", "1X", "2L", "2X", "5Q", "5X")]
    + [("J", c) for c in ("1L", "1X", "2L", "2X", "5Q", "5X", "6L", "6X")]
    + [("E", c) for c in ("1C", "1X", "5Q", "5X", "7Q", "7X", "8Q", "8X", "6C", "6X")]
    + [("C", c) for c in ("1P", "1X", "5P", "5X", "7P", "7Z")]
)


#: (system, codes or None for the system's other data codes) -> (frame sync period [s], sync word [s]) of the
#: navigation message on that signal (module doc); a data code found in none: the GPS subframe
HALF_CYCLE_SYNC = {
    ("G", ("2S",)): (12.0, 0.32),         # L2C-M CNAV: 12 s message at 25 bps, 8-bit preamble (IS-GPS-200N 30.3)
    ("G", None): (6.0, 0.6),              # LNAV (C/A, P(Y)): 6 s subframe, 0.6 s TLM word; L5-I CNAV: 6 s message
    ("J", ("2S",)): (12.0, 0.32),
    ("J", None): (6.0, 0.6),
    ("R", None): (2.0, 0.3),              # 2 s string ending in a 0.3 s time mark
    ("E", ("5I",)): (10.0, 0.24),         # F/NAV page 10 s, 12-symbol sync at 50 sps
    ("E", ("6B",)): (1.0, 0.016),         # C/NAV page 1 s, 16-symbol sync at 1000 sps
    ("E", None): (1.0, 0.04),             # I/NAV page part 1 s, 10-symbol sync at 250 sps (E1-B, E5b-I)
    ("C", None): (6.0, 0.6),              # D1 subframe 6 s (MEO/IGSO); GEO: BEIDOU_GEO_SYNC
    ("I", None): (12.0, 0.32),            # subframe 12 s (600 symbols at 50 sps), 16-symbol sync word
}
#: BeiDou GEO satellites broadcast D2 (500 bps): subframe 0.6 s, 30-bit first word 0.06 s
BEIDOU_GEO_SYNC = (0.6, 0.06)
_BEIDOU_GEO = re.compile(BEIDOU_GEO_PATTERN)


def half_cycle_sync(sv: str, code: str) -> tuple[float, float]:
    """(frame sync period [s], sync word duration [s]) of the navigation data on signal ``code`` of ``sv``."""
    system = sv[:1]
    if system == "C" and _BEIDOU_GEO.fullmatch(sv):
        return BEIDOU_GEO_SYNC
    for (s, codes), v in HALF_CYCLE_SYNC.items():
        if s == system and codes is not None and code in codes:
            return v
    return HALF_CYCLE_SYNC.get((system, None), HALF_CYCLE_SYNC[("G", None)])


def _as_rows(a, dtype, n):
    """``a`` as an (n,) array of ``dtype`` (np.broadcast_to of a scalar; arrays of that shape as they are)."""
    a = np.asarray(a, dtype=dtype)
    return a if a.shape == (n,) else np.broadcast_to(a, (n,))


@dataclass
class TrackingConfig:
    acquisition_cn0_dbhz: float = 33.0
    tracking_cn0_dbhz: float = 28.0
    acquisition_time_s: float = 0.0
    #: None: the wait for the navigation data's frame sync (module doc); a number: that time for every track
    half_cycle_time_s: float | None = None
    ambiguity_max_cyc: int = 1_000_000
    random_slips: bool = True
    pll_bn_hz: float = 15.0
    pll_t_int_s: float = 0.001
    #: "warm": tracks above the tracking threshold at the first epoch locked long ago; "cold": acquired then
    start: str = "warm"
    #: whether the receiver reports LLI bit 1 (half-cycle ambiguity); geodetic receivers do not (module doc)
    half_cycle_flags: bool = True
    #: None: each signal on the thresholds above; a value: a satellite's signals after its first are tracked
    #: while the first is and their C/N0 >= this (aided tracking, module doc)
    aided_cn0_dbhz: float | None = None

    def __post_init__(self):
        if self.start not in TRACKING_STARTS:
            raise ValueError(f"TrackingConfig: 'start' = {self.start!r} (one of {TRACKING_STARTS})")
        if self.aided_cn0_dbhz is not None and not np.isfinite(self.aided_cn0_dbhz):
            raise ValueError(f"TrackingConfig: 'aided_cn0_dbhz' = {self.aided_cn0_dbhz!r} must be a number or null")
        if not isinstance(self.half_cycle_flags, (bool, np.bool_)):
            raise ValueError(f"TrackingConfig: 'half_cycle_flags' = {self.half_cycle_flags!r} must be true or false")
        if self.tracking_cn0_dbhz > self.acquisition_cn0_dbhz:
            raise ValueError(
                f"TrackingConfig: 'tracking_cn0_dbhz' = {self.tracking_cn0_dbhz} exceeds "
                f"'acquisition_cn0_dbhz' = {self.acquisition_cn0_dbhz}")
        if (self.acquisition_time_s < 0 or (self.half_cycle_time_s is not None and self.half_cycle_time_s < 0)
                or self.ambiguity_max_cyc < 1):
            raise ValueError("TrackingConfig: times must be >= 0 and 'ambiguity_max_cyc' >= 1")


@dataclass
class TrackingOutput:
    """Per input row (same order as the keys passed to :meth:`Tracker.update`)."""

    tracked: np.ndarray        #: bool
    lli: np.ndarray            #: int8 RINEX LLI bits (0 when not tracked)
    lock_time_s: np.ndarray    #: float
    ambiguity_cyc: np.ndarray  #: int64 integer ambiguity of the current track
    new_track: np.ndarray      #: bool, acquired at this epoch
    slipped: np.ndarray        #: bool, cycle slip at this epoch


class Tracker:
    """Tracking states for keys (sv, code) that come and go; vectorised over the keys of an epoch."""

    def __init__(self, config: TrackingConfig | None = None, rng: np.random.Generator | int | None = 0):
        self.config = config or TrackingConfig()
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        self._index: dict[tuple[str, str], int] = {}
        self._rows_cache = BoundedCache(64)
        self._idx_prev = None
        self._n_prev = -1
        self._cap = 0
        self._n = 0
        self._t0 = None
        self._t_prev = None
        self._alloc(64)

    def _alloc(self, cap):
        def grow(old, fill, dtype):
            new = np.full(cap, fill, dtype=dtype)
            if old is not None:
                new[: self._n] = old[: self._n]
            return new

        g = self.__dict__.get
        self._tracked = grow(g("_tracked"), False, bool)
        self._cand_since = grow(g("_cand_since"), np.nan, np.float64)
        self._track_start = grow(g("_track_start"), np.nan, np.float64)
        self._lock_start = grow(g("_lock_start"), np.nan, np.float64)
        self._amb = grow(g("_amb"), 0, np.int64)
        self._pilot = grow(g("_pilot"), False, bool)
        self._sync = grow(g("_sync"), 0.0, np.float64)       # frame sync period of the signal's data [s]
        self._sync_word = grow(g("_sync_word"), 0.0, np.float64)
        self._half_end = grow(g("_half_end"), np.nan, np.float64)  # track time when the half cycle is resolved
        self._cap = cap

    def _rows(self, sv, code):
        """Slots of the keys (sv, code); the index array of a key set seen before comes from a cache."""
        ck = (sv.dtype.str, code.dtype.str, sv.tobytes(), code.tobytes())
        hit = self._rows_cache.get(ck)
        if hit is not None:
            return hit
        idx = np.empty(len(sv), dtype=np.int64)
        for j, key in enumerate(zip(sv.tolist(), code.tolist())):
            i = self._index.get(key)
            if i is None:
                if self._n == self._cap:
                    self._alloc(2 * self._cap)
                i = self._n
                self._index[key] = i
                self._pilot[i] = (key[0][:1], key[1]) in PILOT_CODES
                self._sync[i], self._sync_word[i] = half_cycle_sync(key[0], key[1])
                self._n += 1
            idx[j] = i
        if len(np.unique(idx)) != len(idx):
            raise ValueError("Tracker.update: duplicate (sv, code) keys in one epoch")
        self._rows_cache.put(ck, idx)
        return idx

    def _seconds(self, t):
        if self._t0 is None:
            self._t0 = t
        return float(t - self._t0)

    def update(self, t, sv, code, cn0_dbhz, visible=True, force_slip=None) -> TrackingOutput:
        """Advance to epoch ``t`` (GnssTime or float s, increasing) with the keys present now.

        ``sv``, ``code``: (N,) strings; ``cn0_dbhz``: (N,); ``visible``: bool or
        (N,) line of sight usable; ``force_slip``: optional (N,) bool.  Keys
        tracked before and absent now lose lock.
        """
        return self._update(t, sv, code, cn0_dbhz, visible, force_slip)

    def _update(self, t, sv, code, cn0_dbhz, visible=True, force_slip=None, slip_p=None,
                slip_u=None) -> TrackingOutput:
        """:meth:`update`; ``slip_p``: the rows' slip probabilities over this epoch's interval computed already
        (update_many, update_trackers: over every row of their epochs at once; only the rows kept tracking are
        read, a row losing or acquiring its track may hold anything), None: computed here; ``slip_u``: the
        uniforms of the slips drawn already from this tracker's stream (update_trackers, when nothing but a slip
        changes this epoch), None: drawn here."""
        sv = np.atleast_1d(np.asarray(sv, dtype=str))
        code = np.atleast_1d(np.asarray(code, dtype=str))
        n = sv.shape[0]
        if code.shape != (n,):
            raise ValueError(f"Tracker.update: 'code' has shape {code.shape}, expected ({n},) like 'sv'")
        cn0 = _as_rows(cn0_dbhz, np.float64, n)
        vis = _as_rows(visible, bool, n)
        forced = np.zeros(n, bool) if force_slip is None else np.broadcast_to(np.asarray(force_slip, bool), (n,))
        if (~np.isfinite(cn0) & vis).any():
            raise ValueError("Tracker.update: 'cn0_dbhz' has non-finite values for visible rows")
        if not isinstance(t, GnssTime):
            t = float(t)
        first = self._t_prev is None
        ts = self._seconds(t)
        if self._t_prev is not None and ts <= self._t_prev:
            raise ValueError(f"Tracker.update: epoch {t!r} is not after the previous one")
        dt = 0.0 if self._t_prev is None else ts - self._t_prev
        self._t_prev = ts
        c = self.config

        idx = self._rows(sv, code)     # raises on duplicate keys
        # keys absent from this epoch lose lock (nothing to do when the keys are the previous epoch's: their
        # absent keys were cleared then, and only present keys change)
        if idx is not self._idx_prev or self._n != self._n_prev:
            absent = np.ones(self._n, bool)
            absent[idx] = False
            self._tracked[: self._n][absent] = False
            self._cand_since[: self._n][absent] = np.nan
            self._idx_prev, self._n_prev = idx, self._n

        was = self._tracked[idx]
        thr_track, thr_acq, aided = self._thresholds(sv)
        ok_track = vis & (cn0 >= thr_track)
        ok_acq = vis & (cn0 >= thr_acq)
        keep = was & ok_track

        cand = self._cand_since[idx]
        cand = np.where(~was & ok_acq, np.where(np.isnan(cand), ts, cand), np.nan)
        new = ~was & ok_acq & (ts - cand >= c.acquisition_time_s - 1e-9)
        # a warm start: at the run's first epoch every key above the tracking threshold was locked long ago
        warm = ~was & ok_track if (first and c.start == "warm") else np.zeros(n, bool)
        new |= warm
        if aided is not None:           # signals after a satellite's first: only while the first is tracked
            first_on = (keep | new)[aided]
            keep &= first_on
            new &= first_on
            warm &= new
        self._cand_since[idx] = np.where(new, np.nan, cand)

        amb = self._amb[idx]
        n_new = int(new.sum())
        if n_new:
            amb[new] = self.rng.integers(-c.ambiguity_max_cyc, c.ambiguity_max_cyc + 1, size=n_new)
            inew = idx[new]
            if c.half_cycle_time_s is None:
                self._half_end[inew] = self._sync[inew] * self.rng.random(n_new) + self._sync_word[inew]
            else:
                self._half_end[inew] = c.half_cycle_time_s
        slipped = keep & forced
        if c.random_slips and dt > 0 and keep.any():
            p = slip_probability(cn0, dt, c.pll_bn_hz, c.pll_t_int_s) if slip_p is None else slip_p
            u = self.rng.random(n) if slip_u is None else slip_u
            slipped |= keep & (u < p)
        n_slip = int(slipped.sum())
        if n_slip:
            amb[slipped] += self.rng.choice(np.array([-1, 1]), size=n_slip)
        self._amb[idx] = amb

        t_new = np.where(warm, ts - WARM_LOCK_TIME_S, ts)
        track_start = np.where(new, t_new, self._track_start[idx])
        lock_start = np.where(new | slipped, np.where(slipped, ts, t_new), self._lock_start[idx])
        self._track_start[idx] = track_start
        self._lock_start[idx] = lock_start
        tracked = keep | new
        self._tracked[idx] = tracked

        lli = np.zeros(n, np.int8)
        lli[tracked & ((new & ~warm) | slipped)] |= LLI_LOSS_OF_LOCK
        lli[self._half_cycle_open(idx, tracked, ts, track_start)] |= LLI_HALF_CYCLE
        lock_time = np.where(tracked, ts - lock_start, 0.0)
        return TrackingOutput(tracked, lli, lock_time, amb, new, slipped)     # fresh arrays (state holds copies)

    def _thresholds(self, sv):
        """(tracking, acquisition thresholds [dB-Hz], row of each row's satellite's first signal or None) of an
        epoch's rows ``sv``: the config's thresholds, or with ``aided_cn0_dbhz`` that value for every row
        after its satellite's first (module doc)."""
        c = self.config
        if c.aided_cn0_dbhz is None:
            return c.tracking_cn0_dbhz, c.acquisition_cn0_dbhz, None
        _, first_idx, inv = np.unique(sv, return_index=True, return_inverse=True)
        first = first_idx[inv]
        is_first = first == np.arange(len(sv))
        return (np.where(is_first, c.tracking_cn0_dbhz, c.aided_cn0_dbhz),
                np.where(is_first, c.acquisition_cn0_dbhz, c.aided_cn0_dbhz), first)

    def _half_cycle_open(self, idx, tracked, t_s, track_start):
        """Rows (keys ``idx``) whose half-cycle ambiguity is not resolved yet at ``t_s``: tracked data signals
        within their half-cycle time of the start of their track (module doc); none when the receiver does not
        report half cycles (``half_cycle_flags``)."""
        if not self.config.half_cycle_flags:
            return np.zeros(np.shape(tracked), bool)
        return tracked & ~self._pilot[idx] & (t_s - track_start < self._half_end[idx] - 1e-9)

    def update_many(self, ts, sv, code, cn0_dbhz, visible, seg):
        """:meth:`update` for K epochs in order: epoch b's keys are the rows ``seg[b]:seg[b + 1]`` of ``sv``,
        ``code``, ``cn0_dbhz`` and ``visible`` (no forced slips).  Returns (tracked, lli, lock_time_s,
        ambiguity_cyc) per row, what K calls of update give.

        An epoch with the previous epoch's keys where every tracked key is kept (visible, above the tracking
        threshold, a slip probability of exactly 0) and no other key reaches the acquisition threshold
        changes no state but the time: a run of such epochs is filled together, its uniform draws (one per
        key and epoch, as update makes them) taken in one call; every other epoch goes through update."""
        n_all = len(sv)
        (tracked, lli, lock, amb), (seg, sv, code, cn0, vis) = _rows_io(seg, sv, code, cn0_dbhz, visible)
        c = self.config
        ts = [t if isinstance(t, GnssTime) else float(t) for t in ts]
        t_s = [self._seconds(t) for t in ts]
        prev = [self._t_prev] + t_s[:-1]
        dt_ep = np.array([t - p if p is not None else 0.0 for t, p in zip(t_s, prev)])
        n_ep = seg[1:] - seg[:-1]
        # per row: what would change the state of a tracked key (lost, or a possible slip), of an untracked one
        if c.aided_cn0_dbhz is None:
            thr_track = c.tracking_cn0_dbhz
            thr_acq = c.acquisition_cn0_dbhz
        else:               # per epoch: a satellite's first signal on the thresholds, the others aided
            thr_track, thr_acq = np.empty(n_all), np.empty(n_all)
            for b in range(len(ts)):
                s = slice(seg[b], seg[b + 1])
                thr_track[s], thr_acq[s], _ = self._thresholds(sv[s])
        ok_track = vis & (cn0 >= thr_track)
        stop_tracked = ~ok_track
        slip_p = None             # the slip probabilities of the rows keeping their track (the others: 0)
        if c.random_slips and n_all:
            slip_p = slip_probability(np.where(ok_track, cn0, 99.0),
                                      np.repeat(np.where(dt_ep > 0, dt_ep, 1.0), n_ep), c.pll_bn_hz, c.pll_t_int_s)
            stop_tracked |= slip_p > 0
        start_untracked = vis & (cn0 >= thr_acq)
        may = ((n_ep > 0) & (dt_ep > 0)).tolist()
        run: list = []            # epochs of the current steady run
        held = None               # tracked flags of the run's keys

        def flush():
            if not run:
                return
            idx = self._idx_prev
            k_r = len(run)

            def tile(x):                  # the run's keys epoch after epoch (one epoch: as they are)
                return x if k_r == 1 else np.tile(x, k_r)

            if k_r == 1:
                tt = t_s[run[0]]
                rows = slice(seg[run[0]], seg[run[0] + 1])
            else:
                tt = np.repeat(np.array([t_s[b] for b in run]), len(idx))
                rows = np.concatenate([np.arange(seg[b], seg[b + 1]) for b in run])
            if c.random_slips and held.any():
                self.rng.random(len(idx) * k_r)      # the draws update makes (every slip probability is 0)
            on = tile(held)
            tracked[rows] = on
            amb[rows] = tile(self._amb[idx])
            lock[rows] = np.where(on, tt - tile(self._lock_start[idx]), 0.0)
            idx_rows = tile(idx)
            half = self._half_cycle_open(idx_rows, on, tt, self._track_start[idx_rows])
            if k_r == 1:
                lli[rows][half] = LLI_HALF_CYCLE        # a view of the epoch's rows
            else:
                lli[rows[half]] = LLI_HALF_CYCLE
            self._cand_since[idx] = np.nan
            self._t_prev = t_s[run[-1]]
            run.clear()

        for b in range(len(ts)):
            s = slice(seg[b], seg[b + 1])
            if may[b]:
                idx = self._rows(sv[s], code[s])
                if idx is self._idx_prev and self._n == self._n_prev:
                    if not run:
                        held = self._tracked[idx]
                    if not np.where(held, stop_tracked[s], start_untracked[s]).any():
                        run.append(b)
                        continue
            flush()
            out = self._update(ts[b], sv[s], code[s], cn0[s], vis[s], slip_p=None if slip_p is None else slip_p[s])
            tracked[s], lli[s], lock[s], amb[s] = out.tracked, out.lli, out.lock_time_s, out.ambiguity_cyc
        flush()
        return tracked, lli, lock, amb

    def keys(self):
        """All (sv, code) keys seen so far."""
        return list(self._index)

    def is_tracked(self, sv: str, code: str) -> bool:
        i = self._index.get((sv, code))
        return bool(i is not None and self._tracked[i])


def _rows_io(seg, sv, code, cn0_dbhz, visible):
    """The outputs (tracked, lli, lock_time_s, ambiguity_cyc) of update_many / update_trackers, zeroed per row, and
    their inputs (seg, sv, code, cn0_dbhz, visible) as arrays."""
    n_all = len(sv)
    out = (np.zeros(n_all, dtype=bool), np.zeros(n_all, dtype=np.int8), np.zeros(n_all),
           np.zeros(n_all, dtype=np.int64))
    return out, (np.asarray(seg, dtype=np.int64), np.asarray(sv, dtype=str), np.asarray(code, dtype=str),
                 np.asarray(cn0_dbhz, dtype=np.float64), np.asarray(visible, dtype=bool))


def update_trackers(trackers, ts, sv, code, cn0_dbhz, visible, seg):
    """``trackers[r].update_many([ts[r]], rows seg[r]:seg[r + 1])`` for every tracker r (several receivers' one
    epoch each, core/receiver/batch_observe.py; the trackers' configurations equal): (tracked, lli, lock_time_s,
    ambiguity_cyc) per row, the bits of the separate calls.

    What has no memory -- thresholds, the slip probabilities -- is evaluated once over every row; a tracker whose
    epoch is steady (its previous keys, nothing to acquire or lose, and no slip in the uniforms update draws, drawn
    here from its own stream) is filled from its own state with the others' steady rows; every other tracker goes
    through its own update (with the uniforms drawn already when one of them slipped).  update_many stays more
    cautious: an epoch with a slip probability above 0 goes through update."""
    n_all = len(sv)
    (tracked, lli, lock, amb), (seg, sv, code, cn0, vis) = _rows_io(seg, sv, code, cn0_dbhz, visible)
    c = trackers[0].config
    ts = [t if isinstance(t, GnssTime) else float(t) for t in ts]
    t_s = [tr._seconds(t) for tr, t in zip(trackers, ts)]
    dt = [t - tr._t_prev if tr._t_prev is not None else 0.0 for tr, t in zip(trackers, t_s)]
    n_ep = seg[1:] - seg[:-1]
    bounds = seg.tolist()
    if c.aided_cn0_dbhz is None:
        thr_track, thr_acq = c.tracking_cn0_dbhz, c.acquisition_cn0_dbhz
    else:
        thr_track, thr_acq = np.empty(n_all), np.empty(n_all)
        for r in range(len(trackers)):
            s = slice(bounds[r], bounds[r + 1])
            thr_track[s], thr_acq[s], _ = trackers[r]._thresholds(sv[s])
    ok_track = vis & (cn0 >= thr_track)
    slip_p = None                 # the slip probabilities of the rows keeping their track (the others: 0)
    if c.random_slips and n_all:
        dt_row = np.repeat(np.array([d if d > 0 else 1.0 for d in dt]), n_ep)
        slip_p = slip_probability(np.where(ok_track, cn0, 99.0), dt_row, c.pll_bn_hz, c.pll_t_int_s)
    start_untracked = vis & (cn0 >= thr_acq)
    # the steady candidates: their previous epoch's keys; steady when no row changes its state: none lost, none
    # acquired, and no slip in the uniforms update would draw (drawn here, from the tracker's stream)
    cand, idx_of, held_of = [], [], []
    for r, tr in enumerate(trackers):
        j0, j1 = bounds[r], bounds[r + 1]
        if j1 > j0 and dt[r] > 0:
            idx = tr._rows(sv[j0:j1], code[j0:j1])
            if idx is tr._idx_prev and tr._n == tr._n_prev:
                cand.append(r)
                idx_of.append(idx)
                held_of.append(tr._tracked[idx])
    steady = np.zeros(len(trackers), dtype=bool)
    slip_u: dict = {}             # tracker -> the uniforms drawn for it, a slip among them (it steps through update)
    if cand:
        held = np.concatenate(held_of)
        is_cand = np.zeros(len(trackers), dtype=bool)
        is_cand[cand] = True
        rows = np.repeat(is_cand, n_ep)
        change = np.where(held, ~ok_track[rows], start_untracked[rows])
        lens = n_ep[cand]
        starts = np.concatenate([[0], np.cumsum(lens)[:-1]])
        moved = np.logical_or.reduceat(change, starts).tolist()
        may_slip = (np.logical_or.reduceat(held & (slip_p[rows] > 0), starts).tolist() if slip_p is not None
                    else [False] * len(cand))
        for i, r in enumerate(cand):
            if moved[i]:
                continue
            if c.random_slips and held_of[i].any():
                u = trackers[r].rng.random(len(idx_of[i]))      # the uniforms update draws for its slips
                if may_slip[i] and (held_of[i] & (u < slip_p[bounds[r]:bounds[r + 1]])).any():
                    slip_u[r] = u
                    continue
            steady[r] = True
        sel = [i for i, r in enumerate(cand) if steady[r]]
        if sel:
            on = held[np.repeat(steady[cand], lens)]
            parts = []
            for i in sel:
                tr, idx = trackers[cand[i]], idx_of[i]
                tr._cand_since[idx] = np.nan
                tr._t_prev = t_s[cand[i]]
                parts.append((tr._amb[idx], tr._lock_start[idx], tr._track_start[idx], tr._pilot[idx],
                              tr._half_end[idx]))
            amb_c, lock_start, track_start, pilot, half_end = (np.concatenate(p) for p in zip(*parts))
            tt = np.repeat(np.array([t_s[cand[i]] for i in sel]), lens[sel])
            at = np.repeat(steady, n_ep)
            tracked[at] = on
            amb[at] = amb_c
            lock[at] = np.where(on, tt - lock_start, 0.0)
            if c.half_cycle_flags:
                half = on & ~pilot & (tt - track_start < half_end - 1e-9)
                lli[np.flatnonzero(at)[half]] = LLI_HALF_CYCLE
    for r, tr in enumerate(trackers):
        if steady[r]:
            continue
        s = slice(bounds[r], bounds[r + 1])
        out = tr._update(ts[r], sv[s], code[s], cn0[s], vis[s], slip_p=None if slip_p is None else slip_p[s],
                         slip_u=slip_u.get(r))
        tracked[s], lli[s], lock[s], amb[s] = out.tracked, out.lli, out.lock_time_s, out.ambiguity_cyc
    return tracked, lli, lock, amb
