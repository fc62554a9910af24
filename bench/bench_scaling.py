"""Cost and peak memory of the offline chain against triangles, satellites, epochs and rate (printed table).

    python bench/bench_scaling.py [--quick] [--max-hours 1] [--json FILE] [--plot docs/bench_scaling.png]

The same as ``gnss-sim bench --scaling`` (gnss_sim_ros2/benchmarks/scaling.py
says what each axis runs): each point in a fresh process, one after another;
spans longer than ``--max-hours`` (to 24 h) extrapolated from the longest
measured span (benchmarks/scaling.py says how), and marked so.  The load
average before and after is printed with the figures: on a shared machine the
wall times move, the CPU times much less.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from gnss_sim_ros2.benchmarks.scaling import run_scaling, scaling_plot, scaling_table  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--max-hours", type=float, default=1.0)
    ap.add_argument("--json", metavar="FILE")
    ap.add_argument("--plot", metavar="FILE.png")
    a = ap.parse_args(argv)
    load0 = os.getloadavg()
    report = run_scaling(a.quick, a.max_hours, log=lambda m: print(m, flush=True))
    report["load_average"] = {"before": load0, "after": os.getloadavg()}
    report["cores"] = os.cpu_count()
    print(scaling_table(report))
    print(f"[bench_scaling] {os.cpu_count()} cores; load average before {load0[0]:.2f}, "
          f"after {os.getloadavg()[0]:.2f}")
    if a.json:
        Path(a.json).write_text(json.dumps(report, indent=1))
    if a.plot:
        print(f"wrote {scaling_plot(report, a.plot)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
