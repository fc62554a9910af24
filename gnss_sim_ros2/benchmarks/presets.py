"""Speed against accuracy of the fidelity presets (core/presets.py): the harness of ``gnss-sim bench``
(commands/bench.py is its command line).

Runs the same scenarios under every preset, in this process (run_simulation),
prints a table and optionally writes JSON (``--json FILE``) and a cost/accuracy
plot (``--plot FILE.png``).

Scenarios
---------
* ``demo``: the courtyard world (worlds/courtyard.sdf) with the demo path
  looped, the synthetic GRECJI constellation, 2025-06-01T10:00:00 GPS,
  600 s (``--quick``: 300 s), each preset at its own epoch interval
  (presets ``epoch_interval_s``: fast 10 s, balanced/accurate 1 s).
* ``opec``: the OPEC station (NETR9, 2022-01-01, open sky) when the real data
  is present (GNSS_SIM_SHARED_DATA or ../shared/data beside the repository):
  static antenna at the marker, broadcast GPS+Galileo navigation (and the
  CODE SP3 for the ``orbit: precise`` switch), 30 s epochs as the real file,
  03:39:30 h (``--quick``: the first hour).

Figures per preset (JSON ``presets[i]``)
----------------------------------------
* ``realtime_factor``: simulated seconds per wall-clock second of the epoch
  loop of the demo scenario (run_simulation's ``wall_s``: ephemeris/scene
  loading excluded, reported as ``setup_s``); the best (shortest) of
  ``repeats`` runs (default 3), because on a shared machine other processes
  only ever add time.  Runs are repeated further (up to MAX_RUNS, within
  MAX_TIMED_S per preset) while none was "clean" (wall time <= 1.1 x the
  process's CPU time: the loop is single-threaded Python, so a larger ratio
  means another process held the core) or while they add up to less than
  MIN_TIMED_S; the presets' runs alternate.  ``seconds_per_epoch``: that wall time per epoch.  Nested:
  every run's wall and CPU time, ``clean_run`` and ``cpu_realtime_factor``
  (simulated seconds per CPU second, insensitive to other processes).
* ``pseudorange_rms_m``: against the real receiver when the OPEC data is
  present (simulated minus real GPS C1C per satellite and epoch, one receiver
  clock offset per epoch removed as the median over satellites, |d| > 30 m
  dropped as gross; default noise on, seed 1), else against the ``accurate``
  preset (simulated pseudoranges of the signals both runs track at their
  common epochs, noise off in both runs so that only model differences
  remain).
* ``visible_set_jaccard``: mean over epochs of |A & B| / |A | B| of the sets
  of tracked satellites: against the real receiver (GPS+Galileo satellites
  above 10 deg by the simulated geometry; the real set = satellites with a
  code observation) when present, else against ``accurate`` (noise off).
* ``fix_horizontal_rms_m``: RMS horizontal error of the simulated receiver's
  position fix against the true antenna position (OPEC marker when present,
  else the demo path), default noise.
* ``against``: what the three figures above are measured against.
Nested: ``demo`` and ``opec`` blocks with every figure of each comparison.
"""
from __future__ import annotations

import os
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from gnss_sim_ros2.core.demo import DEMO_START
from gnss_sim_ros2.core.metrics import horizontal_errors_m, p95, rms

PRESET_ORDER = ("fast", "balanced", "accurate")
OPEC_START = "2022-01-01T00:00:00"
OPEC_ECEF_M = (3149785.9652, 598260.8822, 5495348.4927)
OPEC_REAL_OBS = "OPEC00NOR_S_20220010000_0340_30S_MO.rnx"
#: first code of each system in the real OPEC file (GPS C/A; Galileo E1 B+C)
OPEC_CODE = {"G": "C1C", "E": "C1X"}
GROSS_M = 30.0
#: timed runs of one preset are repeated (best kept) until they add up to this [s], at most MAX_RUNS runs
MIN_TIMED_S = 5.0
MAX_RUNS = 20
#: more runs while no run was clean, until the runs of one preset add up to this [s]
MAX_TIMED_S = 15.0
#: a run is clean when its wall time is at most this times its CPU time
CLEAN_RATIO = 1.1
REAL_MASK_DEG = 10.0


def shared_data_dir() -> Path:
    """GNSS_SIM_SHARED_DATA, else ../shared/data beside the repository (as test/conftest.py)."""
    repo = Path(__file__).resolve().parents[2]
    return Path(os.environ.get("GNSS_SIM_SHARED_DATA", repo.parent / "shared" / "data"))


