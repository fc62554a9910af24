"""The calibration report: ``report.md`` with PNG figures (fitted against measured C/N0 and code noise per signal
against elevation, rise and set elevations) and ``statistics.json`` (the per-signal statistics)."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..markdown_table import fmt
from ..markdown_table import md_table as _md_table
from .fit import MIN_TRACK_EVENTS, dll_noise_m
from .reading import Recording
from .signal_stats import RecordingStats
from .track_events import HORIZON_MARGIN_DEG, TAIL_PERCENT


def _interp(table: dict | None, key: str, el: float) -> float:
    if not table:
        return math.nan
    return float(np.interp(el, table["el_deg"], table[key]))


def write_figures(stats: RecordingStats, profile: dict, out_dir) -> dict[str, Path]:
    """cn0_elevation.png, code_noise_elevation.png, rise_set.png (those with data); name -> path."""
    from ..figures import pyplot, save_figure
    plt = pyplot()
    out_dir = Path(out_dir)
    figs: dict[str, Path] = {}
    systems = sorted({k_[0] for k_ in stats.signals}, key="GRECJI".index)
    cn0_tab = profile.get("link_budget", {}).get("cn0_table_dbhz", {})
    mp_tab = profile.get("code_multipath_m", {})
    for name, title in (("cn0", "C/N0 against elevation: measured bin mean +- std (points), fitted table (line)"),
                        ("code", "code noise (multipath combination) against elevation: measured (points), "
                                 "fitted multipath + DLL thermal (line)")):
        fig, axes = plt.subplots(len(systems), 1, figsize=(8, 3.0 * len(systems)), squeeze=False, sharex=True)
        drew = False
        for ax, s in zip(axes[:, 0], systems):
            for i, (key, st) in enumerate((k_, v) for k_, v in stats.signals.items() if k_[0] == s):
                col = f"C{i % 10}"
                c = st.el_centres_deg
                if name == "cn0":
                    ok = st.cn0_n > 0
                    if not ok.any():
                        continue
                    ax.errorbar(c[ok], st.cn0_mean_dbhz[ok], yerr=st.cn0_std_db[ok], fmt="o", ms=3, color=col,
                                label=key, capsize=2)
                    if key in cn0_tab:
                        ax.plot(cn0_tab[key]["el_deg"], cn0_tab[key]["cn0_dbhz"], "-", color=col)
                    ax.set_ylabel("C/N0 [dB-Hz]")
                else:
                    if st.mp_sigma_m is None or not np.isfinite(st.mp_sigma_m).any():
                        continue
                    ax.plot(c, st.mp_sigma_m, "o", ms=3, color=col, label=f"{key} (with L{st.mp_partner})")
                    if key in mp_tab:
                        mp = np.interp(c, mp_tab[key]["el_deg"], mp_tab[key]["sigma_m"])
                        cn0 = np.where(np.isfinite(st.mp_cn0_dbhz), st.mp_cn0_dbhz, np.nan)
                        dll = dll_noise_m(key, cn0, profile)
                        ax.plot(c, np.sqrt(mp**2 + dll**2), "-", color=col)
                    ax.set_ylabel("sigma [m]")
                    ax.set_yscale("log")
                drew = True
            ax.set_title(f"{s}", loc="left", fontsize=9)
            ax.grid(alpha=0.3)
            if ax.has_data():
                ax.legend(fontsize=7, ncol=3)
        axes[-1, 0].set_xlabel("elevation [deg]")
        fig.suptitle(title, fontsize=9)
        if drew:
            fname = "cn0_elevation.png" if name == "cn0" else "code_noise_elevation.png"
            figs[name] = save_figure(fig, out_dir / fname)
        else:
            plt.close(fig)
    rise = np.concatenate([st.rise_el_deg for st in stats.signals.values()] or [np.zeros(0)])
    sets = np.concatenate([st.set_el_deg for st in stats.signals.values()] or [np.zeros(0)])
    if rise.size or sets.size:
        fig, ax = plt.subplots(figsize=(7, 4))
        bins = np.arange(0.0, 31.0, 1.0)
        ax.hist(np.clip(rise[np.isfinite(rise)], 0, 30), bins, alpha=0.6, label=f"rise ({rise.size} arcs)")
        ax.hist(np.clip(sets[np.isfinite(sets)], 0, 30), bins, alpha=0.6, label=f"set ({sets.size} arcs)")
        ax.set_xlabel("elevation at the first / last epoch of an arc [deg] (30 = 30 or more)")
        ax.set_ylabel("arcs (all signals)")
        ax.grid(alpha=0.3)
        ax.legend()
        figs["rise_set"] = save_figure(fig, out_dir / "rise_set.png")
    return figs


def write_report(rec: Recording, stats: RecordingStats, profile: dict, notes: list[str], profile_path: Path,
                 out_dir) -> Path:
    """``out_dir/report.md`` + figures + ``statistics.json``; returns the report path."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    figs = write_figures(stats, profile, out_dir)
    (out_dir / "statistics.json").write_text(json.dumps(stats.to_json(), indent=1))
    t0, t1 = rec.span
    L = [f"# Receiver calibration: {profile['name']}", "",
         f"- observations: `{rec.path}` ({rec.header.get('receiver_type') or '?'}, antenna "
         f"{rec.header.get('antenna_type', '').strip() or '?'}), {len(rec.table.time)} epochs, {t0} .. {t1} GPS, "
         f"interval {rec.interval_s:g} s",
         f"- antenna position: {rec.antenna}",
         f"- elevation mask of the statistics: {stats.mask_deg:g} deg, bins of {stats.bin_deg:g} deg",
         f"- profile: `{profile_path.name}` (load it with `--profile {profile_path.name}`)", ""]
    if stats.scene:
        L += ["## Line-of-sight selection", "",
              f"The scene ({stats.scene}) selected the samples: only (epoch, satellite) pairs it leaves in the line "
              f"of sight of the antenna at or above {stats.mask_deg:g} deg enter the C/N0 tables, the C/N0 scatter, "
              "the code noise, the rise / set elevations and with them the tracking thresholds "
              "(core/visibility/line_of_sight.py).", ""]
        L += _md_table(["signal", "C/N0 samples", "kept (line of sight)", "share"],
                       [[k_, a, b, f"{100.0 * b / a:.1f} %" if a else "-"]
                        for k_, (a, b) in ((k_, st.los_samples) for k_, st in stats.signals.items()
                                           if st.los_samples is not None)])
    if notes:
        L += ["## Not fitted", ""] + [f"- {n}" for n in notes] + [""]
    L += ["## Method", "",
          "- C/N0: S observations per elevation bin (mean, std); the table is the bin means with enough samples, "
          "monotone in elevation, filled beyond the covered range with the shape of the system's best-covered "
          "signal (core/calibration/fit.py).",
          "- Code noise: multipath combination MP_i = P_i - (1 + 2/(a-1)) L_i + (2/(a-1)) L_j, a = (f_i/f_j)^2 "
          "(Estey & Meertens 1999, TEQC), mean removed per continuous arc (split at LLI bit 0, gaps over 2 "
          "intervals, jumps over 5 sigma); the profile's code_multipath_m is its sigma minus the DLL thermal noise "
          f"(B_n {profile['dll_bn_hz']:g} Hz, spacing {profile['dll_spacing_chips']:g} chip) in quadrature.",
          "- Rise / set: elevation at the first / last epoch of arcs that rise / set inside the span.",
          f"- Tracking thresholds: {TAIL_PERCENT:g} % percentile of the C/N0 at the first signal's track starts "
          f"(acquisition) and ends (loss) away from a satellite's rise / set (within {HORIZON_MARGIN_DEG:g} deg of "
          f"it: the horizon's, not the receiver's), median over systems, with {MIN_TRACK_EVENTS} such events per "
          "system; else the lowest C/N0 the receiver holds (\"Not fitted\" above; core/calibration/track_events.py).",
          ""]
    rows = []
    cn0_tab = profile.get("link_budget", {}).get("cn0_table_dbhz", {})
    mp_tab = profile.get("code_multipath_m", {})
    for key, st in stats.signals.items():
        rows.append([key, fmt(_interp(cn0_tab.get(key), "cn0_dbhz", 10.0), 1),
                     fmt(_interp(cn0_tab.get(key), "cn0_dbhz", 45.0), 1),
                     fmt(_interp(cn0_tab.get(key), "cn0_dbhz", 90.0), 1),
                     st.mp_partner and f"L{st.mp_partner}" or "-", fmt(st.mp_all_sigma_m, 3),
                     fmt(_interp(mp_tab.get(key), "sigma_m", 10.0), 3),
                     fmt(_interp(mp_tab.get(key), "sigma_m", 45.0), 3),
                     fmt(np.median(st.rise_el_deg), 1) if st.rise_el_deg.size else "-",
                     fmt(np.median(st.set_el_deg), 1) if st.set_el_deg.size else "-",
                     fmt(st.cn0_scatter_db, 2)])
    L += ["## Per signal", ""]
    L += _md_table(["signal", "C/N0 10 deg", "C/N0 45 deg", "C/N0 90 deg", "MP with", "MP sigma [m]",
                    "multipath 10 deg [m]", "multipath 45 deg [m]", "median rise [deg]", "median set [deg]",
                    "C/N0 scatter [dB]"], rows)
    first, starts = stats.lli_share("lli_first"), stats.lli_share("lli_arc_start")
    L += ["## Loss-of-lock indicators", ""]
    for lab, d in (("first epoch", first), ("arc starts", starts), ("every epoch", stats.lli_all)):
        n = d.get("n", 0)
        L.append(f"- {lab}: {n} phases, bit 0 (lost lock) {d.get('bit0', 0)}"
                 + (f" ({100.0 * d['bit0'] / n:.1f} %)" if n else "") + f", bit 1 (half cycle) {d.get('bit1', 0)}")
    L += ["", "## Figures", ""]
    captions = {"cn0": "C/N0 against elevation", "code": "Code noise against elevation",
                "rise_set": "Rise and set elevations"}
    for key, path in figs.items():
        L += [f"![{captions[key]}]({path.name})", ""]
    path = out_dir / "report.md"
    path.write_text("\n".join(L))
    return path
