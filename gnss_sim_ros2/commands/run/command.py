"""``gnss-sim run``'s command line: its options, the output folder and ROS domain of the run, the run itself
(runner.Runner) and its exit code."""
from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

import yaml

from gnss_sim_ros2 import graph
from gnss_sim_ros2.commands import fail
from gnss_sim_ros2.commands.run.isolation import OutputBusy, OutputFolder, OutputNotOurs, choose_domain_id
from gnss_sim_ros2.commands.run.runner import Runner
from gnss_sim_ros2.config_file import load_config
from gnss_sim_ros2.file_parameters import missing_files
from gnss_sim_ros2.graph import LAYOUTS
from gnss_sim_ros2.graph_params import check_robot_config, check_robots


def layout_of(args) -> str:
    """The process layout of --layout and --processes (an alias of --layout node); ValueError naming both."""
    if args.processes and args.layout not in (None, "node"):
        raise ValueError(f"options --processes (one process per node) and --layout {args.layout} do not go "
                         f"together: give one of them")
    return "node" if args.processes else (args.layout or "composed")


def add_arguments(p):
    p.add_argument("--config", help="gnss_sim parameter file (the one the launch file takes)")
    sc = p.add_mutually_exclusive_group()
    sc.add_argument("--world", metavar="SDF", help="Gazebo world (default: worlds/courtyard.sdf)")
    sc.add_argument("--mesh", metavar="FILE", help="mesh exported by export-world")
    from gnss_sim_ros2.core.scene.scene_report import ALLOW_PARTIAL_HELP
    p.add_argument("--allow-partial", action="store_true", help=ALLOW_PARTIAL_HELP)
    p.add_argument("--out", default="gnss_sim_run", metavar="DIR",
                   help="output folder [gnss_sim_run]: new, empty or one of an earlier run (only its files are "
                        "replaced); a folder holding other files is refused")
    p.add_argument("--duration", type=float, default=None, metavar="S", help="simulated seconds [from config]")
    p.add_argument("--rate", type=float, default=None, metavar="HZ", help="epoch rate [from config]")
    p.add_argument("--systems", default=None, help="GNSS systems, letters of GRECJI")
    from gnss_sim_ros2.core.receiver.profile_file import option_help
    p.add_argument("--profile", metavar="NAME|FILE", default=None, help=option_help())
    p.add_argument("--scenario", metavar="FILE", default=None,
                   help="threat scenario (YAML, docs/SCENARIOS.md): timed jammers, spoofers, receiver faults "
                        "(parameter scenario); truth labels on /gnss/threats/active")
    p.add_argument("--layout", choices=LAYOUTS, default=None,
                   help="processes: composed (every node in this one), robot (one process per robot: its player, "
                        "visibility and receiver; the ephemeris node and the recorder in this one), node (one "
                        "process per node), fleet (every node in this one, one visibility node casting every "
                        "robot's antenna per epoch and one receiver node stepping every robot's chain; up to 64 "
                        "robots) [composed]")
    p.add_argument("--processes", action="store_true", help="one process per node: --layout node")
    p.add_argument("--realtime", action="store_true", help="simulated time at wall-clock pace")
    p.add_argument("--no-record", action="store_true", help="do not record a bag")
    p.add_argument("--no-autostart", action="store_true",
                   help="do not configure/activate the nodes (leave them to another lifecycle manager)")
    p.add_argument("--antenna-frame", default=None, help="TF frame of the antenna [from config]")
    p.add_argument("--no-trajectory-player", action="store_true",
                   help="do not move the robot here: its TF comes from elsewhere (Gazebo + ros_gz_bridge)")
    p.add_argument("--domain-id", type=int, default=None, metavar="N",
                   help="ROS_DOMAIN_ID of the run's graph (default: a free one of its own, printed at the start)")
    p.add_argument("--rtk", action="store_true",
                   help="RTK: a base station at base_position and the rtk node (RTKLIB rtkrcv) on the rover's and "
                        "the base's RTCM3; /gnss/rtk/fix recorded, RTK figures in the summary")
    p.add_argument("--robots", type=int, default=1, metavar="N",
                   help="N robots in one graph (1..16): each its own TF frames (robot<k>/...), path (a convoy "
                        "convoy_spacing_s apart along the path, or robot_trajectory_files), visibility and receiver "
                        "node in namespace robot<k> (/robot<k>/gnss/fix, RINEX in OUT/robot<k>), one ephemeris node "
                        "and one scene for all [1]")
    p.add_argument("--quiet", action="store_true")


#: parameter -> command-line option (load_config's ``options``: errors name the option the user typed)
PARAM_OPTIONS = {"systems": "--systems", "rate_hz": "--rate", "antenna_frame": "--antenna-frame",
                 "duration_s": "--duration", "world_file": "--world", "mesh_file": "--mesh",
                 "strict_world": "--allow-partial", "profile": "--profile", "scenario": "--scenario"}


