"""One run of a sweep -> one result row (table.py), on whichever worker runs it.

``run_row(point, setup, cache_dir)`` runs ``setup`` (a ``SimulationSetup`` the
caller built from the scenario and the point) through
``core.simulation.run_simulation`` and summarises its result; any exception
becomes a failed row with its error (the traceback goes to ``error.txt`` in the
run's folder) so that the sweep goes on.

A worker process keeps the scene and the ephemeris its last runs loaded
(``SetupCache``): runs that differ only by seed or preset read them once.  The
scene is cast with one thread (a worker is one core); the results do not depend
on either (test_sweep.py compares a cached run with a fresh one).
"""
from __future__ import annotations

import dataclasses
import itertools
import os
import socket
import time
import traceback
import warnings
from collections import OrderedDict
from pathlib import Path

import numpy as np

from ..metrics import percentile, rms
from .table import COLUMNS, PERCENTILES


class SetupCache:
    """Scenes and ephemerides by what defines them, the ``size`` most recent of each, with the
    warnings their loading gave (repeated into every row that uses them)."""

    def __init__(self, size: int = 4, scene_threads: int = 1):
        self.size = int(size)
        self.scene_threads = int(scene_threads)
        self._items: OrderedDict = OrderedDict()
        self._made = itertools.count(1)

    def get(self, key, make):
        """(value, warnings) of ``key``, made by ``make()`` when absent."""
        if key in self._items:
            self._items.move_to_end(key)
            return self._items[key]
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            value = make()
        item = (value, [str(w.message) for w in caught])
        self._items[key] = item
        kind = key[0]
        same = [k for k in self._items if k[0] == kind]
        while len(same) > self.size:
            del self._items[same.pop(0)]
        return item

    def prepare(self, setup, workdir: Path):
        """``setup`` with its scene and ephemeris from the cache; (setup, warnings of loading them)."""
        from ..ephemeris.provider import open_ephemeris
        from ..simulation import orbit_source, visibility_options
        from ..visibility import load_scene

        notes: list[str] = []
        extra: dict = {}
        world, mesh, materials = setup.scene_files()
        if setup.scene is None and (world or mesh):
            opts = visibility_options(setup)
            key = ("scene", world, _mtime(world), mesh, _mtime(mesh), materials, _mtime(materials), opts.use_visuals,
                   opts.keep_dynamic, opts.strict_world)

            def make_scene():
                scene = load_scene(world, mesh, materials, opts)
                scene.rays.nthreads = self.scene_threads
                return scene

            extra["scene"], w = self.get(key, make_scene)
            notes += w
        # the provider run_simulation would open (the same call), made once
        source = orbit_source(setup)
        eph = dict(setup.ephemeris)
        if source not in eph:
            files = tuple(tuple(group) for group in setup.orbit_files())
            key = ("ephemeris", source, int(setup.start.sec), float(setup.start.frac), float(setup.duration_s),
                   setup.systems, *files, *(_mtime(f) for group in files for f in group))
            where = Path(workdir) / f"eph{next(self._made):04d}"
            eph[source], w = self.get(key, lambda: open_ephemeris(
                source, setup.start, setup.duration_s, setup.systems, *setup.orbit_files(), workdir=where))
            notes += w
        extra["ephemeris"] = eph
        return dataclasses.replace(setup, **extra), notes


def _mtime(path: str) -> float | None:
    try:
        return os.stat(path).st_mtime if path else None
    except OSError:
        return None


#: this worker process's cache of the sweep now running (by its cache folder: a new sweep starts afresh)
_CACHE: dict = {}


def worker_cache(cache_dir) -> SetupCache:
    key = str(cache_dir)
    if key not in _CACHE:
        _CACHE.clear()
        _CACHE[key] = SetupCache()
    return _CACHE[key]


def run_row(point, setup, cache_dir: str | Path | None = None) -> dict:
    """Run ``setup`` (out_dir = the run's own folder) and return its row; never raises for a failed run.

    ``cache_dir``: where this process keeps the ephemeris files it caches (None: no cache, every run
    loads its scene and ephemeris itself)."""
    from ..simulation import run_simulation

    t0 = time.perf_counter()
    row = base_row(point, setup)
    notes: list[str] = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            (Path(setup.out_dir) / "error.txt").unlink(missing_ok=True)
            if cache_dir is not None:
                own = Path(cache_dir) / f"{socket.gethostname()}_{os.getpid()}"
                t_load = time.perf_counter()
                setup, notes = worker_cache(cache_dir).prepare(setup, own)
                row["load_s"] = time.perf_counter() - t_load
            res = run_simulation(setup)
        notes += [str(w.message) for w in caught]
        row.update(result_columns(res))
        row["status"], row["error"] = "ok", ""
    except Exception as exc:  # a failed run is a row with its error: the sweep goes on
        row["status"], row["error"] = "failed", f"{type(exc).__name__}: {exc}"
        try:
            Path(setup.out_dir).mkdir(parents=True, exist_ok=True)
            (Path(setup.out_dir) / "error.txt").write_text(traceback.format_exc())
        except OSError:
            pass
    row["warnings"] = "\n".join(dict.fromkeys(notes))
    row["runtime_s"] = time.perf_counter() - t0
    row["worker"] = f"{socket.gethostname()}:{os.getpid()}"
    return row


def base_row(point, setup) -> dict:
    """Every column of a run's row: its inputs set, the rest null."""
    world, mesh, _ = setup.scene_files()
    return {**dict.fromkeys(COLUMNS), "index": point.index, "run": point.name,
            "seed": int(setup.receiver_params["seed"]), "start_time": setup.start.isoformat("GPS", 0),
            "preset": setup.preset, "trajectory": point.trajectory or "",
            "world": world or mesh or "", "systems": setup.systems,
            "duration_s": float(setup.duration_s), "interval_s": float(setup.interval_s)}


def result_columns(res) -> dict:
    """The result and cost columns of a SimulationResult."""
    e = np.asarray(res.horizontal_error_m, dtype=float)
    tracked = np.asarray(res.tracked_per_epoch, dtype=float)
    cols = {"epochs": int(res.epochs), "fixes": int(res.fixes),
            "fix_availability": res.fixes / res.epochs if res.epochs else None,
            "interval_s": float(res.interval_s),
            "setup_s": float(res.setup_s), "loop_s": float(res.wall_s), "loop_cpu_s": float(res.cpu_s),
            "realtime_factor": float(res.realtime_factor) if res.wall_s > 0 else None}
    for p in PERCENTILES:
        cols[f"h_err_p{p}_m"] = percentile(e, p)
    cols["h_err_max_m"] = float(e.max()) if e.size else None
    cols["h_err_rms_m"] = rms(e)
    cols["sats_tracked_mean"] = float(tracked.mean()) if tracked.size else None
    cols["sats_tracked_min"] = int(tracked.min()) if tracked.size else None
    cols["sats_tracked_max"] = int(tracked.max()) if tracked.size else None
    for name, values in (("visible", res.visible_per_epoch), ("blocked", res.blocked_per_epoch),
                         ("attenuated", res.attenuated_per_epoch)):
        v = np.asarray(values, dtype=float)
        cols[f"sats_{name}_mean"] = float(v.mean()) if v.size else None
    return cols
