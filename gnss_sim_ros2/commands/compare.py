"""``gnss-sim compare``: simulated against real observations, as a Markdown report with figures.

    gnss-sim compare --sim FILE|BAG --real FILE|BAG [--nav FILE ...] [--truth X,Y,Z | --truth-csv FILE]
                     [--real-truth-csv FILE] [--mask-deg DEG] [--solver ours|rtklib] --out DIR
                     [--world SDF | --mesh FILE --fit-offset [--antenna-height-m H] [--strong-cn0-dbhz DB]]

Inputs: RINEX 3 observation files or rosbag2 bags holding gnss_sim_msgs/Observations
(``gnss-sim run``'s ``bag/``).  Writes ``DIR/report.md`` (per system and per satellite
pseudorange, time-differenced carrier phase, Doppler and C/N0 differences after removing
the receiver clock; satellites seen by one side only; position solutions of both files
against each other and the truth; per-signal statistics sim against real: tracked
(satellite, signal) pairs, C/N0 per elevation bin, code noise, LLI at the first epoch, also in
``signals.json``) and PNG figures beside it (only compare's own files in DIR are replaced;
a DIR holding other files is refused: core/output_folder.py).  Method: core/comparison/.
The real file is read over the simulated span only.  Without ``--nav`` there are no
positions and no elevations.  Truth: ``--truth`` (ECEF m), ``--truth-csv`` (time and
x_m,y_m,z_m or lat_deg,lon_deg,h_m, e.g. a simulation's fix.csv) or, by default, the
real file's APPROX POSITION XYZ; ``--real-truth-csv`` gives the real file its own path.  Positions are compared
on the epochs both files solved (the count is printed).  With ``--world`` / ``--mesh`` (the scene, loaded as
``calibrate`` loads it) and ``--nav`` every tracked satellite-epoch of each file is line of sight or NLOS from
that file's truth: tracked/not agreement, NLOS shares, Wasserstein distances and residual tails in report.md and
``urban.json`` (core/comparison/canyon.py).

``--fit-offset`` with ``--world`` / ``--mesh`` (the real recording's surroundings) and ``--nav``: the scene's
georeference error estimated from the real file along the truth (core/comparison/registration.py), with its
uncertainty, as a "Registration" section of report.md and ``registration.json``: a finding, applied to nothing.
"""
from __future__ import annotations

import math
from pathlib import Path

from gnss_sim_ros2.commands import WORLD_OFFSET_HELP, fail, parse_triple


