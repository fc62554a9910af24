"""``gnss-sim plan``: GNSS quality over an area and a time window -- when and where RTK will work.

    gnss-sim plan (--world SDF | --mesh FILE | --sky-mask CSV --origin LAT,LON,H) --out DIR
                  [--polygon 'x,y;x,y;...' | --path CSV] [--step-m 2] [--height-m 1.5]
                  [--start ISO8601] [--hours 24] [--every-min 10] [--systems GREC] [--profile ublox_f9p]
                  [--nav FILE ... | --synthetic] [--mask-deg 10] [--multipath off|nlos|full]
                  [--point x,y ...] [--threshold 0.95] [--workers N | --scheduler ADDRESS]

The area is the world's bounds by default (a regular grid of ``--step-m``), a polygon in world x, y or the
points of a path CSV (x_m,y_m).  Each antenna stands ``--height-m`` above the highest surface under the cell
(one downward cast; a roof where the cell lies on a building).  Per cell and time step: satellites in line of
sight, attenuated, reflected-only (``--multipath nlos|full`` only: off by default, for speed -- reflected-only
satellites then never appear and blocked ones are simply not tracked, as in the simulator), blocked; DOPs;
expected single-point horizontal accuracy (HDOP x UERE of the profile, core/planning/ranging.py); the RTK
indicator (a proxy rule, core/planning/rtk_rule.py).  Casts go through the simulator's own
VisibilityOptions.cast, batched over cells x times x satellites, one call per chunk.

Outputs in ``--out`` (written through core/output_folder.py): plan.nc (xarray Dataset, cell x time), plan.parquet
(one row per cell and time), maps.png (share of time with RTK, mean HDOP), cells.geojson (WGS 84 lon/lat cells
with their summary), timeline_<x>_<y>.png/.csv per ``--point``, summary.md (the best windows, also printed).
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from gnss_sim_ros2.core.scene.scene_report import ALLOW_PARTIAL_HELP

COMMAND = "gnss-sim plan"


def add_arguments(parser):
    src = parser.add_mutually_exclusive_group(required=True)
    src.add_argument("--world", metavar="SDF", help="SDF world file (with <spherical_coordinates>)")
    src.add_argument("--mesh", metavar="FILE", help="exported scene mesh (with its .scene.yaml sidecar)")
    src.add_argument("--sky-mask", metavar="CSV", help="a measured sky mask (azimuth_deg,elevation_deg) at --origin: "
                                                       "the scene of one point (no 3D model)")
    parser.add_argument("--origin", metavar="LAT,LON,H", help="geodetic point of --sky-mask [deg, deg, m]")
    parser.add_argument("--materials", metavar="FILE.yaml", help="material classes/rules (with --world)")
    parser.add_argument("--allow-partial", action="store_true", help=ALLOW_PARTIAL_HELP)
    parser.add_argument("--keep-dynamic", action="store_true",
                        help="keep the world's non-static models as obstacles (parameter keep_dynamic_models; a city "
                             "model whose buildings are not marked static)")
    area = parser.add_mutually_exclusive_group()
    area.add_argument("--polygon", metavar="'x,y;x,y;...'",
                      help="area polygon in world x, y [m] (write --polygon='-5,0;...' when it starts with a minus; "
                           "default: the world's bounds)")
    area.add_argument("--path", metavar="CSV", help="points of a path (columns x_m,y_m, world metres)")
    parser.add_argument("--step-m", type=float, default=2.0, help="grid step [m] (default 2)")
    parser.add_argument("--height-m", type=float, default=1.5, help="antenna height above the ground [m] (default 1.5)")
    parser.add_argument("--start", metavar="ISO8601", help="first time step, GPS time (default: the demo's start)")
    parser.add_argument("--hours", type=float, default=24.0, help="time window [h] (default 24)")
    parser.add_argument("--every-min", type=float, default=10.0, help="time step [min] (default 10)")
    parser.add_argument("--systems", default="GREC", help="systems, RINEX letters (default GREC)")
    parser.add_argument("--profile", default="ublox_f9p", metavar="NAME|FILE",
                        help="receiver profile: signals (dual frequency for the RTK rule), ranging errors "
                             "(default ublox_f9p)")
    sats = parser.add_mutually_exclusive_group()
    sats.add_argument("--nav", nargs="+", metavar="FILE", help="RINEX navigation file(s)")
    sats.add_argument("--synthetic", action="store_true", help="the synthetic constellation (the default)")
    parser.add_argument("--mask-deg", type=float, default=10.0, help="elevation mask [deg] (default 10)")
    parser.add_argument("--multipath", default="off", choices=["off", "nlos", "full"],
                        help="reflections from the scene: reflected-only satellites and their NLOS error "
                             "(default off: much faster)")
    parser.add_argument("--point", action="append", default=[], metavar="x,y",
                        help="a point (world x, y [m]) whose time line is drawn (nearest cell); repeatable")
    parser.add_argument("--good-cn0-dbhz", type=float, default=35.0, metavar="DBHZ",
                        help="a 'good' satellite (n_good): C/N0 predicted from the profile's link budget >= this "
                             "[dB-Hz] (default 35)")
    parser.add_argument("--threshold", type=float, default=0.95,
                        help="area share of the best windows (default 0.95)")
    parser.add_argument("--max-rays", type=int, default=1 << 18,
                        help="rays per cast call (memory bound; default 262144)")
    parser.add_argument("--share-tile-m", type=float, default=None, metavar="M",
                        help="cells within a tile of this size share each satellite's direction, C/N0 link budget and "
                             "UERE terms (exact states, counts and RTK; DOPs within a bound: docs/PLANNING.md); 0: "
                             "every cell its own [m] (default 250: core/planning/quality.DEFAULT_SHARE_TILE_M)")
    cl = parser.add_mutually_exclusive_group()
    cl.add_argument("--workers", type=int, help="run the blocks on a local Dask cluster of N workers")
    cl.add_argument("--scheduler", metavar="ADDRESS", help="run the blocks on an existing Dask scheduler")
    parser.add_argument("--out", required=True, metavar="DIR", help="output folder")


def run(args) -> int:
    from gnss_sim_ros2.core.output_folder import OutputFolder

    try:
        _check_options(args)
        folder = OutputFolder(args.out, COMMAND, inputs=[args.world, args.mesh, args.sky_mask, args.materials,
                                                         args.path, *(args.nav or ())])
        folder.check()
    except ValueError as exc:
        print(f"{COMMAND}: error: {exc}", file=sys.stderr)
        return 2
    try:
        stage = folder.acquire()
    except (ValueError, RuntimeError) as exc:
        print(f"{COMMAND}: error: {exc}", file=sys.stderr)
        return 2
    try:
        _run(args, stage)
    except ValueError as exc:
        folder.abandon()
        print(f"{COMMAND}: error: {exc}", file=sys.stderr)
        return 2
    except BaseException:
        folder.abandon()
        raise
    files = folder.commit()
    print(f"{args.out}: {len(files)} files")
    return 0


def _check_options(args) -> None:
    from gnss_sim_ros2.core.frames import HEIGHT_SPAN_M
    from gnss_sim_ros2.core.planning.area import check_plan_size, check_step
    from gnss_sim_ros2.parameters import MAX_DURATION_S, param

    check_step(args.step_m)
    for opt, val in (("--hours", args.hours), ("--every-min", args.every_min)):
        if not (np.isfinite(val) and val > 0):
            raise ValueError(f"option {opt} is {val}: a value > 0 is needed")
    if args.hours * 3600.0 > MAX_DURATION_S:       # the ephemerides are prepared for the whole window
        raise ValueError(f"option --hours is {args.hours:g}: the maximum is {MAX_DURATION_S / 3600.0:g} h "
                         f"(MAX_DURATION_S, a month)")
    check_plan_size(1, int(args.hours * 60.0 / args.every_min) + 1)   # before the time steps are built
    if not (np.isfinite(args.height_m) and 0 <= args.height_m <= HEIGHT_SPAN_M[1]):
        raise ValueError(f"option --height-m is {args.height_m}: a height 0..{HEIGHT_SPAN_M[1]:g} m above the "
                         f"ground is needed")
    if not (np.isfinite(args.good_cn0_dbhz) and 0.0 <= args.good_cn0_dbhz <= 100.0):
        raise ValueError(f"option --good-cn0-dbhz is {args.good_cn0_dbhz}: a C/N0 in 0..100 dB-Hz is needed")
    if args.workers is not None and args.workers < 1:           # 0 would silently run without a cluster
        raise ValueError(f"option --workers is {args.workers}: at least 1 worker")
    if args.start is not None:
        param("ephemeris", "start_time").check(args.start, "option --start")
    if not 0.0 < args.threshold <= 1.0:
        raise ValueError(f"option --threshold is {args.threshold}: an area share in (0, 1] is needed")
    if args.max_rays < 1:
        raise ValueError(f"option --max-rays is {args.max_rays}: at least 1")
    if args.share_tile_m is not None:
        from gnss_sim_ros2.core.planning.quality import check_share_tile_m

        check_share_tile_m(args.share_tile_m, "option --share-tile-m")
    param("visibility", "elevation_mask_deg").check(args.mask_deg, "option --mask-deg")
    if args.sky_mask and not args.origin:
        raise ValueError("option --sky-mask needs --origin LAT,LON,H (where the mask was measured)")
    if args.origin and not args.sky_mask:
        raise ValueError("option --origin goes with --sky-mask only (a world or mesh has its own origin)")
    if args.sky_mask and (args.polygon is not None or args.path):     # they were ignored / misreported
        raise ValueError(f"option {'--path' if args.path else '--polygon'}: a sky mask is the sky of one point "
                         f"(--origin), it has no area")
    bad = sorted(set(args.systems) - set("GRECJI"))
    if bad or not args.systems:
        raise ValueError(f"option --systems {args.systems!r}: RINEX letters from GRECJI")


def _floats(text: str, n: int, option: str) -> tuple:
    try:
        vals = tuple(float(v) for v in text.replace(" ", "").split(","))
    except ValueError:
        vals = ()
    if len(vals) != n or not all(np.isfinite(vals)):
        raise ValueError(f"option {option} {text!r}: expected {n} comma-separated numbers")
    return vals


def _run(args, stage: Path) -> None:
    from gnss_sim_ros2.commands.export_world import strict_world
    from gnss_sim_ros2.core.demo import DEMO_START
    from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
    from gnss_sim_ros2.core.frames import check_receiver_position
    from gnss_sim_ros2.core.planning import area as pa
    from gnss_sim_ros2.core.planning.predicted_cn0 import predictor_from_profile
    from gnss_sim_ros2.core.planning.quality import DEFAULT_SHARE_TILE_M, PlanInputs
    from gnss_sim_ros2.core.planning.ranging import budget_from_profile, tracked_systems
    from gnss_sim_ros2.core.planning.rtk_rule import RtkRule
    from gnss_sim_ros2.core.planning.runner import SceneSpec, run_blocks
    from gnss_sim_ros2.core.planning.sky import plan_sky, time_steps
    from gnss_sim_ros2.core.receiver.config import ReceiverConfig
    from gnss_sim_ros2.core.scene.world_mesh import world_bounds_xy
    from gnss_sim_ros2.core.time import GnssTime
    from gnss_sim_ros2.core.visibility import VisibilityOptions

    t_wall = time.perf_counter()
    origin = _floats(args.origin, 3, "--origin") if args.origin else ()
    if origin:
        check_receiver_position(origin, "geodetic", "option --origin")
    points = [_floats(p, 2, "--point") for p in args.point]
    polygon = pa.parse_polygon(args.polygon) if args.polygon is not None else None   # --polygon= is refused
    start = GnssTime.from_iso(args.start or DEMO_START, scale="GPS")
    times = time_steps(start, args.hours, args.every_min)
    systems = tracked_systems(args.profile, args.systems)
    budget = budget_from_profile(args.profile, systems)
    spec = SceneSpec(world=str(Path(args.world).resolve()) if args.world else "",
                     mesh=str(Path(args.mesh).resolve()) if args.mesh else "",
                     materials=str(Path(args.materials).resolve()) if args.materials else "",
                     strict_world=strict_world(args), keep_dynamic=bool(args.keep_dynamic),
                     sky_mask=args.sky_mask or "", origin_llh=origin)
    scene = spec.load()
    if scene.spherical is None:
        raise ValueError(f"{args.world or args.mesh}: no geodetic origin (<spherical_coordinates> in the world, "
                         f"spherical_coordinates in the sidecar): satellites cannot be placed")
    bounds = world_bounds_xy(scene)
    if args.path:
        area = pa.read_path_csv(args.path)
        area.step_m = float(args.step_m)
        pa.check_inside_bounds(area.x_m, area.y_m, bounds, lambda i: f"option --path {args.path}, point {i + 1}")
    elif polygon is None and bounds is None:
        area = pa.PlanArea(np.zeros(1), np.zeros(1), "path", float(args.step_m))    # a sky mask: its own point
    else:
        area = pa.grid_area(args.step_m, bounds, polygon)
    pa.check_inside_bounds([p[0] for p in points], [p[1] for p in points], bounds,
                           lambda i: f"option --point {args.point[i]!r}")
    pa.check_plan_size(area.n_cells, len(np.atleast_1d(times.sec)))
    ground = pa.ground_z_m(scene, area.x_m, area.y_m)
    ant = np.stack([area.x_m, area.y_m, ground + args.height_m], axis=1)
    duration_s = float(times[len(times.sec) - 1] - times[0])
    provider, _ = open_ephemeris("broadcast" if args.nav else "synthetic", start, duration_s, systems,
                                 nav_files=args.nav or ())
    excluded = ReceiverConfig(profile=args.profile).excluded_svs or ""
    sky = plan_sky(provider, times, systems, excluded)
    rule = RtkRule()
    inp = PlanInputs(sky.pos_ecef_m, sky.system, budget, rule, int(args.max_rays),
                     predictor_from_profile(args.profile, systems), float(args.good_cn0_dbhz), sky.t_s,
                     DEFAULT_SHARE_TILE_M if args.share_tile_m is None else float(args.share_tile_m))
    vis = VisibilityOptions(mask_deg=float(args.mask_deg), multipath=args.multipath)
    n_t = len(sky.t_s)
    print(f"{COMMAND}: {area.n_cells} cells x {n_t} time steps x {len(sky.sv)} satellites "
          f"({''.join(sorted(set(sky.system)))}), multipath {args.multipath}")
    client, cluster = _cluster(args)
    try:
        fields, stats = run_blocks(spec, vis, ant, inp, client=client, log=lambda s: print(f"  {s}", flush=True))
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
    _write(args, stage, scene, area, ground, sky, fields, stats, rule, budget, points, time.perf_counter() - t_wall)


def _cluster(args):
    if not (args.workers or args.scheduler):
        return None, None
    from gnss_sim_ros2.core.sweep.driver import connect_cluster

    return connect_cluster(args.workers, args.scheduler)


def _write(args, stage, scene, area, ground, sky, fields, stats, rule, budget, points, wall_s) -> None:
    import csv

    from gnss_sim_ros2.core.planning import outputs as po
    from gnss_sim_ros2.core.planning.geojson import cells_feature_collection, write_geojson

    times_iso = [sky.times[k].isoformat("GPS", 0) for k in range(len(sky.t_s))]
    step_s = float(args.every_min) * 60.0
    source = args.world or args.mesh or args.sky_mask
    attrs = {"source": str(source), "profile": budget.profile, "systems": "".join(sorted(set(sky.system))),
             "mask_deg": float(args.mask_deg), "height_m": float(args.height_m), "multipath": args.multipath,
             "rtk_rule": rule.describe(), "time_scale": "GPS", "step_s": step_s,
             "latitude_deg": scene.spherical.latitude_deg, "longitude_deg": scene.spherical.longitude_deg,
             "elevation_m": scene.spherical.elevation_m, "heading_deg": scene.spherical.heading_deg}
    ds = po.plan_dataset(area, ground, float(args.height_m), times_iso, sky.t_s, fields, attrs)
    engine = po.write_netcdf(ds, stage / "plan.nc")
    rows = po.write_parquet(ds, stage / "plan.parquet")
    rtk_share = fields["rtk"].mean(axis=1)
    mean_hdop = _nan_mean(fields["hdop"])          # NaN for a cell that never has a position (too few satellites)
    title = (f"{Path(str(source)).name}: {area.n_cells} cells, {times_iso[0]} + {args.hours:g} h every "
             f"{args.every_min:g} min, {budget.profile}, mask {args.mask_deg:g} deg")
    po.plot_maps(area, rtk_share, mean_hdop, stage / "maps.png", title)
    with np.errstate(invalid="ignore"):
        props = {"x_m": area.x_m, "y_m": area.y_m, "rtk_share": rtk_share.round(4),
                 "mean_hdop": np.round(mean_hdop, 3), "mean_n_los": fields["n_los"].mean(axis=1).round(2),
                 "p95_h_acc_m": np.round(np.nanpercentile(np.where(np.isfinite(fields["h_acc_m"]),
                                                                   fields["h_acc_m"], np.inf), 95, axis=1), 2)}
    write_geojson(stage / "cells.geojson", cells_feature_collection(scene.spherical, area.corners_xy(), ground, props))
    t_h = sky.t_s / 3600.0
    for x, y in points:
        i = int(np.argmin((area.x_m - x) ** 2 + (area.y_m - y) ** 2))
        at = {k: fields[k][i] for k in fields}
        name = f"timeline_{x:g}_{y:g}"
        po.plot_timeline(t_h, at, stage / f"{name}.png",
                         f"cell at x {area.x_m[i]:.1f}, y {area.y_m[i]:.1f} m (asked {x:g}, {y:g}); {title}")
        with open(stage / f"{name}.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["time", *fields])
            for k in range(len(t_h)):
                w.writerow([times_iso[k], *(_fmt(fields[f][i, k]) for f in fields)])
    share_t = fields["rtk"].mean(axis=0)
    lines = [f"# gnss-sim plan: {Path(str(source)).name}", "",
             f"- {area.n_cells} cells ({area.kind}, step {area.step_m:g} m, antenna {args.height_m:g} m above "
             f"the ground), {len(t_h)} time steps from {times_iso[0]} GPS every {args.every_min:g} min, "
             f"profile {budget.profile}, systems {attrs['systems']}, mask {args.mask_deg:g} deg, multipath "
             f"{args.multipath}",
             f"- RTK indicator: {rule.describe()}",
             f"- RTK available over the area and window: {100 * fields['rtk'].mean():.1f} % of cell-times; mean "
             f"HDOP {np.nanmean(mean_hdop):.2f}; median expected horizontal accuracy "
             f"{np.nanmedian(fields['h_acc_m']):.2f} m (HDOP x UERE, 1 sigma)",
             f"- {stats['rays']:,} rays cast in {stats['cast_s']:.1f} s "
             f"({stats['rays'] / max(stats['cast_s'], 1e-9):,.0f} rays/s inside the casts), {stats['blocks']} blocks, "
             f"{wall_s:.1f} s in all; NetCDF engine {engine}, "
             f"{rows:,} Parquet rows", "", "## Best windows", ""]
    wins = po.window_lines(share_t, step_s, times_iso, float(args.threshold), "RTK available")
    lines += [f"- {w}" for w in wins]
    po.write_summary(stage / "summary.md", lines)
    for w in wins:
        print(w)


def _nan_mean(a) -> np.ndarray:
    """Mean over time of each cell, NaN values left out (NaN where all are)."""
    a = np.asarray(a, float)
    n = np.isfinite(a).sum(axis=1)
    return np.where(n > 0, np.where(np.isfinite(a), a, 0.0).sum(axis=1) / np.maximum(n, 1), np.nan)


def _fmt(v):
    if isinstance(v, (np.floating, float)):
        return "" if not np.isfinite(v) else f"{float(v):.3f}"
    return str(int(v))
