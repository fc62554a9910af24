"""The offline speed targets of issue 18, measured in one run (``gnss-sim bench --speed``).

* ``demo hour``: ``gnss-sim simulate --duration 3600 --quiet --out DIR`` (the demo: courtyard world,
  demo path, every system, default preset, 1 Hz), a child process timed from its start to its end
  (start-up included); the real-time factor is 3600 s over that wall time (target >= 1000).
* ``GPS static hour``: gnss_lib_py's own kind of scenario -- GPS only, a static station (the OPEC
  marker), 1 h at 1 Hz -- run by ``gnss-sim simulate --systems G --position-ecef ...`` and by
  gnss_lib_py's ``simulate_measures`` (bench/peer_gnss_lib_py.py: its RinexNav parsing the synthetic
  GPS navigation file of the span, one call per epoch), both child processes timed the same way;
  the ratio is gnss_lib_py's wall time over gnss_sim's (target >= 20).  gnss_lib_py pins other
  pandas/xarray/georinex versions than gnss_sim, so it runs in the interpreter given by
  ``--peer-python`` (or GNSS_SIM_PEER_PYTHON), a venv of its own (requirements/bench-peer.txt);
  without one that imports it the ratio is reported as skipped, with the reason.
* ``GPS hour, real navigation file``: the whole job as a user runs it -- the same static GPS hour from the
  OPEC station's daily GPS navigation file (../shared/data/opec-2022-001, 2022-01-01 12:00-13:00), gnss_sim
  ``--nav FILE`` against the peer script on the same file.  gnss_sim twice per repeat: ``cold`` with an empty
  cache folder (``GNSS_SIM_CACHE``: the file parsed by georinex), ``warm`` right after it (the parsed records
  from core/rinex/nav/cache.py); the ratios to the peer's time of the same run.  Skipped when the data is absent.

Each child is run ``repeats`` times, alternating, the shortest wall time kept (other processes on a
shared machine only ever add time); CPU time (user + system of the child) is reported beside it.
"""
from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from gnss_sim_ros2.core.demo import DEMO_START

DEMO_TARGET_RTF = 1000.0
PEER_TARGET_RATIO = 20.0
#: the OPEC marker (benchmarks/presets.py OPEC_ECEF_M): a static station
GPS_STATION_ECEF_M = (3149785.9652, 598260.8822, 5495348.4927)
#: the real daily GPS navigation file of that station and the hour simulated from it
REAL_NAV = Path("opec-2022-001") / "OPEC00NOR_S_20220010000_01D_GN.rnx"
REAL_START = "2022-01-01T12:00:00"
PEER_SCRIPT = Path(__file__).resolve().parents[2] / "bench" / "peer_gnss_lib_py.py"


