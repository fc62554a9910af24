"""Wall-clock timing of a call repeated in one process, and timers put around named functions, for the benchmark
scripts (bench/*.py)."""
from __future__ import annotations

import importlib
import time

import numpy as np


def wall_times_s(fn, repeat: int, warmup: bool = False) -> np.ndarray:
    """Wall time [s] (time.perf_counter) of each of ``repeat`` calls of ``fn``; with ``warmup`` one untimed call
    first (caches, lazy builds)."""
    if warmup:
        fn()
    times = np.empty(repeat)
    for i in range(repeat):
        t0 = time.perf_counter()
        fn()
        times[i] = time.perf_counter() - t0
    return times


def best_s(fn, repeat: int) -> float:
    """The shortest of ``repeat`` wall times [s]: other processes on a shared machine only ever add time."""
    return float(np.min(wall_times_s(fn, repeat)))


def median_best_ms(fn, repeat: int) -> tuple[float, float]:
    """(median, best) wall time of ``fn`` [ms] after one untimed call: on a loaded machine the best is the quiet
    machine's figure."""
    times = wall_times_s(fn, repeat, warmup=True)
    return 1e3 * float(np.median(times)), 1e3 * float(np.min(times))


def mean_per_call_s(fn, calls: int) -> float:
    """Mean wall time [s] of one call of ``fn(k)`` over ``calls`` calls in a row, k = 0 .. calls - 1 (a call that
    must not hit a cache can use k, e.g. an instant shifted by k ms)."""
    t0 = time.perf_counter()
    for k in range(calls):
        fn(k)
    return (time.perf_counter() - t0) / calls


def wrap_attribute(module: str, path: str, make_wrapper) -> bool:
    """Replace ``module``'s attribute at ``path`` ("Class.method" or "function") by ``make_wrapper(inner)``, so that
    every later call goes through the wrapper; False (nothing replaced) when this version of the code lacks it."""
    owner = importlib.import_module(module)
    *parents, name = path.split(".")
    for p in parents:
        owner = getattr(owner, p, None)
    inner = getattr(owner, name, None) if owner is not None else None
    if inner is None:
        return False
    setattr(owner, name, make_wrapper(inner))
    return True
