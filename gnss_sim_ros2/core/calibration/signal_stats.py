"""Per-signal statistics of one receiver's observations: what ``gnss-sim calibrate`` fits a profile to and what
``gnss-sim compare`` reports simulated against real (one implementation for both).

A signal is a key "G1C": RINEX system letter + band/attribute.  Per signal, from an ObsTable and the elevation of
each (epoch, satellite):

- C/N0 (S observations) per elevation bin: mean, std, count;
- code noise by the multipath combination (Estey & Meertens 1999, "TEQC: the multipurpose toolkit for GPS/GLONASS
  data", GPS Solutions 3(1), eq. MP1/MP2):
  MP_i = P_i - (1 + 2/(a-1)) L_i + (2/(a-1)) L_j, a = (f_i/f_j)^2, phases L in metres; geometry, clocks and the
  first-order ionosphere cancel, leaving code multipath + code noise + a constant (ambiguities, hardware delays)
  per continuous arc.  The constant is removed per arc (arcs split at LLI bit 0 on either phase, gaps over
  ``GAP_INTERVALS`` intervals and jumps over ``JUMP_SIGMAS`` sigma of the epoch differences); the standard
  deviation of what remains per elevation bin and per C/N0 bin;
- track starts / ends with their C/N0, at a rise / set or away from it (core/calibration/track_events.py: the
  tracking thresholds);
- tracking arcs (the signal's code or C/N0 present, split at gaps): rise and set elevations (first / last epoch of
  arcs where the satellite rises / sets; an arc starting at the span's first epoch gives no rise, one ending at
  its last no set), C/N0 there;
- LLI: share of carrier phases with bit 0 (loss of lock) / bit 1 (half-cycle ambiguity) at the first epoch of the
  span and at arc starts (RINEX 3.05 section 5.7);
- the (epoch, satellite) pairs with a code observation above the elevation mask (Jaccard index between two
  receivers);
- the epoch-to-epoch C/N0 scatter: std of the first differences within arcs / sqrt(2) (jumps over
  ``CN0_JUMP_DB`` left out).

With a line-of-sight selection ``los`` ((E, S) bool, from a scene: ``gnss-sim calibrate --world | --mesh``) only
the samples of satellites in the line of sight enter the C/N0 bins, the C/N0 scatter (both epochs of a step) and
the code noise (the multipath combination of other samples is dropped before the arcs are formed); a rise / set
counts only where the satellite is in the line of sight at the arc's first / last epoch and at the epoch before /
after it (an arc that starts as the satellite clears a building is the scene's doing, not the receiver's
threshold).  The tracked pairs, LLI shares and code counts stay over every sample.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..rinex.obs_table import ObsTable
from ..signals import SIGNALS
from .arcs import arc_ends, arc_ids
from .reading import CALIBRATED_SYSTEMS
from .track_events import TrackEvents, track_events

#: a gap longer than this many epoch intervals ends an arc
GAP_INTERVALS = 2.0
#: a multipath-combination step larger than this many sigma (of the steps at that elevation) ends an arc
JUMP_SIGMAS = 5.0
#: arcs shorter than this (epochs) give no code-noise samples (their mean is not known well enough)
MIN_ARC_EPOCHS = 10
#: C/N0 steps larger than this [dB] are obstructions or re-acquisitions, not the receiver's scatter
CN0_JUMP_DB = 5.0
#: output steps of C/N0 receivers use, largest first [dB]
RESOLUTIONS_DB = (1.0, 0.5, 0.25, 0.1, 0.01)
#: C/N0 bins of the code noise [dB-Hz]
CN0_EDGES_DBHZ = np.arange(15.0, 61.0, 3.0)


@dataclass
class SignalStats:
    """Statistics of one signal (arrays over elevation bins ``el_edges_deg``)."""

    key: str                          #: "G1C"
    el_edges_deg: np.ndarray          #: (B+1,)
    cn0_mean_dbhz: np.ndarray         #: (B,) NaN where no sample
    cn0_std_db: np.ndarray
    cn0_n: np.ndarray                 #: (B,) samples
    mp_partner: str = ""              #: band/attribute of the second phase of the combination ("" = none)
    mp_sigma_m: np.ndarray | None = None      #: (B,) std of the arc-mean-removed combination
    mp_cn0_dbhz: np.ndarray | None = None     #: (B,) mean C/N0 of those samples
    mp_n: np.ndarray | None = None
    mp_sigma_by_cn0_m: np.ndarray | None = None   #: over CN0_EDGES_DBHZ bins
    mp_n_by_cn0: np.ndarray | None = None
    mp_all_sigma_m: float = math.nan          #: over every sample above the mask
    rise_el_deg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    set_el_deg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    rise_cn0_dbhz: np.ndarray = field(default_factory=lambda: np.zeros(0))
    set_cn0_dbhz: np.ndarray = field(default_factory=lambda: np.zeros(0))
    cn0_scatter_db: float = math.nan
    cn0_scatter_by_el_db: np.ndarray | None = None    #: (B,) the same per elevation bin
    cn0_scatter_n: np.ndarray | None = None           #: (B,) steps in each bin
    lli_first: dict = field(default_factory=dict)     #: {"n", "bit0", "bit1"} at the span's first epoch
    lli_arc_start: dict = field(default_factory=dict)  #: the same at arc starts (not at the span's start)
    tracked: np.ndarray | None = None    #: (E, S) bool: code observation at or above the mask
    n_code: int = 0                      #: code observations in the span (any elevation, known or not)
    #: with a line-of-sight selection: C/N0 samples with a known elevation, all / in the line of sight
    los_samples: tuple[int, int] | None = None
    #: C/N0 at track starts / ends, at rise / set or not (core/calibration/track_events.py; tracking thresholds)
    track_events: TrackEvents | None = None

    @property
    def system(self) -> str:
        return self.key[0]

    @property
    def code(self) -> str:
        return self.key[1:]

    @property
    def el_centres_deg(self) -> np.ndarray:
        return 0.5 * (self.el_edges_deg[:-1] + self.el_edges_deg[1:])

    def to_json(self) -> dict:
        def arr(a):
            return None if a is None else [None if not np.isfinite(v) else round(float(v), 4) for v in np.ravel(a)]

        return {"n_code": self.n_code, "el_edges_deg": arr(self.el_edges_deg), "cn0_mean_dbhz": arr(self.cn0_mean_dbhz),
                "cn0_std_db": arr(self.cn0_std_db), "cn0_n": [int(v) for v in self.cn0_n],
                "mp_partner": self.mp_partner, "mp_sigma_m": arr(self.mp_sigma_m), "mp_cn0_dbhz": arr(self.mp_cn0_dbhz),
                "mp_n": None if self.mp_n is None else [int(v) for v in self.mp_n],
                "mp_sigma_by_cn0_m": arr(self.mp_sigma_by_cn0_m), "cn0_edges_dbhz": arr(CN0_EDGES_DBHZ),
                "mp_all_sigma_m": arr([self.mp_all_sigma_m])[0],
                "rise_el_deg": arr(self.rise_el_deg), "set_el_deg": arr(self.set_el_deg),
                "rise_cn0_dbhz": arr(self.rise_cn0_dbhz), "set_cn0_dbhz": arr(self.set_cn0_dbhz),
                "cn0_scatter_db": arr([self.cn0_scatter_db])[0],
                "cn0_scatter_by_el_db": arr(self.cn0_scatter_by_el_db), "lli_first": self.lli_first,
                "lli_arc_start": self.lli_arc_start} | (
            {} if self.track_events is None else {"track_events": self.track_events.to_json()}) | (
            {} if self.los_samples is None else {"cn0_samples_all": self.los_samples[0],
                                                 "cn0_samples_line_of_sight": self.los_samples[1]})


@dataclass
class RecordingStats:
    """Per-signal statistics of one recording."""

    time: np.ndarray                  #: (E,) datetime64[ns]
    sv: np.ndarray                    #: (S,)
    mask_deg: float
    bin_deg: float
    interval_s: float
    signals: dict[str, SignalStats]
    #: {"n", "bit0", "bit1"} over every carrier phase of the span (does the receiver ever set the bits?)
    lli_all: dict = field(default_factory=dict)
    #: the step of the reported C/N0 values [dB] (0.25 Septentrio, 1 u-blox; 0: finer than 0.01 or none)
    cn0_resolution_db: float = 0.0
    #: the scene that selected the line-of-sight samples ("": none, every sample counts)
    scene: str = ""

    def lli_share(self, which: str = "lli_first") -> dict:
        """{"n", "bit0", "bit1"} summed over the signals (``which``: "lli_first" | "lli_arc_start")."""
        out = {"n": 0, "bit0": 0, "bit1": 0}
        for s in self.signals.values():
            for k_ in out:
                out[k_] += getattr(s, which).get(k_, 0)
        return out

    def to_json(self) -> dict:
        return {"first_epoch": str(self.time[0])[:19] if len(self.time) else "",
                "last_epoch": str(self.time[-1])[:19] if len(self.time) else "", "epochs": int(len(self.time)),
                "interval_s": self.interval_s, "mask_deg": self.mask_deg, "bin_deg": self.bin_deg,
                "lli_first": self.lli_share("lli_first"), "lli_arc_start": self.lli_share("lli_arc_start"),
                "lli_all": self.lli_all, "cn0_resolution_db": self.cn0_resolution_db,
                "signals": {k_: s.to_json() for k_, s in self.signals.items()}} | (
            {"line_of_sight_selected_by": self.scene} if self.scene else {})


# ---------------------------------------------------------------------------- building blocks
def remove_arc_means(x: np.ndarray, arcs: np.ndarray, min_len: int = MIN_ARC_EPOCHS) -> np.ndarray:
    """``x`` minus the mean of its arc; NaN outside arcs and in arcs shorter than ``min_len`` samples."""
    ok = arcs >= 0
    out = np.full(x.shape, np.nan)
    if not ok.any():
        return out
    a = arcs[ok]
    n = np.bincount(a)
    mean = np.bincount(a, weights=x[ok]) / np.maximum(n, 1)
    r = x[ok] - mean[a]
    r[n[a] < min_len] = np.nan
    out[ok] = r
    return out


def mp_combination(p_i_m, phi_i_m, phi_j_m, f_i_hz, f_j_hz):
    """Code multipath combination MP_i [m] (Estey & Meertens 1999): P_i - (1 + 2/(a-1)) L_i + (2/(a-1)) L_j,
    a = (f_i/f_j)^2, phases in metres (broadcasts)."""
    a = (np.asarray(f_i_hz, float) / np.asarray(f_j_hz, float)) ** 2
    return p_i_m - (1.0 + 2.0 / (a - 1.0)) * phi_i_m + (2.0 / (a - 1.0)) * phi_j_m


def _binned(x: np.ndarray, by: np.ndarray, edges: np.ndarray, fn: str = "mean"):
    """(value per bin, count per bin) of ``x`` binned by ``by`` (finite pairs only): fn "mean" | "std" | "rms"."""
    ok = np.isfinite(x) & np.isfinite(by) & (by >= edges[0]) & (by < edges[-1])
    b = np.clip(np.digitize(by[ok], edges) - 1, 0, len(edges) - 2)
    n = np.bincount(b, minlength=len(edges) - 1)
    s1 = np.bincount(b, weights=x[ok], minlength=len(edges) - 1)
    s2 = np.bincount(b, weights=x[ok] ** 2, minlength=len(edges) - 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = s1 / n
        if fn == "mean":
            v = mean
        elif fn == "rms":
            v = np.sqrt(s2 / n)
        else:
            v = np.sqrt(np.maximum(s2 / n - mean**2, 0.0))
    return np.where(n > 0, v, np.nan), n


def _lli_count(flags: np.ndarray) -> dict:
    f = np.asarray(flags, dtype=np.int64)
    return {"n": int(f.size), "bit0": int(np.sum(f & 1 > 0)), "bit1": int(np.sum(f & 2 > 0))}


def signal_keys(tab: ObsTable) -> list[str]:
    """Signals ("G1C") of the signal table (core/signals.py) with code or C/N0 observations of the calibrated
    systems, in the table's code order."""
    sysc = np.array([s[0] for s in tab.sv.tolist()])
    keys = []
    for code, a in tab.values.items():
        if code[0] not in "CS":
            continue
        for s in CALIBRATED_SYSTEMS:
            k_ = s + code[1:]
            cols = sysc == s
            if k_ not in keys and (s, code[1:]) in SIGNALS and cols.any() and np.isfinite(a[:, cols]).any():
                keys.append(k_)
    order = {s: i for i, s in enumerate(CALIBRATED_SYSTEMS)}
    return sorted(keys, key=lambda k_: (order[k_[0]], k_[1]))   # by system, band; stable: code order in a band


