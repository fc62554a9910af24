"""The C/N0 the receiver profile would report, predicted per satellite from the planner's cast: the planner's "good".

Per antenna row and satellite above the mask (the profile's first signal of the satellite's system):

- line of sight / attenuated: the receiver's own link budget, ``receiver/cn0.cn0_dbhz_from_params`` with the
  profile's ``link_budget`` (its antenna class, or its fitted ``cn0_table_dbhz``) at the satellite's range and
  elevation, less the cast's foliage + diffraction attenuation (the call the receiver engine makes in
  ``_signal_strength``, not a copy of it);
- with reflected paths (``--multipath nlos|full``): the composite amplitude of the direct signal and the scene's
  paths relative to the unobstructed line of sight (``multipath.composite.composite_errors``, the function the
  engine calls for its reflections) replaces the obstruction loss, as the engine does; a reflected-only satellite
  is then as strong as its reflections;
- blocked (or a reflected-only satellite without its paths): -inf, not received.

"Good" = predicted C/N0 >= ``good_cn0_dbhz`` (``gnss-sim plan --good-cn0-dbhz``, 35 dB-Hz by default: the
threshold the Hong Kong validation scores the real receiver with).  The prediction is the mean the link budget
gives: the receiver's C/N0 noise (``cn0_noise_db``) and the land-mobile-satellite fading are not drawn.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..constants import C_MPS
from ..receiver import cn0 as cn0_model
from ..receiver import signal_tables
from ..vocabulary import VisibilityState

#: default threshold of a "good" satellite [dB-Hz] (docs/PLANNING.md, the Hong Kong validation)
DEFAULT_GOOD_CN0_DBHZ = 35.0
#: entries computed at a time without reflected paths: 16,384 float64 = 128 kB a temporary, in the caches
COLUMN_BLOCK_ENTRIES = 1 << 14
#: elevation step of the slope bound [deg] (elevation_slope_db_per_deg)
SLOPE_STEP_DEG = 0.05
#: bound on |d(open-sky C/N0) / d(range)| x range [dB]: 20 log10(e) = 8.69 for the free-space loss, tripled for the
#: power's share and the edge range's dependence on the orbit radius (receiver/cn0.py: both below one)
RANGE_SLOPE_DB = 3.0 * 20.0 / np.log(10.0)


@dataclass
class Cn0Predictor:
    """Per system letter, the profile's first signal's link-budget parameters and the receiver's settings."""

    profile: str
    budget: cn0_model.LinkBudget
    signal: dict                 # system -> (edge power dBW, edge elevation deg, carrier Hz, table key, chip m)
    antenna: str
    dll_spacing_chips: float
    frontend_bandwidth_hz: float
    tracking_cn0_dbhz: float     # the profile's loss-of-lock threshold (a satellite below it is not tracked)

    def cn0_dbhz(self, systems, state, att_db, v, range_m, where=None) -> np.ndarray:
        """(M, S) predicted C/N0 [dB-Hz] of satellites ``systems`` (S,) for cast rows: ``state``, ``att_db``,
        ``v`` as VisibilityOptions.cast returns them, ``range_m`` (M, S) antenna-satellite distances.  -inf
        where not received or the profile does not track the system; NaN off ``where`` (M, S) (None: everywhere)."""
        sysv = np.asarray(systems)
        state = np.asarray(state)
        el = np.asarray(v.el_deg, float)
        att = np.asarray(att_db, float)
        sel = np.ones(state.shape, bool) if where is None else np.asarray(where, bool)
        out = np.where(sel, -np.inf, np.nan)
        blocked = (state == int(VisibilityState.BLOCKED)) | (state == int(VisibilityState.REFLECTED_ONLY))
        paths = getattr(v, "paths", None)
        has = np.isfinite(np.asarray(paths.excess_m)).any(axis=-1) if paths is not None else np.zeros_like(sel)
        need = sel & (~blocked | has)                 # the entries with a signal: computed there only
        rng = np.asarray(range_m, float)
        if paths is None:                             # no reflected path: each system's columns whole (below)
            return self._by_columns(out, sysv, need, rng, el, att)
        for s in np.unique(sysv).tolist():
            if s not in self.signal:
                continue
            p_edge, el_min, freq, key, chip = self.signal[s]
            cols = np.flatnonzero(sysv == s)                  # the system's columns only: no (M, S) pass per system
            r, cc = np.nonzero(need[:, cols])
            if not len(r):
                continue
            c = cols[cc]
            rho = np.maximum(rng[r, c], 1.0)
            es = el[r, c]
            # the receiver's link budget at the unobstructed line of sight (engine._signal_strength's call)
            open_sky = cn0_model.cn0_dbhz_from_params(p_edge, el_min, rho, es, 0.0, budget=self.budget,
                                                      frequency_hz=freq, signal_keys=np.full(len(r), key))
            val = np.where(blocked[r, c], -np.inf, open_sky - att[r, c])
            if paths is not None:
                val = self._with_paths(val, open_sky, paths, r, c, blocked[r, c], att[r, c], es, chip, freq)
            out[r, c] = val
        return out

    def _by_columns(self, out, sysv, need, rng, el, att):
        """``out`` with the C/N0 of the entries ``need`` (M, S), none of them blocked: each system's needed entries
        by flat index (one pass to find them, one take per input, one put of the result; the entries below the
        mask, absent or blocked are not computed), ``COLUMN_BLOCK_ENTRIES`` at a time; the same element-wise
        arithmetic on contiguous float64, so the same numbers."""
        n_s = need.shape[1]
        rng_f, el_f, att_f = (np.asarray(x, float).reshape(-1) for x in (rng, el, att))
        out_f = np.ascontiguousarray(out).reshape(-1)          # ``out`` itself when contiguous (np.where's)
        for s in np.unique(sysv).tolist():
            if s not in self.signal:
                continue
            p_edge, el_min, freq, key, _ = self.signal[s]
            cols = np.flatnonzero(sysv == s)
            run = cols[-1] - cols[0] + 1 == len(cols)          # a run of columns (the planner's: sorted by system)
            sub = need[:, cols[0]:cols[-1] + 1] if run else need[:, cols]
            r = np.repeat(np.arange(len(sub)), np.count_nonzero(sub, axis=1))   # each entry's row: no division
            c = np.flatnonzero(sub) - r * len(cols)
            flat = r * n_s + (cols[0] + c if run else cols[c])
            for i0 in range(0, len(flat), COLUMN_BLOCK_ENTRIES):   # the temporaries stay in the caches
                f = flat[i0:i0 + COLUMN_BLOCK_ENTRIES]
                out_f[f] = self.open_sky_dbhz(s, rng_f.take(f), el_f.take(f)) - att_f.take(f)
        return out_f.reshape(out.shape)

    def open_sky_dbhz(self, system: str, range_m, el_deg) -> np.ndarray:
        """Unobstructed C/N0 [dB-Hz] of ``system``'s first signal at distances ``range_m`` and elevations ``el_deg``
        (1-D, same length; the receiver's link budget, as :meth:`cn0_dbhz` computes it); -inf for a system the
        profile does not track."""
        if system not in self.signal:
            return np.full(len(range_m), -np.inf)
        p_edge, el_min, freq, key, _ = self.signal[system]
        table = bool(self.budget.cn0_table_dbhz)
        with np.errstate(invalid="ignore", divide="ignore"):
            return cn0_model.cn0_dbhz_from_params(p_edge, el_min, np.maximum(range_m, 1.0), el_deg, 0.0,
                                                  budget=self.budget, frequency_hz=freq,
                                                  signal_keys=np.full(len(range_m), key) if table else None)

    def elevation_slope_db_per_deg(self, system: str) -> float:
        """Bound on |d(open-sky C/N0) / d(elevation)| [dB/deg] of ``system`` at any GNSS range: the largest
        difference quotient over 0..90 deg every SLOPE_STEP_DEG at 15,000..45,000 km (the antenna gain and the
        C/N0 tables are piecewise linear in elevation: a step inside a segment gives its slope; the power's
        smooth dependence through the orbit radius is sampled finely), doubled."""
        cache = self.__dict__.setdefault("_slopes", {})
        if system not in cache:
            if system not in self.signal:
                cache[system] = 0.0
            else:
                el = np.arange(0.0, 90.0 + SLOPE_STEP_DEG / 2, SLOPE_STEP_DEG)
                worst = 0.0
                for rho in np.linspace(1.5e7, 4.5e7, 7):
                    f = self.open_sky_dbhz(system, np.full(len(el), rho), el)
                    worst = max(worst, float(np.max(np.abs(np.diff(f)))) / SLOPE_STEP_DEG)
                cache[system] = 2.0 * worst
        return cache[system]

    def _with_paths(self, val, open_sky, paths, r, c, blocked, att, el, chip, freq):
        """Entries with a reflected path: open-sky C/N0 + 20 log10 |composite amplitude| (engine's reflections)."""
        from ..multipath.composite import composite_errors

        ex = np.asarray(paths.excess_m)[r, c]
        k = np.flatnonzero(np.isfinite(ex).any(axis=-1))
        if not len(k):
            return val
        los = np.where(blocked[k], 0.0, 10.0 ** (-att[k] / 20.0))
        n = len(k)
        e = composite_errors(los, ex[k], np.asarray(paths.gamma_co)[r[k], c[k]],
                             np.asarray(paths.gamma_cross)[r[k], c[k]], np.asarray(paths.arrival_el_deg)[r[k], c[k]],
                             el[k], np.full(n, chip), np.full(n, C_MPS / freq), self.dll_spacing_chips,
                             float(self.frontend_bandwidth_hz * chip / C_MPS), self.antenna)
        val = val.copy()
        val[k] = open_sky[k] + 20.0 * np.log10(np.maximum(e.amplitude, 1e-6))
        return val


def predictor_from_profile(profile: str, systems: str) -> Cn0Predictor:
    """The predictor of receiver profile ``profile`` (built-in name or file) for ``systems`` (its first signal of each
    system it tracks)."""
    from .. import signals as sig
    from ..receiver.config import ReceiverConfig

    cfg = ReceiverConfig(profile=profile)
    out = {}
    for s in systems:
        codes = cfg.profile.get(s) or []
        if not codes:
            continue
        code = codes[0]
        p_edge, el_min = cn0_model.power_params(s, code)
        key = signal_tables.signal_keys(np.array([s]), np.array([code]))[0]
        out[s] = (float(p_edge), float(el_min), float(sig.frequency_hz(s, code, 0)), str(key),
                  float(sig.signal(s, code).chip_length_m))
    return Cn0Predictor(str(profile), cfg.link_budget, out, cfg.antenna, float(cfg.dll_spacing_chips),
                        float(cfg.frontend_bandwidth_hz), float(cfg.tracking.tracking_cn0_dbhz))
