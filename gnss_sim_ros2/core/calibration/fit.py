"""A receiver profile (the YAML schema of the receiver profiles, version 1) fitted from per-signal statistics.

What is fitted and how:

- ``signals``: the signals of the file with pseudoranges, per system (RINEX codes the signal table knows; also
  where the navigation data give no elevation);
- ``link_budget.cn0_table_dbhz``: per signal the mean C/N0 of each elevation bin with at least
  ``MIN_BIN_SAMPLES`` samples, made non-decreasing with elevation (weighted pool-adjacent-violators: the
  receiver's C/N0 rises with elevation; what breaks it is noise of few samples or one satellite), bins the signal
  does not reach are filled with the shape of the best-covered signal of the same system, else of GPS on the
  same code, else of the best-covered signal (offset matched at the nearest fitted bin), 0 deg extrapolated
  from the two lowest bins (slope 0 to ``MAX_LOW_SLOPE_DB_PER_DEG``), 90 deg held from the highest;
- ``code_multipath_m``: per signal and elevation bin the multipath-combination sigma minus the DLL thermal noise
  in quadrature (receiver/noise.code_sigma_m as the engine draws it, at the bin's mean C/N0 with the profile's
  DLL bandwidth, correlator spacing, integration time and front end), floored at 0, made non-increasing with
  elevation (pool-adjacent-violators); bins beyond the signal's range filled like the C/N0 (the reference's
  shape scaled);
- ``tracking``: acquisition / tracking thresholds where the receiver itself starts and ends its tracks
  (event_thresholds): per system's first signal the ``TAIL_PERCENT`` (5th) percentile of the C/N0 at its track
  starts / ends away from a rise / set (core/calibration/track_events.py: reacquisitions after a gap, losses while
  the satellite stays up; the rise and set of an open sky are the horizon's, not the receiver's), with at least
  ``MIN_TRACK_EVENTS`` of them; median over systems; the tracking threshold at least ``HYSTERESIS_DB`` under the
  acquisition one; with too few events in every system the lowest C/N0 the receiver holds (``HELD_PERCENT``, 5th,
  percentile over the first signals' tracks of each track's lowest C/N0), or the base profile's value where lower
  (the file only bounds it; with a scene the base profile's), said in the notes;
  ``aided_cn0_dbhz``: the lowest table C/N0 at which the other signals set (they are tracked aided by the
  first; aided_threshold);
  ``start`` warm when under ``COLD_LLI_SHARE`` of the phases carry LLI bit 0 at the first epoch;
  ``half_cycle_flags`` whether the file ever sets LLI bit 1;
- ``cn0_noise_db``: the epoch-to-epoch C/N0 scatter above ``ZENITH_SCATTER_EL_DEG`` (the profile's value is the
  zenith's; the engine grows it towards the horizon), quantisation removed; ``cn0_resolution_db``: the step of
  the reported C/N0 values;
- ``excluded_signals``: per signal the satellites transmitting it (signal plans) that the receiver never tracked
  on it while it tracked them on another signal (fit_excluded_signals);
- ``antenna``: choke_ring when the RINEX antenna type is a known choke-ring model, else patch;
- the DLL bandwidth, correlator spacing and front-end bandwidth cannot be separated from multipath with a
  recording: the DLL bandwidth is that of the built-in profile, lowered where its thermal noise would exceed
  the measured code noise (fit_dll_bn_hz); spacing and front end are those of the built-in profile of the receiver
  class (gnss_sim_ros2/profiles/: u-blox M8 / F9, else geodetic for several bands, single_frequency for one),
  named in ``description``.
"""
from __future__ import annotations

import math

import numpy as np

from ..receiver import cn0 as cn0_model
from ..receiver.noise import code_sigma_m
from ..receiver.profiles import filled_in
from ..signal_plans import default_plans, gps_day
from ..signals import SIGNALS
from .reading import gnss_times
from .signal_stats import RecordingStats, SignalStats
from .track_events import HELD_PERCENT, threshold_from_events

