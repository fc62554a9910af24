"""RTK figures of a run against the true antenna path (``gnss-sim run --rtk``: summary.json, rtk_timeline.csv).

- ``rtk_solution_ratio``: epochs with a /gnss/rtk/fix over the epochs of the run;
- ``rtk_fixed_ratio``, ``rtk_float_ratio``, ``rtk_single_ratio``: epochs with a fixed / float / other
  solution over the epochs of the run;
- ``rtk_fixed_ratio_after_first_quarter``: fixed solutions over the solutions of the epochs after the
  first quarter of the run (the time to the first fix left out);
- ``rtk_horizontal_error_rms_m``: RMS of the horizontal distance from the true antenna position of the
  fixed solutions; ``rtk_horizontal_error_rms_all_m`` of every solution; ``..._p95_m`` their 95th percentiles.

Moving baseline (:func:`heading_figures`): ``heading_ratio`` (epochs with a heading), ``heading_fixed_ratio``,
``heading_error_rms_deg`` (fixed headings against the true baseline first -> second antenna) and
``heading_sd_median_deg`` (the standard deviation rtkrcv gives).
"""
from __future__ import annotations

import io

import numpy as np

from ..frames import ecef_to_enu, ecef_to_geodetic, geodetic_to_ecef
from ..metrics import horizontal_errors_m, p95, rms, rounded


def _rms(x) -> float | None:
    return rounded(rms(x), 4)


def _p95(x) -> float | None:
    return rounded(p95(x), 4)


def rtk_figures(rows, n_epochs: int, period_s: float) -> tuple[dict, str]:
    """(figures, time line CSV) of ``rows`` = (t_s, quality, lat_deg, lon_deg, h_m, truth_ecef_m), one per
    epoch with an RTK solution; ``quality`` an RTKLIB name (solution.QUALITY_NAMES) or "unknown"."""
    n = max(int(n_epochs), 1)
    t = np.array([r[0] for r in rows], dtype=float)
    q = np.array([r[1] for r in rows], dtype=object)
    est = np.array([geodetic_to_ecef(r[2], r[3], r[4]) for r in rows], dtype=float).reshape(-1, 3)
    err = horizontal_errors_m(est, np.array([r[5] for r in rows], dtype=float).reshape(-1, 3))
    fixed, flt = q == "fixed", q == "float"
    late = t >= n * period_s / 4.0
    out = {
        "rtk_epochs": int(len(rows)),
        "rtk_solution_ratio": round(len(rows) / n, 4),
        "rtk_fixed_ratio": round(int(fixed.sum()) / n, 4),
        "rtk_float_ratio": round(int(flt.sum()) / n, 4),
        "rtk_single_ratio": round(int((~fixed & ~flt).sum()) / n, 4),
        "rtk_fixed_ratio_after_first_quarter": round(int((fixed & late).sum()) / int(late.sum()), 4)
        if late.any() else None,
        "rtk_first_fix_s": round(float(t[fixed][0]), 3) if fixed.any() else None,
        "rtk_horizontal_error_rms_m": _rms(err[fixed]),
        "rtk_horizontal_error_p95_m": _p95(err[fixed]),
        "rtk_horizontal_error_rms_all_m": _rms(err),
        "rtk_horizontal_error_p95_all_m": _p95(err),
        "rtk_timeline": "rtk_timeline.csv",
    }
    buf = io.StringIO()
    buf.write("t_s,quality,horizontal_error_m\n")
    for ti, qi, ei in zip(t, q, err):
        buf.write(f"{ti:.3f},{qi},{ei:.4f}\n")
    return out, buf.getvalue()


def true_heading_deg(antenna1_ecef_m, antenna2_ecef_m) -> float:
    """Compass heading [deg, 0 north, 90 east] of the baseline antenna 1 -> antenna 2, in antenna 1's ENU."""
    a1 = np.asarray(antenna1_ecef_m, dtype=float)
    lat, lon, h = ecef_to_geodetic(*a1)
    d = ecef_to_enu(np.asarray(antenna2_ecef_m, dtype=float), lat, lon, h)
    return float(np.degrees(np.arctan2(d[0], d[1])) % 360.0)


def heading_figures(rows, n_epochs: int) -> dict:
    """Figures of ``rows`` = (t_s, quality, heading_deg, sd_deg, antenna1_ecef_m, antenna2_ecef_m)."""
    n = max(int(n_epochs), 1)
    q = np.array([r[1] for r in rows], dtype=object)
    err = np.array([(r[2] - true_heading_deg(r[4], r[5]) + 180.0) % 360.0 - 180.0 for r in rows], dtype=float)
    sd = np.array([r[3] for r in rows], dtype=float)
    fixed = q == "fixed"
    return {
        "heading_epochs": int(len(rows)),
        "heading_ratio": round(len(rows) / n, 4),
        "heading_fixed_ratio": round(int(fixed.sum()) / n, 4),
        "heading_error_rms_deg": _rms(err[fixed]),
        "heading_error_p95_deg": _p95(np.abs(err[fixed])),
        "heading_sd_median_deg": round(float(np.median(sd[fixed])), 4) if fixed.any() else None,
    }
