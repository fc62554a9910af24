"""``gnss-sim bench``: the benchmarks' command line (the harnesses: gnss_sim_ros2/benchmarks/).

Without option: speed against accuracy of the fidelity presets (benchmarks/presets.py); ``--scaling``: cost
and memory against the size of the problem (benchmarks/scaling.py); ``--speed``: the offline speed targets
(benchmarks/speed.py); ``--fleet``: robots in the fleet layout at real-time pace (benchmarks/fleet.py).
Prints a table; ``--json`` and ``--plot`` write the figures.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from gnss_sim_ros2.benchmarks.presets import PRESET_ORDER, plot, run_bench, table


def add_arguments(p):
    p.add_argument("--quick", action="store_true", help="shorter scenarios (under two minutes)")
    p.add_argument("--json", metavar="FILE", nargs="?", const="-",
                   help="write the figures as JSON to FILE (no FILE: to standard output, the table to stderr)")
    p.add_argument("--plot", metavar="FILE.png",
                   help="plot of cost against accuracy (PNG); with --scaling: cost against the size of the problem; "
                   "with --fleet: cost, latency and memory against the robots")
    p.add_argument("--repeats", type=int, default=None, help="timed runs per preset, best kept (3)")
    p.add_argument("--no-real", action="store_true", help="skip the OPEC scenario even when its data is present")
    p.add_argument("--presets", default=",".join(PRESET_ORDER), help="comma-separated presets (all)")
    p.add_argument("--epochs", type=int, default=None, help=argparse.SUPPRESS)   # tiny runs for tests
    p.add_argument("--scaling", action="store_true",
                   help="instead of the presets: cost and peak memory against triangles, satellites, epochs and "
                   "rate (benchmarks/scaling.py); --plot draws them, --json writes them")
    p.add_argument("--scaling-max-hours", type=float, default=1.0, metavar="H",
                   help="with --scaling: spans up to H hours are run, longer ones (to 24 h) extrapolated (1)")
    p.add_argument("--speed", action="store_true",
                   help="instead of the presets: the offline speed targets (benchmarks/speed.py): the demo "
                   "hour's real-time factor and the ratio to gnss_lib_py's simulate_measures on a static GPS hour, "
                   "start-up included")
    p.add_argument("--peer-python", metavar="PYTHON",
                   help="with --speed: an interpreter that imports gnss_lib_py (default: GNSS_SIM_PEER_PYTHON, "
                   "then this one)")
    p.add_argument("--speed-duration", type=float, default=3600.0, metavar="S",
                   help="with --speed: simulated span of each run [s] (3600)")
    p.add_argument("--fleet", action="store_true",
                   help="instead of the presets: robots in the fleet layout at real-time pace (benchmarks/fleet.py): "
                   "p99 states -> observations of the worst robot, epochs without output, added CPU and memory of "
                   "one more robot")
    p.add_argument("--fleet-robots", default="1,4,32", metavar="N[,N...]",
                   help="with --fleet: robot counts, --fleet-repeats runs each (1..64; 1 is needed for the added cost) "
                        "[1,4,32]")
    p.add_argument("--fleet-rate", type=float, default=10.0, metavar="HZ", help="with --fleet: epoch rate [10]")
    p.add_argument("--fleet-duration", type=float, default=20.0, metavar="S",
                   help="with --fleet: simulated (= wall) seconds of each run [20]")
    p.add_argument("--fleet-repeats", type=int, default=3, metavar="R",
                   help="with --fleet: runs per robot count, in rounds over the counts (1..10): CPU and memory are "
                        "their medians, latency the worst run's [3]")
    p.add_argument("--fleet-config", metavar="FILE", default=None,
                   help="with --fleet: gnss_sim parameter file of every run (e.g. multipath: 'off' in the visibility "
                   "section) [the defaults]")


def run_scaling_command(args) -> int:
    from gnss_sim_ros2.benchmarks.scaling import run_scaling, scaling_plot, scaling_table

    if not 0 < args.scaling_max_hours <= 24:
        print(f"gnss-sim bench: error: option --scaling-max-hours is {args.scaling_max_hours:g}: "
              f"must be in (0, 24]", file=sys.stderr)
        return 2
    if args.epochs is not None and args.epochs < 2:
        print("gnss-sim bench: error: --epochs must be >= 2", file=sys.stderr)
        return 2
    report = run_scaling(args.quick, args.scaling_max_hours, log=lambda m: print(m, file=sys.stderr, flush=True),
                         epochs=args.epochs)
    return _report_out(args, report, scaling_table(report), scaling_plot)


def run_speed_command(args) -> int:
    from gnss_sim_ros2.benchmarks.speed import run_speed, speed_table

    try:
        report = run_speed(args.speed_duration, args.repeats or 3, args.peer_python,
                           log=lambda m: print(m, file=sys.stderr, flush=True), real=not args.no_real)
    except (ValueError, RuntimeError) as exc:
        print(f"gnss-sim bench: error: {exc}", file=sys.stderr)
        return 2
    if args.plot:
        print("gnss-sim bench: error: --plot is not available with --speed", file=sys.stderr)
        return 2
    return _report_out(args, report, speed_table(report), None)


def run_fleet_command(args) -> int:
    from gnss_sim_ros2.benchmarks.fleet import check_counts, fleet_table, run_fleet

    try:
        counts = check_counts(args.fleet_robots)
        if not 1 <= args.fleet_repeats <= 10:
            raise ValueError(f"option --fleet-repeats {args.fleet_repeats}: give 1 to 10 runs per robot count")
        if not (0 < args.fleet_rate <= 100 and args.fleet_duration >= 1):
            raise ValueError(f"options --fleet-rate {args.fleet_rate:g} / --fleet-duration {args.fleet_duration:g}: "
                             f"a rate in (0, 100] Hz and a duration of at least 1 s are needed")
        if args.fleet_config and not Path(args.fleet_config).is_file():
            raise ValueError(f"option --fleet-config {args.fleet_config}: no such file")
        report = run_fleet(counts, args.fleet_rate, args.fleet_duration,
                           log=lambda m: print(m, file=sys.stderr, flush=True), config=args.fleet_config,
                           repeats=args.fleet_repeats)
    except (ValueError, RuntimeError) as exc:
        print(f"gnss-sim bench: error: {exc}", file=sys.stderr)
        return 2
    from gnss_sim_ros2.benchmarks.fleet_plot import fleet_plot

    return _report_out(args, report, fleet_table(report), fleet_plot)


def run(args) -> int:
    from gnss_sim_ros2.core.output_folder import check_outputs_not_inputs

    try:     # an output that is a folder is refused before the runs, not after minutes of them
        check_outputs_not_inputs([("--json", None if args.json == "-" else args.json), ("--plot", args.plot)],
                                 inputs=[args.fleet_config])
    except ValueError as exc:
        print(f"gnss-sim bench: error: {exc}", file=sys.stderr)
        return 2
    if args.fleet:
        return run_fleet_command(args)
    if args.scaling:
        return run_scaling_command(args)
    if args.speed:
        return run_speed_command(args)
    try:
        presets = tuple(p.strip() for p in args.presets.split(",") if p.strip())
        if args.epochs is not None and args.epochs < 2:
            raise ValueError("--epochs must be >= 2")
        report = run_bench(args.quick, presets, args.repeats, args.epochs, not args.no_real,
                           log=lambda m: print(m, file=sys.stderr, flush=True))
    except ValueError as exc:
        print(f"gnss-sim bench: error: {exc}", file=sys.stderr)
        return 2
    return _report_out(args, report, table(report), plot)


def _report_out(args, report: dict, text_table: str, plot_fn) -> int:
    """The table (stdout, or stderr when the JSON goes to stdout), --json and --plot."""
    text = sys.stderr if args.json == "-" else sys.stdout
    print(text_table, file=text)
    if args.json == "-":
        print(json.dumps(report, indent=1, default=_json_default))
    elif args.json:
        from gnss_sim_ros2.core.output_folder import staged_files

        with staged_files([("--json", args.json)]) as temp:     # renamed into place when whole
            temp[args.json].write_text(json.dumps(report, indent=1, default=_json_default))
        print(f"wrote {args.json}", file=text)
    if args.plot:
        print(f"wrote {plot_fn(report, args.plot)}", file=text)
    return 0


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)
