"""Receiver realism against real receivers (issue 26): fit on one recording, check on data not used to fit.

Data (``../shared/data``, see its README): the ESBC station (Septentrio PolaRx5, choke ring, C/N0 on every
signal, 2020-06-25) and the OPEC station (Trimble NetR9, 2022-01-01, no C/N0).  Steps, all through the
project's own commands and Debian's RTKLIB (``rnx2rtkp``):

1. ``gnss-sim calibrate`` on ESBC hours 0-12 -> a profile (or ``--profile-file`` to check a given one);
2. the reference antenna positions: RTKLIB static PPP (dual frequency, estimated troposphere) on the real
   files with the precise orbits of the same folders (GRG SP3 + CLK for ESBC, CODE SP3 for OPEC);
3. ``gnss-sim simulate`` of ESBC hours 12..12+H (not used to fit) with the built-in ``geodetic`` profile and
   with the fitted one, and of OPEC's 3.6 h with both; ``gnss-sim compare --mask-deg 10`` against the real
   files: Jaccard of (epoch, satellite, signal) triples, mean C/N0 per signal per 10-deg bin (share of bins
   within 3 dB), code noise (multipath combination) sim/real per signal (share within 0.67-1.5x), LLI at the
   first epoch;
4. single point (RTKLIB: 10 deg mask, broadcast ionosphere, Saastamoinen, same options on both): horizontal
   and vertical RMS against the PPP reference, simulated over real;
5. GPS L1-only RTK on a simulated 1 m baseline (instantaneous ambiguity resolution, ratio 3): fix rate and
   the largest error of a fixed solution (the real pair of the issue: 99.3 % fixed).

Printed: one Markdown table per step.  Takes about 15 minutes on this machine kind (2 cores).

    python bench/bench_realism.py [--hours 12] [--work DIR] [--profile-file FILE.yaml]
"""
from __future__ import annotations

import argparse
import gzip
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))
from gnss_sim_ros2.core.frames import ecef_to_enu, ecef_to_geodetic, enu_to_ecef  # noqa: E402

SHARED = REPO.parent / "shared" / "data"
GNSS_SIM = [sys.executable, "-m", "gnss_sim_ros2.cli"]
ESBC = SHARED / "esbc-2020-177-polarx5"
OPEC = SHARED / "opec-2022-001"
#: RTKLIB pos1-navsys bits: GPS 1, Galileo 8
NAVSYS = {"G": 1, "GE": 9}


def _run(cmd, **kw):
    r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, **kw)
    if r.returncode != 0:
        raise SystemExit(f"bench_realism: {' '.join(map(str, cmd[:4]))} ... failed (rc {r.returncode}):\n"
                         f"{r.stderr[-2000:]}")
    return r


def _gunzip(src: Path, dst: Path) -> Path:
    if not dst.exists():
        with gzip.open(src, "rb") as f, open(dst, "wb") as g:
            shutil.copyfileobj(f, g)
    return dst


def prepare(work: Path) -> dict:
    """Plain copies RTKLIB reads (it reads neither .gz nor Hatanaka)."""
    import hatanaka

    esbc_obs = work / "ESBC_MO.rnx"
    if not esbc_obs.exists():
        esbc_obs.write_bytes(hatanaka.decompress(
            (ESBC / "ESBC00DNK_R_20201770000_01D_30S_MO.crx.gz").read_bytes()))
    return {
        "esbc_obs": esbc_obs,
        "esbc_nav": _gunzip(ESBC / "ESBC00DNK_R_20201770000_01D_MN.rnx.gz", work / "ESBC_MN.rnx"),
        "esbc_sp3": _gunzip(ESBC / "GRG0MGXFIN_20201770000_01D_15M_ORB.SP3.gz", work / "GRG.SP3"),
        "esbc_clk": _gunzip(ESBC / "GRG0MGXFIN_20201770000_01D_30S_CLK.CLK.gz", work / "GRG.CLK"),
        "opec_obs": OPEC / "OPEC00NOR_S_20220010000_0340_30S_MO.rnx",
        "opec_nav": OPEC / "OPEC00NOR_S_20220010000_01D_GN.rnx",
        "opec_nav_all": [OPEC / f"OPEC00NOR_S_20220010000_01D_{s}N.rnx" for s in "GREC"],
        "opec_sp3": OPEC / "COD0MGXFIN_20220010000_01D_05M_ORB.SP3",
    }


