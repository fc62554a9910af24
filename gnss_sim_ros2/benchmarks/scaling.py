"""Cost of the offline chain against the size of the problem (``gnss-sim bench --scaling``).

Four axes, each point one ``run_simulation`` in a fresh process (so that its
peak memory is its own):

* **triangles** 1 k to 2 M: a generated city of boxes (12 triangles each, 20 m
  grid, heights 5-30 m, an open square at the origin) placed at the demo
  world's geodetic origin; a static antenna 1.5 m above the square; every
  system; 1 Hz.  Also the time to build the scene (Open3D BVH).
* **satellites**: the demo (courtyard, demo path, default preset, 1 Hz) with
  GPS only, then adding Galileo, BeiDou, GLONASS, QZSS, NavIC (all six); every
  signal of the geodetic profile.
* **epochs** 1 min to 24 h at 1 Hz on the demo: measured up to ``--scaling-max-hours``
  (default 1 h); longer spans are extrapolated (the cost per epoch of the
  longest measured span; its peak memory growing along a straight line through
  the measured points; no set-up time), marked "extrapolated" in the table, the
  JSON and the plot.
* **rate** 1 to 20 Hz over 60 s on the demo.

Each point's process runs on one thread (BLAS, OpenMP and Open3D limited to one,
as a sweep worker): the figures of one core, and a multi-threaded OpenBLAS
would otherwise spend more time waiting for its threads than computing the
solver's 8 x 8 matrices (docs/BENCHMARKS.md, "Offline speed").

Per point: ``ms_per_epoch`` (wall time of the epoch loop per epoch),
``cpu_ms_per_epoch`` (its CPU time: insensitive to other processes on a shared
machine), ``setup_s`` (ephemeris and files before the first epoch),
``peak_rss_mb`` (the process's peak resident memory: ``getrusage`` maxrss) and
``base_rss_mb`` (the same after the imports, before the point's work).
"""
from __future__ import annotations

import multiprocessing
import os
import resource
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

