"""``gnss-sim calibrate``: fit a receiver profile (YAML) to a real recording, with a report and figures.

    gnss-sim calibrate --obs FILE --nav FILE [FILE ...] [--position-ecef X,Y,Z | --trajectory CSV]
                       [--world SDF | --mesh FILE] [--start ISO --duration S] [--mask-deg 5] [--bin-deg 5]
                       [--name NAME] --out DIR

Reads a RINEX 3 observation file (plain, .gz, Hatanaka .crx / .crx.gz) over the span, its broadcast navigation
file(s) and the antenna position (default: the header's APPROX POSITION XYZ + ANTENNA: DELTA H/E/N) or path
(a trajectory CSV as ``simulate --trajectory`` reads it, ``t_s`` from the span's first epoch), computes per-signal
statistics (C/N0 and code noise against elevation, arcs, LLI flags) and writes into DIR: ``NAME.yaml`` (the
profile, ``--profile DIR/NAME.yaml``), ``report.md`` with PNG figures and ``statistics.json``.  ``--start`` /
``--duration`` fit on part of a file (e.g. hours 0-12, then check on 12-24).  ``--world`` / ``--mesh``: the
scene of the recording (loaded as ``gnss-sim simulate`` loads it): only the (epoch, satellite) pairs it leaves in
the line of sight of the antenna above the mask enter the C/N0 tables, code noise, rise / set and thresholds (an
urban recording's blocked and reflected signals stay out); the path may then be in the scene's world frame.
Method: core/calibration/.
"""
from __future__ import annotations

import re
from pathlib import Path

from gnss_sim_ros2.commands import WORLD_OFFSET_HELP, check_scene_options, fail, parse_triple, world_offset_scene

NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
#: --fit-offset: the registration's elevation mask is at least this [deg] (low satellites see far walls the model
#: lacks; drive_check's 15 deg on the Hong Kong drive)
FIT_MASK_MIN_DEG = 15.0


