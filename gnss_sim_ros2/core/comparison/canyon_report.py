"""The report's line-of-sight / NLOS section (core/comparison/canyon.py): Markdown lines, a figure, ``urban.json``."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..markdown_table import fmt as _f  # one number format for the whole report
from ..markdown_table import md_table as _table
from .canyon import LOS_TAIL_M
from .signal_compare import summary_lines
from .statistics import GROSS_LIMITS, TAIL_THRESHOLDS_M, summary_stats

#: the canyon figures beside report.md (signals.json stays as issue 26 wrote it)
URBAN_JSON = "urban.json"


def _pct(v) -> str:
    return "-" if v is None or not math.isfinite(v) else f"{100.0 * v:.1f} %"


def split_code_stats(cmp) -> dict:
    """Code differences sim - real per signal pair and per system, line of sight / NLOS apart (classes of
    :meth:`Canyon.classes`): {label: {"los": summary_stats, "nlos": summary_stats}}."""
    code = cmp.kinds["code"]
    if cmp.canyon is None or not code.available:
        return {}
    cls = cmp.canyon.classes(cmp.sv)
    sysc = cmp.sys_of_col()
    out = {}
    for p in cmp.pairs:
        d = code.residuals.get(p)
        if d is None:
            continue
        cols = sysc == p.system
        out[p.label] = {name: summary_stats(d[:, cols][cls[:, cols] == c], GROSS_LIMITS["code"])
                        for name, c in (("los", 0), ("nlos", 1))}
    return out


def urban_figures(cmp) -> dict:
    """The JSON of the section: the canyon metrics, the split code differences and the SPP ratio."""
    m = cmp.canyon.metrics()
    m["code_differences"] = split_code_stats(cmp)
    m["signals_split"] = cmp.signals_split
    pos = cmp.positions()
    s, r = pos.get("sim_vs_truth", {}), pos.get("real_vs_truth", {})
    m["spp_h_rms_m_sim"] = s.get("rms_h_m", math.nan)
    m["spp_h_rms_m_real"] = r.get("rms_h_m", math.nan)
    m["spp_ratio"] = (m["spp_h_rms_m_sim"] / m["spp_h_rms_m_real"]
                      if s.get("n") and r.get("n") and m["spp_h_rms_m_real"] > 0 else math.nan)
    m["spp_epochs_both"] = cmp.solved_epochs().get("both", 0)
    return m


def _json_safe(x):
    if isinstance(x, dict):
        return {str(k): _json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_safe(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, np.generic):
        return _json_safe(x.item())
    return x


def write_residual_figure(cmp, out_dir) -> Path | None:
    """Histograms of each file's code residual at its truth, line of sight and NLOS panels."""
    from ..figures import pyplot, save_figure

    c = cmp.canyon
    if not any(c.residuals(n, k).size for n in ("sim", "real") for k in ("los", "nlos")):
        return None
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for ax, cls, title in zip(axes, ("los", "nlos"), ("line of sight", "NLOS (blocked by the scene)")):
        for name, col in (("sim", "tab:blue"), ("real", "tab:red")):
            r = c.residuals(name, cls)
            if r.size:
                lim = max(50.0, float(np.percentile(np.abs(r), 99)))
                ax.hist(np.clip(r, -lim, lim), bins=80, range=(-lim, lim), histtype="step", density=True, color=col,
                        label=f"{'simulated' if name == 'sim' else 'real'} ({r.size})")
        ax.set_yscale("log")
        ax.set_xlabel("code residual at the truth [m] (clipped at the 99th percentile or 50 m)")
        ax.set_title(title)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    return save_figure(fig, Path(out_dir) / "code_residual_los_nlos.png")


