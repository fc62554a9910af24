"""``gnss-sim simulate``: the receiver simulation without ROS, as fast as the machine allows.

Writes exactly one observation file ``DIR/*_MO.rnx``, one navigation file
``DIR/*_MN.rnx`` and ``DIR/fix.csv`` (time,lat_deg,lon_deg,h_m,n_sats,status),
replacing only the files an earlier simulate wrote there (core/output_folder.py).
Options override the configuration file (``--config``, the same file the ROS
launch reads).
"""
from __future__ import annotations

import gc
import sys
from pathlib import Path

from gnss_sim_ros2.commands import fail, parse_triple


def add_arguments(p):
    from gnss_sim_ros2.parameters import param  # choices from the parameter table

    p.add_argument("--config", help="gnss_sim parameter file (ROS 2 format, see config/gnss_sim.yaml)")
    p.add_argument("--nav", nargs="+", default=None, metavar="FILE", help="RINEX navigation files")
    p.add_argument("--sp3", nargs="+", default=None, metavar="FILE", help="SP3 precise orbits")
    p.add_argument("--clk", nargs="+", default=None, metavar="FILE", help="RINEX clock files (with --sp3)")
    p.add_argument("--synthetic", action="store_true", help="synthetic constellation (the default source)")
    p.add_argument("--start", help="first epoch, GPS time ISO 8601 (default: start_time of the config)")
    p.add_argument("--duration", type=float, default=None, metavar="SECONDS", help="simulated span [s] (600)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--rate", type=float, metavar="HZ", help="epoch rate [Hz]")
    g.add_argument("--interval", type=float, metavar="SECONDS", help="epoch interval [s]")
    p.add_argument("--mask-deg", type=float, default=None, help="elevation mask [deg]")
    pos = p.add_mutually_exclusive_group()
    pos.add_argument("--position-ecef", metavar="X,Y,Z", help="static antenna, ECEF [m]")
    pos.add_argument("--position", metavar="LAT,LON,H", help="static antenna, geodetic [deg, deg, m]")
    pos.add_argument("--trajectory", metavar="FILE.csv", help="antenna path (t_s,e_m,n_m,u_m | t_s,lat_deg,"
                     "lon_deg,h_m | t_s,x_m,y_m,z_m)")
    sc = p.add_mutually_exclusive_group()
    sc.add_argument("--world", metavar="SDF", help="Gazebo world for visibility")
    sc.add_argument("--mesh", metavar="FILE", help="mesh exported by export-world")
    sc.add_argument("--sky-mask", metavar="FILE.csv",
                    help="a measured sky mask (azimuth_deg,elevation_deg) as the scene of a static antenna "
                         "(--position or --position-ecef): a satellite under it is blocked")
    from gnss_sim_ros2.core.scene.scene_report import ALLOW_PARTIAL_HELP
    p.add_argument("--obstacle-path", nargs="+", default=[], metavar="FILE.csv",
                   help="paths of moving boxes (other vehicles) that block satellites: CSV t_s,e_m,n_m,u_m[,yaw_deg] "
                        "in the world frame (the base of the box), box size: parameter obstacle_model_size_m")
    p.add_argument("--allow-partial", action="store_true", help=ALLOW_PARTIAL_HELP)
    p.add_argument("--systems", help="systems, RINEX letters from GRECJI")
    p.add_argument("--seed", type=int, default=None)
    p.add_argument("--preset", choices=param("/**", "preset").choices, default=None)
    p.add_argument("--noise-free", action="store_true",
                   help="an ideal receiver: no random errors and no hardware code biases (deterministic models kept)")
    from gnss_sim_ros2.core.receiver.profile_file import option_help
    p.add_argument("--profile", metavar="NAME|FILE", default=None, help=option_help())
    p.add_argument("--tracking-start", choices=("warm", "cold"), default=None,
                   help="warm: the recording starts with the receiver long running (tracks locked, no flags at the "
                        "first epoch); cold: the receiver is switched on at the first epoch (parameter tracking_start; "
                        "default: the profile's)")
    p.add_argument("--scenario", metavar="FILE", default=None,
                   help="threat scenario (YAML, docs/SCENARIOS.md): timed jammers, spoofers, receiver faults "
                        "(parameter scenario)")
    p.add_argument("--marker", default=None, help="RINEX marker name")
    p.add_argument("--rtcm", nargs="?", const="", default=None, metavar="FILE",
                   help="also write the observations as RTCM3 (1006, 1033, MSM, broadcast ephemerides); "
                        "FILE default: next to the RINEX observation file, .rtcm3")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="output folder: new, empty or one of an earlier simulate (only its files are replaced); "
                        "a folder holding other files is refused")


