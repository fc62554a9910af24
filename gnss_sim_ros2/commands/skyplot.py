"""``gnss-sim skyplot``: line-of-sight state of every satellite seen from a point of a world.

    gnss-sim skyplot (--world SDF | --mesh FILE) --at E,N,U --time ISO8601 (--nav FILE ... | --synthetic)
                     [--mask-deg D] --csv FILE [--png FILE [--skyline-csv FILE]]
                     [--sky-mask FILE [--mask-report FILE] [--sector-deg D]]

``--at`` is in the world frame (Gazebo world, ENU at the origin when heading is 0), metres.  The CSV
has one row ``sv,az_deg,el_deg,state,attenuation_db`` for each satellite at or above the horizon and
the mask, with state ``visible``, ``blocked`` or ``attenuated``; az/el in the local ENU frame of the
antenna.  ``--time`` is read in ``--time-scale`` (GPS by default).

The PNG draws every satellite above the horizon (those under the mask as hollow grey "below mask" discs), the
sky cells the casts find blocked (grey) or in foliage (green), and the scene's skyline and foliage outline
(``Scene.horizon_profile``: the highest blocked elevation per azimuth, 1 degree apart, found by casting rays
on the scene).  The skyline goes beside it as CSV (``--skyline-csv``, default ``skyline.csv`` in the PNG's
folder): ``azimuth_deg,elevation_deg,foliage_elevation_deg``, one row per degree of azimuth, to compare with
a measured sky mask.

``--sky-mask FILE`` (azimuth_deg,elevation_deg; core/visibility/sky_mask.py) compares a measured mask with that
skyline at ``--at``: ``--mask-report`` (default ``sky_mask_comparison.csv`` beside ``--csv``) has one row per
azimuth sector (``--sector-deg``, 30 by default) ``sector,az_from_deg,az_to_deg,mean_diff_deg,rms_diff_deg,
miss_deg,miss_az_deg,r`` with difference = model - mask (> 0: the model's skyline is higher) and miss the
difference of largest magnitude in the sector, then a row ``all`` with the Pearson correlation r over every
azimuth; the PNG draws the mask as a dashed magenta line.
"""
from __future__ import annotations

import csv
import sys
import tempfile
from pathlib import Path

import numpy as np

from gnss_sim_ros2.commands import WORLD_OFFSET_HELP, world_offset_scene
from gnss_sim_ros2.core.output_folder import check_outputs_not_inputs, check_unnamed_output, staged_files
from gnss_sim_ros2.core.scene.scene_report import ALLOW_PARTIAL_HELP


def add_arguments(parser):
    src = parser.add_mutually_exclusive_group(required=True)
    src.add_argument("--world", metavar="SDF", help="SDF world file")
    src.add_argument("--mesh", metavar="FILE", help="exported scene mesh (with its .scene.yaml sidecar)")
    parser.add_argument("--world-offset", metavar="E,N,U", help=WORLD_OFFSET_HELP + " (--at stays in the world frame)")
    parser.add_argument("--materials", metavar="FILE.yaml", help="material classes/rules (with --world)")
    parser.add_argument("--allow-partial", action="store_true", help=ALLOW_PARTIAL_HELP)
    parser.add_argument("--at", required=True, metavar="E,N,U", help="antenna position in the world frame [m]")
    parser.add_argument("--time", required=True, metavar="ISO8601", help="instant, e.g. 2022-01-01T00:05:00")
    parser.add_argument("--time-scale", default="GPS", choices=["GPS", "UTC"], help="scale of --time [GPS]")
    sats = parser.add_mutually_exclusive_group(required=True)
    sats.add_argument("--nav", nargs="+", metavar="FILE", help="RINEX navigation file(s)")
    sats.add_argument("--synthetic", action="store_true", help="a synthetic constellation (no files needed)")
    parser.add_argument("--mask-deg", type=float, default=0.0, help="elevation mask [deg] (default 0)")
    parser.add_argument("--fresnel-rays", type=int, default=0, help="soft-edge rays per satellite (0 = off)")
    parser.add_argument("--csv", required=True, metavar="FILE", help="output CSV")
    parser.add_argument("--png", metavar="FILE", help="output sky plot PNG")
    parser.add_argument("--skyline-csv", metavar="FILE",
                        help="the scene's skyline per degree of azimuth as CSV (default with --png: skyline.csv in "
                             "the PNG's folder)")
    parser.add_argument("--sky-mask", metavar="FILE.csv",
                        help="a measured sky mask at --at (azimuth_deg,elevation_deg) compared with the scene's "
                             "skyline: per sector difference, correlation r, largest misses (--mask-report); drawn "
                             "on the PNG")
    parser.add_argument("--mask-report", metavar="FILE",
                        help="the comparison with --sky-mask as CSV (default: sky_mask_comparison.csv beside --csv)")
    parser.add_argument("--sector-deg", type=float, default=30.0,
                        help="azimuth sector of the --sky-mask comparison [deg] (default 30)")