# ============================================================================ collection
class Recorder:
    """Observer for run_simulation: what the comparisons need from each epoch."""

    def __init__(self, systems: str):
        self.systems = systems
        self.epochs: dict[int, dict] = {}

    def __call__(self, t, true_ecef, obs, sol):
        key = int(np.asarray(t.sec)) * 1_000_000 + int(round(float(np.asarray(t.frac)) * 1e6))
        sv = obs.sv.tolist()
        self.epochs[key] = {
            "tracked": {s for s in sv if s[0] in self.systems},
            "pr": {(s, c): p for s, c, p in zip(sv, obs.code.tolist(), obs.pseudorange_m.tolist())},
            "el": dict(zip(obs.sat_sv.tolist(), obs.sat_el_deg.tolist())),
            "fix": None if not sol.is_fix else np.asarray(sol.pos_ecef_m, dtype=float),
            "true": np.asarray(true_ecef, dtype=float),
        }


def _rms(x) -> float | None:
    return rms(x, skip_nonfinite=True)


def _jaccard(a: set, b: set) -> float:
    u = a | b
    return 1.0 if not u else len(a & b) / len(u)


def compare_runs(run: Recorder, ref: Recorder) -> dict:
    """Pseudoranges, tracked sets and fixes of ``run`` against ``ref`` at their common epochs."""
    common = sorted(set(run.epochs) & set(ref.epochs))
    d, jac, fa, fb = [], [], [], []
    for key in common:
        a, b = run.epochs[key], ref.epochs[key]
        d.extend(a["pr"][k] - b["pr"][k] for k in a["pr"].keys() & b["pr"].keys())
        jac.append(_jaccard(a["tracked"], b["tracked"]))
        if a["fix"] is not None and b["fix"] is not None:
            fa.append(a["fix"])
            fb.append(b["fix"])
    fix_diff = horizontal_errors_m(np.array(fa), np.array(fb)) if fa else np.zeros(0)
    return {"epochs": len(common), "signals": len(d), "pseudorange_rms_m": _rms(d),
            "pseudorange_max_abs_m": float(np.max(np.abs(d))) if d else None,
            "visible_set_jaccard": float(np.mean(jac)) if jac else None,
            "fix_difference_horizontal_rms_m": _rms(fix_diff)}


def fix_error(run: Recorder) -> dict:
    est = [e["fix"] for e in run.epochs.values() if e["fix"] is not None]
    true = [e["true"] for e in run.epochs.values() if e["fix"] is not None]
    h = horizontal_errors_m(np.array(est), np.array(true)) if est else np.zeros(0)
    return {"fix_horizontal_rms_m": _rms(h), "fix_horizontal_p95_m": p95(h),
            "fix_availability": len(est) / max(len(run.epochs), 1)}


# ============================================================================ real data
class RealObs:
    """Code observations of the real OPEC receiver: keys (GPS seconds * 1e6) -> {sv: code [m]}."""

    def __init__(self, path: Path, systems: str):
        import georinex as gr

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ds = gr.load(path, use=set(systems), meas=sorted({OPEC_CODE[s] for s in systems}))
        t0 = np.datetime64("1980-01-06T00:00:00", "us")
        secs = ((ds.time.values.astype("datetime64[us]") - t0) / np.timedelta64(1, "s")).astype(np.int64)
        svs = [str(v) for v in ds.sv.values]
        cols = {s: np.asarray(ds[OPEC_CODE[s]].values, dtype=float) if OPEC_CODE[s] in ds else None for s in systems}
        self.epochs: dict[int, dict[str, float]] = {}
        for i, sec in enumerate(secs):
            row = {}
            for j, sv in enumerate(svs):
                col = cols.get(sv[0])
                if col is not None and np.isfinite(col[i, j]):
                    row[sv] = float(col[i, j])
            self.epochs[int(sec) * 1_000_000] = row


def compare_real(run: Recorder, real: RealObs) -> dict:
    """Simulated minus real GPS C1C (one clock offset per epoch removed) and tracked sets above 10 deg."""
    common = sorted(set(run.epochs) & set(real.epochs))
    d, jac = [], []
    for key in common:
        a, r = run.epochs[key], real.epochs[key]
        sim_c1c = {s: p for (s, c), p in a["pr"].items() if s[0] == "G" and c == "1C"}
        both = sorted(sim_c1c.keys() & {s for s in r if s[0] == "G"})
        if len(both) >= 2:
            x = np.array([sim_c1c[s] - r[s] for s in both])
            x = x - np.median(x)
            d.extend(x[np.abs(x) <= GROSS_M].tolist())
        high = {s for s, e in a["el"].items() if e >= REAL_MASK_DEG and s[0] in run.systems}
        jac.append(_jaccard(a["tracked"] & high, set(r) & high))
    return {"epochs": len(common), "samples": len(d), "pseudorange_rms_m": _rms(d),
            "visible_set_jaccard": float(np.mean(jac)) if jac else None}


