"""``gnss-sim sweep``: one ``gnss-sim simulate`` scenario over axes, on dask.distributed.

The scenario takes every option of ``gnss-sim simulate`` (parameter file and
overrides, built by its ``setup_from_args``); the axes (``--seeds 1-100``,
``--dates``, ``--presets``, ``--trajectories``, ``--worlds``) replace its
single ``--seed``, ``--start``, ``--preset``, ``--trajectory`` and ``--world``.
Every combination of the axes is one run, writing into ``OUT/runs/runNNNNN/``;
``OUT/results.parquet`` has one row per run (core/sweep/table.py) and
``OUT/summary.png`` the percentiles.  A local cluster of ``--workers``
processes (one thread each) by default, an existing one with ``--scheduler``.
"""
from __future__ import annotations

import argparse
import copy
import os
import sys
from pathlib import Path

from gnss_sim_ros2.commands import simulate

#: axis option -> (the single option of simulate it replaces, attribute of args)
AXIS_OPTIONS = {"--seeds": ("--seed", "seed"), "--dates": ("--start", "start"), "--presets": ("--preset", "preset"),
                "--trajectories": ("--trajectory", "trajectory"), "--worlds": ("--world", "world")}
WORLD_SUFFIXES = (".sdf", ".world")
#: the writer named in the manifest of OUT
SWEEP_COMMAND = "gnss-sim sweep"


def default_workers() -> int:
    """Worker processes of the local cluster when ``--workers`` is not given: the machine's cores."""
    return os.cpu_count() or 1


def add_arguments(p):
    simulate.add_arguments(p)
    a = p.add_argument_group("sweep axes (every combination is one run)")
    a.add_argument("--seeds", metavar="LIST", help="seeds: 1-100, 1,5,9 or 1-10,20-29")
    a.add_argument("--dates", metavar="LIST", help="start times, GPS, comma-separated: 2025-06-01T10:00:00, "
                   "2025-06-01 (the scenario's time of day) or FIRST..LAST (every day)")
    a.add_argument("--presets", metavar="LIST", help="presets, comma-separated: fast,balanced,accurate")
    a.add_argument("--trajectories", nargs="+", metavar="FILE.csv", help="antenna paths (as --trajectory)")
    a.add_argument("--worlds", nargs="+", metavar="FILE", help="Gazebo worlds (.sdf) or exported meshes")
    c = p.add_argument_group("where the runs go")
    w = c.add_mutually_exclusive_group()
    w.add_argument("--workers", type=int, default=None, metavar="N",
                   help=f"local cluster of N worker processes, one thread each "
                        f"(default: the cores, {default_workers()})")
    w.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler, e.g. tcp://10.0.0.5:8786")
    c.add_argument("--no-cache", action="store_true",
                   help="every run loads its scene and ephemeris (default: a worker keeps them between runs)")
    c.add_argument("--plot", metavar="FILE.png", default=None, help="summary plot (default OUT/summary.png)")
    p.add_argument("--print-setup", action="store_true", help=argparse.SUPPRESS)   # tests: the points, no run
    for action in p._actions:
        if action.dest == "out":
            action.help = ("output folder: runs/runNNNNN/, results.parquet, summary.png; new, empty or one of an "
                           "earlier sweep (only its files are replaced); a folder holding other files is refused")