#: an elevation bin needs this many samples to enter a table
MIN_BIN_SAMPLES = 30
#: a table whose lowest bin lies above this elevation is extended down with the link budget's shape [deg]
LOW_SHAPE_EL_DEG = 10.0
#: largest slope used to extrapolate C/N0 from the lowest bin down to 0 deg [dB/deg]
MAX_LOW_SLOPE_DB_PER_DEG = 1.5
#: the DLL thermal noise may exceed the measured code noise in this share of the elevation bins (fit_dll_bn_hz)
DLL_EXCEED_SHARE = 0.05
#: arcs starting / ending above this elevation are re-acquisitions, not rises / sets (aided_threshold) [deg]
MAX_RISE_SET_EL_DEG = 30.0
#: a system's threshold needs this many track starts (ends) away from rise (set) on its first signal
MIN_TRACK_EVENTS = 15
#: the tracking threshold lies at least this far under the acquisition threshold [dB]
HYSTERESIS_DB = 1.0
#: a satellite tracked on other signals this many epochs but never on one is excluded from it (excluded_signals)
MIN_EXCLUDE_EPOCHS = 20
#: the zenith C/N0 scatter is measured at and above this elevation [deg]
ZENITH_SCATTER_EL_DEG = 60.0
#: at or above this share of phases with LLI bit 0 at the first epoch the recording starts cold
COLD_LLI_SHARE = 0.5
#: RINEX antenna types (IGS antenna names, first characters) of choke-ring antennas
CHOKE_RING_TYPES = ("ASH700936", "ASH701945", "ASH701946", "JAV_RINGANT", "JAVRINGANT", "LEIAR25", "LEIAT504",
                    "TRM29659", "TRM59800", "TRM159800", "SEPCHOKE", "AOAD/M_T", "NOV750", "JPSREGANT_DD")


def pava(y: np.ndarray, w: np.ndarray, increasing: bool = True) -> np.ndarray:
    """Weighted least-squares monotone fit of ``y`` (pool adjacent violators; Barlow et al. 1972)."""
    y = np.asarray(y, float) if increasing else -np.asarray(y, float)
    vals, wts, cnt = [], [], []
    for yi, wi in zip(y.tolist(), np.asarray(w, float).tolist()):
        vals.append(yi)
        wts.append(wi)
        cnt.append(1)
        while len(vals) > 1 and vals[-2] > vals[-1]:
            wsum = wts[-2] + wts[-1]
            v = (vals[-2] * wts[-2] + vals[-1] * wts[-1]) / wsum
            n = cnt[-2] + cnt[-1]
            del vals[-1], wts[-1], cnt[-1]
            vals[-1], wts[-1], cnt[-1] = v, wsum, n
    out = np.repeat(vals, cnt)
    return out if increasing else -out


def _antenna(antenna_type: str) -> str:
    t = antenna_type.strip().upper()
    return "choke_ring" if any(t.startswith(c) for c in CHOKE_RING_TYPES) else "patch"


def _traits_name(receiver_type: str, n_bands: int) -> str:
    r = receiver_type.upper().replace("-", "")
    if "M8" in r:
        return "ublox_m8t"
    if "F9" in r:
        return "ublox_f9p"
    return "geodetic" if n_bands > 1 else "single_frequency"


def _round(a, digits):
    return [round(float(v), digits) for v in a]


def dll_noise_m(key: str, cn0_dbhz, loops: dict):
    """DLL thermal code noise [m] of signal ``key`` ("G1C") as the receiver engine draws it (receiver/noise.py
    code_sigma_m: chip length, BOC factor, front end) with the loop fields of ``loops`` (a profile)."""
    return code_sigma_m(key[0], key[1:], cn0_dbhz, float(loops["dll_bn_hz"]), float(loops["dll_spacing_chips"]),
                        float(loops.get("dll_t_int_s") or 0.02), loops.get("frontend_bandwidth_hz"))


def _cn0_bins(st: SignalStats) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    ok = (st.cn0_n >= MIN_BIN_SAMPLES) & np.isfinite(st.cn0_mean_dbhz)
    return st.el_centres_deg[ok], st.cn0_mean_dbhz[ok], st.cn0_n[ok]


