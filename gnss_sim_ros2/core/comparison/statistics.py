"""Differences sim - real: common receiver offsets removed, statistics, position errors."""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..frames import ecef_to_enu, ecef_to_geodetic
from ..metrics import p95, rms
from ..rinex.obs_table import REFERENCE_ORDER
from .pairing import SignalPair

#: observation kinds compared and their names in the report
KINDS = {"C": "code", "L": "phase", "D": "doppler", "S": "cn0"}
#: units of the differences per kind
UNITS = {"code": "m", "phase": "m", "doppler": "m/s", "cn0": "dB-Hz"}
DESCRIPTION = {
    "code": "pseudorange, sim - real, receiver clock and inter-system bias removed",
    "phase": "time-differenced carrier phase (delta range between consecutive common epochs), sim - real, "
             "receiver clock change removed",
    "doppler": "range rate from Doppler (-lambda D), sim - real, receiver clock drift removed",
    "cn0": "C/N0 (S observations), sim - real, nothing removed",
}
#: residuals beyond these count as gross errors: left out of the robust statistics (count, mean, RMS, std), counted;
#: the tails (:func:`tails`, nothing left out) are reported beside them, so that an NLOS range is never hidden
GROSS_LIMITS = {"code": 30.0, "phase": 5.0, "doppler": 10.0, "cn0": math.inf}
#: |residual| thresholds whose exceedance shares are reported [unit of the kind; m for code]
TAIL_THRESHOLDS_M = (10.0, 30.0, 100.0)


@dataclass
class KindResult:
    """Residuals of one kind (code, phase, doppler, cn0) over (common epoch, satellite)."""

    kind: str
    available: bool
    reason: str                                  #: why unavailable ("" when available)
    residuals: dict[SignalPair, np.ndarray]      #: pair -> (E, S) residual (NaN: none; gross ones kept)
    clock: np.ndarray | None = None              #: (E,) removed common offset of the reference system
    isb: dict[str, float] = field(default_factory=dict)   #: system -> constant removed on top of ``clock``
    ref_system: str = ""


def summary_stats(x: np.ndarray, gross: float) -> dict:
    """Robust statistics of the finite ``x`` within ``gross`` (count, mean, RMS, std, max) and the number beyond it;
    ``tails``: :func:`tails` of every finite value (what the robust ones leave out)."""
    x = np.asarray(x, dtype=float).ravel()
    x = x[np.isfinite(x)]
    bad = np.abs(x) > gross
    g = x[~bad]
    if g.size == 0:
        return {"n": 0, "n_gross": int(bad.sum()), "mean": math.nan, "rms": math.nan, "std": math.nan,
                "max_abs": math.nan, "tails": tails(x)}
    return {"n": int(g.size), "n_gross": int(bad.sum()), "mean": float(g.mean()),
            "rms": float(np.sqrt(np.mean(g**2))), "std": float(g.std()), "max_abs": float(np.abs(g).max()),
            "tails": tails(x)}


def tails(x) -> dict:
    """Count, RMS, mean, shares of |x| above each of :data:`TAIL_THRESHOLDS_M`, 95th / 99th percentile and maximum
    of |x| over every finite value (nothing excluded)."""
    x = np.asarray(x, dtype=float).ravel()
    x = x[np.isfinite(x)]
    out = {"n": int(x.size)}
    if not x.size:
        out.update({"mean": math.nan, "rms": math.nan, "p95_abs": math.nan, "p99_abs": math.nan,
                    "max_abs": math.nan})
        out.update({f"share_above_{t:g}": math.nan for t in TAIL_THRESHOLDS_M})
        return out
    a = np.abs(x)
    out.update({"mean": float(x.mean()), "rms": float(np.sqrt(np.mean(x**2))), "p95_abs": float(np.percentile(a, 95)),
                "p99_abs": float(np.percentile(a, 99)), "max_abs": float(a.max())})
    out.update({f"share_above_{t:g}": float(np.mean(a > t)) for t in TAIL_THRESHOLDS_M})
    return out