def _parse_at(text: str) -> np.ndarray:
    try:
        vals = [float(v) for v in text.replace(" ", "").split(",")]
    except ValueError:
        vals = []
    if len(vals) != 3 or not all(np.isfinite(vals)):
        raise ValueError(f"--at {text!r}: expected three numbers E,N,U in metres, e.g. --at 0,-60,1.5")
    return np.array(vals)


def _ephemeris(args, t):
    from gnss_sim_ros2.core.ephemeris.broadcast import BroadcastEphemeris

    if args.nav:
        return BroadcastEphemeris.from_files(args.nav)
    try:
        from gnss_sim_ros2.core.ephemeris.synthetic import write_synthetic_nav
    except ImportError as exc:
        raise ValueError(f"--synthetic: the synthetic constellation is not available ({exc})") from exc
    tmp = Path(tempfile.mkdtemp(prefix="gnss_sim_skyplot_")) / "synthetic.rnx"
    write_synthetic_nav(tmp, t + (-3600.0), 7200.0)
    return BroadcastEphemeris.from_files([tmp])


def run(args) -> int:
    from gnss_sim_ros2.core.figures import check_png_name

    try:
        # an output file is never one of the inputs (core/output_folder.py)
        check_outputs_not_inputs([("--csv", args.csv), ("--png", args.png),
                                  ("--skyline-csv", _skyline_csv_path(args)),
                                  ("--mask-report", _mask_report_path(args))],
                                 inputs=[args.world, args.mesh, args.materials, *(args.nav or ()),
                                         getattr(args, "sky_mask", None)])
        if args.png:
            check_png_name(args.png, f"option --png {args.png}")
        # a default output beside a named one replaces only the file skyplot writes there
        if args.png and not getattr(args, "skyline_csv", None):
            check_unnamed_output(_skyline_csv_path(args), "--skyline-csv", ",".join(SKYLINE_HEADER))
        if getattr(args, "sky_mask", None) and not args.mask_report:
            check_unnamed_output(_mask_report_path(args), "--mask-report", ",".join(MASK_REPORT_HEADER))
        return _run(args)
    except ValueError as exc:
        print(f"gnss-sim skyplot: error: {exc}", file=sys.stderr)
        return 2