def axis_values(args) -> dict:
    """{axis: values or None} from the options; ValueError naming the option."""
    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.core.figures import check_png_name
    from gnss_sim_ros2.core.sweep.axes import parse_dates, parse_names, parse_seeds
    from gnss_sim_ros2.parameters import SHARED_KEY, param

    for axis_opt, (single, attr) in AXIS_OPTIONS.items():
        if getattr(args, axis_opt[2:]) is not None and getattr(args, attr) is not None:
            raise ValueError(f"options {axis_opt} and {single} exclude each other (the axis replaces the option)")
    if args.trajectories and (args.position or args.position_ecef):
        raise ValueError("option --trajectories excludes --position/--position-ecef")
    if args.worlds and args.mesh:
        raise ValueError("option --worlds excludes --mesh")
    if args.plot:                                  # found before the runs, not after them
        check_png_name(args.plot, f"option --plot {args.plot}")
    presets = parse_names(args.presets, "--presets") if args.presets is not None else None
    for name in presets or ():
        param(SHARED_KEY, "preset").check(name, "option --presets")
    dates = None
    if args.dates is not None:
        ov, names = simulate.parameter_overrides(args)
        start = load_config(args.config, ov, names).node("receiver")["start_time"]
        dates = parse_dates(args.dates, start.split("T", 1)[1] if "T" in start else "00:00:00")
    return {"seeds": parse_seeds(args.seeds) if args.seeds is not None else None, "dates": dates,
            "presets": presets, "trajectories": _files(args.trajectories, "--trajectories"),
            "worlds": _files(args.worlds, "--worlds")}


def _files(paths, option):
    if not paths:
        return None
    from gnss_sim_ros2.core.input_file import not_a_file

    out = [str(Path(p)) for p in paths]
    dup = sorted({p for p in out if out.count(p) > 1})
    if dup:
        raise ValueError(f"option {option}: {dup[0]} given twice")
    for p in out:              # every run's file, before the cluster starts (a run would fail on its worker)
        if (why := not_a_file(p)) is not None:
            raise ValueError(f"option {option}: {p}: {why}")
    return out


def point_args(args, point, out: Path):
    """The ``gnss-sim simulate`` arguments of one run point (its own output folder, quiet)."""
    ns = copy.copy(args)
    ns.out, ns.quiet = str(out / "runs" / point.name), True
    if point.seed is not None:
        ns.seed = point.seed
    if point.date is not None:
        ns.start = point.date
    if point.preset is not None:
        ns.preset = point.preset
    if point.trajectory is not None:
        ns.trajectory, ns.position, ns.position_ecef = point.trajectory, None, None
    if point.world is not None:
        is_world = Path(point.world).suffix.lower() in WORLD_SUFFIXES
        ns.world, ns.mesh = (point.world, None) if is_world else (None, point.world)
    return ns


def build_tasks(args, out: Path):
    """[(RunPoint, SimulationSetup)] of every run; a bad axis value is a ValueError naming its option."""
    from gnss_sim_ros2.core.sweep.axes import RunPoint, run_points

    axes = axis_values(args)
    points = run_points(**axes)        # the number of runs is checked before any is built
    # each axis value alone first, so that an error names the option and the value
    for axis_opt, field_name in (("--seeds", "seed"), ("--dates", "date"), ("--presets", "preset"),
                                 ("--trajectories", "trajectory"), ("--worlds", "world")):
        for value in axes[axis_opt[2:]] or ():
            try:
                simulate.setup_from_args(point_args(args, RunPoint(0, **{field_name: value}), out))
            except ValueError as exc:
                raise ValueError(f"option {axis_opt}: {value}: {exc}") from None
    tasks = []
    for point in points:
        try:
            tasks.append((point, absolute_paths(simulate.setup_from_args(point_args(args, point, out)))))
        except ValueError as exc:
            given = ", ".join(f"{k}={v}" for k, v in point.inputs().items() if k != "index" and v is not None)
            raise ValueError(f"run {point.name} ({given}): {exc}") from None
    return tasks


def absolute_paths(setup):
    """``setup`` with its files and output folder as absolute paths (from this process's working folder), so
    that a worker started in another folder finds them."""
    import dataclasses

    def absolute(p):
        return str(Path(p).absolute()) if p else p

    world, mesh, materials = setup.scene_files()
    nav, sp3, clk = setup.orbit_files()
    return dataclasses.replace(setup, out_dir=Path(setup.out_dir).absolute()).with_params(
        world_file=absolute(world), mesh_file=absolute(mesh), materials_file=absolute(materials),
        nav_files=[absolute(f) for f in nav], sp3_files=[absolute(f) for f in sp3],
        clk_files=[absolute(f) for f in clk])


