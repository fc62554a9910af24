"""Cost of the scene multipath model on the Hong Kong city and the demo courtyard (prints figures; no assertions).

    .venv/bin/python bench/bench_multipath.py [--epochs 120] [--range 50 100 200] [--demo-only]

The antenna on the first epochs of the Tsim Sha Tsui drive (../shared/data/hk-tst-2019-118-urban-drive,
truth path placed 1.8 m above the model's ground), the day's GPS + BeiDou broadcast satellites above
15 deg, the city model of ../shared/data/hk-tst-city-model (44,928 triangles, 21,314 unique facets).
Figures per epoch: the visibility cast with multipath off / nlos / full (ms; rays: one line-of-sight ray per
satellite above the mask, two per reflection candidate, the diffraction edge searches; paths found) for
several facet ranges, and the receiver chain's step with and without the paths (ms).
Demo courtyard (``make demo``'s scenario: the demo path, the default configuration, preset balanced): the
whole offline chain (``run_simulation``) with multipath off / nlos / full (and the last two with the walls'
diffuse scattering): ms per epoch, rays and paths per
epoch, satellites tracked on reflections only, the fix's horizontal RMS.
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

from gnss_sim_ros2.core.comparison import drive_check  # noqa: E402
from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris  # noqa: E402
from gnss_sim_ros2.core.receiver.chain import ChainSettings, ReceiverChain  # noqa: E402
from gnss_sim_ros2.core.visibility import VisibilityOptions  # noqa: E402
from gnss_sim_ros2.parameters import validate_node  # noqa: E402

DATA = ROOT.parent / "shared" / "data"
DRIVE = DATA / "hk-tst-2019-118-urban-drive"
CITY = DATA / "hk-tst-city-model"


def demo_figures() -> None:
    """The demo scenario through the whole offline chain with each multipath mode."""
    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.core.simulation import run_simulation, setup_from_config

    print("demo courtyard, whole offline chain (preset balanced, the demo path, default systems):")
    print(f"{'mode':>9} {'ms/epoch':>9} {'rays/epoch':>11} {'paths/epoch':>12} {'refl-only tracked':>18} "
          f"{'fix H RMS m':>12}")
    real_cast = VisibilityOptions.cast
    for mode, scattering in (("off", False), ("nlos", False), ("full", False), ("nlos", True), ("full", True)):
        count = {"rays": 0, "paths": 0, "los_rays": 0}

        def cast(self, scene, antenna_world_m, sat_ecef_m, _count=count):
            state, att, v = real_cast(self, scene, antenna_world_m, sat_ecef_m)
            _count["los_rays"] += int(np.sum(np.asarray(v.el_deg) >= self.mask_deg))
            p = getattr(v, "paths", None)
            if p is not None:
                _count["rays"] += p.rays_cast
                _count["paths"] += int(p.valid.sum())
            return state, att, v

        refl = []

        def observer(t, ecef, obs, sol, refl=refl):
            r = set(np.asarray(obs.sat_sv)[np.asarray(obs.sat_vis_state) == 3])
            refl.append(len(r & set(np.asarray(obs.sv))))

        with tempfile.TemporaryDirectory() as tmp:
            setup = setup_from_config(load_config(), Path(tmp), progress=False, observer=observer)
            setup = setup.with_params(multipath=mode, multipath_scattering=scattering)
            VisibilityOptions.cast = cast
            try:
                res = run_simulation(setup)
            finally:
                VisibilityOptions.cast = real_cast
        n = res.epochs
        err = np.asarray(res.horizontal_error_m)
        name = mode + ("+scat" if scattering else "")
        print(f"{name:>9} {res.wall_s / n * 1e3:9.2f} {(count['rays'] + count['los_rays']) / n:11.1f} "
              f"{count['paths'] / n:12.1f} {np.mean(refl):18.2f} {np.sqrt(np.mean(err ** 2)):12.2f}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--epochs", type=int, default=120)
    ap.add_argument("--range", type=float, nargs="+", default=[50.0, 100.0, 200.0])
    ap.add_argument("--demo-only", action="store_true", help="only the demo courtyard")
    ap.add_argument("--quick", action="store_true", help="fewer epochs on the city (make bench)")
    args = ap.parse_args()
    demo_figures()
    if args.demo_only:
        return 0
    if args.quick:
        args.epochs = min(args.epochs, 30)
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
        print(f"{'mode':>9} {'range m':>8} {'ms/epoch':>9} {'rays/epoch':>11} {'paths/epoch':>12} {'NLOS sats':>10}")
        casts = {}
        for mode, ranges, scat in (("off", [0.0], False), ("nlos", args.range, False), ("full", args.range, False),
                                   ("nlos", [100.0], True), ("full", [100.0], True)):
            for rng in ranges:
                opt = VisibilityOptions(mask_deg=15.0, multipath=mode, multipath_range_m=max(rng, 1.0),
                                        multipath_scattering=scat)
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
                label = mode + ("+scat" if scat else "")
                print(f"{label:>9} {rng:8.0f} {ms:9.2f} {(rays + los_rays) / n:11.1f} {paths / n:12.1f} "
                      f"{nlos / n:10.2f}")
                casts[(mode, rng, scat)] = out
        print("\nreceiver chain step per epoch (ublox_m8t):")
        p = validate_node("receiver", {"profile": "ublox_m8t", "systems": "GC", "elevation_mask_deg": 15.0,
                                       "output_dir": ""}, "bench")
        for key in (("off", 0.0, False), ("full", 100.0, False), ("full", 100.0, True)):
            chain = ReceiverChain(ChainSettings.from_params(p, interval_s=1.0, have_ephemeris=True), prov)
            t = time.perf_counter()
            for i in range(n):
                state, att, paths = casts[key][i]
                chain.step(drive.t[i], drive.antenna_ecef_m[i], states[i], state, att, multipath=paths)
            label = key[0] + ("+scat" if key[2] else "")
            print(f"  multipath {label:>9}: {(time.perf_counter() - t) / n * 1e3:.2f} ms/epoch, "
                  f"{chain.fixes}/{chain.epochs} fixes")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