def _overrides(args) -> dict:
    shared = {}
    if args.systems is not None:
        shared["systems"] = args.systems
    if args.rate is not None:
        shared["rate_hz"] = args.rate
    if args.antenna_frame is not None:
        shared["antenna_frame"] = args.antenna_frame
    out = {"/**": shared}
    if args.world:
        out["visibility"] = {"world_file": str(Path(args.world).resolve()), "mesh_file": ""}
    if args.mesh:
        out["visibility"] = {"mesh_file": str(Path(args.mesh).resolve()), "world_file": ""}
    if getattr(args, "allow_partial", False):
        out.setdefault("visibility", {})["strict_world"] = False
    if args.duration is not None:
        out["ephemeris"] = {"duration_s": args.duration}
    if getattr(args, "profile", None) is not None:    # checked (and a file made absolute) by the table
        out.setdefault("receiver", {})["profile"] = args.profile
    if getattr(args, "scenario", None) is not None:   # checked (and made absolute) by the table
        out.setdefault("receiver", {})["scenario"] = args.scenario
    if getattr(args, "rtk", False):
        out.setdefault("receiver", {})["rtcm"] = True      # the rover's RTCM3 for the rtk node
    return out


def run(args) -> int:
    folder = OutputFolder(Path(args.out), command="gnss-sim run", inputs=(args.config, args.world, args.mesh))
    try:
        folder.check()           # a folder with files the run did not write: refused before anything starts
        args.layout = layout_of(args)
        args.robots = check_robots(args.robots, "option --robots", fleet=args.layout == "fleet")
        args.processes = args.layout == "node"
        if args.rtk and args.robots > 1:
            raise ValueError(f"options --rtk and --robots {args.robots} do not go together: an RTK run has one "
                             f"rover (and its base station); run RTK with --robots 1")
        ov = _overrides(args)
        ov["/**"]["output_dir"] = str(folder.staging)
        cfg = load_config(args.config, ov, PARAM_OPTIONS)
        given = {name: opt for name, opt in PARAM_OPTIONS.items() if any(name in sec for sec in ov.values())}
        missing = missing_files(cfg, given)   # before the graph starts (a missing --world failed the visibility
        if missing:                           # node's configure after every node had started: config --check's list)
            raise ValueError("; ".join(missing))
        check_robot_config(cfg, args.robots, "option --robots")
        robot_sections = graph.robot_parameter_sections(cfg, args.robots)   # a robot's bad path file stops here
        # the base station's (and moving baseline's) sections: a bad base_position stops here, before any start
        rtk_sections = graph.rtk_parameter_sections(cfg) if args.rtk else {}
        if args.domain_id is not None and not 0 <= args.domain_id <= 232:
            raise ValueError(f"option --domain-id is {args.domain_id}; a ROS domain id is 0..232")
    except ValueError as exc:
        print(f"gnss-sim run: error: {exc}", file=sys.stderr)
        return 2
    try:
        staging = folder.acquire()
        if args.domain_id is None:
            user = os.environ.get("ROS_DOMAIN_ID", "")
            domain, _domain_lock = choose_domain_id(avoid={int(user)} if user.isdigit() else set())
        else:
            domain = args.domain_id
    except (OutputBusy, OutputNotOurs) as exc:
        return fail("run", exc)
    os.environ["ROS_DOMAIN_ID"] = str(domain)   # this process and its node processes
    params_file = staging / "params.yaml"
    params_file.write_text(yaml.safe_dump({**cfg.ros_parameter_file_dict(), **rtk_sections, **robot_sections},
                                          sort_keys=False))
    runner = Runner(cfg, staging, params_file, args)
    runner.domain_id = domain
    for old in folder.stale:
        runner.warn(f"note: {old} holds the outputs of a run that was killed; left as it is")
    stop = {"flag": False, "signal": 0}

    def on_signal(signum, _frame):
        stop["flag"] = True
        stop["signal"] = signum

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    code = 1
    try:
        code = runner.run(stop)
    finally:
        runner.close()
        if runner.epochs_done > 0:
            try:
                if code == 0 and not stop["signal"]:
                    folder.commit()
                    moved = True
                else:       # a run stopped or failed midway never replaces earlier results: its own stay staged
                    moved = folder.keep_stopped()
                if moved:
                    runner.log(f"outputs in {folder.final}")
                else:
                    runner.warn(f"stopped: the earlier results in {folder.final} are kept; this run's closed "
                                f"outputs are in {folder.staging}")
            except OutputNotOurs as exc:    # a foreign file appeared under one of the run's names meanwhile
                runner.warn(f"gnss-sim run: error: {exc}")
                code = code or 1
        else:
            folder.abandon()
            if folder.final.exists():
                runner.log(f"nothing produced: the previous results in {folder.final} are left untouched")
    if stop["signal"] and code == 0:
        return 128 + stop["signal"]       # the convention: 130 after SIGINT, 143 after SIGTERM
    return code