def remove_common_offsets(diffs: dict[SignalPair, np.ndarray], sys_of_col: np.ndarray, min_sats: int = 1):
    """Per-epoch receiver offset and per-system constant bias of sim - real differences.

    For each system the first pair in ``diffs`` is its reference signal; m_s(e) = median over the
    system's satellites.  Reference system r: the first of REFERENCE_ORDER with values; clock(e) = m_r(e)
    (epochs where r has none: median over other systems of m_s(e) - ISB_s); ISB_s = median over epochs of
    m_s(e) - m_r(e).  Returns (residuals, clock, isb, r): residual = d - clock(e) - ISB(system).
    """
    ref_pair: dict[str, SignalPair] = {}
    for p in diffs:
        if p.system not in ref_pair and np.isfinite(diffs[p]).any():
            ref_pair[p.system] = p
    if not ref_pair:
        e = next(iter(diffs.values())).shape[0] if diffs else 0
        return {p: d.copy() for p, d in diffs.items()}, np.full(e, np.nan), {}, ""
    n_e = next(iter(diffs.values())).shape[0]
    med = {}
    for s, p in ref_pair.items():
        d = diffs[p][:, sys_of_col == s]
        cnt = np.isfinite(d).sum(axis=1)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            m = np.nanmedian(d, axis=1) if d.shape[1] else np.full(n_e, np.nan)
        med[s] = np.where(cnt >= min_sats, m, np.nan)
    r = max((s for s in REFERENCE_ORDER if s in med), key=lambda s: (np.isfinite(med[s]).sum(),
                                                                     -REFERENCE_ORDER.index(s)))
    isb = {r: 0.0}
    for s, m in med.items():
        if s != r:
            both = np.isfinite(m) & np.isfinite(med[r])
            isb[s] = float(np.median(m[both] - med[r][both])) if both.any() else math.nan
    clock = med[r].copy()
    miss = ~np.isfinite(clock)
    if miss.any():
        others = [med[s] - isb[s] for s in med if s != r and np.isfinite(isb[s])]
        if others:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                fill = np.nanmedian(np.vstack(others), axis=0)
            clock[miss] = fill[miss]
    # a system never seen together with the reference: its own per-epoch median
    res = {}
    for p, d in diffs.items():
        b = isb.get(p.system, math.nan)
        off = clock + b if np.isfinite(b) else med.get(p.system, np.full(n_e, np.nan))
        res[p] = d - off[:, None]
    return res, clock, isb, r


def enu_errors_m(pos_ecef_m: np.ndarray, ref_ecef_m: np.ndarray) -> np.ndarray:
    """(E, 3) east, north, up of ``pos`` relative to ``ref`` ((3,) or (E, 3)), ENU at each reference point."""
    ref = np.broadcast_to(np.asarray(ref_ecef_m, float), pos_ecef_m.shape)
    out = np.full(pos_ecef_m.shape, np.nan)
    ok = np.all(np.isfinite(pos_ecef_m), axis=1) & np.all(np.isfinite(ref), axis=1)
    for i in np.flatnonzero(ok):
        lat, lon, h = ecef_to_geodetic(*ref[i])
        out[i] = ecef_to_enu(pos_ecef_m[i], lat, lon, h)
    return out


def position_stats(enu: np.ndarray) -> dict:
    ok = np.all(np.isfinite(enu), axis=1)
    e = enu[ok]
    if not len(e):
        return {"n": 0}
    hz = np.hypot(e[:, 0], e[:, 1])
    return {"n": int(ok.sum()), "mean_e_m": float(e[:, 0].mean()), "mean_n_m": float(e[:, 1].mean()),
            "mean_u_m": float(e[:, 2].mean()), "rms_h_m": rms(hz), "rms_v_m": rms(e[:, 2]), "p95_h_m": p95(hz)}
