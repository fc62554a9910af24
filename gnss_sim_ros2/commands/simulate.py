"""``gnss-sim simulate``: the receiver simulation without ROS, as fast as the machine allows.

Writes exactly one observation file ``DIR/*_MO.rnx``, one navigation file
``DIR/*_MN.rnx`` and ``DIR/fix.csv`` (time,lat_deg,lon_deg,h_m,n_sats,status).
Options override the configuration file (``--config``, the same file the ROS
launch reads).
"""
from __future__ import annotations

import sys
from pathlib import Path

from gnss_sim_ros2.commands import parse_triple


def add_arguments(p):
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
    p.add_argument("--systems", help="systems, RINEX letters from GRECJI")
    p.add_argument("--seed", type=int, default=None)
    p.add_argument("--preset", choices=("fast", "balanced", "accurate"), default=None)
    p.add_argument("--noise-free", action="store_true",
                   help="an ideal receiver: no random errors and no hardware code biases (deterministic models kept)")
    p.add_argument("--profile", choices=("geodetic", "single_frequency"), default=None)
    p.add_argument("--marker", default=None, help="RINEX marker name")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")


def setup_from_args(args):
    from gnss_sim_ros2.core.simulation import SimulationSetup
    from gnss_sim_ros2.core.time import GnssTime
    from gnss_sim_ros2.core.trajectory import Trajectory, demo_trajectory
    from gnss_sim_ros2.parameters import load_config

    cfg = load_config(args.config)
    eph, vis, rcv = cfg.node("ephemeris"), cfg.node("visibility"), cfg.node("receiver")
    source = eph["source"]
    nav, sp3, clk = eph["nav_files"], eph["sp3_files"], eph["clk_files"]
    if args.nav:
        source, nav = "broadcast", args.nav
    if args.sp3:
        source, sp3 = "sp3", args.sp3
    if args.clk:
        clk = args.clk
    if args.synthetic:
        source = "synthetic"
    world = args.world if args.world is not None else (vis["world_file"] if not args.mesh else "")
    mesh = args.mesh if args.mesh is not None else (vis["mesh_file"] if not args.world else "")
    if args.position_ecef:
        tr = Trajectory.static(parse_triple(args.position_ecef, "--position-ecef"), "ecef")
    elif args.position:
        tr = Trajectory.static(parse_triple(args.position, "--position"), "geodetic")
    elif args.trajectory:
        tr = Trajectory.from_csv(args.trajectory)
    else:
        if not world and not mesh:
            world = str(default_world())
        tr = demo_trajectory()
    interval = 1.0 / (args.rate or rcv["rate_hz"]) if not args.interval else args.interval
    if interval <= 0:
        raise ValueError("--interval/--rate must be positive")
    systems = args.systems or rcv["systems"]
    if not systems or set(systems) - set("GRECJI"):
        raise ValueError(f"--systems {systems!r}: use letters of GRECJI")
    receiver = {"noise": False if args.noise_free else rcv["noise"], "profile": args.profile or rcv["profile"],
                "ionosphere": rcv["ionosphere"], "troposphere": rcv["troposphere"]}
    from gnss_sim_ros2.core.receiver.tracking import TrackingConfig

    receiver["tracking"] = TrackingConfig(acquisition_cn0_dbhz=rcv["cn0_acquire_dbhz"],
                                          tracking_cn0_dbhz=rcv["cn0_lose_dbhz"])
    return SimulationSetup(
        start=GnssTime.from_iso(args.start or rcv["start_time"]),
        duration_s=args.duration if args.duration is not None else eph["duration_s"],
        interval_s=interval, out_dir=Path(args.out), trajectory=tr, systems=systems,
        elevation_mask_deg=args.mask_deg if args.mask_deg is not None else rcv["elevation_mask_deg"],
        source=source, nav_files=nav, sp3_files=sp3, clk_files=clk, world_file=world or "", mesh_file=mesh or "",
        materials_file=vis["materials_file"], preset=args.preset or rcv["preset"], fresnel_rays=vis["fresnel_rays"],
        receiver=receiver, marker_name=args.marker or rcv["marker_name"],
        seed=args.seed if args.seed is not None else rcv["seed"], progress=not args.quiet,
    )


def default_world() -> Path:
    """worlds/courtyard.sdf from the source tree or the installed share folder."""
    here = Path(__file__).resolve().parents[2] / "worlds" / "courtyard.sdf"
    if here.is_file():
        return here
    try:
        from ament_index_python.packages import get_package_share_directory

        return Path(get_package_share_directory("gnss_sim")) / "worlds" / "courtyard.sdf"
    except Exception:  # noqa: BLE001
        raise ValueError("the demo world worlds/courtyard.sdf was not found; give --world or --mesh") from None


def run(args) -> int:
    from gnss_sim_ros2.core.simulation import run_simulation

    try:
        setup = setup_from_args(args)
        res = run_simulation(setup)
    except ValueError as exc:
        print(f"gnss-sim simulate: error: {exc}", file=sys.stderr)
        return 2
    import numpy as np

    print(f"epochs {res.epochs}, fixes {res.fixes} ({100.0 * res.fixes / max(res.epochs, 1):.1f} %), "
          f"satellites tracked per epoch {np.mean(res.tracked_per_epoch):.1f} "
          f"(min {min(res.tracked_per_epoch)}, max {max(res.tracked_per_epoch)})")
    if res.horizontal_error_m:
        e = np.asarray(res.horizontal_error_m)
        print(f"horizontal error against the true path: RMS {np.sqrt(np.mean(e**2)):.2f} m, "
              f"95 % {np.percentile(e, 95):.2f} m")
    print(f"{res.sim_s:.0f} s simulated in {res.wall_s:.1f} s: {res.realtime_factor:.0f}x real time")
    print(f"wrote {res.obs_path}\nwrote {res.nav_path}\nwrote {res.fix_path}")
    return 0
