"""CPU time and peak memory of ``gnss-sim run``'s processes (Linux /proc): summary.json ``processes`` and
``peak_rss_mb``."""
from __future__ import annotations

import os
import time
from pathlib import Path

#: the summary's name of the run's own process
RUN_PROCESS = "gnss_sim_run"


def proc_cpu_s(pid: int) -> float | None:
    """CPU time [s] (user + system) of a process so far (Linux /proc/<pid>/stat: fields 14, 15 in clock ticks)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def proc_peak_rss_mb(pid: int) -> float | None:
    """Peak resident memory of a process [MB] (Linux /proc/<pid>/status VmHWM, kB)."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return round(int(line.split()[1]) / 1024.0, 1)
    except OSError:
        pass
    return None


class ProcessStats:
    """CPU time over the epochs of this process and of the node processes ``pids`` ({name: pid}): ``start()``
    when the epochs start, ``figures(n_epochs)`` after them (before the processes stop)."""

    def __init__(self, pids: dict[str, int]):
        self.pids = {RUN_PROCESS: os.getpid(), **pids}
        self.cpu0: dict = {}

    def cpu_s(self) -> dict:
        """CPU time [s] (user + system) so far of this process and of each node process (None: unknown)."""
        return {name: time.process_time() if name == RUN_PROCESS else proc_cpu_s(pid)
                for name, pid in self.pids.items()}

    def start(self):
        self.cpu0 = self.cpu_s()

    def figures(self, n_epochs: int) -> dict:
        """{process: {"cpu_ms_per_epoch": CPU time per epoch [ms] over the epochs, "peak_rss_mb": peak memory}}."""
        cpu1 = self.cpu_s()
        out = {}
        for name, pid in self.pids.items():
            a, b = self.cpu0.get(name), cpu1.get(name)
            out[name] = {"cpu_ms_per_epoch": round(1e3 * (b - a) / n_epochs, 2) if None not in (a, b) and n_epochs
                         else None, "peak_rss_mb": proc_peak_rss_mb(pid)}
        return out
