"""Run the points of a sweep on dask.distributed and collect one row per run.

A ``LocalCluster`` of ``workers`` processes with one thread each by default, or
the cluster of an existing scheduler (``scheduler="tcp://host:port"``; its
workers must import gnss_sim_ros2 and reach the paths of the scenario and of
``out_dir``).  Rows arrive as runs finish: a progress bar counts them, and
``results.parquet`` is rewritten (atomically) at most every ``WRITE_EVERY_S``
seconds and at the end, so an interrupted sweep keeps what it finished (and, for the runs it did not redo,
the rows of the earlier sweep in the folder).  A run
that failed is a row with its error (row.py); a run whose worker died or whose
task could not run at all becomes a failed row too.
"""
from __future__ import annotations

import logging
import shutil
import sys
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

from .row import run_row
from .table import read_previous_rows, rows_so_far, write_rows

#: results.parquet is rewritten at most this often while rows arrive [s]
WRITE_EVERY_S = 2.0
#: an existing scheduler must answer and have a worker within this [s]
CONNECT_TIMEOUT_S = 30.0
RESULTS_NAME = "results.parquet"


class SweepClusterError(ValueError):
    """The scheduler cannot be reached, has no worker, or its workers cannot run gnss_sim."""


@dataclass
class SweepOutcome:
    rows: list = field(default_factory=list)
    results_path: Path | None = None
    wall_s: float = 0.0          # from the first run submitted to the last row [s]
    cluster_s: float = 0.0       # starting (or reaching) the cluster [s]
    workers: int = 0


#: what the local cluster's worker processes import before their first run: the fork server imports it once
#: (in parallel with the sweep's own set-up) and every worker forked from it starts with it (trimesh: SDF
#: primitives, 0.3 s of a worker's first scene otherwise)
WORKER_PRELOAD = ("distributed", "gnss_sim_ros2.core.simulation", "gnss_sim_ros2.core.scene.visibility", "trimesh")
_METHOD_KEY = "distributed.worker.multiprocessing-method"


def start_local_workers() -> str:
    """Start the process that the local cluster's workers will be forked from, now (returns at once).

    Dask starts worker processes with ``spawn`` by default: each one a fresh interpreter that imports
    distributed, gnss_sim and Open3D before its first run (1-3 s, paid after the set-up). With
    ``forkserver`` (the Python 3.14 default; no threads are forked) one server imports them while the
    sweep imports distributed and builds its runs, and each worker is a fork of it.  A method the user
    chose in the Dask configuration is kept.  Returns the method in use."""
    import multiprocessing
    import multiprocessing.forkserver

    import dask  # the user's configuration (distributed's defaults come with distributed: spawn)

    method = dask.config.get(_METHOD_KEY, "spawn")
    if method != "spawn" or "forkserver" not in multiprocessing.get_all_start_methods():
        return method
    # a server already running (the sweep command started it) goes on; the list applies to a new one only
    multiprocessing.forkserver.set_forkserver_preload(list(WORKER_PRELOAD))
    multiprocessing.forkserver.ensure_running()      # the server imports WORKER_PRELOAD from now on
    from distributed.utils import get_mp_context  # (loads distributed's configuration: set ours after it)

    dask.config.set({_METHOD_KEY: "forkserver"})
    get_mp_context()
    return "forkserver"


def _probe() -> str:
    """Run on every worker before the sweep: can it import the simulation?  (The imports, Open3D's
    included, are then paid before the first run, not by it.)"""
    import gnss_sim_ros2.core.scene.visibility  # noqa: F401
    import gnss_sim_ros2.core.simulation  # noqa: F401

    return "ok"


def _connect(workers: int | None, scheduler: str | None):
    """(client, cluster or None)."""
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
        except (OSError, TimeoutError, ValueError) as exc:      # ValueError: "missing port number in address"
            raise SweepClusterError(f"option --scheduler {scheduler}: cannot reach the scheduler ({exc})") from None
        try:
            client.wait_for_workers(1, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError):
            client.close()
            raise SweepClusterError(f"option --scheduler {scheduler}: no worker joined within "
                                    f"{CONNECT_TIMEOUT_S:.0f} s (start one with `dask worker {scheduler}`)") from None
        return client, None
    if workers is not None and int(workers) < 1:
        raise SweepClusterError(f"option --workers is {workers}: at least 1 worker")
    start_local_workers()                        # no-op when the sweep's command started it already
    cluster = LocalCluster(n_workers=int(workers or 1), threads_per_worker=1, processes=True,
                           dashboard_address=None, silence_logs=logging.ERROR)
    return Client(cluster), cluster