def _rtklib_pos(conf: str, out: Path, files, ts=None, te=None) -> np.ndarray:
    """rnx2rtkp solutions as rows (ECEF x, y, z, quality)."""
    cfile = out.with_suffix(".conf")
    cfile.write_text(conf)
    cmd = ["rnx2rtkp"] + (["-ts", *ts.split()] if ts else []) + (["-te", *te.split()] if te else [])
    _run(cmd + ["-k", cfile, "-o", out, *files])
    rows = [ln.split() for ln in out.read_text().splitlines() if ln and not ln.startswith("%")]
    return np.array([[float(r[2]), float(r[3]), float(r[4]), float(r[5])] for r in rows]).reshape(-1, 4)


def ppp_reference(files, out: Path, ts=None, te=None) -> np.ndarray:
    """Static PPP (RTKLIB: L1+L2 ionosphere-free, estimated zenith delay, precise orbits/clocks): the last
    solution, ECEF [m] (the antenna reference point to a few cm, phase centre offsets not applied)."""
    conf = ("pos1-posmode=ppp-static\npos1-elmask=10\npos1-navsys=1\npos1-ionoopt=dual-freq\n"
            "pos1-tropopt=est-ztd\npos1-sateph=precise\nout-solformat=xyz\n")
    sol = _rtklib_pos(conf, out, files, ts, te)
    return sol[-1, :3]


def spp_rms(obs, nav, ref, systems: str, out: Path, ts=None, te=None) -> tuple[float, float]:
    """RTKLIB single point: (horizontal RMS, vertical RMS) [m] against ``ref``."""
    conf = (f"pos1-posmode=single\npos1-elmask=10\npos1-navsys={NAVSYS[systems]}\npos1-ionoopt=brdc\n"
            "pos1-tropopt=saas\nout-solformat=xyz\n")
    sol = _rtklib_pos(conf, out, [obs, nav], ts, te)
    enu = ecef_to_enu(sol[:, :3], *ecef_to_geodetic(*ref))
    return float(np.sqrt(np.mean(enu[:, 0] ** 2 + enu[:, 1] ** 2))), float(np.sqrt(np.mean(enu[:, 2] ** 2)))


def simulate(out: Path, nav, position, start: str, duration_s: float, profile, seed: int = 1,
             systems: str | None = None, marker: str = "SIMU") -> Path:
    if out.exists():
        shutil.rmtree(out)
    cmd = GNSS_SIM + ["simulate", "--quiet", "--nav", *([nav] if isinstance(nav, (str, Path)) else nav),
                      "--position-ecef", ",".join(f"{v:.4f}" for v in position), "--start", start,
                      "--duration", duration_s, "--interval", 30 if duration_s > 3600 else 10,
                      "--profile", profile, "--seed", seed, "--marker", marker, "--out", out]
    if systems:
        cmd += ["--systems", systems]
    _run(cmd, cwd=REPO)
    return next(out.glob("*_MO.rnx"))


def compare_signals(sim_obs, real_obs, nav, truth, out: Path) -> dict:
    if out.exists():
        shutil.rmtree(out)
    _run(GNSS_SIM + ["compare", "--quiet", "--sim", sim_obs, "--real", real_obs, "--nav", *nav, "--truth",
                     ",".join(f"{v:.4f}" for v in truth), "--mask-deg", 10, "--out", out], cwd=REPO)
    return json.loads((out / "signals.json").read_text())["comparison"]


def signal_figures(cmp: dict) -> dict:
    """Acceptance figures of issue 26 from a compare's signals.json."""
    diffs, ratios = [], []
    for key, row in cmp["signals"].items():
        if key.startswith("("):
            continue
        for c, d in zip(row.get("el_centres_deg", []), row.get("cn0_diff_db", [])):
            if d is not None and c > 10:
                diffs.append(d)
        if row.get("code_ratio") is not None:
            ratios.append(row["code_ratio"])
    diffs, ratios = np.array(diffs), np.array(ratios)
    lf = cmp["lli_first"]
    return {
        "jaccard": cmp["jaccard_all"],
        "cn0_bins": len(diffs),
        "cn0_within_3db": float(np.mean(np.abs(diffs) <= 3.0)) if len(diffs) else None,
        "cn0_median_abs_db": float(np.median(np.abs(diffs))) if len(diffs) else None,
        "code_signals": len(ratios),
        "code_within": float(np.mean((ratios >= 0.67) & (ratios <= 1.5))) if len(ratios) else None,
        "code_ratio_range": (float(ratios.min()), float(ratios.max())) if len(ratios) else None,
        "lli_first_sim": lf["sim"]["bit0_share"], "lli_first_real": lf["real"]["bit0_share"],
    }