#: command-line option -> (section of the parameter table, parameter): errors name the option
OPTION_PARAMS = {
    "--start": ("/**", "start_time"), "--rate": ("/**", "rate_hz"), "--interval": ("/**", "rate_hz"),
    "--mask-deg": ("/**", "elevation_mask_deg"), "--systems": ("/**", "systems"), "--seed": ("/**", "seed"),
    "--preset": ("/**", "preset"), "--marker": ("/**", "marker_name"), "--duration": ("ephemeris", "duration_s"),
    "--nav": ("ephemeris", "nav_files"), "--sp3": ("ephemeris", "sp3_files"), "--clk": ("ephemeris", "clk_files"),
    "--world": ("visibility", "world_file"), "--mesh": ("visibility", "mesh_file"),
    "--profile": ("receiver", "profile"), "--noise-free": ("receiver", "noise"),
    "--allow-partial": ("visibility", "strict_world"), "--tracking-start": ("receiver", "tracking_start"),
    "--scenario": ("receiver", "scenario"), "--sky-mask": ("visibility", "sky_mask_csv"),
}


def parameter_overrides(args) -> tuple[dict, dict]:
    """(overrides {section: {param: value}}, {param: option}) of the options given on the command line."""
    given = {"--start": args.start, "--rate": args.rate,
             "--interval": None if args.interval is None else (1.0 / args.interval if args.interval > 0 else
                                                               args.interval),
             "--mask-deg": args.mask_deg, "--systems": args.systems, "--seed": args.seed, "--preset": args.preset,
             "--marker": args.marker, "--duration": args.duration, "--nav": args.nav, "--sp3": args.sp3,
             "--clk": args.clk, "--world": args.world, "--mesh": args.mesh, "--profile": args.profile,
             "--noise-free": False if args.noise_free else None,
             "--tracking-start": getattr(args, "tracking_start", None),
             "--scenario": getattr(args, "scenario", None), "--sky-mask": getattr(args, "sky_mask", None),
             "--allow-partial": False if getattr(args, "allow_partial", False) else None}
    ov: dict = {}
    names: dict = {}
    for opt, value in given.items():
        if value is None:
            continue
        if opt == "--interval" and value <= 0:
            raise ValueError(f"option --interval is {args.interval!r}; the epoch interval must be > 0 s")
        section, name = OPTION_PARAMS[opt]
        ov.setdefault(section, {})[name] = value
        names[name] = opt
    eph = ov.setdefault("ephemeris", {})
    if args.synthetic and (args.nav or args.sp3):     # the files were ignored without a word
        raise ValueError(f"option --synthetic and {'--nav' if args.nav else '--sp3'}: the synthetic constellation "
                         f"reads no file; give one of them")
    if args.clk and not args.sp3:
        raise ValueError("option --clk: clock files go with --sp3 (precise orbits); without it they were ignored")
    if args.nav:
        eph["source"] = "broadcast"
    if args.sp3:
        eph["source"] = "sp3"
    if args.synthetic:
        eph["source"] = "synthetic"
    vis = ov.setdefault("visibility", {})
    if args.world is not None:
        vis["mesh_file"] = ""
    if args.mesh is not None:
        vis["world_file"] = ""
    return ov, names


