"""Cost of the scene multipath model on the Hong Kong city (prints figures; no assertions).

    .venv/bin/python bench/bench_multipath.py [--epochs 120] [--range 50 100 200]

The antenna on the first epochs of the Tsim Sha Tsui drive (../shared/data/hk-tst-2019-118-urban-drive,
truth path placed 1.8 m above the model's ground), the day's GPS + BeiDou broadcast satellites above
15 deg, the city model of ../shared/data/hk-tst-city-model (44,928 triangles, 21,314 unique facets).
Figures per epoch: the visibility cast with multipath off / nlos / full (ms; rays: one line-of-sight ray per
satellite above the mask, two per reflection candidate, the diffraction edge searches; paths found) for
several facet ranges, and the receiver chain's step with and without the paths (ms).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris  # noqa: E402
from gnss_sim_ros2.core.multipath import drive_check  # noqa: E402
from gnss_sim_ros2.core.receiver.chain import ChainSettings, ReceiverChain, VisibilityOptions  # noqa: E402
from gnss_sim_ros2.parameters import validate_node  # noqa: E402

DATA = ROOT.parent / "shared" / "data"
DRIVE = DATA / "hk-tst-2019-118-urban-drive"
CITY = DATA / "hk-tst-city-model"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--epochs", type=int, default=120)
    ap.add_argument("--range", type=float, nargs="+", default=[50.0, 100.0, 200.0])
    args = ap.parse_args()
    if not DRIVE.is_dir() or not CITY.is_dir():
        print(f"needs {DRIVE} and {CITY}")
        return 1
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        scene = drive_check.city_scene(CITY, tmp)
        print(f"city scene: {len(scene.world.triangles)} triangles, loaded in {time.perf_counter() - t0:.2f} s")
        drive = drive_check.load_drive(DRIVE / "groundTruth_TST.csv", scene)
        nav = [str(DRIVE / "hksc1180.19n"), str(DRIVE / "hksc1180.19b")]
        prov, _ = open_ephemeris("broadcast", drive.t[0], args.epochs + 60.0, "GC", nav, check=False)
        t1 = time.perf_counter()
        from gnss_sim_ros2.core.multipath.scene_paths import facets_of

        facets = facets_of(scene)
        print(f"facets: {len(facets)} unique, built in {time.perf_counter() - t1:.2f} s")
        n = min(args.epochs, len(drive.t))
        states = [prov.states(drive.t[i], systems="GC") for i in range(n)]
        print(f"{n} epochs, {np.mean([len(s) for s in states]):.1f} satellites served per epoch")
        print("\nvisibility cast per epoch (one antenna position per call):")
        print(f"{'mode':>5} {'range m':>8} {'ms/epoch':>9} {'rays/epoch':>11} {'paths/epoch':>12} {'NLOS sats':>10}")
        casts = {}
        for mode, ranges in (("off", [0.0]), ("nlos", args.range), ("full", args.range)):
            for rng in ranges:
                opt = VisibilityOptions(mask_deg=15.0, multipath=mode, multipath_range_m=max(rng, 1.0))
                out = []
                rays = paths = nlos = 0
                los_rays = 0
                t = time.perf_counter()
                for i in range(n):
                    state, att, v = opt.cast(scene, drive.antenna_world_m[i], states[i].pos_ecef_m)
                    p = getattr(v, "paths", None)
                    los_rays += int(np.sum(v.el_deg >= 15.0))       # one line-of-sight ray per satellite cast
                    if p is not None:
                        rays += p.rays_cast
                        paths += int(p.valid.sum())
                        nlos += int(np.sum(state == 3))
                    out.append((state, att, p))
                ms = (time.perf_counter() - t) / n * 1e3
                print(f"{mode:>5} {rng:8.0f} {ms:9.2f} {(rays + los_rays) / n:11.1f} {paths / n:12.1f} "
                      f"{nlos / n:10.2f}")
                casts[(mode, rng)] = out
        print("\nreceiver chain step per epoch (ublox_m8t):")
        p = validate_node("receiver", {"profile": "ublox_m8t", "systems": "GC", "elevation_mask_deg": 15.0,
                                       "output_dir": ""}, "bench")
        for key in (("off", 0.0), ("full", 100.0)):
            chain = ReceiverChain(ChainSettings.from_params(p, interval_s=1.0, have_ephemeris=True), prov)
            t = time.perf_counter()
            for i in range(n):
                state, att, paths = casts[key][i]
                chain.step(drive.t[i], drive.antenna_ecef_m[i], states[i], state, att, multipath=paths)
            print(f"  multipath {key[0]:>4}: {(time.perf_counter() - t) / n * 1e3:.2f} ms/epoch, "
                  f"{chain.fixes}/{chain.epochs} fixes")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