def rtk_l1(work: Path, nav, base, start: str, profile, duration_s: float = 3600) -> dict:
    """GPS L1 RTK of a rover 1 m east of the base (both simulated, one world: same world seed)."""
    rover = enu_to_ecef(np.array([1.0, 0.0, 0.0]), *ecef_to_geodetic(*base))    # 1 m east
    b = simulate(work / "rtk_base", nav, base, start, duration_s, profile, seed=11, systems="G", marker="BASE")
    r = simulate(work / "rtk_rover", nav, rover, start, duration_s, profile, seed=12, systems="G",
                 marker="ROVR")
    conf = ("pos1-posmode=kinematic\npos1-frequency=l1\npos1-elmask=10\npos1-navsys=1\n"
            "pos2-armode=instantaneous\npos2-arthres=3\npos1-ionoopt=brdc\npos1-tropopt=saas\n"
            "ant2-postype=xyz\n" + "".join(f"ant2-pos{i + 1}={v:.4f}\n" for i, v in enumerate(base))
            + "out-solformat=xyz\n")
    sol = _rtklib_pos(conf, work / "rtk.pos", [r, b, nav])
    err = np.linalg.norm(sol[:, :3] - rover, axis=1)
    fixed = sol[:, 3] == 1
    return {"epochs": len(sol), "fix_rate": float(fixed.mean()) if len(sol) else 0.0,
            "max_fixed_error_m": float(err[fixed].max()) if fixed.any() else None,
            "fixed_over_10cm": int((err[fixed] > 0.10).sum())}


def _label(profile: str) -> str:
    return "geodetic" if profile == "geodetic" else "fitted on ESBC 0-12 h"