# ============================================================================ scenarios
def _demo_setup(out: Path, duration_s: float, scene, ephemeris):
    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.core.simulation import setup_from_config
    from gnss_sim_ros2.core.time import GnssTime
    from gnss_sim_ros2.core.trajectory import demo_trajectory

    return setup_from_config(load_config(), out, demo_trajectory(loop=True), start=GnssTime.from_iso(DEMO_START),
                             duration_s=duration_s, interval_s=0.0, scene=scene, ephemeris=ephemeris).with_params(
        systems="GRECJI", source="synthetic")


def _opec_setup(out: Path, duration_s: float, data: Path, ephemeris):
    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.core.simulation import setup_from_config
    from gnss_sim_ros2.core.time import GnssTime
    from gnss_sim_ros2.core.trajectory import Trajectory

    d = data / "opec-2022-001"
    return setup_from_config(load_config(), out, Trajectory.static(OPEC_ECEF_M, "ecef"),
                             start=GnssTime.from_iso(OPEC_START), duration_s=duration_s, interval_s=30.0,
                             ephemeris=ephemeris).with_params(
        systems="GE", source="broadcast", nav_files=[str(d / f"OPEC00NOR_S_20220010000_01D_{s}N.rnx") for s in "GE"],
        sp3_files=[str(d / "COD0MGXFIN_20220010000_01D_05M_ORB.SP3")], marker_name="OPEC")


def _run(setup, preset: str, noise: bool | None, record: bool, tag: str):
    import dataclasses

    from gnss_sim_ros2.core.simulation import run_simulation

    rec = Recorder(setup.systems) if record else None
    sw = {} if noise is None else {"noise": bool(noise)}
    s = dataclasses.replace(setup, switches=sw, observer=rec, out_dir=Path(setup.out_dir) / tag).with_params(
        preset=preset)
    res = run_simulation(s)
    return res, rec


def _clean(walls, cpus) -> bool:
    """Did at least one run keep its core (wall <= CLEAN_RATIO x CPU time)?"""
    return any(w <= CLEAN_RATIO * max(c, 1e-9) for w, c in zip(walls, cpus))


def bench_scenario(name: str, setup, presets, repeats: int, real: RealObs | None, log) -> dict:
    """Timed runs (default noise) and noise-free runs of every preset; comparisons.

    The timed runs go round-robin over the presets (fast, balanced, accurate, fast, ...), so that a
    burst of load from other processes hits every preset instead of all runs of one."""
    out = {"presets": {}}
    walls = {p: [] for p in presets}
    cpus = {p: [] for p in presets}
    first = {}

    def more(p, r):
        # at least `repeats` runs, more (within MAX_TIMED_S and MAX_RUNS) while they add up to less than
        # MIN_TIMED_S or none was clean (the loop is single-threaded Python: a wall time above
        # CLEAN_RATIO x the CPU time means another process held the core)
        w = sum(walls[p])
        return r < repeats or (repeats > 1 and r < MAX_RUNS and w < MAX_TIMED_S
                               and (w < MIN_TIMED_S or not _clean(walls[p], cpus[p])))

    r = 0
    while any(more(p, r) for p in presets):
        for p in presets:
            if more(p, r):
                res, rec = _run(setup, p, None, record=(r == 0), tag=f"{p}_{r % 2}")
                walls[p].append(res.wall_s)
                cpus[p].append(res.cpu_s)
                if r == 0:
                    first[p] = (res, rec)
        r += 1
    free: dict[str, Recorder] = {}
    for p in presets:
        res, rec = first[p]
        best = min(walls[p])
        entry = {"epochs": res.epochs, "interval_s": res.interval_s, "simulated_s": res.sim_s,
                 "orbit_source": res.orbit_source, "wall_s_runs": [round(w, 4) for w in walls[p]],
                 "cpu_s_runs": [round(c, 4) for c in cpus[p]], "clean_run": _clean(walls[p], cpus[p]),
                 "wall_s_best": best, "wall_s_median": float(np.median(walls[p])),
                 "cpu_realtime_factor": res.sim_s / min(cpus[p]) if min(cpus[p]) > 0 else None,
                 "realtime_factor": res.sim_s / best, "seconds_per_epoch": best / max(res.epochs, 1),
                 "setup_s_first_run": res.setup_s, "satellites_tracked_mean": float(np.mean(res.tracked_per_epoch))}
        entry.update(fix_error(rec))
        if real is not None:
            entry["vs_real"] = compare_real(rec, real)
        _, free[p] = _run(setup, p, False, record=True, tag=f"{p}_noisefree")
        entry["noise_free"] = fix_error(free[p])
        out["presets"][p] = entry
        log(f"[bench] {name:5s} {p:9s} {res.epochs:5d} epochs @ {res.interval_s:g} s: best of {len(walls[p])} "
            f"{best:.3f} s ({entry['realtime_factor']:.0f}x real time, "
            f"{1e3 * entry['seconds_per_epoch']:.2f} ms/epoch)")
    if "accurate" in free:
        for p in presets:
            out["presets"][p]["vs_accurate"] = compare_runs(free[p], free["accurate"])
    return out