def _timed(cmd, env=None, cwd=None) -> dict:
    """Wall and CPU time [s] of a child process; its standard output."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=cwd)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, cmd[:4]))} ... failed ({p.returncode}): {p.stderr.strip()[-800:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall_s": wall, "cpu_s": cpu, "stdout": p.stdout}


def peer_python(given: str | None) -> tuple[str | None, str]:
    """(interpreter with gnss_lib_py or None, why not)."""
    candidates = [given] if given else [os.environ.get("GNSS_SIM_PEER_PYTHON") or "", sys.executable]
    for py in [c for c in candidates if c]:
        try:
            r = subprocess.run([py, "-c", "import gnss_lib_py"], capture_output=True, text=True, timeout=120)
        except (OSError, subprocess.TimeoutExpired) as e:
            if given:
                return None, f"--peer-python {py}: {e}"
            continue
        if r.returncode == 0:
            return py, ""
        if given:
            return None, f"--peer-python {py} cannot import gnss_lib_py"
    return None, ("gnss_lib_py not importable (pip install gnss-lib-py in a venv of its own and give its "
                  "python with --peer-python or GNSS_SIM_PEER_PYTHON)")


def run_speed(duration_s: float = 3600.0, repeats: int = 3, peer: str | None = None, log=print,
              real: bool = True) -> dict:
    from gnss_sim_ros2.benchmarks.presets import shared_data_dir
    from gnss_sim_ros2.core.ephemeris.synthetic import write_synthetic_nav
    from gnss_sim_ros2.core.time import GnssTime

    if not duration_s > 0 or repeats < 1:
        raise ValueError(f"duration {duration_s!r} must be > 0 and repeats {repeats!r} >= 1")
    py, why = peer_python(peer)
    if peer and py is None:      # the interpreter the user named: refused up front (was a note after the runs)
        raise ValueError(why)
    work = Path(tempfile.mkdtemp(prefix="gnss_sim_speed_"))
    env = dict(os.environ)
    repo = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = repo + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    # the children start from compiled modules, as an installed package (pip compiles at install, and the
    # peer's site-packages are compiled): a shell with PYTHONDONTWRITEBYTECODE would otherwise make every
    # gnss_sim run compile its sources again (about 0.1 s), the peer's not
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env.pop("GNSS_SIM_NAV_CACHE", None)
    cache = work / "cache"
    env["GNSS_SIM_CACHE"] = str(cache)       # never the user's cache: cold runs start from an empty one
    peer_env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    subprocess.run([sys.executable, "-m", "compileall", "-q", str(Path(repo) / "gnss_sim_ros2")],
                   capture_output=True, env=env)
    sim = [sys.executable, "-m", "gnss_sim_ros2.cli", "simulate", "--duration", f"{duration_s:g}", "--quiet"]
    demo_cmd = sim + ["--out", str(work / "demo")]
    xyz = ",".join(f"{v:.4f}" for v in GPS_STATION_ECEF_M)
    gps_cmd = sim + ["--systems", "G", "--position-ecef", xyz, "--start", DEMO_START, "--out", str(work / "gps")]
    peer_cmd = None
    if py is not None:
        start = GnssTime.from_iso(DEMO_START)
        nav = write_synthetic_nav(work / "gps_nav.rnx", start - 7200.0, duration_s + 4 * 3600.0, systems="G")
        peer_cmd = [py, str(PEER_SCRIPT), str(nav), str(int(start.sec) * 1000), f"{duration_s:g}", "1", xyz]
    real_nav = shared_data_dir() / REAL_NAV
    real_why = "" if real else "not asked (--no-real)"
    if real and not real_nav.is_file():
        real_why = f"{real_nav} not found (GNSS_SIM_SHARED_DATA)"
    real_cmd = real_peer_cmd = None
    if not real_why:
        real_cmd = sim + ["--nav", str(real_nav), "--systems", "G", "--position-ecef", xyz, "--start", REAL_START,
                          "--out", str(work / "real")]
        if py is not None:
            real_start_ms = int(GnssTime.from_iso(REAL_START).sec) * 1000
            real_peer_cmd = [py, str(PEER_SCRIPT), str(real_nav), str(real_start_ms), f"{duration_s:g}", "1", xyz]
    runs = {"demo": [], "gps": [], "peer": [], "real_cold": [], "real_warm": [], "real_peer": []}
    for r in range(repeats):
        for name, cmd, e in (("demo", demo_cmd, env), ("gps", gps_cmd, env), ("peer", peer_cmd, peer_env),
                             ("real_cold", real_cmd, env), ("real_warm", real_cmd, env),
                             ("real_peer", real_peer_cmd, peer_env)):
            if cmd is None:
                continue
            if name == "real_cold":
                shutil.rmtree(cache, ignore_errors=True)
            # in the repository: `python -m` puts the working folder first on the path (another checkout there
            # would be run instead)
            got = _timed(cmd, e, repo if e is env else str(work))
            if name in ("peer", "real_peer"):
                got["peer"] = json.loads(got["stdout"].strip().splitlines()[-1])
            got.pop("stdout")
            runs[name].append(got)
            log(f"[bench --speed] run {r + 1}/{repeats} {name}: {got['wall_s']:.2f} s wall, {got['cpu_s']:.2f} s CPU")
    best = {k: min(v, key=lambda x: x["wall_s"]) for k, v in runs.items() if v}
    epochs = int(duration_s) + 1
    rep = {"duration_s": duration_s, "epochs": epochs, "repeats": repeats, "machine": _machine(), "runs": runs,
           "demo": {"command": "gnss-sim " + " ".join(demo_cmd[3:]), "wall_s": best["demo"]["wall_s"],
                    "cpu_s": best["demo"]["cpu_s"], "realtime_factor": duration_s / best["demo"]["wall_s"],
                    "cpu_realtime_factor": duration_s / max(best["demo"]["cpu_s"], 1e-9),
                    "target_realtime_factor": DEMO_TARGET_RTF},
           "gps_static": {"gnss_sim_wall_s": best["gps"]["wall_s"], "gnss_sim_cpu_s": best["gps"]["cpu_s"],
                          "gnss_sim_epochs_per_s": epochs / best["gps"]["wall_s"],
                          "target_ratio": PEER_TARGET_RATIO}}
    g = rep["gps_static"]
    if "peer" in best:
        g.update({"gnss_lib_py_wall_s": best["peer"]["wall_s"], "gnss_lib_py_cpu_s": best["peer"]["cpu_s"],
                  "gnss_lib_py_epochs_per_s": epochs / best["peer"]["wall_s"], "gnss_lib_py": best["peer"]["peer"],
                  "ratio": best["peer"]["wall_s"] / best["gps"]["wall_s"],
                  "cpu_ratio": best["peer"]["cpu_s"] / max(best["gps"]["cpu_s"], 1e-9), "peer_python": py})
    else:
        g["skipped"] = why
    rep["real_nav"] = _real_figures(best, epochs, str(real_nav), real_why or ("" if py else why))
    rep["demo"]["target_met"] = rep["demo"]["realtime_factor"] >= DEMO_TARGET_RTF
    if "ratio" in g:
        g["target_met"] = g["ratio"] >= PEER_TARGET_RATIO
    return rep


def _real_figures(best: dict, epochs: int, nav: str, why: str) -> dict:
    """The whole job from the real navigation file: gnss_sim cold and warm, the peer, their ratios."""
    if "real_cold" not in best:
        return {"skipped": why}
    out = {"nav": nav, "start": REAL_START, "target_ratio": PEER_TARGET_RATIO}
    for k in ("cold", "warm"):
        out[f"gnss_sim_{k}_wall_s"] = best[f"real_{k}"]["wall_s"]
        out[f"gnss_sim_{k}_cpu_s"] = best[f"real_{k}"]["cpu_s"]
    if "real_peer" not in best:
        out["peer_skipped"] = why
        return out
    p = best["real_peer"]
    out.update({"gnss_lib_py_wall_s": p["wall_s"], "gnss_lib_py_cpu_s": p["cpu_s"], "gnss_lib_py": p["peer"]})
    for k in ("cold", "warm"):
        out[f"ratio_{k}"] = p["wall_s"] / out[f"gnss_sim_{k}_wall_s"]
        out[f"cpu_ratio_{k}"] = p["cpu_s"] / max(out[f"gnss_sim_{k}_cpu_s"], 1e-9)
    out["target_met"] = out["ratio_warm"] >= PEER_TARGET_RATIO
    return out


def _machine() -> str:
    import platform

    return f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, " \
           f"load average {os.getloadavg()[0]:.1f} at the end"


def speed_table(rep: dict) -> str:
    d, g = rep["demo"], rep["gps_static"]
    lines = [f"offline speed, {rep['duration_s']:g} s at 1 Hz, start-up included, best of {rep['repeats']} "
             f"({rep['machine']})",
             f"  demo (courtyard, demo path, GRECJI, default preset): {d['wall_s']:.2f} s wall, {d['cpu_s']:.2f} s CPU"
             f" -> {d['realtime_factor']:.0f}x real time (CPU {d['cpu_realtime_factor']:.0f}x; target "
             f">= {d['target_realtime_factor']:.0f}x: {'met' if d['target_met'] else 'not met'})",
             f"  GPS static: gnss_sim {g['gnss_sim_wall_s']:.2f} s wall, {g['gnss_sim_cpu_s']:.2f} s CPU "
             f"({g['gnss_sim_epochs_per_s']:.0f} epochs/s)"]
    if "ratio" in g:
        lines.append(f"              gnss_lib_py simulate_measures {g['gnss_lib_py_wall_s']:.2f} s wall, "
                     f"{g['gnss_lib_py_cpu_s']:.2f} s CPU ({g['gnss_lib_py_epochs_per_s']:.0f} epochs/s)")
        lines.append(f"              ratio {g['ratio']:.1f}x wall, {g['cpu_ratio']:.1f}x CPU (target "
                     f">= {g['target_ratio']:.0f}x: {'met' if g['target_met'] else 'not met'})")
    else:
        lines.append(f"              gnss_lib_py: skipped ({g['skipped']})")
    r = rep.get("real_nav", {})
    if "skipped" in r:
        lines.append(f"  GPS hour, real navigation file: skipped ({r['skipped']})")
    elif r:
        lines.append(f"  GPS hour, real navigation file (OPEC {r['start'][:10]}, whole job): gnss_sim cold "
                     f"{r['gnss_sim_cold_wall_s']:.2f} s wall, {r['gnss_sim_cold_cpu_s']:.2f} s CPU; warm (parsed "
                     f"navigation cached) {r['gnss_sim_warm_wall_s']:.2f} s wall, {r['gnss_sim_warm_cpu_s']:.2f} s CPU")
        if "ratio_warm" in r:
            lines.append(f"              gnss_lib_py {r['gnss_lib_py_wall_s']:.2f} s wall, "
                         f"{r['gnss_lib_py_cpu_s']:.2f} s CPU")
            lines.append(f"              ratio cold {r['ratio_cold']:.1f}x wall ({r['cpu_ratio_cold']:.1f}x CPU), warm "
                         f"{r['ratio_warm']:.1f}x wall ({r['cpu_ratio_warm']:.1f}x CPU) (target >= "
                         f"{r['target_ratio']:.0f}x: {'met' if r['target_met'] else 'not met'})")
        else:
            lines.append(f"              gnss_lib_py: skipped ({r['peer_skipped']})")
    return "\n".join(lines)
