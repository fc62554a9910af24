"""The running system at real-time pace: epochs dropped and chain latency (printed figures).

Runs `gnss-sim run --realtime` (simulated clock at wall-clock pace) at RATE Hz
for DURATION s of simulated time with every system, then prints the epochs
without output, the latency from the satellite states published to the
observations published (p50, p95, p99) per robot and for the worst robot, the
start-up (the configure transition's wall time: scene, ephemeris, receivers;
the run process's peak memory) and per process its CPU time per epoch and peak
memory, with the load average before and after each run (the machine may be shared).

    python bench/bench_realtime.py [--rate 10] [--duration 600] [--robots 1,4] [--layouts composed,robot,node]

``--robots 1,4``: one run per count (`gnss-sim run --robots N`: N robots in one graph sharing the ephemeris
node); ``--layouts``: one run per process layout and count, back to back (`gnss-sim run --layout`: every
node in one process, one process per robot, one per node; ``--processes``: ``--layouts node``).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path


def _robot_counts(text: str) -> list[int]:
    try:
        counts = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise SystemExit(f"bench_realtime: --robots {text!r}: give robot counts such as 1 or 1,4") from None
    if not counts:
        raise SystemExit("bench_realtime: --robots is empty: give robot counts such as 1 or 1,4")
    return counts


def _lat(f: dict) -> str:
    return (f"p50 {f['latency_ms_median']} ms, p95 {f['latency_ms_p95']} ms, p99 {f['latency_ms_p99']} ms "
            f"(-> fix: p50 {f.get('fix_latency_ms_median')} ms, p99 {f.get('fix_latency_ms_p99')} ms)")


def _layouts(text: str) -> list[str]:
    from gnss_sim_ros2.graph import LAYOUTS

    layouts = [v.strip() for v in text.split(",") if v.strip()]
    bad = [v for v in layouts if v not in LAYOUTS]
    if bad or not layouts:
        raise SystemExit(f"bench_realtime: --layouts {text!r}: give layouts among {', '.join(LAYOUTS)}")
    return layouts


def run_once(rate: float, duration: float, layout: str, robots: int) -> dict:
    out = Path(tempfile.mkdtemp(prefix="gnss_sim_rt_"))
    cmd = [sys.executable, "-m", "gnss_sim_ros2.cli", "run", "--realtime", "--rate", str(rate), "--duration",
           str(duration), "--systems", "GRECJI", "--out", str(out), "--quiet", "--robots", str(robots),
           "--layout", layout]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return json.loads((out / "summary.json").read_text())


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rate", type=float, default=10.0)
    ap.add_argument("--duration", type=float, default=600.0)
    ap.add_argument("--processes", action="store_true", help="one process per node: --layouts node")
    ap.add_argument("--layouts", default="composed", metavar="L[,L...]",
                    help="process layouts (composed, robot, node), one run per layout and robot count [composed]")
    ap.add_argument("--robots", default="1", metavar="N[,N...]", help="robots in the graph, one run per count [1]")
    ap.add_argument("--quick", action="store_true", help="60 s instead of the duration")
    a = ap.parse_args()
    duration = 60.0 if a.quick else a.duration
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())} ({os.cpu_count()} cores)")
    layouts = ["node"] if a.processes else _layouts(a.layouts)
    runs = [(layout, n) for layout in layouts for n in _robot_counts(a.robots)]
    for layout, n in runs:
        s = run_once(a.rate, duration, layout, n)
        print(f"{a.rate:g} Hz for {duration:g} s at real-time pace, all systems, {n} robot(s), "
              f"layout {layout} ({s['mode']}):")
        fix_topic = "/gnss/fix" if n == 1 else "/robot0/gnss/fix"
        print(f"  epochs {s['epochs']}, without output {s['epochs_without_output']}, "
              f"bag fix messages {s.get('bag_messages', {}).get(fix_topic)} ({fix_topic})")
        print(f"  start-up: configure {s['configure_wall_s']} s, peak memory {s['peak_rss_mb']} MB"
              + (f", scenes built {s['scene_loads']['loaded']}, shared {s['scene_loads']['shared']}"
                 if n > 1 else ""))
        per = s.get("per_robot", {"robot0": s})
        for name, f in per.items():
            print(f"  {name}: latency states -> observations {_lat(f)}; fix availability {f['fix_availability']}, "
                  f"without output {f.get('epochs_without_output', s['epochs_without_output'])}")
        if n > 1:
            w = s["worst_robot"]
            print("  worst robot: " + ", ".join(f"{k} {v['value']} ({v['robot']})" for k, v in w.items()))
        else:
            print(f"  worst robot: {_lat(s)} (robot0)")
        print("  per process: " + "; ".join(f"{name} CPU {p['cpu_ms_per_epoch']} ms/epoch, peak {p['peak_rss_mb']} MB"
                                           for name, p in s.get("processes", {}).items()))
        print(f"  satellites tracked per epoch {s['satellites_tracked_mean']}, "
              f"fix availability {s['fix_availability']}")
        print(f"  load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