def _f(v, d=2):
    if v is None:
        return "-"
    if isinstance(v, tuple):
        return "-".join(f"{x:.{d}f}" for x in v)
    return f"{v:.{d}f}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=12.0, help="checked span of ESBC after hour 12 [h] (12)")
    ap.add_argument("--work", help="working folder (kept; default a temporary one)")
    ap.add_argument("--profile-file", help="check this profile instead of calibrating one on ESBC 0-12 h")
    a = ap.parse_args(argv)
    if not ESBC.is_dir() or not OPEC.is_dir():
        print(f"bench_realism: the real data {SHARED} is absent (it exists beside the clone in CI only)")
        return 2
    work = Path(a.work) if a.work else Path(tempfile.mkdtemp(prefix="gnss_sim_realism_"))
    work.mkdir(parents=True, exist_ok=True)
    f = prepare(work)

    if a.profile_file:
        fitted = Path(a.profile_file).resolve()
    else:
        cal = work / "calibrate"
        if cal.exists():
            shutil.rmtree(cal)
        _run(GNSS_SIM + ["calibrate", "--quiet", "--obs", ESBC / "ESBC00DNK_R_20201770000_01D_30S_MO.crx.gz",
                         "--nav", f["esbc_nav"], "--start", "2020-06-25T00:00:00", "--duration", 43200,
                         "--name", "esbc_fit_0_12", "--out", cal], cwd=REPO)
        fitted = next(cal.glob("*.yaml"))
    print(f"profile checked: {fitted}")

    if not 0 < a.hours <= 12:
        raise SystemExit("bench_realism: --hours must be in (0, 12] (ESBC's file ends at 24 h)")
    end_s = 12 * 3600 + int(a.hours * 3600) - 30            # the last 30 s epoch of the checked span
    t0, t1 = "2020/06/25 12:00:00", f"2020/06/25 {end_s // 3600:02d}:{end_s % 3600 // 60:02d}:{end_s % 60:02d}"
    ref_esbc = ppp_reference([f["esbc_obs"], f["esbc_nav"], f["esbc_sp3"], f["esbc_clk"]],
                             work / "esbc_ppp.pos", "2020/06/25 08:00:00", t1)
    ref_opec = ppp_reference([f["opec_obs"], f["opec_nav"], f["opec_sp3"]], work / "opec_ppp.pos")
    print(f"PPP reference ESBC {ref_esbc.round(4).tolist()}, OPEC {ref_opec.round(4).tolist()}")

    dur = 3600.0 * a.hours
    cases = []
    for prof in ("geodetic", str(fitted)):
        name = _label(prof)
        sim = simulate(work / f"esbc_{len(cases)}", f["esbc_nav"], ref_esbc, "2020-06-25T12:00:00", dur, prof)
        sig = signal_figures(compare_signals(sim, f["esbc_obs"], [f["esbc_nav"]], ref_esbc,
                                             work / f"cmp_esbc_{len(cases)}"))
        spp = {s: (spp_rms(sim, f["esbc_nav"], ref_esbc, s, work / f"spp_sim_{len(cases)}_{s}.pos"),
                   spp_rms(f["esbc_obs"], f["esbc_nav"], ref_esbc, s, work / f"spp_real_esbc_{s}.pos", t0, t1))
               for s in ("G", "GE")}
        cases.append((f"ESBC 12-{12 + a.hours:g} h", name, sig, spp))
        sim = simulate(work / f"opec_{len(cases)}", f["opec_nav_all"], ref_opec, "2022-01-01T00:00:00",
                       13170.0, prof, systems="GREC")
        sig = signal_figures(compare_signals(sim, f["opec_obs"], f["opec_nav_all"], ref_opec,
                                             work / f"cmp_opec_{len(cases)}"))
        spp = {"G": (spp_rms(sim, f["opec_nav"], ref_opec, "G", work / f"spp_sim_opec_{len(cases)}.pos"),
                     spp_rms(f["opec_obs"], f["opec_nav"], ref_opec, "G", work / "spp_real_opec.pos"))}
        cases.append(("OPEC 0-3.6 h", name, sig, spp))
    # single point over the whole day and per 6 h (the ionosphere's error follows the time of day: one window is
    # one sample of it): the built-in geodetic profile, G and GE, against the real file's same windows
    day = simulate(work / "esbc_day", f["esbc_nav"], ref_esbc, "2020-06-25T00:00:00", 86370.0, "geodetic",
                   systems="GE")
    windows = [("0-24 h", "00:00:00", "23:59:30")] + [(f"{h}-{h + 6} h", f"{h:02d}:00:00", f"{h + 5:02d}:59:30")
                                                     for h in (0, 6, 12, 18)]
    spp_day = []
    for label, w0, w1 in windows:
        ts, te = f"2020/06/25 {w0}", f"2020/06/25 {w1}"
        spp_day.append((f"ESBC {label}", {
            s: (spp_rms(day, f["esbc_nav"], ref_esbc, s, work / f"spp_day_{s}.pos", ts, te),
                spp_rms(f["esbc_obs"], f["esbc_nav"], ref_esbc, s, work / f"spp_day_real_{s}.pos", ts, te))
            for s in ("G", "GE")}))

    print("\n| data (not fitted on) | profile | Jaccard | C/N0 bins within 3 dB | median abs C/N0 diff [dB] | "
          "code noise within 0.67-1.5x | code noise ratios | LLI bit 0 at first epoch sim / real |")
    print("|---|---|---|---|---|---|---|---|")
    for data, name, s, _ in cases:
        cn0 = f"{100 * s['cn0_within_3db']:.0f} % of {s['cn0_bins']}" if s["cn0_within_3db"] is not None else "-"
        code = f"{100 * s['code_within']:.0f} % of {s['code_signals']}" if s["code_within"] is not None else "-"
        lli = f"{_f(s['lli_first_sim'])} / {_f(s['lli_first_real'])}"
        print(f"| {data} | {name} | {_f(s['jaccard'], 3)} | {cn0} | {_f(s['cn0_median_abs_db'], 1)} | {code} | "
              f"{_f(s['code_ratio_range'])} | {lli} |")
    print("\n| data | profile | systems | H RMS sim / real [m] | ratio | V RMS sim / real [m] | ratio |")
    print("|---|---|---|---|---|---|---|")
    for data, name, _, spp in cases:
        for s, ((hs, vs), (hr, vr)) in spp.items():
            print(f"| {data} | {name} | {s} | {hs:.2f} / {hr:.2f} | {hs / hr:.2f} | {vs:.2f} / {vr:.2f} | "
                  f"{vs / vr:.2f} |")
    for data, spp in spp_day:
        for s, ((hs, vs), (hr, vr)) in spp.items():
            print(f"| {data} | geodetic | {s} | {hs:.2f} / {hr:.2f} | {hs / hr:.2f} | {vs:.2f} / {vr:.2f} | "
                  f"{vs / vr:.2f} |")
    print("\n| GPS L1 RTK, 1 m simulated baseline, instantaneous AR | profile | epochs | fixed | largest fixed "
          "error [m] | fixed > 10 cm |")
    print("|---|---|---|---|---|---|")
    for prof in ("geodetic", str(fitted)):
        r = rtk_l1(work, f["esbc_nav"], ref_esbc, "2020-06-25T12:00:00", prof)
        name = _label(prof)
        print(f"| ESBC sky 12-13 h | {name} | {r['epochs']} | {100 * r['fix_rate']:.1f} % | "
              f"{_f(r['max_fixed_error_m'], 3)} | {r['fixed_over_10cm']} |")
    print(f"\nworking files: {work}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