def run(args) -> int:
    import threading
    import time

    import numpy as np

    from gnss_sim_ros2.core.figures import pyplot
    from gnss_sim_ros2.core.output_folder import check_output_folder, record_outputs
    from gnss_sim_ros2.core.sweep.driver import run_sweep, start_local_workers
    from gnss_sim_ros2.core.sweep.plot import summary_plot
    from gnss_sim_ros2.core.sweep.timing import sweep_time

    started = process_start()
    out = Path(args.out)
    try:
        if not args.print_setup:   # a folder with files the sweep did not write is refused (core/output_folder.py)
            check_output_folder(out, SWEEP_COMMAND, ignore_dirs=(".cache",))
        if not args.scheduler and not args.print_setup:
            start_local_workers()          # the workers' imports go on while the runs are built
        tasks = build_tasks(args, out)
        if args.print_setup:
            for point, setup in tasks:
                world, mesh, _ = setup.scene_files()
                print(point.name, setup.receiver_params["seed"], setup.start.isoformat("GPS"), setup.preset, world,
                      mesh, setup.out_dir)
            return 0
        # matplotlib is imported while the runs go (this process only waits for them)
        threading.Thread(target=pyplot, name="import-matplotlib", daemon=True).start()
        # --workers absent: the cores, as its help says (the driver alone would start one worker)
        workers = None if args.scheduler else (args.workers if args.workers is not None else default_workers())
        t_sweep = time.time()
        outcome = run_sweep(tasks, out, workers=workers, scheduler=args.scheduler, progress=not args.quiet,
                            cache=not args.no_cache)
        t_rows = time.time()
    except ValueError as exc:
        print(f"gnss-sim sweep: error: {exc}", file=sys.stderr)
        return 2
    rows = outcome.rows
    ok = [r for r in rows if r["status"] == "ok"]
    failed = [r for r in rows if r["status"] != "ok"]
    print(f"{len(rows)} runs on {outcome.workers} worker(s) in {outcome.wall_s:.1f} s "
          f"(+ {outcome.cluster_s:.1f} s starting the cluster): {len(ok)} ok, {len(failed)} failed")
    if ok:
        def med(col):
            v = [r[col] for r in ok if r[col] is not None]
            return f"{np.median(v):.2f}" if v else "-"
        print(f"median over the runs: horizontal error p50 {med('h_err_p50_m')} m, p95 {med('h_err_p95_m')} m, "
              f"fix availability {med('fix_availability')}, satellites tracked {med('sats_tracked_mean')}")
    for r in failed[:5]:
        print(f"failed {r['run']}: {r['error']}", file=sys.stderr)
    if len(failed) > 5:
        print(f"... and {len(failed) - 5} more failed runs (column 'error' of {outcome.results_path})",
              file=sys.stderr)
    if rows:
        print(f"wrote {outcome.results_path}")
        plot_path = Path(args.plot) if args.plot else out / "summary.png"
        print(f"wrote {summary_plot(rows, plot_path)}")
        # what the sweep wrote beside its runs' own folders (each with the manifest of its simulate)
        record_outputs(out, SWEEP_COMMAND, [outcome.results_path, plot_path, *out.glob("runs/*/error.txt")])
        # what divides among the workers and what does not (core/sweep/timing.py)
        print(sweep_time(rows, outcome.workers, t_sweep - started + outcome.cluster_s, outcome.wall_s,
                         time.time() - t_rows).line())
    return 0 if not failed else 1


def process_start() -> float:
    """When this process started (UNIX time): the interpreter and the imports count in a sweep's fixed time."""
    import time

    import psutil  # a dependency of distributed

    try:
        return psutil.Process().create_time()
    except (psutil.Error, OSError):
        return time.time()
