"""Where a sweep's time goes: what divides among the workers and what is paid once whatever their number.

A sweep of N runs on W workers takes ``before + runs_wall + after``: ``before`` (the interpreter, imports,
the runs built, the cluster started) and ``after`` (results.parquet and the plot) are fixed; ``runs_wall``
is about ``work / W``, where ``work`` is the sum of the runs' own times (``runtime_s``), of which ``load``
(``load_s``: scenes and ephemerides loaded into a worker's cache) is paid once per worker and input rather
than per run.  With two workers the whole command gains at most ``total / (before + after + work / 2)``.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass
class SweepTime:
    before_s: float          # from the command's start to the first run submitted [s]
    runs_wall_s: float       # from the first run submitted to the last row [s]
    after_s: float           # results and plot written [s]
    work_s: float            # the runs' own times summed (runtime_s) [s]
    load_s: float            # of work_s: loading scenes and ephemerides into the workers' caches [s]
    workers: int

    @property
    def total_s(self) -> float:
        return self.before_s + self.runs_wall_s + self.after_s

    def line(self) -> str:
        return (f"time {self.total_s:.1f} s: {self.before_s:.1f} s before the first run (interpreter, imports, runs "
                f"built, cluster started) + {self.runs_wall_s:.1f} s of runs on {self.workers} worker(s) "
                f"({self.work_s:.1f} s of work dividing among them, {self.load_s:.1f} s of it loading scenes and "
                f"ephemerides once per worker) + {self.after_s:.1f} s results and plot")


def sweep_time(rows: list[dict], workers: int, before_s: float, runs_wall_s: float, after_s: float) -> SweepTime:
    """The split of a sweep's rows' times (failed runs included: they took their time too)."""
    work = sum(r.get("runtime_s") or 0.0 for r in rows)
    load = sum(r.get("load_s") or 0.0 for r in rows)
    return SweepTime(float(before_s), float(runs_wall_s), float(after_s), float(work), float(load), int(workers))