def _fill(own: dict, refs: list[dict], centres, ratio: bool) -> dict:
    """``own`` (elevation -> value) completed beyond its covered range from the first of ``refs`` that has the bin:
    the reference's value shifted (``ratio`` False) or scaled (True) to agree at ``own``'s nearest end bin."""
    out = dict(own)
    lo, hi = min(own), max(own)
    for c in centres:
        if c in out or lo <= c <= hi:
            continue                    # a hole inside the covered range: the consumer interpolates across it
        anchor = hi if c > hi else lo
        for ref in refs:
            if c in ref and anchor in ref:
                if ratio:
                    out[c] = ref[c] * (own[anchor] / ref[anchor]) if ref[anchor] > 0 else own[anchor]
                else:
                    out[c] = ref[c] + (own[anchor] - ref[anchor])
                break
    return out


def cn0_bins_monotone(st: SignalStats) -> dict:
    """elevation -> C/N0 of the usable bins, non-decreasing (weighted PAVA)."""
    el, y, n = _cn0_bins(st)
    return dict(zip(el.tolist(), pava(y, n, increasing=True).tolist())) if len(el) >= 2 else {}


def link_budget_shape_db(el_deg, antenna: str, system: str = "G", code: str = "1C") -> np.ndarray:
    """C/N0 of the link budget (receiver/cn0.py: the signal's power, the satellites' shaped beam, the antenna
    class's gain per elevation) at ``el_deg`` [dB-Hz], for a MEO satellite (26 560 km orbit radius, GPS)."""
    el = np.asarray(el_deg, dtype=float)
    r_sat_m = 26_560e3
    budget = cn0_model.LinkBudget(antenna=antenna)
    return cn0_model.cn0_dbhz(system, code, cn0_model.slant_range_m(r_sat_m, el), el, sat_radius_m=r_sat_m,
                              budget=budget)


def fit_cn0_table(st: SignalStats, references: list[SignalStats] = (), antenna: str | None = None) -> dict | None:
    """{"el_deg": [...], "cn0_dbhz": [...]} of one signal (None: fewer than two usable bins); bins beyond its
    range from the first of ``references`` covering them (their shape, offset to agree at the end bin); below the
    lowest bin: with an ``antenna`` class and the lowest bin above LOW_SHAPE_EL_DEG, the link budget's elevation
    shape for that class (an urban drive sees no low satellite in the line of sight), else a linear slope."""
    table = cn0_bins_monotone(st)
    if len(table) < 2:
        return None
    table = _fill(table, [cn0_bins_monotone(r) for r in references if r is not st], st.el_centres_deg.tolist(),
                  ratio=False)
    els = np.array(sorted(table))
    vals = pava(np.array([table[e] for e in els]), np.ones(len(els)), increasing=True)
    slope = (vals[1] - vals[0]) / (els[1] - els[0])
    slope = min(max(slope, 0.0), MAX_LOW_SLOPE_DB_PER_DEG)
    if antenna is not None and els[0] > LOW_SHAPE_EL_DEG:
        low = np.arange(0.0, els[0] - 1e-9, float(st.el_edges_deg[1] - st.el_edges_deg[0]))   # 0, 5, ... [deg]
        shape = link_budget_shape_db(np.r_[low, els[0]], antenna, st.key[0], st.key[1:])
        els, vals = np.r_[low, els], np.r_[vals[0] + shape[:-1] - shape[-1], vals]
    elif els[0] > 0:
        els, vals = np.r_[0.0, els], np.r_[vals[0] - slope * els[0], vals]
    if els[-1] < 90:
        els, vals = np.r_[els, 90.0], np.r_[vals, vals[-1]]
    return {"el_deg": _round(els, 1), "cn0_dbhz": _round(vals, 2)}


def _mp_bins(st: SignalStats) -> np.ndarray:
    if st.mp_sigma_m is None:
        return np.zeros(len(st.el_centres_deg), dtype=bool)
    return (st.mp_n >= MIN_BIN_SAMPLES) & np.isfinite(st.mp_sigma_m) & np.isfinite(st.mp_cn0_dbhz)