def add_arguments(p):
    from gnss_sim_ros2.core.receiver.profiles import builtin_names

    p.add_argument("--obs", required=True, metavar="FILE",
                   help="real RINEX 3 observation file (plain, .gz, Hatanaka .crx / .crx.gz)")
    p.add_argument("--nav", required=True, nargs="+", metavar="FILE", help="broadcast navigation file(s) of the day")
    a = p.add_mutually_exclusive_group()
    a.add_argument("--position-ecef", metavar="X,Y,Z",
                   help="static antenna position, ECEF [m] (default: header APPROX POSITION XYZ + ANTENNA: "
                        "DELTA H/E/N)")
    a.add_argument("--trajectory", metavar="CSV",
                   help="antenna path: t_s,lat_deg,lon_deg,h_m or t_s,x_m,y_m,z_m (t_s from the span's first epoch)")
    sc = p.add_mutually_exclusive_group()
    sc.add_argument("--world", metavar="SDF", help="Gazebo world of the recording's surroundings: only satellites it "
                    "leaves in the line of sight are fitted")
    sc.add_argument("--mesh", metavar="FILE", help="mesh exported by export-world, instead of --world")
    p.add_argument("--world-offset", metavar="E,N,U", help=WORLD_OFFSET_HELP)
    p.add_argument("--fit-offset", action="store_true",
                   help="with --world / --mesh: estimate the scene's georeference error from the recording along "
                        "the antenna's positions, with its uncertainty: reported in report.md and statistics.json, "
                        "never applied (core/comparison/registration.py)")
    p.add_argument("--strong-cn0-dbhz", type=float, default=38.0, metavar="DB",
                   help="with --fit-offset: C/N0 from which a real signal counts as line of sight (default 38)")
    p.add_argument("--start", metavar="ISO", help="first epoch of the span, GPS time (default: the file's first)")
    p.add_argument("--duration", type=float, metavar="S", help="length of the span [s] (default: to the file's end)")
    p.add_argument("--mask-deg", type=float, default=5.0,
                   help="elevation mask of the tracked pairs and the overall code noise [deg] (default 5)")
    p.add_argument("--bin-deg", type=float, default=5.0, choices=(5.0, 10.0),
                   help="elevation bins of the tables [deg] (5 or 10; default 5)")
    p.add_argument("--name", help="profile name (default: <file stem>_calibrated)")
    p.add_argument("--base-profile", choices=builtin_names(), metavar="NAME",
                   help="built-in profile of the receiver's class (its loops and front end; its thresholds where the "
                        "recording has no rise or set): one of " + ", ".join(builtin_names())
                        + " (default: from the RINEX header's receiver type)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="output folder: new, empty or one of an earlier calibrate (only its files are replaced)")


def _fit_offset(args, rec, scene, scene_name, staging, report):
    """--fit-offset: the scene's georeference error from the recording along its antenna positions
    (core/comparison/registration.py), a "Registration" section of report.md and a "registration" entry of
    statistics.json, with its uncertainty; a finding, never applied."""
    import json
    from dataclasses import asdict

    from gnss_sim_ros2.core.comparison import registration as rg
    from gnss_sim_ros2.core.ephemeris.broadcast import BroadcastEphemeris

    eph = BroadcastEphemeris.from_files([str(p) for p in args.nav])
    sight = rg.sight_from_table(rec.table, rec.table.time, rec.antenna_world_m, eph,
                                strong_cn0_dbhz=args.strong_cn0_dbhz)
    reg = rg.fit_offset(scene, sight, mask_deg=max(args.mask_deg, FIT_MASK_MIN_DEG),
                        strong_cn0_dbhz=args.strong_cn0_dbhz)
    with open(report, "a") as f:
        f.write("\n" + rg.registration_markdown(reg, scene_name, rg.apply_hint(reg)))
    stats_path = Path(staging) / "statistics.json"
    d = json.loads(stats_path.read_text())
    d["registration"] = {**asdict(reg), "scene": scene_name, "applied": False, "how_to_apply": rg.apply_hint(reg)}
    stats_path.write_text(json.dumps(d, indent=1, default=float))
    return reg


def _default_name(obs: str) -> str:
    stem = re.sub(r"[^A-Za-z0-9_-]", "", Path(obs).name.split(".")[0].split("_")[0]).lower()
    return f"{stem or 'receiver'}_calibrated"


def _scene(args):
    """(scene or None, its option and file for the report) of --world / --mesh; ValueError naming the option."""
    world, mesh = getattr(args, "world", None), getattr(args, "mesh", None)
    if not world and not mesh:
        return None, ""
    from gnss_sim_ros2.core.visibility import load_scene

    opt, path = ("--world", world) if world else ("--mesh", mesh)
    if not Path(path).is_file():
        raise ValueError(f"option {opt} {path}: no such file")
    try:
        scene = load_scene(world or "", mesh or "")
    except Exception as exc:  # the loaders raise ValueError, OSError, XML and mesh errors: one line naming the file
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ValueError(f"option {opt} {path}: {msg}") from None
    return world_offset_scene(scene, getattr(args, "world_offset", None)), f"{opt} {path}"


def run(args) -> int:
    import yaml

    from gnss_sim_ros2.core.calibration.fit import fit_profile
    from gnss_sim_ros2.core.calibration.reading import read_recording
    from gnss_sim_ros2.core.calibration.report import write_report
    from gnss_sim_ros2.core.calibration.signal_stats import signal_statistics
    from gnss_sim_ros2.core.output_folder import OutputBusy, OutputFolder

    name = args.name if args.name is not None else _default_name(args.obs)
    folder = OutputFolder(Path(args.out), command="gnss-sim calibrate",
                          inputs=[args.obs, *(args.nav or ()), args.trajectory, getattr(args, "world", None),
                                  getattr(args, "mesh", None)])
    try:
        if not NAME_RE.match(name):
            raise ValueError(f"option --name {name!r}: letters, digits, '_', '-' and '.' only")
        if not 0.0 <= args.mask_deg < 90.0:
            raise ValueError(f"option --mask-deg {args.mask_deg!r}: must be in [0, 90)")
        pos = parse_triple(args.position_ecef, "option --position-ecef (ECEF X,Y,Z [m])") \
            if args.position_ecef else None
        check_scene_options(args)
        scene, scene_name = _scene(args)
        if args.fit_offset and scene is None:
            raise ValueError("option --fit-offset: needs the scene of the recording (--world SDF or --mesh FILE)")
        rec = read_recording(args.obs, args.nav, pos, args.trajectory, args.start, args.duration, scene,
                             args.mask_deg, scene_name)
        stats = signal_statistics(rec.table, rec.el_deg, rec.interval_s, args.mask_deg, args.bin_deg, rec.los,
                                  rec.scene)
        profile, notes = fit_profile(stats, rec.header, Path(args.obs).name, name, args.base_profile)
        staging = folder.acquire()
        try:
            prof_path = staging / f"{name}.yaml"
            prof_path.write_text(yaml.safe_dump(profile, sort_keys=False, default_flow_style=None, width=120))
            report = write_report(rec, stats, profile, notes, prof_path, staging)
            reg = _fit_offset(args, rec, scene, scene_name, staging, report) if args.fit_offset else None
        except BaseException:
            folder.abandon()
            raise
        folder.commit()
        report, prof_path = folder.final_path(report), folder.final_path(prof_path)
    except (ValueError, OutputBusy) as exc:
        return fail("calibrate", exc)
    t0, t1 = rec.span
    print(f"calibrated on {args.obs}: {len(rec.table.time)} epochs {t0} .. {t1} GPS, "
          f"{len(stats.signals)} signals")
    if stats.scene:
        kept = ", ".join(f"{k_} {st.los_samples[1]}/{st.los_samples[0]}" for k_, st in stats.signals.items()
                         if st.los_samples is not None)
        print(f"line of sight from {stats.scene}: C/N0 samples kept {kept}")
    for n in notes:
        print(f"note: {n}")
    if reg is not None:
        print(f"registration of {scene_name}: antenna offset in the world east {reg.offset_en_m[0]:+.2f} +- "
              f"{reg.sigma_en_m[0]:.2f} m, north {reg.offset_en_m[1]:+.2f} +- {reg.sigma_en_m[1]:.2f} m (not applied; "
              f"report.md, statistics.json)")
    print(f"wrote {prof_path}")
    print(f"wrote {report}")
    return 0