def _freq(tab: ObsTable, svs: list[str], code: str) -> np.ndarray:
    """Carrier [Hz] of ``code`` per satellite; NaN where the signal table does not know it (GLONASS L3 CDMA)."""
    out = []
    for s in svs:
        try:
            out.append(tab.frequency_hz(s, code))
        except ValueError:
            out.append(math.nan)
    return np.array(out, dtype=float)


def _mp_partners(tab: ObsTable, cols: np.ndarray, svs: list[str], code: str) -> list[str]:
    """Per satellite the other carrier phase of the combination ("" = none): among those of another frequency
    with at least 80 % of the epochs (together with L``code``) of the best, the one farthest in frequency
    (a = (f_i/f_j)^2 far from 1: close bands such as L5/L2 multiply the phases by 2/(a-1) = -24 and with them
    every phase error).  Chosen per satellite: BeiDou-2 and -3 share B1I and B3I but not B2I."""
    li = tab.values.get("L" + code)
    out = [""] * len(svs)
    if li is None:
        return out
    li = np.isfinite(li[:, cols])
    f_i = _freq(tab, svs, code)
    counts, seps, names = [], [], []
    for c in tab.values:
        if c[0] != "L" or c[1] == code[0]:
            continue
        f_j = _freq(tab, svs, c[1:])
        usable = np.isfinite(f_i) & np.isfinite(f_j) & ~np.isclose(f_i, f_j)
        counts.append(np.where(usable, (li & np.isfinite(tab.values[c][:, cols])).sum(axis=0), 0))
        with np.errstate(invalid="ignore", divide="ignore"):
            seps.append(np.where(usable, np.abs(np.log(f_i / f_j)), 0.0))
        names.append(c[1:])
    if not names:
        return out
    n, sep = np.array(counts), np.array(seps)          # (candidates, satellites)
    ok = (n > 0) & (n >= 0.8 * n.max(axis=0, keepdims=True))
    best = np.argmax(np.where(ok, sep, -1.0), axis=0)
    return [names[b] if ok[b, j] else "" for j, b in enumerate(best)]


