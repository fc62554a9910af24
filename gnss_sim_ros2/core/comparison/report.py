"""The comparison report: ``report.md`` and its PNG figures (matplotlib Agg)."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..markdown_table import fmt as _f
from ..markdown_table import md_table as _md_table
from .canyon_report import canyon_lines
from .compare import Comparison
from .pairing import unpaired_signals
from .signal_compare import summary_lines
from .statistics import DESCRIPTION, GROSS_LIMITS, TAIL_THRESHOLDS_M, UNITS, enu_errors_m

#: the per-signal statistics of both sides and their comparison, beside report.md
SIGNALS_JSON = "signals.json"


def write_figures(cmp: Comparison, out_dir) -> dict[str, Path]:
    """PNG figures; returns name -> path of those written."""
    import matplotlib.dates as mdates
    from matplotlib.colors import ListedColormap

    from ..figures import pyplot, save_figure

    plt = pyplot()

    out_dir = Path(out_dir)
    figs: dict[str, Path] = {}
    t = cmp.time.astype("datetime64[ms]").astype(object)
    sysc = cmp.sys_of_col()

    # pseudorange residual vs time per satellite (reference signal of each system)
    code = cmp.kinds["code"]
    if code.available:
        refs = []
        for p in cmp.pairs:
            if p in code.residuals and p.system not in [q.system for q in refs]:
                refs.append(p)
        if refs:
            fig, axes = plt.subplots(len(refs), 1, figsize=(10, 3.0 * len(refs)), sharex=True, squeeze=False)
            for ax, p in zip(axes[:, 0], refs):
                d = code.residuals[p]
                for j in np.flatnonzero(sysc == p.system):
                    if np.isfinite(d[:, j]).any():
                        ax.plot(t, d[:, j], ".-", ms=3, lw=0.8, label=cmp.sv[j])
                ax.set_ylabel(f"{p.label} [m]")
                ax.grid(alpha=0.3)
                ax.legend(fontsize=6, ncol=8, loc="upper right")
            axes[0, 0].set_title("pseudorange sim - real (receiver clock and ISB removed)")
            axes[-1, 0].xaxis.set_major_formatter(mdates.DateFormatter("%H:%M"))
            axes[-1, 0].set_xlabel("GPS time")
            figs["code"] = save_figure(fig, out_dir / "code_difference.png")

    # C/N0 vs elevation
    if (cmp.sim_cn0 or cmp.real_cn0) and cmp.el_deg is not None:
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for lab, dd, mk in (("simulated", cmp.sim_cn0, "o"), ("real", cmp.real_cn0, "x")):
            seen_sys = set()
            for p, m in dd.items():
                if p.system in seen_sys:
                    continue            # the first (reference) signal of each system
                seen_sys.add(p.system)
                ok = np.isfinite(m) & np.isfinite(cmp.el_deg)
                ax.plot(cmp.el_deg[ok], m[ok], mk, ms=3, alpha=0.5, label=f"{lab} {p.label}")
        ax.set_xlabel("elevation [deg]")
        ax.set_ylabel("C/N0 [dB-Hz]")
        if not cmp.real_cn0:
            ax.set_title("C/N0 vs elevation (the real file has no C/N0)")
        elif not cmp.sim_cn0:
            ax.set_title("C/N0 vs elevation (the simulated file has no C/N0)")
        else:
            ax.set_title("C/N0 vs elevation, simulated and real")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
        figs["cn0"] = save_figure(fig, out_dir / "cn0_elevation.png")

    # visibility timeline: 0 none, 1 both, 2 only sim, 3 only real
    state = np.zeros(cmp.seen_sim.shape, dtype=int)
    state[cmp.seen_sim & cmp.seen_real] = 1
    state[cmp.seen_sim & ~cmp.seen_real] = 2
    state[~cmp.seen_sim & cmp.seen_real] = 3
    keep = state.any(axis=0)
    if keep.any():
        st = state[:, keep].T
        fig, ax = plt.subplots(figsize=(10, max(3.0, 0.18 * st.shape[0] + 1.2)))
        cmap = ListedColormap(["white", "tab:green", "tab:blue", "tab:red"])
        x0, x1 = mdates.date2num(t[0]), mdates.date2num(t[-1])
        if x1 == x0:
            x1 = x0 + 1e-5
        ax.imshow(st, aspect="auto", interpolation="nearest", cmap=cmap, vmin=0, vmax=3,
                  extent=(x0, x1, st.shape[0] - 0.5, -0.5))
        ax.xaxis_date()
        ax.xaxis.set_major_formatter(mdates.DateFormatter("%H:%M"))
        ax.set_yticks(range(st.shape[0]))
        ax.set_yticklabels(cmp.sv[keep], fontsize=6)
        from matplotlib.patches import Patch

        ax.legend(handles=[Patch(color="tab:green", label="both"), Patch(color="tab:blue", label="only simulated"),
                           Patch(color="tab:red", label="only real")], fontsize=7, loc="upper right",
                  bbox_to_anchor=(1.0, 1.12), ncol=3)
        ax.set_xlabel("GPS time")
        ax.set_title("tracked satellites" + (f" above {cmp.mask_deg:g} deg" if cmp.mask_deg > 0 else ""), loc="left")
        figs["visibility"] = save_figure(fig, out_dir / "visibility.png")

    # horizontal positions
    if cmp.sol_sim is not None and cmp.sol_real is not None:
        ref = cmp.truth_ecef_m if cmp.truth_ecef_m is not None else cmp.sol_real.pos_ecef_m
        fig, ax = plt.subplots(figsize=(6, 6))
        for lab, sol, mk in (("simulated", cmp.sol_sim, "o"), ("real", cmp.sol_real, "x")):
            enu = enu_errors_m(sol.pos_ecef_m, ref)
            ok = np.all(np.isfinite(enu), axis=1)
            ax.plot(enu[ok, 0], enu[ok, 1], mk, ms=4, alpha=0.7, label=f"{lab} ({ok.sum()} fixes)")
        ax.plot([0], [0], "k+", ms=14, mew=2, label="truth" if cmp.truth_ecef_m is not None else "real solution")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("east [m]")
        ax.set_ylabel("north [m]")
        ax.set_title(f"single point solutions ({cmp.sol_sim.solver})")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        figs["positions"] = save_figure(fig, out_dir / "positions.png")
    return figs


def write_report(cmp: Comparison, out_dir) -> Path:
    """``out_dir/report.md`` with its figures; returns the report path."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    figs = write_figures(cmp, out_dir)
    L = ["# Simulated vs real observations", ""]
    L += [f"- simulated: `{cmp.sim.source}` ({cmp.sim.kind}, {len(cmp.sim.time)} epochs, systems {cmp.sim.systems})",
          f"- real: `{cmp.real.source}` ({cmp.real.kind}, {len(cmp.real.time)} epochs read, systems "
          f"{cmp.real.systems})",
          f"- common epochs: {len(cmp.time)} ({str(cmp.time[0])[:19]} .. {str(cmp.time[-1])[:19]} GPS); "
          f"only simulated {cmp.epochs_only_sim}, only real {cmp.epochs_only_real} (real read over the simulated "
          f"span)",
          f"- systems compared: {cmp.systems or '-'}; only simulated: {cmp.systems_only_sim or '-'}; "
          f"only real: {cmp.systems_only_real or '-'}",
          f"- epochs matched within {cmp.epoch_tol_ms:g} ms (largest time-tag difference "
          f"{cmp.max_tag_difference_ms:.3f} ms"
          + ("; the code differences carry range rate x tag difference, up to 0.8 m per ms)"
             if cmp.max_tag_difference_ms > 0.01 else ")"),
          f"- elevation mask given: {cmp.mask_deg:g} deg" + ("" if cmp.el_deg is not None else
                                                            " (not applied: no elevations without --nav)"), ""]
    L += [f"**Warning**: {w}" for w in cmp.warnings] + ([""] if cmp.warnings else [])
    L += ["## Signal pairs", ""]
    L += _md_table(["system", "simulated", "real"], [[p.system, p.sim_code, p.real_code] for p in cmp.pairs])
    one_sided = unpaired_signals(cmp.sim, cmp.real, cmp.systems, cmp.pairs)
    for side, lab in (("sim", "simulated"), ("real", "real")):
        L.append(f"- Signals only the {lab} file has (not compared): "
                 + (", ".join(f"{s} {c}" for s, c in one_sided[side]) or "none"))
    L.append("")
    L += ["## Method", ""]
    for name, kr in cmp.kinds.items():
        L.append(f"- **{name}** [{UNITS[name]}]: {DESCRIPTION[name]}."
                 + ("" if kr.available else f" **Unavailable**: {kr.reason}."))
    code = cmp.kinds["code"]
    if code.available:
        L.append(f"- Receiver clock reference system: {code.ref_system}; inter-system biases (code, m): "
                 + ", ".join(f"{s} {_f(v)}" for s, v in code.isb.items()) + ".")
        clk = code.clock[np.isfinite(code.clock)]
        if clk.size:
            L.append(f"- Removed per-epoch code offset (sim - real receiver clock): median {_f(np.median(clk))} m, "
                     f"span {_f(clk.max() - clk.min())} m.")
    L.append("- Signals other than the first of each system keep the inter-frequency (differential code) bias "
             "between the two receivers: it shows as their mean.")
    if cmp.mask_deg > 0:
        L.append(f"- Tracked-satellite sets: above {cmp.mask_deg:g} deg where the broadcast ephemeris gives an "
                 "elevation; satellites without a healthy record keep every epoch.")
    L.append("- Count, mean, RMS and std are robust statistics: they leave out gross errors (|residual| above "
             + ", ".join(f"{k_} {v:g} {UNITS[k_]}" for k_, v in GROSS_LIMITS.items() if math.isfinite(v))
             + "), counted in column 'gross'; 'RMS all' and the 99th percentile of |residual| keep every value, "
             "and the code tails table gives the shares above " + "/".join(f"{t:g}" for t in TAIL_THRESHOLDS_M)
             + " m (an NLOS range is never hidden).")
    L.append("")

    L += ["## Differences per system and signal", ""]
    rows = []
    for name, kr in cmp.kinds.items():
        if not kr.available:
            rows.append([name, "all", "unavailable", "", "", "", "", ""])
            continue
        for s in cmp.systems:
            for p in cmp.pairs:
                if p.system != s or p not in kr.residuals:
                    continue
                st = cmp.stats(name, p)
                rows.append([name, p.label, st["n"], st["n_gross"], _f(st["mean"]), _f(st["rms"]), _f(st["std"]),
                             _f(st["tails"]["rms"]), _f(st["tails"]["p99_abs"]), UNITS[name]])
            st = cmp.system_stats(name, s)
            if st["n"] or st["n_gross"]:
                rows.append([name, f"**{s} all**", st["n"], st["n_gross"], _f(st["mean"]), _f(st["rms"]),
                             _f(st["std"]), _f(st["tails"]["rms"]), _f(st["tails"]["p99_abs"]), UNITS[name]])
    L += _md_table(["kind", "signal", "count", "gross", "mean", "RMS", "std", "RMS all", "p99 abs", "unit"], rows)
    if code.available:
        rows = []
        for s in cmp.systems:
            for p in [q for q in cmp.pairs if q.system == s and q in code.residuals] + [None]:
                t = (cmp.stats("code", p) if p is not None else cmp.system_stats("code", s))["tails"]
                if t["n"]:
                    rows.append([p.label if p is not None else f"**{s} all**", t["n"], _f(t["p95_abs"]),
                                 _f(t["p99_abs"]), _f(t["max_abs"])]
                                + [f"{100.0 * t[f'share_above_{x:g}']:.2f} %" for x in TAIL_THRESHOLDS_M])
        if rows:
            L += ["Code tails (every residual, none left out):", ""]
            L += _md_table(["signal", "n", "p95 abs [m]", "p99 abs [m]", "max abs [m]"]
                           + [f"> {x:g} m" for x in TAIL_THRESHOLDS_M], rows)

    L += ["## Differences per satellite", ""]
    for s in cmp.systems:
        rows = []
        for p in cmp.pairs:
            if p.system != s:
                continue
            for sv in [v for v in cmp.sv.tolist() if v[0] == s]:
                cells = [sv, p.label]
                any_ = False
                for name, kr in cmp.kinds.items():
                    if not kr.available or p not in kr.residuals:
                        cells += ["-", "-", "-"]
                        continue
                    st = cmp.stats(name, p, sv)
                    any_ |= bool(st["n"] or st["n_gross"])
                    cells += [st["n"] + st["n_gross"], _f(st["mean"]), _f(st["rms"])]
                if any_:
                    rows.append(cells)
        if rows:
            L += [f"### {s}", ""]
            hdr = ["sv", "signal"]
            for name in cmp.kinds:
                hdr += [f"{name} n", f"{name} mean", f"{name} RMS"]
            L += _md_table(hdr, rows)

    vis = cmp.visibility()
    L += ["## Tracked satellites", ""]
    L.append("Satellite-epochs with a code observation" + (f", above {cmp.mask_deg:g} deg elevation where the "
                                                           "ephemeris gives one" if cmp.mask_deg > 0 else "")
             + f": both {vis['n_both']}, only simulated {vis['n_only_sim']}, only real {vis['n_only_real']}.")
    L.append("")
    L += _md_table(["system", "Jaccard"], [[s, _f(v)] for s, v in vis["jaccard"].items()])
    L.append(f"- Seen only by the simulation (never by the real receiver): {', '.join(vis['only_sim_svs']) or 'none'}")
    L.append(f"- Seen only by the real receiver (never simulated): {', '.join(vis['only_real_svs']) or 'none'}")
    L.append("")
    rows = [[s, c["both"], c["only_sim"], c["only_real"]] for s, c in vis["per_sv"].items()
            if c["only_sim"] or c["only_real"]]
    if rows:
        L += ["Satellites with epochs seen by one side only:", ""]
        L += _md_table(["sv", "both", "only sim", "only real"], rows)

    L += ["## Signals", ""]
    if cmp.signals is None:
        L += ["No per-signal statistics: they need elevations (give broadcast navigation files with --nav).", ""]
    else:
        L += summary_lines(cmp.signals)
        L += [f"Machine-readable: `{SIGNALS_JSON}` (both sides' statistics and their comparison).", ""]
        (out_dir / SIGNALS_JSON).write_text(json.dumps(
            {"comparison": cmp.signals, "sim": cmp.signal_stats_sim.to_json(),
             "real": cmp.signal_stats_real.to_json()}, indent=1))

    L += ["## Positions", ""]
    if cmp.sol_sim is None:
        L += ["No position solutions (give broadcast navigation files with --nav).", ""]
    else:
        sol = cmp.solved_epochs()
        L.append(f"Single point solutions of both files by {cmp.sol_sim.solver} (broadcast ephemeris, Klobuchar "
                 "ionosphere, Saastamoinen troposphere, 10 deg mask), compared on the "
                 f"**{sol['both']} epochs both solved** (of {len(cmp.time)} common epochs; the simulated file solved "
                 f"{sol['sim']}, the real {sol['real']}). "
                 + (f"Truth: {cmp.truth_label}." if cmp.truth_label else "No truth.")
                 + (f" The real file's own truth: {cmp.truth_real_label}." if cmp.truth_real_label else ""))
        if cmp.position_note:
            L.append(cmp.position_note)
        L.append("")
        rows = []
        for lab, st in cmp.positions().items():
            if st.get("n"):
                rows.append([lab.replace("_", " "), st["n"], _f(st["mean_e_m"]), _f(st["mean_n_m"]),
                             _f(st["mean_u_m"]), _f(st["rms_h_m"]), _f(st["rms_v_m"]), _f(st["p95_h_m"])])
            else:
                rows.append([lab.replace("_", " "), 0, "-", "-", "-", "-", "-", "-"])
        L += _md_table(["solutions", "epochs", "mean E [m]", "mean N [m]", "mean U [m]", "RMS horizontal [m]",
                        "RMS vertical [m]", "95 % horizontal [m]"], rows)

    L += canyon_lines(cmp, out_dir)

    L += ["## Figures", ""]
    captions = {"code": "Pseudorange difference per satellite", "cn0": "C/N0 against elevation",
                "visibility": "Tracked satellites (green both, blue only simulated, red only real)",
                "positions": "Horizontal positions"}
    for key, path in figs.items():
        L += [f"![{captions[key]}]({path.name})", ""]
    if "cn0" not in figs:
        L += ["(No C/N0 figure: " + ("no C/N0 on either side" if not (cmp.sim_cn0 or cmp.real_cn0)
                                     else "no elevations without --nav") + ".)", ""]
    path = out_dir / "report.md"
    path.write_text("\n".join(L))
    return path
