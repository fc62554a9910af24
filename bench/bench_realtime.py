"""The running system at real-time pace: epochs dropped and chain latency (printed figures).

Runs `gnss-sim run --realtime` (every node in one process, simulated clock at
wall-clock pace) at RATE Hz for DURATION s of simulated time with every
system, then prints the epochs without output and the latency from the
satellite states published to the observations published (median, p99).

    python bench/bench_realtime.py [--rate 10] [--duration 600] [--processes]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rate", type=float, default=10.0)
    ap.add_argument("--duration", type=float, default=600.0)
    ap.add_argument("--processes", action="store_true")
    ap.add_argument("--quick", action="store_true", help="60 s instead of the duration")
    a = ap.parse_args()
    duration = 60.0 if a.quick else a.duration
    out = Path(tempfile.mkdtemp(prefix="gnss_sim_rt_"))
    cmd = [sys.executable, "-m", "gnss_sim_ros2.cli", "run", "--realtime", "--rate", str(a.rate), "--duration",
           str(duration), "--systems", "GRECJI", "--out", str(out), "--quiet"]
    if a.processes:
        cmd.append("--processes")
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    s = json.loads((out / "summary.json").read_text())
    print(f"{a.rate:g} Hz for {duration:g} s at real-time pace, all systems, "
          f"{'one process per node' if a.processes else 'composed'}:")
    print(f"  epochs {s['epochs']}, without output {s['epochs_without_output']}, "
          f"bag fix messages {s.get('bag_messages', {}).get('/gnss/fix')}")
    print(f"  latency states -> observations: median {s['latency_ms_median']} ms, p99 {s['latency_ms_p99']} ms")
    print(f"  satellites tracked per epoch {s['satellites_tracked_mean']}, fix availability {s['fix_availability']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