# ---------------------------------------------------------------------------- the statistics
def signal_statistics(tab: ObsTable, el_deg: np.ndarray, interval_s: float | None = None, mask_deg: float = 5.0,
                      bin_deg: float = 5.0, los: np.ndarray | None = None, scene: str = "") -> RecordingStats:
    """Per-signal statistics of ``tab`` with ``el_deg`` ((E, S) elevation of ``tab.sv``, NaN unknown); ``los``:
    (E, S) bool line-of-sight selection (module docstring; None: every sample), ``scene`` its source's name."""
    if bin_deg <= 0 or 90.0 % bin_deg:
        raise ValueError(f"signal statistics: bin_deg {bin_deg!r} must divide 90")
    t_s = (tab.time - tab.time[0]).astype("timedelta64[ns]").astype(np.int64) / 1e9 if len(tab.time) else np.zeros(0)
    if interval_s is None or not interval_s > 0:
        steps = np.diff(t_s)
        interval_s = float(np.median(steps)) if steps.size else 1.0
    max_gap = GAP_INTERVALS * interval_s + 1e-3
    edges = np.arange(0.0, 90.0 + bin_deg / 2, bin_deg)
    sysc = np.array([s[0] for s in tab.sv.tolist()])
    out: dict[str, SignalStats] = {}
    n_e = len(tab.time)
    seen = np.zeros((n_e, len(tab.sv)), dtype=bool)        # the satellite observed on any signal (its passes)
    for a in tab.values.values():
        seen |= np.isfinite(a)
    for key in signal_keys(tab):
        system, code = key[0], key[1:]
        cols = sysc == system
        svs = tab.sv[cols].tolist()
        el = el_deg[:, cols]
        sel = None if los is None else los[:, cols]
        el_sel = el if sel is None else np.where(sel, el, np.nan)     # the samples the statistics take
        pr = tab.column("C" + code)[:, cols]
        cn0 = tab.column("S" + code)[:, cols]
        cn0_mean, n = _binned(cn0, el_sel, edges, "mean")
        cn0_std, _ = _binned(cn0, el_sel, edges, "std")
        st = SignalStats(key, edges, cn0_mean, cn0_std, n)
        if sel is not None:
            known = np.isfinite(cn0) & np.isfinite(el)
            st.los_samples = (int(known.sum()), int((known & sel).sum()))

        # tracking arcs: the signal's code or C/N0 present
        present = np.isfinite(pr) | np.isfinite(cn0)
        arcs = arc_ids(present, t_s, max_gap)
        first_ep, last_ep = arc_ends(arcs)
        longer = last_ep[:, 0] > first_ep[:, 0]
        el_a = el_sel[first_ep[:, 0], first_ep[:, 1]]
        el_a2 = el[np.minimum(first_ep[:, 0] + 1, n_e - 1), first_ep[:, 1]]
        el_b = el_sel[last_ep[:, 0], last_ep[:, 1]]
        el_b2 = el[np.maximum(last_ep[:, 0] - 1, 0), last_ep[:, 1]]
        rising = longer & (first_ep[:, 0] > 0) & (el_a2 > el_a)          # not at the span's start
        setting = longer & (last_ep[:, 0] < n_e - 1) & (el_b2 > el_b)    # not at the span's end
        if sel is not None:      # in the line of sight also the epoch before the rise / after the set
            rising &= sel[np.maximum(first_ep[:, 0] - 1, 0), first_ep[:, 1]]
            setting &= sel[np.minimum(last_ep[:, 0] + 1, n_e - 1), last_ep[:, 1]]
        st.rise_el_deg, st.set_el_deg = el_a[rising], el_b[setting]
        st.rise_cn0_dbhz = cn0[first_ep[rising, 0], first_ep[rising, 1]]
        st.set_cn0_dbhz = cn0[last_ep[setting, 0], last_ep[setting, 1]]
        st.track_events = track_events(present, cn0, el, t_s, max_gap, seen[:, cols], sel)

        # C/N0 scatter, epoch to epoch within arcs
        same = (arcs[1:] == arcs[:-1]) & (arcs[1:] >= 0)
        if sel is not None:
            same &= sel[1:] & sel[:-1]
        step = np.where(same, cn0[1:] - cn0[:-1], np.nan)
        step[np.abs(np.nan_to_num(step)) >= CN0_JUMP_DB] = np.nan
        d = step[np.isfinite(step)]
        st.cn0_scatter_db = float(np.std(d) / math.sqrt(2.0)) if d.size > 10 else math.nan
        sc, st.cn0_scatter_n = _binned(step, el[1:], edges, "std")
        st.cn0_scatter_by_el_db = sc / math.sqrt(2.0)

        # LLI at the first epoch and at arc starts
        lli = tab.lli.get("L" + code)
        phase = tab.column("L" + code)[:, cols]
        if lli is not None:
            lli = lli[:, cols]
            st.lli_first = _lli_count(lli[0][np.isfinite(phase[0])]) if n_e else _lli_count([])
            starts = first_ep[first_ep[:, 0] > 0]
            has = np.isfinite(phase[starts[:, 0], starts[:, 1]])
            st.lli_arc_start = _lli_count(lli[starts[has, 0], starts[has, 1]])
        st.tracked = np.isfinite(pr) & (el >= mask_deg)
        st.n_code = int(np.isfinite(pr).sum())

        # code noise by the multipath combination
        partners = _mp_partners(tab, cols, svs, code) if np.isfinite(pr).any() else [""] * len(svs)
        used = [p for p in partners if p]
        if used:
            st.mp_partner = "/".join(sorted(set(used), key=lambda p: -used.count(p)))
            _code_noise(st, tab, cols, svs, code, partners, pr, cn0, el, t_s, max_gap, mask_deg, sel)
        out[key] = st
    keep = np.isin(sysc, list(CALIBRATED_SYSTEMS))
    flags = [f[:, keep][np.isfinite(tab.column(c)[:, keep])] for c, f in tab.lli.items()]
    lli_all = _lli_count(np.concatenate(flags) if flags else np.zeros(0, np.int8))
    s_all = [a[:, keep][np.isfinite(a[:, keep])] for c, a in tab.values.items() if c[0] == "S"]
    res = cn0_resolution_db(np.concatenate(s_all) if s_all else np.zeros(0))
    return RecordingStats(tab.time, tab.sv, float(mask_deg), float(bin_deg), float(interval_s), out, lli_all, res,
                          scene if los is not None else "")


