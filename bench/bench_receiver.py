"""Benchmark of the receiver core and of the offline simulation.

1. ``Receiver.epoch`` with 40 satellites x 3 signals (synthetic GPS/GLONASS/Galileo/BeiDou/QZSS,
   static antenna, transmit time recomputed from the ephemeris as in the "balanced" preset): median and
   90th percentile of the wall time of one call over many successive epochs (1 s apart); the same for
   ``position_fix`` on those observables (prior: the previous fix, as the simulation and the node do)
   and for ``Receiver.epoch`` without an ephemeris provider (the receiver node: expansion from the
   states at the epoch).
2. ``gnss-sim simulate --synthetic --duration 3600 --rate 1`` (demo world worlds/courtyard.sdf and the
   demo path: raycast visibility, receiver, position fix, RINEX writing) as a factor of real time
   (target >= 200x), timed from outside the process (start-up included) and as the command reports it.
   ``--profile`` runs cProfile on an in-process copy of the same simulation and prints the top entries.

    .venv/bin/python bench/bench_receiver.py [--epochs 300] [--duration 3600] [--skip-simulate] [--profile]
"""
from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
#: three signals per satellite (the geodetic receiver's first three of each system)
PROFILE_3 = {"G": ["1C", "2W", "5Q"], "E": ["1C", "5Q", "7Q"], "C": ["2I", "7I", "6I"], "J": ["1C", "2L", "5Q"],
             "R": ["1C", "1P", "2C"]}
SYSTEMS = "GRECJ"


def bench_epoch(n_epochs: int, n_sats: int = 40) -> dict:
    from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
    from gnss_sim_ros2.core.frames import az_el_from_ecef
    from gnss_sim_ros2.core.receiver.config import ReceiverConfig
    from gnss_sim_ros2.core.receiver.engine import Receiver
    from gnss_sim_ros2.core.receiver.outputs import position_fix
    from gnss_sim_ros2.core.time import GnssTime

    t0 = GnssTime.from_iso("2022-01-01T00:00:00")
    rx = np.array([3149785.9652, 598260.8822, 5495348.4927])
    with tempfile.TemporaryDirectory() as tmp:
        prov, _ = open_ephemeris("synthetic", t0, n_epochs + 60.0, SYSTEMS, workdir=tmp)
        st = prov.states(t0, systems=SYSTEMS)
        _, el, _ = az_el_from_ecef(rx, st.pos_ecef_m)
        order = np.argsort(-el)
        if np.sum(el > 0.0) < n_sats:
            raise SystemExit(f"only {np.sum(el > 0.0)} satellites above the horizon; cannot bench {n_sats}")
        svs = list(np.asarray(st.sv)[order[:n_sats]])
        cfg = ReceiverConfig(profile=PROFILE_3, systems=SYSTEMS, elevation_mask_deg=0.0)
        rcv = Receiver(cfg, prov, prov.iono)
        rcv_node = Receiver(ReceiverConfig(profile=PROFILE_3, systems=SYSTEMS, elevation_mask_deg=0.0), None,
                            prov.iono)
        times, times_fix, times_node = [], [], []
        n_sig = []
        prior = None
        for i in range(n_epochs):
            t = t0 + float(i)
            s = prov.states(t, svs=svs)
            w0 = time.perf_counter()
            obs = rcv.epoch(t, rx, s)
            w1 = time.perf_counter()
            sol = position_fix(obs, cfg.profile, prior)
            w2 = time.perf_counter()
            rcv_node.epoch(t, rx, s)
            w3 = time.perf_counter()
            prior = sol.pos_ecef_m if sol.is_fix else prior
            times.append(w1 - w0)
            times_fix.append(w2 - w1)
            times_node.append(w3 - w2)
            n_sig.append(len(obs.sv))
    out = {"signals": int(np.median(n_sig)), "sats": n_sats}
    for name, v in (("", times), ("fix_", times_fix), ("node_", times_node)):
        v = np.array(v[5:])          # first epochs fill caches
        out.update({name + "median_s": float(np.median(v)), name + "p90_s": float(np.percentile(v, 90)),
                    name + "p99_s": float(np.percentile(v, 99)), "epochs": len(v)})
    return out


def bench_simulate(duration_s: float) -> dict:
    exe = REPO / ".venv" / "bin" / "gnss-sim"
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "gnss_sim_ros2.cli"]
    with tempfile.TemporaryDirectory() as tmp:
        w0 = time.perf_counter()
        out = subprocess.run(cmd + ["simulate", "--synthetic", "--duration", str(duration_s), "--rate", "1",
                                    "--out", tmp, "--quiet"], capture_output=True, text=True, check=True)
        wall = time.perf_counter() - w0
    m = re.search(r"in ([0-9.]+) s: ([0-9]+)x real time", out.stdout)
    return {"wall_s": wall, "factor_outside": duration_s / wall, "loop_s": float(m.group(1)) if m else float("nan"),
            "factor_reported": float(m.group(2)) if m else float("nan"), "stdout": out.stdout}


def profile_simulate(duration_s: float, top: int = 25):
    import cProfile
    import pstats

    from gnss_sim_ros2.commands import simulate as cmd
    from gnss_sim_ros2.core.simulation import run_simulation

    p = argparse.ArgumentParser()
    cmd.add_arguments(p)
    with tempfile.TemporaryDirectory() as tmp:
        args = p.parse_args(["--synthetic", "--duration", str(duration_s), "--rate", "1", "--out", tmp, "--quiet"])
        setup = cmd.setup_from_args(args)
        prof = cProfile.Profile()
        prof.enable()
        run_simulation(setup)
        prof.disable()
    pstats.Stats(prof).sort_stats("cumulative").print_stats(top)
    pstats.Stats(prof).sort_stats("tottime").print_stats(top)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--epochs", type=int, default=300)
    ap.add_argument("--duration", type=float, default=3600.0)
    ap.add_argument("--skip-simulate", action="store_true")
    ap.add_argument("--profile", action="store_true", help="cProfile an in-process simulation (--duration)")
    a = ap.parse_args(argv)

    r = bench_epoch(a.epochs)
    print(f"Receiver.epoch, {r['sats']} satellites x 3 signals ({r['signals']} tracked signals): "
          f"median {r['median_s'] * 1e3:.2f} ms, p90 {r['p90_s'] * 1e3:.2f} ms over {r['epochs']} epochs "
          f"({1.0 / r['median_s']:.0f} epochs/s)")
    print(f"position_fix on those observables: median {r['fix_median_s'] * 1e3:.2f} ms, "
          f"p90 {r['fix_p90_s'] * 1e3:.2f} ms, p99 {r['fix_p99_s'] * 1e3:.2f} ms")
    print(f"Receiver.epoch without provider (receiver node, expansion): median {r['node_median_s'] * 1e3:.2f} ms, "
          f"p90 {r['node_p90_s'] * 1e3:.2f} ms, p99 {r['node_p99_s'] * 1e3:.2f} ms")
    if not a.skip_simulate:
        s = bench_simulate(a.duration)
        print(f"gnss-sim simulate --synthetic (demo world and path), {a.duration:.0f} s at 1 Hz: "
              f"{s['wall_s']:.1f} s wall incl. start-up = {s['factor_outside']:.0f}x real time; "
              f"simulation loop {s['loop_s']:.1f} s = {s['factor_reported']:.0f}x (target >= 200x)")
    if a.profile:
        profile_simulate(a.duration)
    return 0


if __name__ == "__main__":
    sys.exit(main())