def setup_from_args(args):
    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.core.output_folder import check_outputs_not_inputs
    from gnss_sim_ros2.core.simulation import setup_from_config
    from gnss_sim_ros2.core.trajectory import Trajectory

    # --rtcm naming an input (the --trajectory CSV, a navigation file) wrote the RTCM stream over it
    check_outputs_not_inputs([("--rtcm", args.rtcm or None)], inputs=[
        args.config, args.trajectory, *(args.nav or ()), *(args.sp3 or ()), *(args.clk or ()), args.world, args.mesh,
        getattr(args, "sky_mask", None), getattr(args, "scenario", None), args.profile,
        *getattr(args, "obstacle_path", [])])
    ov, names = parameter_overrides(args)
    cfg = load_config(args.config, ov, names)
    tr = None
    if args.position_ecef:
        tr = Trajectory.static(parse_triple(args.position_ecef, "--position-ecef"), "ecef", "option --position-ecef")
    elif args.position:
        tr = Trajectory.static(parse_triple(args.position, "--position"), "geodetic", "option --position")
    elif args.trajectory:
        tr = Trajectory.from_csv(args.trajectory)
    obstacles = [_obstacle_path(f) for f in getattr(args, "obstacle_path", [])]
    setup = setup_from_config(cfg, Path(args.out), tr, progress=not args.quiet, rtcm_path=args.rtcm,
                              obstacle_paths=obstacles)
    return setup


def _obstacle_path(path):
    """One --obstacle-path file: a world-frame path (a geodetic or ECEF one is refused, naming the option)."""
    from gnss_sim_ros2.core.trajectory import Trajectory

    tr = Trajectory.from_csv(path)
    if tr.frame != "world":
        raise ValueError(f"option --obstacle-path {path}: a {tr.frame} path; an obstacle's path is in the world frame "
                         f"(header t_s,e_m,n_m,u_m[,yaw_deg])")
    return tr


def run(args) -> int:
    from gnss_sim_ros2.core.metrics import p95, rms
    from gnss_sim_ros2.core.output_folder import OutputBusy
    from gnss_sim_ros2.core.simulation import run_simulation

    try:
        setup = setup_from_args(args)
        # the garbage collector during the run: what the start-up loaded (modules, tables) out of its sight, as
        # the nodes do after configure (nodes/common.py), and a youngest generation of 10000 objects instead of
        # 700 (the run allocates many short-lived ones, few in cycles): on the static GPS hour 2 collections
        # instead of about 120, 4 ms instead of 25-30; as before after it (a caller in the same process, the tests)
        threshold = gc.get_threshold()
        gc.freeze()
        gc.set_threshold(max(threshold[0], 10_000), *threshold[1:])
        try:
            res = run_simulation(setup)
        finally:
            gc.set_threshold(*threshold)
            gc.unfreeze()
    except (ValueError, OutputBusy) as exc:
        return fail("simulate", exc)
    import numpy as np

    print(f"epochs {res.epochs}, fixes {res.fixes} ({100.0 * res.fixes / max(res.epochs, 1):.1f} %), "
          f"satellites tracked per epoch {np.mean(res.tracked_per_epoch):.1f} "
          f"(min {min(res.tracked_per_epoch)}, max {max(res.tracked_per_epoch)})")
    if res.horizontal_error_m:
        e = res.horizontal_error_m
        print(f"horizontal error against the true path: RMS {rms(e):.2f} m, 95 % {p95(e):.2f} m")
    print(f"{res.sim_s:.0f} s simulated in {res.wall_s:.1f} s: {res.realtime_factor:.0f}x real time")
    if res.obs_path is None:
        print("no observation file written: no epoch was simulated", file=sys.stderr)
    for path in (res.obs_path, res.nav_path, res.fix_path, res.rtcm_path):
        if path is not None and Path(path).is_file() and Path(path).stat().st_size > 0:
            print(f"wrote {path}")
    return 0