def connect_cluster(workers: int | None, scheduler: str | None):
    """(client, local cluster or None): the existing scheduler at ``scheduler``, else a local cluster of ``workers``
    (1 by default) started as the sweep's (``gnss-sim plan`` runs its blocks on it too); SweepClusterError naming
    --scheduler / --workers when it cannot."""
    return _connect(workers, scheduler)


def run_sweep(tasks, out_dir: Path, workers: int | None = None, scheduler: str | None = None,
              progress: bool = True, cache: bool = True, log=None) -> SweepOutcome:
    """Run ``tasks`` [(RunPoint, SimulationSetup with out_dir = the run's folder)] and return the rows.

    ``cache``: workers keep scenes and ephemerides between runs (row.SetupCache)."""
    log = log or (lambda m: print(m, file=sys.stderr, flush=True))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    results = out / RESULTS_NAME
    cache_dir = out / ".cache" / uuid.uuid4().hex[:8] if cache else None
    outcome = SweepOutcome(results_path=results)
    t0 = time.perf_counter()
    client, cluster = _connect(workers, scheduler)
    try:
        try:
            answers = client.run(_probe)
        except Exception as exc:  # a worker that cannot unpickle or import: its error names the module
            raise SweepClusterError(f"the workers cannot run gnss_sim ({type(exc).__name__}: {exc}); start them "
                                    f"in an environment where `import gnss_sim_ros2` works") from None
        outcome.workers = len(answers)
        outcome.cluster_s = time.perf_counter() - t0
        log(f"[sweep] {len(tasks)} runs on {outcome.workers} worker(s) "
            f"({'scheduler ' + scheduler if scheduler else 'local cluster'}, ready in {outcome.cluster_s:.1f} s)")
        outcome.rows = _collect(client, tasks, cache_dir, results, progress)
        outcome.wall_s = time.perf_counter() - t0 - outcome.cluster_s
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
        if cache_dir is not None:
            shutil.rmtree(cache_dir, ignore_errors=True)
            try:
                cache_dir.parent.rmdir()
            except OSError:
                pass
    return outcome


def _collect(client, tasks, cache_dir, results: Path, progress: bool) -> list[dict]:
    from distributed import as_completed

    from .row import base_row

    tag = uuid.uuid4().hex[:8]
    futures = {}
    for point, setup in tasks:
        fut = client.submit(run_row, point, setup, None if cache_dir is None else str(cache_dir),
                            key=f"gnss-sim-sweep-{tag}-{point.name}", pure=False)
        futures[fut.key] = (fut, point, setup)
    rows: list[dict] = []
    # until every run is in, the table keeps the earlier sweep's rows of the runs not redone yet
    previous = read_previous_rows(results)

    def table():
        return rows if len(rows) >= len(tasks) else rows_so_far(rows, previous)

    bar = _bar(len(tasks), progress)
    last = time.perf_counter()
    try:
        for fut in as_completed([f for f, _, _ in futures.values()]):
            _, point, setup = futures[fut.key]
            try:
                row = fut.result()
            except Exception as exc:  # the worker died, or the task could not be unpickled there
                row = {**base_row(point, setup), "status": "failed", "error": f"{type(exc).__name__}: {exc}",
                       "warnings": ""}
            rows.append(row)
            fut.release()
            bar.update(1)
            failed = sum(r["status"] != "ok" for r in rows)
            if failed:
                bar.set_postfix(failed=failed)
            if time.perf_counter() - last >= WRITE_EVERY_S:
                write_rows(table(), results)
                last = time.perf_counter()
    finally:
        bar.close()
        if rows:
            write_rows(table(), results)
        for fut, _, _ in futures.values():
            if not fut.done():
                fut.cancel()
    return rows


def _bar(total: int, enabled: bool):
    from tqdm import tqdm

    return tqdm(total=total, unit="run", desc="[sweep]", disable=not enabled, file=sys.stderr, dynamic_ncols=True)
