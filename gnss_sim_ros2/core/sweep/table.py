"""The sweep's result table: one row per run, its columns and its Parquet file.

Columns (units in the names):

* inputs: ``index``, ``run`` (folder under ``runs/``), ``seed``, ``start_time``
  (GPS, ISO 8601), ``preset``, ``trajectory`` (file, or "" for the scenario's
  own path), ``world`` (SDF or mesh file, "" for none), ``systems``,
  ``duration_s``, ``interval_s``;
* outcome: ``status`` ("ok" | "failed"), ``error`` (exception type and message
  of a failed run, "" else), ``warnings`` (the run's warnings, one per line);
* results: ``epochs``, ``fixes``, ``fix_availability`` (fixes / epochs),
  ``h_err_p50_m``, ``h_err_p68_m``, ``h_err_p95_m``, ``h_err_p99_m``,
  ``h_err_max_m``, ``h_err_rms_m`` (horizontal error of the fixes against the
  true antenna position), ``sats_tracked_mean`` / ``_min`` / ``_max``,
  ``sats_visible_mean``, ``sats_blocked_mean``, ``sats_attenuated_mean``
  (satellites above the mask per epoch by line-of-sight state);
* cost: ``runtime_s`` (the whole run on its worker: set-up, epochs, files),
  ``load_s`` (of it, loading the scene and ephemeris into the worker's cache: paid by a worker's first run
  of those inputs, about 0 by the next; null without the cache), ``setup_s``, ``loop_s`` (the epoch loop),
  ``loop_cpu_s`` (its CPU time: a ``loop_s`` well above it means the core was shared), ``realtime_factor`` (simulated
  seconds per second of the loop), ``worker`` (host:pid).

A failed run has nulls in the results.  ``TIMING_COLUMNS`` differ between two
runs of the same inputs; every other column is determined by the inputs.
"""
from __future__ import annotations

from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from ..user_cache import write_whole

#: horizontal error percentiles of every row
PERCENTILES = (50, 68, 95, 99)

SCHEMA = pa.schema([
    ("index", pa.int64()), ("run", pa.string()), ("seed", pa.int64()), ("start_time", pa.string()),
    ("preset", pa.string()), ("trajectory", pa.string()), ("world", pa.string()), ("systems", pa.string()),
    ("duration_s", pa.float64()), ("interval_s", pa.float64()),
    ("status", pa.string()), ("error", pa.string()), ("warnings", pa.string()),
    ("epochs", pa.int64()), ("fixes", pa.int64()), ("fix_availability", pa.float64()),
    *[(f"h_err_p{p}_m", pa.float64()) for p in PERCENTILES],
    ("h_err_max_m", pa.float64()), ("h_err_rms_m", pa.float64()),
    ("sats_tracked_mean", pa.float64()), ("sats_tracked_min", pa.int64()), ("sats_tracked_max", pa.int64()),
    ("sats_visible_mean", pa.float64()), ("sats_blocked_mean", pa.float64()),
    ("sats_attenuated_mean", pa.float64()),
    ("runtime_s", pa.float64()), ("load_s", pa.float64()), ("setup_s", pa.float64()), ("loop_s", pa.float64()),
    ("loop_cpu_s", pa.float64()),
    ("realtime_factor", pa.float64()), ("worker", pa.string()),
])
COLUMNS = tuple(SCHEMA.names)
#: columns that measure the machine, not the simulation (differ between identical runs)
TIMING_COLUMNS = ("runtime_s", "load_s", "setup_s", "loop_s", "loop_cpu_s", "realtime_factor", "worker")


def to_table(rows: list[dict]) -> pa.Table:
    """The rows (dicts with the columns of SCHEMA; absent keys are null) as an Arrow table, by run index."""
    extra = sorted({k for r in rows for k in r} - set(COLUMNS))
    if extra:
        raise ValueError(f"sweep row: unknown column(s) {', '.join(extra)}")
    rows = sorted(rows, key=lambda r: r["index"])
    return pa.Table.from_pylist([{c: r.get(c) for c in COLUMNS} for r in rows], schema=SCHEMA)


def write_rows(rows: list[dict], path: Path) -> Path:
    """Write the rows to ``path`` (Parquet) whole (core/user_cache.write_whole): a reader never sees a half-written
    file, and a failed write leaves the earlier table and no temporary."""
    path = Path(path)
    table = to_table(rows)
    write_whole(path, lambda f: pq.write_table(table, f))
    return path


def read_rows(path: Path) -> list[dict]:
    """The rows of a sweep's Parquet file, as dicts."""
    return pq.read_table(path).to_pylist()


def read_previous_rows(path: Path) -> list[dict]:
    """The rows of an earlier sweep's table at ``path`` (columns of SCHEMA only; [] when absent or unreadable)."""
    try:
        rows = read_rows(path)
    except (OSError, ValueError, pa.ArrowException):
        return []
    return [{c: r.get(c) for c in COLUMNS} for r in rows if isinstance(r.get("run"), str)]


def rows_so_far(rows: list[dict], previous: list[dict]) -> list[dict]:
    """The table of a sweep not yet complete (still going, or interrupted): its rows, then the earlier sweep's rows
    of the runs it has not redone (their folders under runs/ are still the earlier ones): nothing is lost."""
    done = {r["run"] for r in rows}
    return rows + [r for r in previous if r["run"] not in done]
