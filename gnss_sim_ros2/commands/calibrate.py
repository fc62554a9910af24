"""``gnss-sim calibrate``: fit a receiver profile (YAML) to a real recording, with a report and figures.

    gnss-sim calibrate --obs FILE --nav FILE [FILE ...] [--position-ecef X,Y,Z | --trajectory CSV]
                       [--start ISO --duration S] [--mask-deg 5] [--bin-deg 5] [--name NAME] --out DIR

Reads a RINEX 3 observation file (plain, .gz, Hatanaka .crx / .crx.gz) over the span, its broadcast navigation
file(s) and the antenna position (default: the header's APPROX POSITION XYZ + ANTENNA: DELTA H/E/N) or path
(a trajectory CSV as ``simulate --trajectory`` reads it, ``t_s`` from the span's first epoch), computes per-signal
statistics (C/N0 and code noise against elevation, arcs, LLI flags) and writes into DIR: ``NAME.yaml`` (the
profile, ``--profile DIR/NAME.yaml``), ``report.md`` with PNG figures and ``statistics.json``.  ``--start`` /
``--duration`` fit on part of a file (e.g. hours 0-12, then check on 12-24).  Method: core/calibration/.
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

from gnss_sim_ros2.commands import parse_triple

NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


def add_arguments(p):
    p.add_argument("--obs", required=True, metavar="FILE",
                   help="real RINEX 3 observation file (plain, .gz, Hatanaka .crx / .crx.gz)")
    p.add_argument("--nav", required=True, nargs="+", metavar="FILE", help="broadcast navigation file(s) of the day")
    a = p.add_mutually_exclusive_group()
    a.add_argument("--position-ecef", metavar="X,Y,Z",
                   help="static antenna position, ECEF [m] (default: header APPROX POSITION XYZ + ANTENNA: "
                        "DELTA H/E/N)")
    a.add_argument("--trajectory", metavar="CSV",
                   help="antenna path: t_s,lat_deg,lon_deg,h_m or t_s,x_m,y_m,z_m (t_s from the span's first epoch)")
    p.add_argument("--start", metavar="ISO", help="first epoch of the span, GPS time (default: the file's first)")
    p.add_argument("--duration", type=float, metavar="S", help="length of the span [s] (default: to the file's end)")
    p.add_argument("--mask-deg", type=float, default=5.0,
                   help="elevation mask of the tracked pairs and the overall code noise [deg] (default 5)")
    p.add_argument("--bin-deg", type=float, default=5.0, choices=(5.0, 10.0),
                   help="elevation bins of the tables [deg] (5 or 10; default 5)")
    p.add_argument("--name", help="profile name (default: <file stem>_calibrated)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="output folder: new, empty or one of an earlier calibrate (only its files are replaced)")


def _default_name(obs: str) -> str:
    stem = re.sub(r"[^A-Za-z0-9_-]", "", Path(obs).name.split(".")[0].split("_")[0]).lower()
    return f"{stem or 'receiver'}_calibrated"


def run(args) -> int:
    import yaml

    from gnss_sim_ros2.core.calibration.fit import fit_profile
    from gnss_sim_ros2.core.calibration.reading import read_recording
    from gnss_sim_ros2.core.calibration.report import write_report
    from gnss_sim_ros2.core.calibration.signal_stats import signal_statistics
    from gnss_sim_ros2.core.output_folder import OutputBusy, OutputFolder

    name = args.name if args.name is not None else _default_name(args.obs)
    folder = OutputFolder(Path(args.out), command="gnss-sim calibrate",
                          inputs=[args.obs, *(args.nav or ()), args.trajectory])
    try:
        if not NAME_RE.match(name):
            raise ValueError(f"option --name {name!r}: letters, digits, '_', '-' and '.' only")
        if not 0.0 <= args.mask_deg < 90.0:
            raise ValueError(f"option --mask-deg {args.mask_deg!r}: must be in [0, 90)")
        pos = parse_triple(args.position_ecef, "option --position-ecef (ECEF X,Y,Z [m])") \
            if args.position_ecef else None
        rec = read_recording(args.obs, args.nav, pos, args.trajectory, args.start, args.duration)
        stats = signal_statistics(rec.table, rec.el_deg, rec.interval_s, args.mask_deg, args.bin_deg)
        profile, notes = fit_profile(stats, rec.header, Path(args.obs).name, name)
        staging = folder.acquire()
        try:
            prof_path = staging / f"{name}.yaml"
            prof_path.write_text(yaml.safe_dump(profile, sort_keys=False, default_flow_style=None, width=120))
            report = write_report(rec, stats, profile, notes, prof_path, staging)
        except BaseException:
            folder.abandon()
            raise
        folder.commit()
        report, prof_path = folder.final_path(report), folder.final_path(prof_path)
    except ValueError as exc:
        print(f"gnss-sim calibrate: error: {exc}", file=sys.stderr)
        return 2
    except OutputBusy as exc:
        print(f"gnss-sim calibrate: error: {exc}", file=sys.stderr)
        return 1
    t0, t1 = rec.span
    print(f"calibrated on {args.obs}: {len(rec.table.time)} epochs {t0} .. {t1} GPS, "
          f"{len(stats.signals)} signals")
    for n in notes:
        print(f"note: {n}")
    print(f"wrote {prof_path}")
    print(f"wrote {report}")
    return 0
