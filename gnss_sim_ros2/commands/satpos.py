"""``gnss-sim satpos``: satellite positions, velocities and clocks on a time grid, as CSV.

    gnss-sim satpos --nav FILE [FILE ...] [--sp3 FILE ...] --start ISO8601 --end ISO8601 --step SECONDS
                    [--systems GRECJI] [--clk FILE ...] --out FILE.csv

One row per satellite and epoch: ``time,sv,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps,clock_s``.
- ``time``: GPS time, ISO 8601 (``2022-01-01T00:05:00``; decimals only when the
  grid has fractions of a second).  The grid is start, start + step, ... and
  includes ``--end`` when it falls on the grid (end inclusive).
- ``x_m``..``vz_mps``: ECEF of the source (broadcast: WGS 84 / GTRF / CGCS2000 /
  PZ-90.11 as broadcast; SP3: the product's frame, e.g. IGS14), the satellite at
  that instant: no light time, no Earth rotation correction.
- ``clock_s``: satellite clock offset in the SP3 convention: the broadcast clock
  polynomial only (no periodic relativistic term, no group delay).  GPS clocks
  refer to L1/L2 P(Y), Galileo I/NAV to E1/E5b (F/NAV: E1/E5a), BeiDou D1/D2 to
  B3I, GLONASS to GLONASST.
- Broadcast: a row only where a healthy record is valid at that instant
  (core/ephemeris/select.py windows).  With ``--sp3`` positions and clocks come
  from the precise products (interpolated between their epochs, rows where the
  products have the satellite); ``--nav`` may then be omitted and is not used.
Rows are sorted by time, then satellite.
"""
from __future__ import annotations

import math
import sys

import numpy as np

HEADER = "time,sv,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps,clock_s"


def add_arguments(parser):
    parser.add_argument("--nav", nargs="+", metavar="FILE", help="RINEX 2/3/4 navigation file(s) (gz/Z accepted)")
    parser.add_argument("--sp3", nargs="+", metavar="FILE", help="SP3 precise orbit file(s): use them instead")
    parser.add_argument("--clk", nargs="+", metavar="FILE", default=(), help="RINEX clock file(s) with --sp3")
    parser.add_argument("--start", required=True, metavar="ISO8601", help="first epoch, GPS time")
    parser.add_argument("--end", required=True, metavar="ISO8601", help="last epoch, GPS time (inclusive)")
    parser.add_argument("--step", required=True, type=float, metavar="SECONDS", help="grid step [s]")
    parser.add_argument("--systems", default="GRECJI", help="system letters (default GRECJI)")
    parser.add_argument("--galileo-nav", default="inav", choices=["inav", "fnav", "any"],
                        help="Galileo messages to use (broadcast): inav (default), fnav, any")
    parser.add_argument("--out", required=True, metavar="FILE.csv",
                        help="output CSV (written under a temporary name, renamed when complete; an input is refused)")


def _grid(start, end, step_s):
    from gnss_sim_ros2.core.time import GnssTime
    from gnss_sim_ros2.parameters import MAX_EPOCHS

    if not (math.isfinite(step_s) and step_s > 0):
        raise ValueError(f"--step {step_s}: must be a positive number of seconds")
    span = end - start
    if span < 0:
        raise ValueError(f"--end {end.isoformat()} is before --start {start.isoformat()}")
    n = int(math.floor(span / step_s + 1e-9)) + 1
    if n > MAX_EPOCHS:      # the grid and the CSV grow with the epochs: refused before anything is read
        raise ValueError(f"option --step {step_s:g} s over {span:g} s gives {n:.3g} epochs; satpos takes at most "
                         f"{MAX_EPOCHS:.0e} (MAX_EPOCHS in gnss_sim_ros2/parameters.py; one CSV row of ~120 bytes "
                         f"per satellite and epoch: {n * 100 * 120 / 1e9:.3g} GB for 100 satellites): give a larger "
                         f"--step or a shorter span")
    k = np.arange(n, dtype=np.float64) * step_s
    whole = np.floor(k)
    return GnssTime(np.full(n, start.sec, dtype=np.int64) + whole.astype(np.int64), start.frac + (k - whole))


def run(args) -> int:
    try:
        return _run(args)
    except (ValueError, FileNotFoundError) as e:
        print(f"gnss-sim satpos: error: {e}", file=sys.stderr)
        return 2


def _run(args) -> int:
    from gnss_sim_ros2.core.time import GnssTime
    from gnss_sim_ros2.parameters import SHARED_KEY, check_iso_time, param

    start = GnssTime.from_iso(check_iso_time(args.start, "option --start"), "GPS")
    end = GnssTime.from_iso(check_iso_time(args.end, "option --end"), "GPS")
    grid = _grid(start, end, args.step)

    systems = param(SHARED_KEY, "systems").check(args.systems.upper(), "option --systems")
    if args.sp3:
        from gnss_sim_ros2.core.ephemeris.sp3 import Sp3Ephemeris

        if args.nav:
            print("gnss-sim satpos: --sp3 given: positions and clocks come from SP3, --nav is not used",
                  file=sys.stderr)
        eph = Sp3Ephemeris.from_files(args.sp3, clk_paths=tuple(args.clk or ()), start=start, end=end)
    elif args.nav:
        from gnss_sim_ros2.core.ephemeris.broadcast import BroadcastEphemeris

        eph = BroadcastEphemeris.from_files(args.nav, start=start, end=end, systems=systems,
                                            galileo_nav=args.galileo_nav)
    else:
        raise ValueError("give --nav FILE(s) or --sp3 FILE(s)")
    frac_digits = 0 if (float(args.step).is_integer() and start.frac == 0.0) else 6
    n_rows = 0
    from gnss_sim_ros2.core.output_folder import staged_files

    # no half-written CSV under the final name, never an input overwritten (core/output_folder.py)
    with staged_files([("--out", args.out)], inputs=[*(args.nav or ()), *(args.sp3 or ()), *args.clk]) as temp, \
            open(temp[args.out], "w", encoding="ascii", newline="\n") as f:
        f.write(HEADER + "\n")
        for k in range(len(grid)):
            t = grid[k]
            st = eph.states(t, systems=systems)
            if not len(st):
                continue
            order = np.argsort(st.sv, kind="stable")
            ts = t.isoformat("GPS", frac_digits)
            p, v, c = st.pos_ecef_m[order], st.vel_ecef_mps[order], st.clock_bias_s[order]
            svs = st.sv[order]
            lines = [f"{ts},{svs[i]},{p[i, 0]:.4f},{p[i, 1]:.4f},{p[i, 2]:.4f},"
                     f"{v[i, 0]:.6f},{v[i, 1]:.6f},{v[i, 2]:.6f},{c[i]:.12e}\n" for i in range(len(svs))]
            f.writelines(lines)
            n_rows += len(lines)
        if not n_rows:         # an empty table is no answer: the files do not cover the span (the CSV is not kept)
            raise ValueError(f"no satellite of systems {systems} has a valid record from --start {args.start} to "
                             f"--end {args.end} in the given files (records of other days or systems)")
    print(f"gnss-sim satpos: {n_rows} rows, {len(grid)} epochs -> {args.out}", file=sys.stderr)
    return 0