def _run(args) -> int:
    from gnss_sim_ros2.commands.export_world import strict_world
    from gnss_sim_ros2.core.frames import check_receiver_position
    from gnss_sim_ros2.core.scene.visibility import STATE_NAMES
    from gnss_sim_ros2.core.time import GnssTime
    from gnss_sim_ros2.core.visibility import VisibilityOptions, load_scene
    from gnss_sim_ros2.parameters import check_iso_time, param

    at = _parse_at(args.at)
    # options that are parameters of the visibility node: checked by the parameter table, before any work
    fresnel_rays = param("visibility", "fresnel_rays").check(args.fresnel_rays, "option --fresnel-rays")
    if fresnel_rays < 0:
        raise ValueError(f"option --fresnel-rays is {fresnel_rays}: a number of rays >= 0 is needed (0: off)")
    mask_deg = param("visibility", "elevation_mask_deg").check(args.mask_deg, "option --mask-deg")
    t = GnssTime.from_iso(check_iso_time(args.time, "option --time"), scale=args.time_scale)
    sky_mask = None
    if getattr(args, "sky_mask", None):
        from gnss_sim_ros2.core.visibility.sky_mask import read_sky_mask, sector_count

        sector_count(args.sector_deg, "option --sector-deg")
        sky_mask = read_sky_mask(args.sky_mask)     # a bad mask is refused before the scene is loaded
    # the world as every front end loads it (simulate, run, the visibility node): strict unless --allow-partial
    scene = load_scene(args.world or "", args.mesh or "", args.materials or "",
                       VisibilityOptions(strict_world=strict_world(args)))
    scene = world_offset_scene(scene, getattr(args, "world_offset", None))
    if scene.spherical is None:
        raise ValueError(f"{args.world or args.mesh}: no geodetic origin (<spherical_coordinates> in the world, "
                         f"spherical_coordinates in the sidecar): satellites cannot be placed")
    check_receiver_position(scene.antenna_ecef(at.reshape(1, 3))[0], "ecef", f"option --at {args.at}")
    eph = _ephemeris(args, t)
    st = eph.states(t)
    if len(st.sv) == 0:
        raise ValueError(f"no satellite has a valid navigation record at {args.time}")
    mask = max(0.0, mask_deg)
    res = scene.visibility_ecef(at, np.asarray(st.pos_ecef_m), mask_deg=mask, fresnel_rays=fresnel_rays)
    keep = np.flatnonzero(res.el_deg >= mask)
    order = keep[np.argsort(np.asarray(st.sv)[keep])]
    names = [STATE_NAMES[int(s)] for s in res.state]
    with staged_files([("--csv", args.csv)]) as temp, open(temp[args.csv], "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["sv", "az_deg", "el_deg", "state", "attenuation_db"])
        for i in order:
            w.writerow([st.sv[i], f"{res.az_deg[i]:.3f}", f"{res.el_deg[i]:.3f}", names[i],
                        f"{res.attenuation_db[i]:.2f}"])
    counts = {k: sum(names[i] == k for i in order) for k in ("visible", "attenuated", "blocked")}
    print(f"{args.csv}: {len(order)} satellites above {mask:g} deg: "
          + ", ".join(f"{v} {k}" for k, v in counts.items()))
    skyline_csv = _skyline_csv_path(args)
    comparison = None
    if sky_mask is not None:
        comparison = _compare_mask(args, scene, at, sky_mask)
    if skyline_csv is not None:
        horizon = scene.horizon_profile(at, az_step_deg=SKYLINE_STEP_DEG)
        foliage = scene.horizon_profile(at, az_step_deg=SKYLINE_STEP_DEG, which="foliage") \
            if scene.has_foliage else (horizon[0], np.zeros_like(horizon[1]))
        write_skyline_csv(skyline_csv, horizon[0], horizon[1], foliage[1])
        print(f"{skyline_csv}: skyline, {len(horizon[0])} azimuths, elevation up to {np.max(horizon[1]):.1f} deg")
    if args.png:
        from gnss_sim_ros2.core.skyplot import plot_skyplot

        # every satellite above the horizon (under the mask: drawn as such); the blocked sky from casts over
        # the whole sky (gaps under overhangs stay open) and the skyline and foliage outline over it
        up = np.flatnonzero(res.el_deg >= 0.0)
        up = up[np.argsort(np.asarray(st.sv)[up])]
        plot_skyplot(args.png, np.asarray(st.sv)[up], res.az_deg[up], res.el_deg[up],
                     [names[i] for i in up], sky=scene.sky_grid(at), horizon=horizon,
                     foliage_horizon=foliage if scene.has_foliage else None, mask_deg=mask or None,
                     title=f"{Path(args.world or args.mesh).name} at E,N,U = {args.at} m, "
                           f"{args.time} {args.time_scale}"
                           + (f"\nmeasured mask {Path(args.sky_mask).name}: r = {comparison.r:.2f}, "
                              f"RMS {comparison.rms_deg:.1f} deg" if comparison is not None else ""),
                     sky_mask=None if sky_mask is None else (MASK_AZ_DEG, sky_mask.elevation_at(MASK_AZ_DEG)))
        print(f"{args.png}: sky plot")
    return 0


def _skyline_csv_path(args):
    return getattr(args, "skyline_csv", None) or (Path(args.png).parent / "skyline.csv" if args.png else None)


def _mask_report_path(args):
    if not getattr(args, "sky_mask", None):
        return None
    return args.mask_report or str(Path(args.csv).parent / "sky_mask_comparison.csv")


def _compare_mask(args, scene, at, sky_mask):
    """The scene's skyline at ``at`` against the measured mask: the report CSV and one summary line."""
    from gnss_sim_ros2.core.visibility.sky_mask import compare_skylines

    az, el = scene.horizon_profile(at, az_step_deg=SKYLINE_STEP_DEG)
    cmp = compare_skylines(az, el, sky_mask, sector_deg=args.sector_deg)
    path = _mask_report_path(args)
    with staged_files([("--mask-report", path)]) as temp, open(temp[path], "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(MASK_REPORT_HEADER)
        for k, (lo, hi, mean, rms, miss, miss_az) in enumerate(cmp.sectors):
            w.writerow([k, f"{lo:g}", f"{hi:g}", f"{mean:.2f}", f"{rms:.2f}", f"{miss:.2f}", f"{miss_az:.1f}", ""])
        worst = max(cmp.sectors, key=lambda s_: abs(s_[4]))
        w.writerow(["all", "0", "360", f"{cmp.mean_deg:.2f}", f"{cmp.rms_deg:.2f}", f"{worst[4]:.2f}",
                    f"{worst[5]:.1f}", f"{cmp.r:.3f}"])
    misses = ", ".join(f"{m:+.1f} deg at {a:.0f}" for _, _, _, _, m, a in cmp.largest_misses(3))
    print(f"{path}: model skyline - measured mask {Path(args.sky_mask).name}: r = {cmp.r:.2f}, RMS "
          f"{cmp.rms_deg:.1f} deg, mean {cmp.mean_deg:+.1f} deg; largest misses {misses}")
    return cmp


#: azimuth step of the skyline [deg]
SKYLINE_STEP_DEG = 1.0
#: azimuths at which a measured mask is drawn (as interpolated, periodic)
MASK_AZ_DEG = np.arange(0.0, 360.0, 0.5)
#: first rows of the skyline CSV and of the mask report (a default path holding another file is refused)
SKYLINE_HEADER = ["azimuth_deg", "elevation_deg", "foliage_elevation_deg"]
MASK_REPORT_HEADER = ["sector", "az_from_deg", "az_to_deg", "mean_diff_deg", "rms_diff_deg", "miss_deg",
                      "miss_az_deg", "r"]


def write_skyline_csv(path, az_deg, el_deg, foliage_el_deg) -> None:
    """The skyline as CSV: azimuth_deg,elevation_deg,foliage_elevation_deg (0: nothing above the horizon)."""
    with staged_files([("--skyline-csv", path)]) as temp, open(temp[path], "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(SKYLINE_HEADER)
        for a, e, f in zip(az_deg, el_deg, foliage_el_deg):
            w.writerow([f"{a:.1f}", f"{e:.3f}", f"{f:.3f}"])