def add_arguments(p):
    p.add_argument("--sim", required=True, metavar="FILE", help="simulated observations: RINEX file or bag folder")
    p.add_argument("--real", required=True, metavar="FILE", help="real observations: RINEX file or bag folder")
    p.add_argument("--nav", nargs="+", default=None, metavar="FILE",
                   help="broadcast navigation files (positions, elevations)")
    t = p.add_mutually_exclusive_group()
    t.add_argument("--truth", metavar="X,Y,Z", help="true antenna position, ECEF [m]")
    t.add_argument("--truth-csv", metavar="FILE", help="true path: time + x_m,y_m,z_m or lat_deg,lon_deg,h_m")
    p.add_argument("--real-truth-csv", metavar="FILE",
                   help="the real file's own true path when the simulation was made on another one (same columns as "
                        "--truth-csv; default: the one truth of both)")
    p.add_argument("--mask-deg", type=float, default=0.0,
                   help="elevation mask of the tracked-satellite comparison [deg] (needs --nav; default 0)")
    p.add_argument("--epoch-tol-ms", type=float, metavar="MS",
                   help="match the two files' epochs within MS milliseconds (default 1; a receiver whose time tags "
                        "wander, e.g. a u-blox's +-3 ms, needs more; its code differences then carry range rate x tag "
                        "difference, up to 0.8 m per ms)")
    p.add_argument("--solver", choices=("ours", "rtklib"), default="ours",
                   help="position solver: gnss_sim solve_pvt (default) or RTKLIB rnx2rtkp (RINEX inputs)")
    sc = p.add_mutually_exclusive_group()
    sc.add_argument("--world", metavar="SDF", help="Gazebo world of the real recording's surroundings: the "
                    "line-of-sight / NLOS split of the figures (urban.json) and --fit-offset")
    sc.add_argument("--mesh", metavar="FILE", help="mesh exported by export-world, instead of --world")
    p.add_argument("--world-offset", metavar="E,N,U", help=WORLD_OFFSET_HELP + " (with --world / --mesh)")
    p.add_argument("--fit-offset", action="store_true",
                   help="estimate the scene's georeference error (east, north [m]) from the real file along the "
                        "truth, with its uncertainty: reported in report.md and registration.json, never applied "
                        "(needs --world or --mesh and --nav; its mask: --mask-deg, or 15 deg when that is 0)")
    p.add_argument("--antenna-height-m", type=float, metavar="H",
                   help="with --world / --mesh: place the antenna H above the scene's ground under the truth (a city "
                        "model's vertical datum is not the ellipsoid; default: the truth's own height)")
    p.add_argument("--strong-cn0-dbhz", type=float, default=38.0, metavar="DB",
                   help="with --fit-offset: C/N0 from which a real signal counts as line of sight (default 38)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="output folder (report.md + PNG figures): new, empty or one of an earlier compare (only its "
                        "files are replaced); a folder holding other files is refused")


#: the registration's elevation mask when --mask-deg is 0 [deg] (drive_check's, the Hong Kong drive)
FIT_MASK_DEG = 15.0


def _check_fit_options(args) -> None:
    """ValueError naming the option for a --fit-offset combination that cannot work."""
    from gnss_sim_ros2.commands import check_scene_options

    check_scene_options(args)
    scene = getattr(args, "world", None) or getattr(args, "mesh", None)
    h = args.antenna_height_m
    if h is not None and not (math.isfinite(h) and 0.0 <= h <= 100.0):     # -5 m ended as a non-finite position
        raise ValueError(f"option --antenna-height-m is {h}: a height 0..100 m above the ground is needed")
    if not getattr(args, "fit_offset", False):
        if args.antenna_height_m is not None and not scene:
            raise ValueError("option --antenna-height-m: only used with --world / --mesh")
        return
    if not scene:
        raise ValueError("option --fit-offset: needs the scene of the real recording (--world SDF or --mesh FILE)")
    if not args.nav:
        raise ValueError("option --fit-offset: needs --nav (the satellites' positions)")


def _registration(args, cmp, staging, report, scene, scene_name) -> object:
    """--fit-offset: the Registration of ``scene`` against the real file along its truth, appended to ``report`` as
    a section and written as registration.json (core/comparison/registration.py); ValueError naming the option."""
    import numpy as np

    from gnss_sim_ros2.core.comparison import registration as rg
    from gnss_sim_ros2.core.comparison.drive_check import place_on_ground
    from gnss_sim_ros2.core.ephemeris.broadcast import BroadcastEphemeris

    if scene.spherical is None:
        raise ValueError(f"option {scene_name}: no spherical_coordinates (geodetic origin): cannot place the truth")
    real_truth = cmp.real_truth() if hasattr(cmp, "real_truth") else cmp.truth_ecef_m
    if real_truth is None or not np.isfinite(real_truth).any():
        raise ValueError("option --fit-offset: no truth position over the compared epochs (--truth or --truth-csv)")
    if not any(c[0] == "S" and np.isfinite(a).any() for c, a in cmp.real.values.items()):
        raise ValueError(f"option --fit-offset: {args.real} has no C/N0 (S) observations to tell strong signals")
    truth = np.asarray(real_truth, float)
    world = np.full(truth.shape, np.nan)
    ok = np.all(np.isfinite(truth), axis=1)
    world[ok] = scene.spherical.ecef_to_world(truth[ok])
    if args.antenna_height_m is not None:
        world[ok] = place_on_ground(scene, world[ok, :2], args.antenna_height_m)[0]
    eph = BroadcastEphemeris.from_files([str(p) for p in args.nav])
    sight = rg.sight_from_table(cmp.real, cmp.time, world, eph, strong_cn0_dbhz=args.strong_cn0_dbhz)
    mask = args.mask_deg if args.mask_deg > 0 else FIT_MASK_DEG
    reg = rg.fit_offset(scene, sight, mask_deg=mask, strong_cn0_dbhz=args.strong_cn0_dbhz)
    with open(report, "a") as f:
        f.write("\n" + rg.registration_markdown(reg, scene_name, rg.apply_hint(reg)))
    rg.write_registration(reg, staging, scene_name)
    return reg


def _los_scene(args):
    """(scene, "--world FILE") of --world / --mesh for the line-of-sight split (None, "" without); ValueError naming
    the option."""
    from gnss_sim_ros2.commands.calibrate import _scene

    if not (getattr(args, "world", None) or getattr(args, "mesh", None)):
        return None, ""
    scene, name = _scene(args)
    if not args.nav:
        raise ValueError(f"option {name.split()[0]}: the line-of-sight split needs --nav (satellite positions)")
    return scene, name


def run(args) -> int:
    from gnss_sim_ros2.core.comparison import compare, write_report
    from gnss_sim_ros2.core.frames import check_receiver_position
    from gnss_sim_ros2.core.output_folder import OutputBusy, OutputFolder
    from gnss_sim_ros2.parameters import param

    # written beside --out, moved there at the end: only compare's own files replaced (core/output_folder.py)
    folder = OutputFolder(Path(args.out), command="gnss-sim compare",
                          inputs=[args.sim, args.real, *(args.nav or ()), args.truth_csv, args.world, args.mesh,
                                  getattr(args, "real_truth_csv", None)])
    try:
        truth = parse_triple(args.truth, "--truth (ECEF X,Y,Z [m])") if args.truth else None
        if truth is not None:                   # the Earth's centre or space: refused as every position is
            check_receiver_position(truth, "ecef", f"option --truth {args.truth}")
        param("visibility", "elevation_mask_deg").check(args.mask_deg, "option --mask-deg")   # -5..90 deg
        _check_fit_options(args)
        scene, scene_name = _los_scene(args)
        staging = folder.acquire()
        reg = None
        try:
            cmp = compare(args.sim, args.real, nav_paths=args.nav, truth_ecef_m=truth, truth_csv=args.truth_csv,
                          mask_deg=args.mask_deg, solver=args.solver, workdir=staging,
                          real_truth_csv=getattr(args, "real_truth_csv", None), scene=scene, scene_name=scene_name,
                          epoch_tol_ms=getattr(args, "epoch_tol_ms", None),
                          ground_height_m=args.antenna_height_m)
            report = write_report(cmp, staging)
            if args.fit_offset:
                reg = _registration(args, cmp, staging, report, scene, scene_name)
        except BaseException:
            folder.abandon()
            raise
        folder.commit()
        report = folder.final_path(report)
    except (ValueError, OutputBusy) as exc:
        return fail("compare", exc)
    code = cmp.kinds["code"]
    if code.available:
        parts = []
        for s in cmp.systems:
            st = cmp.system_stats("code", s)
            if st["n"]:
                parts.append(f"{s} {st['rms']:.2f} m ({st['n']})")
        print(f"code sim - real RMS after clock removal: {', '.join(parts)}")
    for name, kr in cmp.kinds.items():
        if not kr.available:
            print(f"{name}: unavailable ({kr.reason})")
    vis = cmp.visibility()
    print("tracked sets, Jaccard: " + ", ".join(f"{k} {v:.3f}" for k, v in vis["jaccard"].items()))
    if cmp.signals is not None and cmp.signals["jaccard_all"] is not None:
        ratios = [f"{k} {r['code_ratio']:.2f}" for k, r in cmp.signals["signals"].items() if r.get("code_ratio")]
        print(f"(epoch, satellite, signal) triples, Jaccard: {cmp.signals['jaccard_all']:.3f}; code noise sim/real: "
              + (", ".join(ratios) or "-"))
    if cmp.canyon is not None:
        from gnss_sim_ros2.core.comparison.canyon_report import urban_figures

        m = urban_figures(cmp)
        w = m["residuals"]
        print(f"line of sight ({cmp.canyon.scene}, mask {cmp.mask_deg:g} deg): tracked/not agreement "
              f"{m['agreement']['agreement']:.3f} (anchor 0.878); NLOS share sim {m['nlos_share_sim']:.3f} / real "
              f"{m['nlos_share_real']:.3f}; Wasserstein LOS {w['los']['wasserstein_m']:.2f} m, NLOS "
              f"{w['nlos']['wasserstein_m']:.2f} m; LOS |residual| > 10 m sim {m['los_above_10m_sim']:.3f} / real "
              f"{m['los_above_10m_real']:.3f}")
    pos = cmp.positions()
    sol = cmp.solved_epochs()
    if sol:
        print(f"positions on the {sol['both']} epochs both solved (simulated {sol['sim']}, real {sol['real']})")
    for lab, st in pos.items():
        if st.get("n"):
            print(f"positions {lab.replace('_', ' ')}: horizontal RMS {st['rms_h_m']:.2f} m, "
                  f"vertical RMS {st['rms_v_m']:.2f} m ({st['n']} epochs)")
    if reg is not None:
        print(f"registration (not applied): east {reg.offset_en_m[0]:+.2f} +- {reg.sigma_en_m[0]:.2f} m, north "
              f"{reg.offset_en_m[1]:+.2f} +- {reg.sigma_en_m[1]:.2f} m; criterion {reg.criterion_zero:.3f} -> "
              f"{reg.criterion_best:.3f} ({reg.sat_epochs} satellite-epochs, {reg.wall_s:.1f} s)")
    print(f"wrote {report}")
    return 0