# ============================================================================ command
def run_bench(quick: bool = False, presets=PRESET_ORDER, repeats: int | None = None, epochs: int | None = None,
              use_real: bool = True, workdir: Path | None = None, log=print) -> dict:
    from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
    from gnss_sim_ros2.core.scene.demo_world import demo_world_path
    from gnss_sim_ros2.core.time import GnssTime
    from gnss_sim_ros2.core.visibility import load_scene

    for p in presets:
        if p not in PRESET_ORDER:
            raise ValueError(f"--presets: unknown preset {p!r} (use {', '.join(PRESET_ORDER)})")
    repeats = repeats if repeats is not None else (1 if epochs else 3)
    if repeats < 1:
        raise ValueError("--repeats must be >= 1")
    if workdir is None:
        with tempfile.TemporaryDirectory(prefix="gnss_sim_bench_") as tmp:
            return run_bench(quick, presets, repeats, epochs, use_real, Path(tmp), log)
    work = Path(workdir)
    report: dict = {"quick": bool(quick), "repeats": repeats, "timing": "best (shortest) of the repeated runs; "
                    "epoch loop only (run_simulation wall_s), setup excluded", "scenarios": {}}

    # demo: courtyard world, looped demo path, synthetic constellation
    demo_s = (10.0 * (epochs - 1) if epochs else (300.0 if quick else 600.0))
    t0 = time.perf_counter()
    scene = load_scene(str(demo_world_path()))
    eph = {"synthetic": open_ephemeris("synthetic", GnssTime.from_iso(DEMO_START), demo_s, "GRECJI",
                                       workdir=work / "ephemeris")}
    log(f"[bench] demo scenario loaded in {time.perf_counter() - t0:.1f} s")
    demo = bench_scenario("demo", _demo_setup(work / "demo", demo_s, scene, eph), presets, repeats, None, log)
    demo.update({"description": "worlds/courtyard.sdf, demo path looped, synthetic GRECJI constellation, "
                                f"{DEMO_START} GPS, {demo_s:g} s, epoch interval from each preset",
                 "duration_s": demo_s, "scenario_wall_s": time.perf_counter() - t0})
    report["scenarios"]["demo"] = demo

    data = shared_data_dir()
    opec = None
    if use_real and (data / "opec-2022-001" / OPEC_REAL_OBS).is_file():
        opec_s = 30.0 * (epochs - 1) if epochs else (3570.0 if quick else 13170.0)
        t0 = time.perf_counter()
        base = _opec_setup(work / "opec", opec_s, data, {})
        start = GnssTime.from_iso(OPEC_START)
        nav_files, sp3_files, _ = base.orbit_files()
        base.ephemeris["broadcast"] = open_ephemeris("broadcast", start, opec_s, "GE", nav_files)
        base.ephemeris["sp3"] = open_ephemeris("sp3", start, opec_s, "GE", sp3_files=sp3_files)
        real = RealObs(data / "opec-2022-001" / OPEC_REAL_OBS, "GE")
        log(f"[bench] OPEC scenario loaded in {time.perf_counter() - t0:.1f} s")
        opec = bench_scenario("opec", base, presets, repeats, real, log)
        opec.update({"description": "OPEC (NETR9) 2022-01-01, static at the marker, broadcast GPS+Galileo "
                                    "(SP3 for orbit: precise), 30 s epochs, against the real receiver's file",
                     "duration_s": opec_s, "real_file": OPEC_REAL_OBS})
        report["scenarios"]["opec"] = opec
    else:
        report["scenarios"]["opec"] = {"skipped": f"no real data at {data / 'opec-2022-001'}"
                                       if use_real else "--no-real"}

    from gnss_sim_ros2.core.presets import preset as preset_switches

    rows = []
    for p in presets:
        d = demo["presets"][p]
        e = {"name": p, "switches": preset_switches(p),
             "realtime_factor": d["realtime_factor"], "seconds_per_epoch": d["seconds_per_epoch"],
             "epoch_interval_s": d["interval_s"], "demo": d}
        if opec is not None:
            o = opec["presets"][p]
            e.update({"against": "real receiver OPEC 2022-001 (pseudorange, tracked set); true marker (fix)",
                      "pseudorange_rms_m": o["vs_real"]["pseudorange_rms_m"],
                      "visible_set_jaccard": o["vs_real"]["visible_set_jaccard"],
                      "fix_horizontal_rms_m": o["fix_horizontal_rms_m"],
                      "vs_real": o["vs_real"], "vs_accurate": d.get("vs_accurate"), "opec": o})
        else:
            va = d.get("vs_accurate") or {}
            e.update({"against": "accurate preset, noise off (pseudorange, tracked set); true demo path (fix)",
                      "pseudorange_rms_m": va.get("pseudorange_rms_m"),
                      "visible_set_jaccard": va.get("visible_set_jaccard"),
                      "fix_horizontal_rms_m": d["fix_horizontal_rms_m"], "vs_accurate": d.get("vs_accurate")})
        rows.append(e)
    report["presets"] = rows
    return report


