"""How well a profile's per-signal tables describe a recording: measured C/N0 minus the profile's table and
measured code noise over the profile's (multipath table + DLL thermal noise in quadrature), per signal and
10-degree elevation bin.  Checks a fit on data it was not fitted on (hours 12-24 of a day fitted on 0-12, another
day of the station)."""
from __future__ import annotations

import math

import numpy as np

from .fit import MIN_BIN_SAMPLES, dll_noise_m
from .signal_stats import RecordingStats

#: width of the bins of the check [deg]
CHECK_BIN_DEG = 10.0


def check_profile(stats: RecordingStats, profile: dict, min_el_deg: float = 10.0) -> dict:
    """{signal: {"el_deg": bin centres, "cn0_diff_db": measured - table, "code_ratio": measured / modelled}}
    over the 10-degree bins at or above ``min_el_deg`` (bins of ``stats`` with MIN_BIN_SAMPLES samples pooled,
    weighted by their counts; NaN where no data); "cn0_max_abs_db" / "code_ratio_range" summarise each signal."""
    cn0_tab = profile.get("link_budget", {}).get("cn0_table_dbhz", {})
    mp_tab = profile.get("code_multipath_m", {})
    out = {}
    for key, st in stats.signals.items():
        c = st.el_centres_deg
        band = np.floor(c / CHECK_BIN_DEG).astype(int)
        bands = [b for b in np.unique(band) if (b + 0.5) * CHECK_BIN_DEG >= min_el_deg]
        res = {"el_deg": [(b + 0.5) * CHECK_BIN_DEG for b in bands], "cn0_diff_db": [], "code_ratio": []}
        for b in bands:
            m = (band == b) & (st.cn0_n >= MIN_BIN_SAMPLES) & np.isfinite(st.cn0_mean_dbhz)
            if key in cn0_tab and m.any():
                t = cn0_tab[key]
                model = np.interp(c[m], t["el_deg"], t["cn0_dbhz"])
                res["cn0_diff_db"].append(float(np.average(st.cn0_mean_dbhz[m] - model, weights=st.cn0_n[m])))
            else:
                res["cn0_diff_db"].append(math.nan)
            ok = st.mp_sigma_m is not None
            m = (band == b) & (st.mp_n >= MIN_BIN_SAMPLES) & np.isfinite(st.mp_sigma_m) & np.isfinite(st.mp_cn0_dbhz) \
                if ok else np.zeros(len(c), bool)
            if key in mp_tab and m.any():
                t = mp_tab[key]
                mp = np.interp(c[m], t["el_deg"], t["sigma_m"])
                dll = dll_noise_m(key, st.mp_cn0_dbhz[m], profile)
                w = st.mp_n[m]
                meas = math.sqrt(np.average(st.mp_sigma_m[m] ** 2, weights=w))
                model = math.sqrt(np.average(mp**2 + dll**2, weights=w))
                res["code_ratio"].append(meas / model if model > 0 else math.nan)
            else:
                res["code_ratio"].append(math.nan)
        dc = np.array(res["cn0_diff_db"], float)
        rc = np.array(res["code_ratio"], float)
        res["cn0_max_abs_db"] = float(np.nanmax(np.abs(dc))) if np.isfinite(dc).any() else math.nan
        res["code_ratio_range"] = ((float(np.nanmin(rc)), float(np.nanmax(rc))) if np.isfinite(rc).any()
                                   else (math.nan, math.nan))
        out[key] = res
    return out