def cn0_resolution_db(values: np.ndarray) -> float:
    """The largest of RESOLUTIONS_DB that every C/N0 value is a multiple of (0.0: none)."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if v.size < 10:
        return 0.0
    for q in RESOLUTIONS_DB:
        if np.all(np.abs(v / q - np.round(v / q)) < 1e-3):
            return q
    return 0.0


def _code_noise(st: SignalStats, tab, cols, svs, code, partners, pr, cn0, el, t_s, max_gap, mask_deg,
                sel=None) -> None:
    from .. import constants as k

    f_i = _freq(tab, svs, code)[None, :]
    phi_i = tab.column("L" + code)[:, cols] * (k.C_MPS / f_i)
    mp = np.full(pr.shape, np.nan)
    lli_i = tab.lli.get("L" + code)
    breaks = ((lli_i[:, cols] & 1) > 0) if lli_i is not None else np.zeros(pr.shape, dtype=bool)
    for p in set(partners) - {""}:
        j = np.array([q == p for q in partners])
        f_j = _freq(tab, svs, p)[None, :]
        phi_j = tab.column("L" + p)[:, cols] * (k.C_MPS / f_j)
        mp[:, j] = mp_combination(pr, phi_i, phi_j, f_i, f_j)[:, j]
        lli_j = tab.lli.get("L" + p)
        if lli_j is not None:
            breaks[:, j] |= (lli_j[:, cols][:, j] & 1) > 0
    if sel is not None:
        mp[~sel] = np.nan         # only line-of-sight samples: the arcs end where the scene blocks the satellite
    valid = np.isfinite(mp)
    arcs = arc_ids(valid, t_s, max_gap, breaks)
    # jumps: steps over JUMP_SIGMAS robust sigma of the steps in the same 10-deg elevation band
    step = np.full(mp.shape, np.nan)
    same = (arcs[1:] == arcs[:-1]) & (arcs[1:] >= 0)
    step[1:][same] = (mp[1:] - mp[:-1])[same]
    band = np.clip(np.floor(np.nan_to_num(el, nan=0.0) / 10.0), 0, 8).astype(int)
    jump = np.zeros(mp.shape, dtype=bool)
    for b in range(9):
        m = (band == b) & np.isfinite(step)
        if m.sum() < 10:
            continue
        s = step[m]
        sig = 1.4826 * np.median(np.abs(s - np.median(s)))
        if sig > 0:
            jump[m] = np.abs(s) > JUMP_SIGMAS * sig
    if jump.any():
        arcs = arc_ids(valid, t_s, max_gap, breaks | jump)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        r = remove_arc_means(mp, arcs)
    st.mp_sigma_m, st.mp_n = _binned(r, el, st.el_edges_deg, "rms")
    st.mp_cn0_dbhz, _ = _binned(np.where(np.isfinite(r), cn0, np.nan), el, st.el_edges_deg, "mean")
    above = np.where(el >= mask_deg, r, np.nan)
    st.mp_sigma_by_cn0_m, st.mp_n_by_cn0 = _binned(above, cn0, CN0_EDGES_DBHZ, "rms")
    a = above[np.isfinite(above)]
    st.mp_all_sigma_m = float(np.sqrt(np.mean(a**2))) if a.size else math.nan