def fit_dll_bn_hz(stats: list[SignalStats], loops: dict) -> float:
    """The DLL bandwidth: ``loops["dll_bn_hz"]`` or less, so that the DLL thermal noise (dll_noise_m, which grows
    as sqrt(B_n)) stays within the measured code noise in all but DLL_EXCEED_SHARE of the usable bins."""
    r2 = []
    for st in stats:
        ok = _mp_bins(st)
        if ok.any():
            dll = dll_noise_m(st.key, st.mp_cn0_dbhz[ok], loops)
            r2.append((st.mp_sigma_m[ok] / dll) ** 2)
    bn_hz = float(loops["dll_bn_hz"])
    if not r2:
        return bn_hz
    q = float(np.quantile(np.concatenate(r2), DLL_EXCEED_SHARE))
    return bn_hz if q >= 1.0 else float(f"{bn_hz * q:.2g}")


def fit_code_multipath(st: SignalStats, loops: dict, references: list[SignalStats] = ()) -> dict | None:
    """{"el_deg": [...], "sigma_m": [...]}: multipath-combination sigma minus DLL thermal noise in quadrature,
    non-increasing with elevation (None: no bins); bins beyond its range from the first of ``references``
    covering them (their shape, scaled to agree at the end bin)."""
    def bins(s: SignalStats) -> dict:
        ok = _mp_bins(s)
        if not ok.any():
            return {}
        el, sig, cn0, n = s.el_centres_deg[ok], s.mp_sigma_m[ok], s.mp_cn0_dbhz[ok], s.mp_n[ok]
        dll = dll_noise_m(s.key, cn0, loops)
        mp = np.maximum(pava(np.sqrt(np.maximum(sig**2 - dll**2, 0.0)), n, increasing=False), 0.0)
        return dict(zip(el.tolist(), mp.tolist()))

    own = bins(st)
    if not own:
        return None
    table = _fill(own, [bins(r) for r in references if r is not st], st.el_centres_deg.tolist(), ratio=True)
    el = np.array(sorted(table))
    mp = np.maximum(pava(np.array([table[e] for e in el]), np.ones(len(el)), increasing=False), 0.0)
    if el[0] > 0:
        el, mp = np.r_[0.0, el], np.r_[mp[0], mp]
    if el[-1] < 90:
        el, mp = np.r_[el, 90.0], np.r_[mp, mp[-1]]
    return {"el_deg": _round(el, 1), "sigma_m": _round(mp, 3)}


def _references(stats: RecordingStats, key: str, score) -> list[SignalStats]:
    """Signals whose shape fills the bins ``key`` does not reach: the best-covered of its system, GPS on the same
    code, the best-covered of all (``score(st)`` orders them)."""
    sigs = stats.signals
    same_sys = [s for k_, s in sigs.items() if k_[0] == key[0]]
    out = [max(same_sys, key=score)] if same_sys else []
    if "G" + key[1:] in sigs:
        out.append(sigs["G" + key[1:]])
    if sigs:
        out.append(max(sigs.values(), key=score))
    return out


def zenith_cn0_scatter_db(stats: RecordingStats) -> float:
    """Epoch-to-epoch C/N0 scatter at and above ZENITH_SCATTER_EL_DEG (all signals pooled, weighted by steps),
    the output resolution's share (q^2/12 per value) removed: the receiver's ``cn0_noise_db`` (its zenith value;
    receiver/code_multipath.py fading_scale grows it towards the horizon)."""
    s2 = n = 0.0
    for st in stats.signals.values():
        if st.cn0_scatter_by_el_db is None:
            continue
        ok = (st.el_centres_deg >= ZENITH_SCATTER_EL_DEG) & np.isfinite(st.cn0_scatter_by_el_db)
        s2 += float(np.sum(st.cn0_scatter_by_el_db[ok] ** 2 * st.cn0_scatter_n[ok]))
        n += float(np.sum(st.cn0_scatter_n[ok]))
    if n < MIN_BIN_SAMPLES:
        return math.nan
    return math.sqrt(max(s2 / n - stats.cn0_resolution_db**2 / 12.0, 0.0))