def _f(v, fmt):
    return "-" if v is None else format(v, fmt)


def table(report: dict) -> str:
    opec = "presets" in report["scenarios"].get("opec", {})
    head = ["preset", "interval s", "ms/epoch", "x real time", "PR RMS vs acc m", "Jaccard vs acc", "fix H RMS m"]
    if opec:
        head += ["PR RMS vs real m", "Jaccard vs real", "OPEC fix H RMS m", "OPEC x real time"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for e in report["presets"]:
        d = e["demo"]
        va = d.get("vs_accurate") or {}
        row = [e["name"], _f(d["interval_s"], "g"), _f(1e3 * d["seconds_per_epoch"], ".2f"),
               _f(d["realtime_factor"], ".0f"), _f(va.get("pseudorange_rms_m"), ".2e"),
               _f(va.get("visible_set_jaccard"), ".3f"), _f(d["fix_horizontal_rms_m"], ".2f")]
        if opec:
            o = report["scenarios"]["opec"]["presets"][e["name"]]
            row += [_f(o["vs_real"]["pseudorange_rms_m"], ".3f"), _f(o["vs_real"]["visible_set_jaccard"], ".3f"),
                    _f(o["fix_horizontal_rms_m"], ".2f"), _f(o["realtime_factor"], ".0f")]
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def plot(report: dict, path) -> Path:
    """Two panels over the cost (wall seconds per simulated second of the demo scenario, log scale):
    the headline pseudorange RMS (vs real when present) and the demo's tracked-set Jaccard vs accurate."""
    from matplotlib.ticker import NullFormatter

    from gnss_sim_ros2.core.figures import pyplot, save_figure

    plt = pyplot()

    rows = report["presets"]
    cost = [1.0 / e["realtime_factor"] for e in rows]
    opec = "presets" in report["scenarios"].get("opec", {})
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    jac = [(e["demo"].get("vs_accurate") or {}).get("visible_set_jaccard") for e in rows]
    panels = [([e["pseudorange_rms_m"] for e in rows],
               "pseudorange RMS [m] " + ("vs real OPEC receiver (GPS C1C)" if opec else "vs accurate (noise off)")),
              (jac, "tracked-set Jaccard vs accurate\n(demo courtyard, noise off)")]
    for ax, (y, label) in zip(axes, panels):
        y = [v if v is not None else np.nan for v in y]
        ax.plot(cost, y, "o-", color="tab:blue")
        for k, (c, v, e) in enumerate(zip(cost, y, rows)):
            ax.annotate(f"{e['name']}\n{e['realtime_factor']:.0f}x", (c, v), textcoords="offset points",
                        xytext=(6, 6 if k % 2 == 0 else -22), fontsize=9)
        ax.set_xscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlim(min(cost) / 2.0, max(cost) * 3.0)
        ax.set_xlabel("wall seconds per simulated second (demo scenario, log)")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle("gnss-sim presets: cost against accuracy")
    return save_figure(fig, path, dpi=120)
