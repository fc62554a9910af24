"""Accuracy figures, once: the horizontal error of position estimates and the RMS and 95th percentile of errors.

Used by the offline loop (``SimulationResult.horizontal_error_m``), the sweeps' rows, the RTK and run summaries,
the Hong Kong drive check and the benchmarks.  An empty input gives ``None`` (no figure), never a NaN or a
numpy warning; a caller that wants NaN says so.
"""
from __future__ import annotations

import numpy as np

from .frames import ecef_to_geodetic


def horizontal_errors_m(est_ecef_m, true_ecef_m) -> np.ndarray:
    """Horizontal distance [m] of estimates (K, 3) from true positions (K, 3) (or one (3,) each), in the local
    ENU of the truth; (K,), (0,) for no rows."""
    est = np.asarray(est_ecef_m, dtype=np.float64).reshape(-1, 3)
    true = np.asarray(true_ecef_m, dtype=np.float64).reshape(-1, 3)
    lat, lon, _ = ecef_to_geodetic(true[:, 0], true[:, 1], true[:, 2])
    la, lo = np.radians(lat), np.radians(lon)
    d = est - true
    e = -np.sin(lo) * d[:, 0] + np.cos(lo) * d[:, 1]
    n = -np.sin(la) * np.cos(lo) * d[:, 0] - np.sin(la) * np.sin(lo) * d[:, 1] + np.cos(la) * d[:, 2]
    return np.hypot(e, n)


def _values(x, skip_nonfinite: bool) -> np.ndarray:
    v = np.asarray(x, dtype=np.float64).ravel()
    return v[np.isfinite(v)] if skip_nonfinite else v


def rms(x, *, skip_nonfinite: bool = False) -> float | None:
    """Root mean square of the values of ``x`` (a scalar, a list or an array of any shape); None if there are
    none (after dropping NaN and infinities with ``skip_nonfinite``)."""
    v = _values(x, skip_nonfinite)
    return float(np.sqrt(np.mean(np.square(v)))) if v.size else None


def percentile(x, q: float, *, skip_nonfinite: bool = False) -> float | None:
    """The ``q``-th percentile (numpy's linear interpolation) of the values of ``x``; None if there are none."""
    v = _values(x, skip_nonfinite)
    return float(np.percentile(v, q)) if v.size else None


def p95(x, *, skip_nonfinite: bool = False) -> float | None:
    """The 95th percentile of the values of ``x``; None if there are none."""
    return percentile(x, 95, skip_nonfinite=skip_nonfinite)


def rounded(value: float | None, digits: int) -> float | None:
    """``round(value, digits)``, None kept (a figure written to a summary)."""
    return None if value is None else round(value, digits)


def horizontal_stats(est_ecef_m, true_ecef_m) -> dict:
    """RMS and 95th percentile [m] of the horizontal errors of the finite estimates (rows with a NaN: no
    solution), NaN when there is none, and the number of epochs with a solution."""
    est = np.asarray(est_ecef_m, dtype=np.float64).reshape(-1, 3)
    true = np.asarray(true_ecef_m, dtype=np.float64).reshape(-1, 3)
    ok = np.all(np.isfinite(est), axis=1)
    e = horizontal_errors_m(est[ok], true[ok])
    return {"rms_m": rms(e) if len(e) else np.nan, "p95_m": p95(e) if len(e) else np.nan, "epochs": int(ok.sum())}