def event_thresholds(stats: RecordingStats, signals: dict, base_tracking: dict | None = None
                     ) -> tuple[float, float, list[str]]:
    """(acquisition, tracking) thresholds [dB-Hz] and notes: per system, its first signal's TAIL_PERCENT percentile
    of the C/N0 at track starts / ends away from rise and set (track_events.py) with at least MIN_TRACK_EVENTS of
    them, the median over systems.  A threshold no system gives enough events for falls back to the lowest C/N0 the
    receiver holds (median over systems of track_events' lowest_held_dbhz): the receiver held that, so its threshold
    is at most there; the ``base_tracking`` profile's value where it is lower (the file does not say it is higher:
    a short span whose tracks never reach the receiver's limit); with a line-of-sight selection (a scene) the
    base profile's value.  A note says which (NaN: no C/N0 at all)."""
    acq, trk, held, n_starts, n_ends = [], [], [], 0, 0
    for sys_, codes in signals.items():
        st = stats.signals.get(sys_ + codes[0])
        ev = None if st is None else st.track_events
        if ev is None:
            continue
        n_starts, n_ends = n_starts + ev.acquisitions_dbhz.size, n_ends + ev.losses_dbhz.size
        acq.append(threshold_from_events(ev.acquisitions_dbhz, MIN_TRACK_EVENTS))
        trk.append(threshold_from_events(ev.losses_dbhz, MIN_TRACK_EVENTS))
        held.append(ev.lowest_held_dbhz)
    notes, out = [], []
    low = _median(held)
    for vals, field, what, n in ((acq, "acquisition_cn0_dbhz", "track starts after a gap", n_starts),
                                 (trk, "tracking_cn0_dbhz", "track ends", n_ends)):
        v = _median(vals)
        base_v = (base_tracking or {}).get(field)
        if not np.isfinite(v) and stats.scene and base_v is not None:
            # the scene's line of sight keeps weak tracks the model calls clear (HK drive: 13 dB-Hz): no bound
            v = float(base_v)
            notes.append(f"tracking.{field}: {n} {what} away from rise / set in the line of sight on the systems' "
                         f"first signals, fewer than {MIN_TRACK_EVENTS} on each: set to the base profile's "
                         f"{base_v:g} dB-Hz")
        elif not np.isfinite(v) and np.isfinite(low):
            v = low
            why = (f"the lowest C/N0 the receiver holds ({HELD_PERCENT:g} % percentile over its tracks of each "
                   f"track's lowest C/N0), {low:.1f} dB-Hz")
            if base_v is not None and float(base_v) < low:
                v = float(base_v)
                why = f"the base profile's {base_v:g} dB-Hz (under the lowest C/N0 the receiver holds, {low:.1f})"
            notes.append(f"tracking.{field}: {n} {what} away from rise / set on the systems' first signals, fewer "
                         f"than {MIN_TRACK_EVENTS} on each (an open sky's tracks start and end at the horizon): "
                         f"set to {why}")
        out.append(v)
    return out[0], out[1], notes


def aided_threshold(stats: RecordingStats, signals: dict, cn0_table: dict) -> float:
    """``tracking.aided_cn0_dbhz`` [dB-Hz]: the lowest, over the signals after each system's first, of the signal's
    fitted C/N0 table at the median elevation of its setting arcs below MAX_RISE_SET_EL_DEG, so that each sets no
    later than the real one (ESBC: L2 P(Y) as the PolaRx5 reports it sets at about 13 dB-Hz); NaN without any."""
    out = []
    for sys_, codes in signals.items():
        for code in codes[1:]:
            st, tab = stats.signals.get(sys_ + code), cn0_table.get(sys_ + code)
            if st is None or tab is None:
                continue
            el = np.asarray(st.set_el_deg, dtype=float)
            el = el[np.isfinite(el) & (el < MAX_RISE_SET_EL_DEG)]
            if el.size:
                out.append(float(np.interp(np.median(el), tab["el_deg"], tab["cn0_dbhz"])))
    return min(out) if out else math.nan


