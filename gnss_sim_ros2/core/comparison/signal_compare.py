"""Per-signal statistics of two receivers side by side (``gnss-sim compare``: simulated against real):

- Jaccard index of the (epoch, satellite, signal) triples with a code observation above the mask, per signal
  and over all (a signal only one side has counts in the union);
- mean C/N0 simulated minus real per signal and elevation bin (bins with ``MIN_BIN_SAMPLES`` on both sides);
- code noise (multipath combination, the same method on both files) simulated over real per signal: over every
  sample above the mask and per elevation bin;
- share of carrier phases with LLI bit 0 / bit 1 at the first epoch, each side.
"""
from __future__ import annotations

import math

import numpy as np

from ..calibration.signal_stats import RecordingStats
from ..markdown_table import md_table

#: a bin needs this many samples on each side to be compared
MIN_BIN_SAMPLES = 10


def _ms(t: np.ndarray) -> np.ndarray:
    return np.round(t.astype("datetime64[ns]").astype(np.int64) / 1e6).astype(np.int64)


def _share(d: dict) -> dict:
    n = d.get("n", 0)
    return {"n": n, "bit0_share": d.get("bit0", 0) / n if n else None,
            "bit1_share": d.get("bit1", 0) / n if n else None}


def _num(v):
    return None if v is None or not np.isfinite(v) else round(float(v), 4)


def compare_statistics(sim: RecordingStats, real: RecordingStats, pairs=None) -> dict:
    """Simulated against real statistics; ``pairs``: (system, sim code, real code) of signals matched across
    attributes (e.g. gnss-sim compare's pairing), default: the same keys."""
    if pairs is None:
        pairs = [(k_[0], k_[1:], k_[1:]) for k_ in sim.signals if k_ in real.signals]
    match = {s + a: s + b for s, a, b in pairs if s + a in sim.signals and s + b in real.signals}
    t_s, t_r = _ms(sim.time), _ms(real.time)
    common, i_s, i_r = np.intersect1d(t_s, t_r, return_indices=True)
    svs = sorted(set(sim.sv.tolist()) | set(real.sv.tolist()))
    col = {s: j for j, s in enumerate(svs)}

    def tracked(st, idx, tab_sv) -> np.ndarray:
        out = np.zeros((len(common), len(svs)), dtype=bool)
        if st.tracked is None:
            return out
        sys_cols = [j for j, s in enumerate(tab_sv.tolist()) if s[0] == st.system]
        out[:, [col[tab_sv[j]] for j in sys_cols]] = st.tracked[idx]
        return out

    per_signal = {}
    both_n = union_n = 0
    for k_s, st in sim.signals.items():
        a = tracked(st, i_s, sim.sv)
        k_r = match.get(k_s)
        b = tracked(real.signals[k_r], i_r, real.sv) if k_r else np.zeros_like(a)
        both, union = int((a & b).sum()), int((a | b).sum())
        both_n, union_n = both_n + both, union_n + union
        row = {"real_signal": k_r, "jaccard": both / union if union else None, "n_sim": int(a.sum()),
               "n_real": int(b.sum())}
        if k_r:
            rs = real.signals[k_r]
            ok = (st.cn0_n >= MIN_BIN_SAMPLES) & (rs.cn0_n >= MIN_BIN_SAMPLES)
            row["el_centres_deg"] = [float(v) for v in st.el_centres_deg]
            row["cn0_diff_db"] = [_num(v) if o else None for v, o in zip(st.cn0_mean_dbhz - rs.cn0_mean_dbhz, ok)]
            if st.mp_sigma_m is not None and rs.mp_sigma_m is not None:
                ok = (st.mp_n >= MIN_BIN_SAMPLES) & (rs.mp_n >= MIN_BIN_SAMPLES)
                with np.errstate(invalid="ignore", divide="ignore"):
                    r = st.mp_sigma_m / rs.mp_sigma_m
                row["code_ratio_bins"] = [_num(v) if o else None for v, o in zip(r, ok)]
                row["code_ratio"] = _num(st.mp_all_sigma_m / rs.mp_all_sigma_m) if rs.mp_all_sigma_m > 0 else None
                row["code_sigma_sim_m"], row["code_sigma_real_m"] = _num(st.mp_all_sigma_m), _num(rs.mp_all_sigma_m)
        per_signal[k_s] = row
    for k_r, rs in real.signals.items():             # real signals the simulation does not have
        if k_r in match.values():
            continue
        b = tracked(rs, i_r, real.sv)
        union_n += int(b.sum())
        per_signal[f"({k_r})"] = {"real_signal": k_r, "jaccard": 0.0 if b.any() else None, "n_sim": 0,
                                  "n_real": int(b.sum())}
    return {"common_epochs": int(len(common)), "mask_deg": sim.mask_deg, "bin_deg": sim.bin_deg,
            "jaccard_all": both_n / union_n if union_n else None,
            "lli_first": {"sim": _share(sim.lli_share("lli_first")), "real": _share(real.lli_share("lli_first"))},
            "signals": per_signal}


def summary_lines(cmp: dict) -> list[str]:
    """Markdown of :func:`compare_statistics` (the ``Signals`` section of the compare report)."""
    def f(v, d=2):
        return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v:.{d}f}"

    L = [f"(Epoch, satellite, signal) triples with a code observation above {cmp['mask_deg']:g} deg over "
         f"{cmp['common_epochs']} common epochs: Jaccard {f(cmp['jaccard_all'], 3)} over all signals.", ""]
    rows = []
    for k_, r in cmp["signals"].items():
        rows.append([k_, r["real_signal"] or "-", r["n_sim"], r["n_real"], f(r["jaccard"], 3),
                     f(r.get("code_sigma_sim_m"), 3), f(r.get("code_sigma_real_m"), 3), f(r.get("code_ratio"))])
    L += md_table(["signal", "real", "triples sim", "triples real", "Jaccard", "code noise sim [m]",
                   "code noise real [m]", "ratio sim/real"], rows)
    bins = next((r["el_centres_deg"] for r in cmp["signals"].values() if "el_centres_deg" in r), None)
    if bins:
        w = cmp["bin_deg"] / 2
        L += [f"Mean C/N0 simulated minus real [dB] per {cmp['bin_deg']:g}-degree elevation bin ('-': fewer than "
              f"{MIN_BIN_SAMPLES} samples on a side):", ""]
        L += md_table(["signal"] + [f"{c - w:g}-{c + w:g}" for c in bins],
                      [[k_] + [f(v, 1) for v in r["cn0_diff_db"]] for k_, r in cmp["signals"].items()
                       if "cn0_diff_db" in r and any(v is not None for v in r["cn0_diff_db"])])
    lf = cmp["lli_first"]
    for side in ("sim", "real"):
        d = lf[side]
        L.append(f"- LLI at the first epoch, {'simulated' if side == 'sim' else 'real'}: "
                 + (f"{d['n']} phases, bit 0 {100 * d['bit0_share']:.1f} %, bit 1 {100 * d['bit1_share']:.1f} %"
                    if d["n"] else "no loss-of-lock indicators (no phases, or a source without them)"))
    return L + [""]
