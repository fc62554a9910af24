"""``gnss-sim threats-plot``: the threat timeline of a run with a scenario (docs/SCENARIOS.md).

    gnss-sim threats-plot RUN_DIR --png FILE [--trajectory FILE.csv] [--world SDF]

``RUN_DIR``: a folder of ``gnss-sim simulate --scenario`` (or ``gnss-sim run --scenario``): its ``fix.csv`` (with
the ``active_events`` truth labels) and RINEX observation file.  The PNG has four panels over the run time: the
median C/N0 of the tracked signals per band, the satellites tracked and used, the fix's horizontal error against
the antenna's true path, and when each event of the scenario is active.  The true path is ``--trajectory`` (the
CSV given to simulate) or the demo path, in ``--world``'s frame (default the demo courtyard).  A line per event
says what the receiver did while it was active.
"""
from __future__ import annotations

from pathlib import Path

from gnss_sim_ros2.commands import fail


def add_arguments(parser):
    parser.add_argument("run_dir", metavar="RUN_DIR", help="output folder of a run with --scenario (fix.csv, RINEX)")
    parser.add_argument("--png", required=True, metavar="FILE", help="the figure to write (PNG)")
    parser.add_argument("--trajectory", metavar="FILE.csv", help="the antenna's true path as given to simulate "
                        "(default: the demo path)")
    parser.add_argument("--world", metavar="SDF", help="the world whose spherical_coordinates place a world-frame "
                        "path (default: the demo courtyard)")


def run(args) -> int:
    from gnss_sim_ros2.core.output_folder import OutputNotOurs, staged_files
    from gnss_sim_ros2.core.scene.demo_world import demo_world_path
    from gnss_sim_ros2.core.scene.georeference import spherical_of_world_file
    from gnss_sim_ros2.core.scene.sdf_xml import SdfError
    from gnss_sim_ros2.core.threats.timeline import plot_timeline, read_timeline, summary
    from gnss_sim_ros2.core.trajectory import Trajectory, demo_trajectory

    try:
        if Path(args.png).suffix.lower() != ".png":
            raise ValueError(f"option --png {args.png}: the figure is a PNG, give a file name ending in .png")
        truth = Trajectory.from_csv(args.trajectory) if args.trajectory else demo_trajectory()
        spherical = spherical_of_world_file(args.world or demo_world_path()) if truth.frame == "world" else None
        tl = read_timeline(args.run_dir, truth, spherical)
        with staged_files([("--png", args.png)]) as temp:
            plot_timeline(tl, temp[args.png], title=f"threat scenario: {Path(args.run_dir).name}")
    except (ValueError, SdfError, OutputNotOurs) as exc:
        return fail("threats-plot", exc)
    if not tl.events:          # a scenario without events, or none of them inside the run: the events panel is empty
        print(f"note: {Path(args.run_dir) / 'fix.csv'}: no event of the scenario was active in any epoch "
              f"(column active_events empty): the figure's events panel is empty")
    for line in summary(tl):
        print(line)
    print(f"wrote {args.png}")
    return 0