def fit_excluded_signals(stats: RecordingStats, signals: dict) -> dict:
    """{signal key: regular expression of the satellites the receiver did not track it on}: satellites tracked on
    another signal of their system above the mask for at least MIN_EXCLUDE_EPOCHS epochs, never on this one,
    although their signal plan (core/signal_plans: generation by PRN and date) says they transmit it; e.g. a
    receiver configured without B3I on BeiDou-3 (ESBC 2020-177, PolaRx5 5.2.0: C6I on BeiDou-2 only)."""
    if not len(stats.time):
        return {}
    day = gps_day(int(gnss_times(stats.time[:1]).sec[0]))
    plans = default_plans()
    out = {}
    for sys_, codes in signals.items():
        svs = [sv for sv in stats.sv.tolist() if sv[0] == sys_]
        own = {c: stats.signals[sys_ + c].tracked for c in codes
               if sys_ + c in stats.signals and stats.signals[sys_ + c].tracked is not None}
        if not own:
            continue
        seen = np.sum(np.logical_or.reduce(list(own.values())), axis=0)
        for code, tr in own.items():
            n = tr.sum(axis=0)
            if not n.any():
                continue
            skip = [sv for j, sv in enumerate(svs) if seen[j] >= MIN_EXCLUDE_EPOCHS and n[j] == 0
                    and plans.codes(sv, (code,), day)]
            if skip:
                out[sys_ + code] = "|".join(skip)
    return out


def _median(values) -> float:
    v = np.array([x for x in values if x is not None and np.isfinite(x)], dtype=float)
    return float(np.median(v)) if v.size else math.nan


