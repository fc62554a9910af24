"""Benchmark of the broadcast ephemeris (prints figures; no assertions).

    .venv/bin/python bench/bench_ephemeris.py [--hours 24] [--nav FILE ...]

Uses the OPEC 2022-001 navigation files (GPS, Galileo, BeiDou, GLONASS) from
../shared/data when present, else a synthetic constellation written by
core/ephemeris/synthetic.py.  Figures:
- loading (georinex parsing, selection timelines, GLONASS integration);
- ``states(t)`` of every satellite at one epoch (target < 1 ms for ~130);
- 24 h at 1 s for every satellite, two ways: one ``states(t)`` call per epoch,
  and ``states_at`` over blocks of epochs x satellites.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gnss_sim_ros2.benchmarks.timing import mean_per_call_s  # noqa: E402
from gnss_sim_ros2.core.ephemeris.broadcast import BroadcastEphemeris  # noqa: E402
from gnss_sim_ros2.core.time import GnssTime  # noqa: E402

OPEC = ROOT.parent / "shared" / "data" / "opec-2022-001"


def _nav_files(args):
    if args.nav:
        return [Path(p) for p in args.nav], "given files"
    files = [OPEC / f"OPEC00NOR_S_20220010000_01D_{s}N.rnx" for s in "GECR"]
    if all(f.is_file() for f in files):
        return files, "OPEC 2022-001 (G, E, C, R)"
    from gnss_sim_ros2.core.ephemeris.synthetic import write_synthetic_nav

    out = Path("/tmp/bench_ephemeris_synthetic.rnx")
    write_synthetic_nav(out, GnssTime.from_iso("2021-12-31T22:00:00"), 28 * 3600.0)
    return [out], "synthetic constellation"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--nav", nargs="+")
    ap.add_argument("--hours", type=float, default=24.0)
    args = ap.parse_args()
    files, label = _nav_files(args)
    t_load = time.perf_counter()
    eph = BroadcastEphemeris.from_files(files)
    t_load = time.perf_counter() - t_load
    t0 = GnssTime.from_iso("2022-01-01T00:00:00")
    print(f"navigation: {label}; {len(eph.svs())} satellites, {len(eph.kepler_rec)} Keplerian + "
          f"{len(eph.glonass_rec)} GLONASS records; load {t_load:.2f} s")

    # every satellite of the files at once: validity windows widened to a day (a station file
    # holds records only while the satellite was in view, ~45 at a time)
    wide = BroadcastEphemeris(eph.nav, windows_s={s: 86400.0 for s in "GECRJI"})
    tw = t0 + 12 * 3600.0
    n_all = len(wide.states(tw))
    reps = 2000
    per_all = mean_per_call_s(lambda k: wide.states(tw + 0.001 * k), reps)
    print(f"states(t), one epoch, all {n_all} satellites of the files (wide windows): {per_all * 1e3:.3f} ms "
          f"per call ({per_all / n_all * 1e6:.2f} us per satellite)")

    # one epoch with the nominal windows: the epoch with the most satellites in the first hour
    best = max((len(eph.states(t0 + 60.0 * k)), k) for k in range(60))
    t = t0 + 60.0 * best[1]
    n_sat = best[0]
    for _ in range(50):
        eph.states(t)
    per = mean_per_call_s(lambda k: eph.states(t + 0.001 * k), reps)
    print(f"states(t), one epoch, {n_sat} satellites: {per * 1e3:.3f} ms per call "
          f"({per / n_sat * 1e6:.2f} us per satellite)")
    glo = eph.states(t, systems="R")
    per_r = mean_per_call_s(lambda k: eph.states(t + 0.001 * k, systems="R"), reps)
    kep = eph.states(t, systems="GECJI")
    per_k = mean_per_call_s(lambda k: eph.states(t + 0.001 * k, systems="GECJI"), reps)
    print(f"  of which Keplerian only ({len(kep)} sat): {per_k * 1e3:.3f} ms; GLONASS only ({len(glo)} sat): "
          f"{per_r * 1e3:.3f} ms")

    # a whole span at 1 s, one call per epoch
    n_ep = int(args.hours * 3600)
    tic = time.perf_counter()
    rows = 0
    for k in range(n_ep):
        rows += len(eph.states(t0 + float(k)))
    dt = time.perf_counter() - tic
    print(f"{args.hours:g} h at 1 s, states(t) per epoch: {n_ep} epochs, {rows} rows in {dt:.1f} s "
          f"({dt / n_ep * 1e3:.3f} ms per epoch, {rows / dt / 1e3:.0f} k rows/s)")

    # the same span with states_at over blocks of epochs x satellites
    svs = np.array(eph.svs())
    block = 600
    tic = time.perf_counter()
    rows = 0
    for k0 in range(0, n_ep, block):
        n = min(block, n_ep - k0)
        ks = np.arange(k0, k0 + n)
        tt = GnssTime(np.repeat(t0.sec + ks, len(svs)).astype(np.int64), np.zeros(n * len(svs)))
        rows += len(eph.states_at(np.tile(svs, n), tt))
    dt = time.perf_counter() - tic
    print(f"{args.hours:g} h at 1 s, states_at in blocks of {block} epochs: {rows} rows in {dt:.1f} s "
          f"({dt / n_ep * 1e3:.3f} ms per epoch, {rows / dt / 1e3:.0f} k rows/s)")


if __name__ == "__main__":
    main()
