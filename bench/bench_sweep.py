"""Speed-up of ``gnss-sim sweep`` with two local workers against one (printed ratio).

    python bench/bench_sweep.py [--seeds 1-8] [--duration 600] [--rounds 1] [--command]

The same sweep (the demo scenario: courtyard, demo path, every system, default
preset, ``--duration`` s at 1 Hz, one run per seed) on a LocalCluster of 1 and
of 2 worker processes (one thread each), in alternating order over ``--rounds``
rounds.  Times per sweep: ``total`` = starting the cluster (processes, imports)
+ every run + closing it, what a user waits for; ``runs`` = from the first run
submitted to the last row.  The ratio is workers-1 time / workers-2 time of the
best round of each.  The machine's load average is printed with the figures:
other processes on the cores lower the ratio (a 2-core machine shared with
other work cannot give two free cores).

``--command``: the whole ``gnss-sim sweep`` as a user runs it, a child process timed from its start to its
end (interpreter, imports, cluster, runs, results and plot); its last line splits that time into what is
paid once and the runs' work that divides among the workers (core/sweep/timing.py), printed beside it.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from gnss_sim_ros2.commands import sweep as sweep_cmd  # noqa: E402
from gnss_sim_ros2.core.sweep.driver import run_sweep  # noqa: E402
from gnss_sim_ros2.core.sweep.table import read_rows  # noqa: E402


def one_sweep(seeds: str, duration_s: float, workers: int, out: Path) -> dict:
    p = argparse.ArgumentParser()
    sweep_cmd.add_arguments(p)
    args = p.parse_args(["--seeds", seeds, "--duration", str(duration_s), "--out", str(out), "--quiet"])
    tasks = sweep_cmd.build_tasks(args, out)
    t0 = time.perf_counter()
    outcome = run_sweep(tasks, out, workers=workers, progress=False)
    total = time.perf_counter() - t0
    failed = [r for r in outcome.rows if r["status"] != "ok"]
    if failed:
        raise SystemExit(f"{len(failed)} runs failed: {failed[0]['error']}")
    return {"total_s": total, "runs_s": outcome.wall_s, "cluster_s": outcome.cluster_s,
            "mean_run_s": sum(r["runtime_s"] for r in outcome.rows) / len(outcome.rows),
            # epoch-loop wall / CPU time over the runs: 1.0 when every worker had its core to itself
            "wall_per_cpu": sum(r["loop_s"] for r in outcome.rows) / sum(r["loop_cpu_s"] for r in outcome.rows),
            "rows": len(outcome.rows), "load": os.getloadavg()[0]}


def one_command(seeds: str, duration_s: float, workers: int, out: Path) -> dict:
    """The whole command as a child process: its wall time and its own split of it (last line)."""
    cmd = [sys.executable, "-m", "gnss_sim_ros2.cli", "sweep", "--seeds", seeds, "--duration", f"{duration_s:g}",
           "--workers", str(workers), "--quiet", "--out", str(out)]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise SystemExit(f"gnss-sim sweep failed ({p.returncode}): {p.stderr.strip()[-800:]}")
    split = next((ln for ln in p.stdout.splitlines() if ln.startswith("time ")), "")
    runs = len(read_rows(out / "results.parquet"))
    return {"total_s": wall, "runs_s": wall, "split": split, "rows": runs, "load": os.getloadavg()[0]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1-8")
    ap.add_argument("--duration", type=float, default=600.0)
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--command", action="store_true", help="time the whole `gnss-sim sweep` command as a process")
    a = ap.parse_args(argv)
    print(f"[bench_sweep] {os.cpu_count()} cores, load average before: "
          f"{', '.join(f'{x:.2f}' for x in os.getloadavg())}")
    res = {1: [], 2: []}
    with tempfile.TemporaryDirectory(prefix="gnss_sim_bench_sweep_") as tmp:
        for r in range(a.rounds):
            for w in ((1, 2) if r % 2 == 0 else (2, 1)):
                if a.command:
                    m = one_command(a.seeds, a.duration, w, Path(tmp) / f"w{w}_{r}")
                    res[w].append(m)
                    print(f"[bench_sweep] round {r + 1} workers {w}: {m['rows']} runs, whole command "
                          f"{m['total_s']:.1f} s; {m['split']}; load average {m['load']:.2f}", flush=True)
                    continue
                m = one_sweep(a.seeds, a.duration, w, Path(tmp) / f"w{w}_{r}")
                res[w].append(m)
                print(f"[bench_sweep] round {r + 1} workers {w}: {m['rows']} runs, total {m['total_s']:.1f} s "
                      f"(cluster {m['cluster_s']:.1f} s, runs {m['runs_s']:.1f} s, mean run {m['mean_run_s']:.1f} s, "
                      f"loop wall/CPU {m['wall_per_cpu']:.2f}), "
                      f"load average {m['load']:.2f}", flush=True)
    best = {w: {k: min(m[k] for m in res[w]) for k in ("total_s", "runs_s")} for w in res}
    if a.command:
        print(f"[bench_sweep] speed-up 2 workers / 1 worker, whole command: "
              f"{best[1]['total_s'] / best[2]['total_s']:.2f}x (seeds {a.seeds}, {a.duration:g} s each; load "
              f"average after: {', '.join(f'{x:.2f}' for x in os.getloadavg())})")
        return 0
    print(f"[bench_sweep] speed-up 2 workers / 1 worker: total {best[1]['total_s'] / best[2]['total_s']:.2f}x, "
          f"runs only {best[1]['runs_s'] / best[2]['runs_s']:.2f}x (seeds {a.seeds}, {a.duration:g} s each; "
          f"load average after: {', '.join(f'{x:.2f}' for x in os.getloadavg())})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