def fit_profile(stats: RecordingStats, header: dict, source_file: str, name: str | None = None,
                base_profile: str | None = None) -> tuple[dict, list]:
    """(profile dict in the YAML schema, notes): what could not be fitted and why, for the report.
    ``base_profile``: the built-in profile of the receiver's class (default: guessed from the RINEX header's
    receiver type); its loops and front end are used, and its tracking thresholds where they lie under what the
    recording bounds them by (event_thresholds)."""
    notes: list[str] = []
    signals: dict[str, list[str]] = {}
    for key, st in stats.signals.items():
        if st.n_code and (key[0], key[1:]) in SIGNALS:
            signals.setdefault(key[0], []).append(key[1:])
    if not signals:
        raise ValueError(f"{source_file}: no pseudoranges of a signal the simulator knows: nothing to fit")
    n_bands = max(len({c[0] for c in codes}) for codes in signals.values())
    traits_name = base_profile or _traits_name(header.get("receiver_type", ""), n_bands)
    base = filled_in(traits_name)
    loops = {f: base.get(f) for f in ("dll_bn_hz", "dll_spacing_chips", "dll_t_int_s", "frontend_bandwidth_hz")}
    bn_hz = float(loops["dll_bn_hz"])
    has_cn0 = any((st.cn0_n > 0).any() for st in stats.signals.values())

    antenna = _antenna(header.get("antenna_type", "")) if header.get("antenna_type", "").strip() else \
        base.get("antenna") or _antenna("")
    cn0_table = {}
    if has_cn0:
        for key, st in stats.signals.items():
            if key[1:] not in signals.get(key[0], []):
                continue
            t = fit_cn0_table(st, _references(stats, key, lambda s: (len(cn0_bins_monotone(s)), int(s.cn0_n.sum()))),
                              antenna)
            if t is None:
                notes.append(f"{key}: fewer than two elevation bins with {MIN_BIN_SAMPLES} C/N0 samples: no C/N0 table")
            else:
                cn0_table[key] = t
    else:
        notes.append("the file has no C/N0 (S) observations: C/N0 cannot be fitted (no link_budget.cn0_table_dbhz, "
                     "no tracking thresholds, no cn0_noise_db); still fitted: signals, code multipath (with the DLL "
                     "noise at 45 dB-Hz), LLI behaviour, rinex, antenna")
    for st in stats.signals.values():
        if not has_cn0 and st.mp_sigma_m is not None:
            st.mp_cn0_dbhz = np.where(np.isfinite(st.mp_sigma_m), 45.0, np.nan)
    fitted = [st for k_, st in stats.signals.items() if k_[1:] in signals.get(k_[0], [])]
    bn_fit = fit_dll_bn_hz(fitted, loops)
    if bn_fit < bn_hz:
        notes.append(f"dll_bn_hz {bn_fit:g} Hz instead of the {traits_name} profile's {bn_hz:g} Hz: with it the DLL "
                     f"thermal noise would exceed the measured code noise in more than {100 * DLL_EXCEED_SHARE:g} % "
                     "of the elevation bins")
        loops["dll_bn_hz"] = bn_hz = bn_fit
    code_mp = {}
    for st in fitted:
        key = st.key
        t = fit_code_multipath(st, loops, _references(stats, key, lambda s: int(_mp_bins(s).sum())))
        if t is None:
            why = "no second carrier phase for the multipath combination" if not st.mp_partner else \
                f"fewer than {MIN_BIN_SAMPLES} multipath-combination samples in every bin"
            notes.append(f"{key}: {why}: no code_multipath_m")
        else:
            code_mp[key] = t

    tracking: dict = {}
    if has_cn0:
        acq, trk, t_notes = event_thresholds(stats, signals, base.get("tracking"))
        notes += t_notes
        if np.isfinite(acq) and np.isfinite(trk):
            tracking["acquisition_cn0_dbhz"] = round(acq, 1)
            tracking["tracking_cn0_dbhz"] = round(min(trk, acq - HYSTERESIS_DB), 1)
            aided = aided_threshold(stats, signals, cn0_table)
            if np.isfinite(aided) and aided < tracking["tracking_cn0_dbhz"]:
                tracking["aided_cn0_dbhz"] = round(aided, 1)
    first = stats.lli_share("lli_first")
    if first["n"]:
        tracking["start"] = "cold" if first["bit0"] / first["n"] >= COLD_LLI_SHARE else "warm"
    else:
        notes.append("no LLI flags in the file (RINEX 2 or no carrier phase): tracking.start not fitted")
    if stats.lli_all.get("n"):
        tracking["half_cycle_flags"] = bool(stats.lli_all["bit1"] > 0)

    t0, t1 = str(stats.time[0])[:19], str(stats.time[-1])[:19]
    prof: dict = {
        "gnss_sim_profile": 1,
        "name": name or "calibrated",
        "description": (f"{header.get('receiver_type') or 'receiver'} with "
                        f"{header.get('antenna_type', '').strip() or 'antenna'}, fitted from a recording; correlator "
                        f"spacing and front end of the built-in profile {traits_name}, DLL bandwidth at most "
                        "that profile's"),
        "source": f"fitted by gnss-sim calibrate on {source_file}, span {t0} .. {t1} GPS",
        "signals": signals,
        "antenna": antenna,
        "rinex": {"receiver_type": header.get("receiver_type", ""), "antenna_type": header.get("antenna_type", "")},
        "frontend_bandwidth_hz": float(loops["frontend_bandwidth_hz"]),
        "dll_bn_hz": bn_hz,
        "dll_spacing_chips": float(loops["dll_spacing_chips"]),
        "dll_t_int_s": float(loops.get("dll_t_int_s") or 0.02),
    }
    scatter = zenith_cn0_scatter_db(stats)
    if np.isfinite(scatter):
        prof["cn0_noise_db"] = round(scatter, 2)
    if stats.cn0_resolution_db > 0:
        prof["cn0_resolution_db"] = stats.cn0_resolution_db
    if code_mp:
        prof["code_multipath_m"] = code_mp
    excluded = fit_excluded_signals(stats, signals)
    if excluded:
        prof["excluded_signals"] = excluded
    if tracking:
        prof["tracking"] = tracking
    if cn0_table:
        prof["link_budget"] = {"cn0_table_dbhz": cn0_table}
    return prof, notes
