"""The scaling figure's robots axis: ``gnss-sim bench --fleet --plot FILE.png`` (issue 31).

One point per robot count of a ``bench --fleet`` report (benchmarks/fleet.run_fleet, one real-time run each):
the run process's CPU time per epoch and the period of the epoch rate (the line above which the graph falls
behind real time), the worst robot's p50 and p99 latency from the satellite states to its observations, and
the peak resident memory, against the robots (log axis, 1 to 64), drawn as bench_scaling.png's four axes are.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np


def fleet_plot(report: dict, path) -> Path:
    from gnss_sim_ros2.core.figures import pyplot, save_figure

    plt = pyplot()
    runs = sorted(report["runs"], key=lambda r: r["robots"])
    robots = np.array([r["robots"] for r in runs], float)
    cpu_ms = np.array([r["cpu_ms_per_epoch"] for r in runs])
    p50_ms = np.array([r["p50_ms_worst"] for r in runs])
    p99_ms = np.array([r["p99_ms_worst"] for r in runs])
    rss_mb = np.array([r["peak_rss_mb"] for r in runs])
    period_ms = 1000.0 / report["rate_hz"]

    fig, (ax_cpu, ax_lat) = plt.subplots(1, 2, figsize=(12, 4.5))
    ax_cpu.plot(robots, cpu_ms, "s-", color="tab:cyan", label="CPU ms/epoch (whole run process)")
    ax_cpu.axhline(period_ms, color="gray", ls=":", label=f"epoch period at {report['rate_hz']:g} Hz")
    ax_cpu.set_ylabel("CPU per epoch [ms]")
    mem = ax_cpu.twinx()
    mem.plot(robots, rss_mb, "^-", color="tab:red", ms=4, label="peak RSS MB")
    mem.set_ylabel("peak resident memory [MB]", color="tab:red")
    mem.set_ylim(0, max(rss_mb) * 1.15)
    h1, l1 = ax_cpu.get_legend_handles_labels()
    h2, l2 = mem.get_legend_handles_labels()
    ax_cpu.legend(h1 + h2, l1 + l2, fontsize=8, loc="upper left")

    ax_lat.plot(robots, p50_ms, "o-", color="tab:blue", label="worst robot p50")
    ax_lat.plot(robots, p99_ms, "o--", color="tab:purple", label="worst robot p99")
    ax_lat.set_ylabel("satellite states -> observations [ms]")
    ax_lat.legend(fontsize=8, loc="upper left")
    for ax in (ax_cpu, ax_lat):
        ax.set_xscale("log", base=2)
        ax.set_xticks(robots, [f"{int(n)}" for n in robots])
        ax.set_xlabel("robots (fleet layout, one process)")
        ax.set_ylim(bottom=0)
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"gnss-sim run --layout fleet at real-time pace, {report['rate_hz']:g} Hz, "
                 f"{report['duration_s']:g} s per point ({report['cores']} cores; configuration: "
                 f"{Path(str(report['config'])).name})")
    fig.tight_layout()
    return save_figure(fig, path)