TRIANGLES = (1_000, 10_000, 100_000, 1_000_000, 2_000_000)
SYSTEM_STEPS = ("G", "GE", "GEC", "GECR", "GECRJ", "GECRJI")
EPOCH_SPANS_S = (60.0, 600.0, 3600.0, 6 * 3600.0, 24 * 3600.0)
RATES_HZ = (1.0, 2.0, 5.0, 10.0, 20.0)
#: the triangles axis: seconds simulated per point
TRIANGLE_SPAN_S = 120.0
SAT_SPAN_S = 300.0
RATE_SPAN_S = 60.0
BOX_PITCH_M = 20.0
#: the 12 triangles of a unit box [0,1]^3 (outward normals), vertex k = bits (x, y, z) of k
_BOX_FACES = np.array([[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
                       [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]])
_BOX_CORNERS = np.array([[(k >> 2) & 1, (k >> 1) & 1, k & 1] for k in range(8)], dtype=float)[:, [2, 1, 0]]


def box_city(n_triangles: int, spherical, seed: int = 0):
    """A WorldMesh of ceil(n/12) opaque boxes on a square grid around an open square at the origin."""
    from gnss_sim_ros2.core.scene.materials import MaterialTable
    from gnss_sim_ros2.core.scene.world_mesh import WorldMesh

    n_boxes = max(1, int(np.ceil(n_triangles / 12)))
    side = int(np.ceil(np.sqrt(n_boxes + 16))) | 1            # odd: a cell at the origin, left open
    idx = np.arange(side * side)
    ij = np.c_[idx // side, idx % side] - side // 2
    ij = ij[np.max(np.abs(ij), axis=1) > 1][:n_boxes]          # the 3 x 3 cells around the origin stay open
    rng = np.random.default_rng(seed)
    lo = np.c_[ij * BOX_PITCH_M - 0.35 * BOX_PITCH_M, np.zeros(len(ij))]
    size = np.c_[np.full((len(ij), 2), 0.7 * BOX_PITCH_M), rng.uniform(5.0, 30.0, len(ij))]
    verts = (lo[:, None, :] + _BOX_CORNERS[None] * size[:, None, :]).reshape(-1, 3)
    tris = (_BOX_FACES[None] + 8 * np.arange(len(ij))[:, None, None]).reshape(-1, 3)
    return WorldMesh(verts, tris.astype(np.int64), np.zeros(len(tris), np.int16), MaterialTable(), spherical,
                     [], f"box city {len(tris)} triangles")


def measure_point(point: dict) -> dict:
    """One point, in this (fresh) process: build the scenario, run it, time and memory."""
    import open3d  # noqa: F401  (part of the baseline: imported by every run with a scene)

    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.core.demo import DEMO_START
    from gnss_sim_ros2.core.scene.demo_world import demo_world_path
    from gnss_sim_ros2.core.scene.visibility import Scene
    from gnss_sim_ros2.core.simulation import run_simulation, setup_from_config
    from gnss_sim_ros2.core.time import GnssTime
    from gnss_sim_ros2.core.trajectory import Trajectory, demo_trajectory
    from gnss_sim_ros2.core.visibility import load_scene

    base_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    demo = load_scene(str(demo_world_path()))
    out = dict(point)
    if point["axis"] == "triangles":
        t0 = time.perf_counter()
        scene = Scene(box_city(int(point["value"]), demo.spherical), nthreads=1)
        out["build_s"] = time.perf_counter() - t0
        out["triangles"] = int(len(scene.world.triangles))
        trajectory = Trajectory.static([0.0, 0.0, 1.5], "world")
    else:
        demo.rays.nthreads = 1
        scene, trajectory = demo, demo_trajectory(loop=True)
        out["triangles"] = int(len(demo.world.triangles))
    with tempfile.TemporaryDirectory(prefix="gnss_sim_scaling_") as tmp:
        res = run_simulation(setup_from_config(
            load_config(), Path(tmp), trajectory, start=GnssTime.from_iso(DEMO_START), duration_s=point["duration_s"],
            interval_s=1.0 / point["rate_hz"], scene=scene).with_params(systems=point["systems"], source="synthetic"))
    peak_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    out.update({"epochs": res.epochs, "loop_s": res.wall_s, "cpu_s": res.cpu_s, "setup_s": res.setup_s,
                "ms_per_epoch": 1e3 * res.wall_s / max(res.epochs, 1),
                "cpu_ms_per_epoch": 1e3 * res.cpu_s / max(res.epochs, 1),
                "realtime_factor": res.realtime_factor,
                "satellites_tracked_mean": float(np.mean(res.tracked_per_epoch)) if res.tracked_per_epoch else 0.0,
                "peak_rss_mb": peak_kb / 1024.0, "base_rss_mb": base_kb / 1024.0, "extrapolated": False})
    return out


def scaling_points(quick: bool = False, max_hours: float = 1.0, epochs: int | None = None) -> list[dict]:
    """The points of the four axes (``quick``: shorter spans, up to 100 k triangles; ``epochs``: tiny
    points of that many epochs at 1 Hz for the tests, two spans, the small scenes)."""
    if epochs is not None:
        d = float(epochs - 1)
        return ([{"axis": "triangles", "value": n, "systems": "GRECJI", "duration_s": d, "rate_hz": 1.0}
                 for n in TRIANGLES[:2]]
                + [{"axis": "satellites", "value": s, "systems": s, "duration_s": d, "rate_hz": 1.0}
                   for s in SYSTEM_STEPS[::5]]
                + [{"axis": "epochs", "value": x, "systems": "GRECJI", "duration_s": x, "rate_hz": 1.0}
                   for x in (d, 2 * d)]
                + [{"axis": "rate", "value": r, "systems": "GRECJI", "duration_s": d / r, "rate_hz": r}
                   for r in RATES_HZ[:2]])
    f = 0.5 if quick else 1.0
    pts = [{"axis": "triangles", "value": n, "systems": "GRECJI", "duration_s": TRIANGLE_SPAN_S * f, "rate_hz": 1.0}
           for n in TRIANGLES if not (quick and n > 100_000)]
    pts += [{"axis": "satellites", "value": s, "systems": s, "duration_s": SAT_SPAN_S * f, "rate_hz": 1.0}
            for s in SYSTEM_STEPS]
    pts += [{"axis": "epochs", "value": d, "systems": "GRECJI", "duration_s": d, "rate_hz": 1.0}
            for d in EPOCH_SPANS_S if d <= max_hours * 3600.0 * (0.17 if quick else 1.0) + 1e-6]
    pts += [{"axis": "rate", "value": r, "systems": "GRECJI", "duration_s": RATE_SPAN_S * f, "rate_hz": r}
            for r in RATES_HZ if not (quick and r > 10)]
    return pts


#: BLAS and OpenMP pools of the point's process: one thread, as a sweep worker (Dask sets the same)
ONE_THREAD_ENV = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


class _one_thread_env:
    """ONE_THREAD_ENV in os.environ while a point's process is spawned (it inherits it), restored after."""

    def __enter__(self):
        self.saved = {k: os.environ.get(k) for k in ONE_THREAD_ENV}
        os.environ.update(ONE_THREAD_ENV)

    def __exit__(self, *exc):
        for k, v in self.saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def extrapolate_epochs(measured: list[dict]) -> list[dict]:
    """The spans of EPOCH_SPANS_S beyond the measured ones, each marked ``extrapolated``: the loop's
    (wall and CPU) time per epoch of the longest measured span, and the peak memory of that span plus the
    slope (never negative) of a straight line through every measured (epochs, peak memory)."""
    if len(measured) < 2:
        return []
    last = max(measured, key=lambda m: m["epochs"])
    n = np.array([m["epochs"] for m in measured], float)
    slope_mb = max(float(np.polyfit(n, [m["peak_rss_mb"] for m in measured], 1)[0]), 0.0)
    out = []
    for d in EPOCH_SPANS_S:
        if d <= last["duration_s"] + 1e-6:
            continue
        e = int(d) + 1
        loop_s, cpu_s = last["loop_s"] * e / last["epochs"], last["cpu_s"] * e / last["epochs"]
        out.append({"axis": "epochs", "value": d, "systems": "GRECJI", "duration_s": d, "rate_hz": 1.0,
                    "epochs": e, "loop_s": loop_s, "cpu_s": cpu_s, "setup_s": None,
                    "peak_rss_mb": last["peak_rss_mb"] + slope_mb * (e - last["epochs"]),
                    "ms_per_epoch": 1e3 * loop_s / e, "cpu_ms_per_epoch": 1e3 * cpu_s / e,
                    "realtime_factor": d / loop_s, "extrapolated": True, "base_rss_mb": last["base_rss_mb"]})
    return out


def run_scaling(quick: bool = False, max_hours: float = 1.0, log=print, epochs: int | None = None) -> dict:
    """Every point in its own process, one after another (one core each: the figures of one core)."""
    points = scaling_points(quick, max_hours, epochs)
    ctx = multiprocessing.get_context("spawn")
    rows = []
    for p in points:
        with _one_thread_env(), ProcessPoolExecutor(max_workers=1, mp_context=ctx) as pool:
            r = pool.submit(measure_point, p).result()
        rows.append(r)
        log(f"[bench --scaling] {_label(r):28s} {r['epochs']:6d} epochs  {r['ms_per_epoch']:7.2f} ms/epoch "
            f"(CPU {r['cpu_ms_per_epoch']:6.2f})  setup {r['setup_s']:5.1f} s  peak {r['peak_rss_mb']:6.0f} MB"
            + (f"  scene build {r['build_s']:.2f} s" if "build_s" in r else ""))
    rows += extrapolate_epochs([r for r in rows if r["axis"] == "epochs"])
    return {"quick": bool(quick), "measured_up_to_hours": max_hours,
            "timing": "epoch loop wall time per epoch (run_simulation wall_s), one process per point",
            "points": rows}


def _label(r: dict) -> str:
    v = r["value"]
    if r["axis"] == "triangles":
        return f"triangles {r.get('triangles', v):,}"
    if r["axis"] == "satellites":
        return f"systems {v}"
    if r["axis"] == "epochs":
        span = f"{v / 3600.0:g} h" if v >= 3600.0 else f"{v / 60.0:.3g} min"
        return f"span {span}" + (" (extrapolated)" if r.get("extrapolated") else "")
    return f"rate {v:g} Hz"


def scaling_table(report: dict) -> str:
    head = ["axis", "point", "epochs", "sats tracked", "ms/epoch", "CPU ms/epoch", "x real time", "setup s",
            "peak RSS MB", "note"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in report["points"]:
        note = "extrapolated (linear fit)" if r.get("extrapolated") else (
            f"scene build {r['build_s']:.2f} s" if "build_s" in r else "")
        sats = f"{r['satellites_tracked_mean']:.1f}" if "satellites_tracked_mean" in r else "-"
        lines.append("| " + " | ".join([r["axis"], _label(r).split(" ", 1)[1], str(r["epochs"]), sats,
                                        f"{r['ms_per_epoch']:.2f}", f"{r['cpu_ms_per_epoch']:.2f}",
                                        f"{r['realtime_factor']:.0f}",
                                        "-" if r["setup_s"] is None else f"{r['setup_s']:.1f}",
                                        f"{r['peak_rss_mb']:.0f}", note]) + " |")
    return "\n".join(lines)


def scaling_plot(report: dict, path) -> Path:
    from gnss_sim_ros2.core.figures import pyplot, save_figure

    plt = pyplot()

    fig, axes = plt.subplots(2, 2, figsize=(12, 8))
    spec = [("triangles", "scene triangles (generated boxes)", True),
            ("satellites", "satellites tracked (systems added: G, E, C, R, J, I)", False),
            ("epochs", "epochs at 1 Hz (1 min to 24 h)", True), ("rate", "epoch rate [Hz] (60 s)", True)]
    for ax, (axis, xlabel, logx) in zip(axes.ravel(), spec):
        rows = [r for r in report["points"] if r["axis"] == axis]
        if not rows:
            ax.set_visible(False)
            continue
        x = np.array([r.get("triangles", r["value"]) if axis == "triangles" else
                      (r.get("satellites_tracked_mean", np.nan) if axis == "satellites" else
                       (r["epochs"] if axis == "epochs" else r["value"])) for r in rows], float)
        meas = np.array([not r.get("extrapolated") for r in rows])
        y = np.array([r["ms_per_epoch"] for r in rows])
        yc = np.array([r["cpu_ms_per_epoch"] for r in rows])
        mem = np.array([r["peak_rss_mb"] for r in rows])
        ax.plot(x[meas], y[meas], "o-", color="tab:blue", label="wall ms/epoch")
        ax.plot(x[meas], yc[meas], "s--", color="tab:cyan", ms=4, label="CPU ms/epoch")
        if (~meas).any():
            k = np.r_[np.flatnonzero(meas)[-1:], np.flatnonzero(~meas)]
            ax.plot(x[k], y[k], "o:", color="tab:blue", mfc="white", label="extrapolated")
        ax2 = ax.twinx()
        ax2.plot(x[meas], mem[meas], "^-", color="tab:red", ms=4, label="peak RSS MB")
        if (~meas).any():
            ax2.plot(x[k], mem[k], "^:", color="tab:red", mfc="white", ms=4)
        ax2.set_ylabel("peak resident memory [MB]", color="tab:red")
        ax2.set_ylim(0, max(mem) * 1.15)
        if axis == "satellites":
            for xi, yi, r in zip(x, y, rows):
                ax.annotate(r["value"], (xi, yi), textcoords="offset points", xytext=(-8, 6), fontsize=8)
        if logx:
            ax.set_xscale("log")
        ax.set_ylim(0, max(max(y), max(yc)) * 1.15)
        ax.set_xlabel(xlabel)
        ax.set_ylabel("epoch loop per epoch [ms]")
        ax.grid(True, which="both", alpha=0.3)
        h1, l1 = ax.get_legend_handles_labels()
        h2, l2 = ax2.get_legend_handles_labels()
        ax.legend(h1 + h2, l1 + l2, fontsize=8, loc="upper left")
    fig.suptitle("gnss-sim simulate: cost against the size of the problem (one process per point)")
    return save_figure(fig, path)
