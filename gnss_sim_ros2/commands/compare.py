"""``gnss-sim compare``: simulated against real observations, as a Markdown report with figures.

    gnss-sim compare --sim FILE|BAG --real FILE|BAG [--nav FILE ...] [--truth X,Y,Z | --truth-csv FILE]
                     [--mask-deg DEG] [--solver ours|rtklib] --out DIR

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
real file's APPROX POSITION XYZ.
"""
from __future__ import annotations

from pathlib import Path

from gnss_sim_ros2.commands import fail, parse_triple


def add_arguments(p):
    p.add_argument("--sim", required=True, metavar="FILE", help="simulated observations: RINEX file or bag folder")
    p.add_argument("--real", required=True, metavar="FILE", help="real observations: RINEX file or bag folder")
    p.add_argument("--nav", nargs="+", default=None, metavar="FILE",
                   help="broadcast navigation files (positions, elevations)")
    t = p.add_mutually_exclusive_group()
    t.add_argument("--truth", metavar="X,Y,Z", help="true antenna position, ECEF [m]")
    t.add_argument("--truth-csv", metavar="FILE", help="true path: time + x_m,y_m,z_m or lat_deg,lon_deg,h_m")
    p.add_argument("--mask-deg", type=float, default=0.0,
                   help="elevation mask of the tracked-satellite comparison [deg] (needs --nav; default 0)")
    p.add_argument("--solver", choices=("ours", "rtklib"), default="ours",
                   help="position solver: gnss_sim solve_pvt (default) or RTKLIB rnx2rtkp (RINEX inputs)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="output folder (report.md + PNG figures): new, empty or one of an earlier compare (only its "
                        "files are replaced); a folder holding other files is refused")


def run(args) -> int:
    from gnss_sim_ros2.core.comparison import compare, write_report
    from gnss_sim_ros2.core.output_folder import OutputBusy, OutputFolder

    # written beside --out, moved there at the end: only compare's own files replaced (core/output_folder.py)
    folder = OutputFolder(Path(args.out), command="gnss-sim compare",
                          inputs=[args.sim, args.real, *(args.nav or ()), args.truth_csv])
    try:
        truth = parse_triple(args.truth, "--truth (ECEF X,Y,Z [m])") if args.truth else None
        staging = folder.acquire()
        try:
            cmp = compare(args.sim, args.real, nav_paths=args.nav, truth_ecef_m=truth, truth_csv=args.truth_csv,
                          mask_deg=args.mask_deg, solver=args.solver, workdir=staging)
            report = write_report(cmp, staging)
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
    pos = cmp.positions()
    for lab, st in pos.items():
        if st.get("n"):
            print(f"positions {lab.replace('_', ' ')}: horizontal RMS {st['rms_h_m']:.2f} m, "
                  f"vertical RMS {st['rms_v_m']:.2f} m ({st['n']} epochs)")
    print(f"wrote {report}")
    return 0