def canyon_lines(cmp, out_dir) -> list[str]:
    """The report section; writes ``urban.json`` and the residual figure into ``out_dir``."""
    if cmp.canyon is None:
        return []

    m = urban_figures(cmp)
    (Path(out_dir) / URBAN_JSON).write_text(json.dumps(_json_safe(m), indent=1))
    a = m["agreement"]
    L = ["## Line of sight and NLOS", "",
         f"Scene {m['scene']}, mask {m['mask_deg']:g} deg. Each file at its own truth placed in the scene "
         "(core/comparison/canyon.py): tracked = a pseudorange of the system's reference signal "
         f"(simulated {m['codes_sim']}, real {m['codes_real']}) above the mask; NLOS = the scene blocks its line of "
         "sight; residual = pseudorange at the truth minus range, satellite clock, Klobuchar, Saastamoinen and the "
         "epoch's receiver clock (median line-of-sight GPS residual).", ""]
    L += _table(["figure", "simulated", "real", "sim / real"], [
        ["tracked satellite-epochs", m["tracked_sim"], m["tracked_real"], "-"],
        ["NLOS share of tracked", _pct(m["nlos_share_sim"]), _pct(m["nlos_share_real"]), _f(m["nlos_share_ratio"], 2)],
        [f"line-of-sight share with abs(residual) > {LOS_TAIL_M:g} m", _pct(m["los_above_10m_sim"]),
         _pct(m["los_above_10m_real"]), _f(m["los_above_10m_ratio"], 2)],
        ["SPP horizontal RMS [m]", _f(m["spp_h_rms_m_sim"], 2), _f(m["spp_h_rms_m_real"], 2), _f(m["spp_ratio"], 2)],
    ])
    L.append(f"- Tracked/not agreement per satellite-epoch above the mask: **{_pct(a['agreement'])}** over {a['n']} "
             f"satellite-epochs (both {a['both']}, neither {a['neither']}, only simulated {a['only_sim']}, only real "
             f"{a['only_real']}); published anchor {_pct(a['anchor'])} (issue 27).")
    w = m["residuals"]
    L.append(f"- Wasserstein-1 distance between the simulated and the real residual distributions: line of sight "
             f"{_f(w['los']['wasserstein_m'], 2)} m, NLOS {_f(w['nlos']['wasserstein_m'], 2)} m.")
    L.append("")
    hdr = ["class", "file", "n", "mean [m]", "RMS [m]", "p95 abs [m]", "p99 abs [m]", "max abs [m]"] \
        + [f"> {t:g} m" for t in TAIL_THRESHOLDS_M]
    rows = []
    for cls in ("los", "nlos"):
        for name in ("sim", "real"):
            t = m["residuals"][cls][name]
            rows.append([cls.upper(), name, t["n"], _f(t["mean"], 2), _f(t["rms"], 2), _f(t["p95_abs"], 2),
                         _f(t["p99_abs"], 2), _f(t["max_abs"], 1)]
                        + [_pct(t[f"share_above_{x:g}"]) for x in TAIL_THRESHOLDS_M])
    L += ["Code residuals at the truth (nothing left out):", ""] + _table(hdr, rows)
    rows = []
    for lab, st in m["code_differences"].items():
        for cls in ("los", "nlos"):
            s = st[cls]
            t = s["tails"]
            rows.append([lab, cls.upper(), t["n"], s["n_gross"], _f(s["rms"], 2), _f(t["rms"], 2), _f(t["p99_abs"], 2)]
                        + [_pct(t[f"share_above_{x:g}"]) for x in TAIL_THRESHOLDS_M])
    if rows:
        L += ["Code differences sim - real (clock removed), where both track: line of sight at both antennas or "
              f"blocked at either; 'RMS within' leaves out the 'gross' |d| > {GROSS_LIMITS['code']:g} m, 'RMS all' "
              "does not:", ""]
        L += _table(["signal", "class", "n", "gross", "RMS within [m]", "RMS all [m]",
                     "p99 abs [m]"] + [f"> {t:g} m" for t in TAIL_THRESHOLDS_M], rows)
    for cls, title in (("los", "line of sight"), ("nlos", "NLOS")):
        if cmp.signals_split.get(cls) is not None:
            L += [f"### Per-signal statistics, {title} only", "",
                  "(The tracked triples and their Jaccard count every satellite-epoch; the selection applies to "
                  "the C/N0 per elevation bin and the code noise.)", ""] + summary_lines(cmp.signals_split[cls])
    fig = write_residual_figure(cmp, out_dir)
    if fig is not None:
        L += [f"![Code residuals, line of sight and NLOS]({fig.name})", ""]
    L += [f"Machine-readable: `{URBAN_JSON}`.", ""]
    return L


__all__ = ["URBAN_JSON", "canyon_lines", "split_code_stats", "urban_figures"]
