"""Cost of the scene multipath model on the Hong Kong city and the demo courtyard (prints figures; no assertions).

    .venv/bin/python bench/bench_multipath.py [--epochs 120] [--range 50 100 200] [--demo-only] [--auto]

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
``--auto`` (only): what multipath "auto" (the default preset's: core/presets.py) costs against "off" where the
scene has no wall within range (an open field: the courtyard's ground alone), in the demo courtyard and on the
city: the whole offline chain on the demo path (ms per epoch, of which the visibility cast; fix availability and
horizontal RMS; whether auto's RINEX and fixes equal off's) and the city's cast per epoch (off, auto, full; the
wall test alone), best of ``--repeats`` runs.
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


def _open_field(scene):
    """The scene's ground alone (triangles lying in z = 0), same georeference: a world without walls."""
    from gnss_sim_ros2.core.scene.visibility import Scene
    from gnss_sim_ros2.core.scene.world_mesh import WorldMesh

    w = scene.world
    v, tri = np.asarray(w.vertices_m), np.asarray(w.triangles)
    flat = np.all(np.abs(v[tri][:, :, 2]) < 1e-6, axis=1)
    return Scene(WorldMesh(v, tri[flat], np.asarray(w.material)[flat], w.materials,
                           spherical_coordinates=w.spherical_coordinates))


def _timed_cast(count):
    """VisibilityOptions.cast wrapped to add its wall-clock time into ``count["cast_s"]``."""
    real_cast = VisibilityOptions.cast

    def cast(self, *args, **kwargs):
        t = time.perf_counter()
        try:
            return real_cast(self, *args, **kwargs)
        finally:
            count["cast_s"] += time.perf_counter() - t
    return real_cast, cast


def auto_figures(epochs: int, repeats: int) -> None:
    """Multipath "auto" against "off" (and "full" on the city): an open field, the demo courtyard, the city."""
    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.core.multipath.wall_proximity import antennas_near_walls, walls_of
    from gnss_sim_ros2.core.scene.demo_world import demo_world_path
    from gnss_sim_ros2.core.simulation import run_simulation, setup_from_config
    from gnss_sim_ros2.core.visibility import load_scene

    court = load_scene(str(demo_world_path()), "")
    field = _open_field(court)
    print(f"whole offline chain on the demo path (601 epochs, preset balanced, best of {repeats}):")
    print(f"{'scene':>10} {'mode':>5} {'ms/epoch':>9} {'cast ms/epoch':>14} {'fixes %':>8} {'fix H RMS m':>12} "
          f"{'same files as off':>18}")
    for name, scene in (("open field", field), ("courtyard", court)):
        files = {}
        for mode in ("off", "auto"):
            best = None
            for _ in range(repeats):
                count = {"cast_s": 0.0}
                real_cast, cast = _timed_cast(count)
                with tempfile.TemporaryDirectory() as tmp:
                    setup = setup_from_config(load_config(), Path(tmp), scene=scene, progress=False)
                    VisibilityOptions.cast = cast
                    try:
                        res = run_simulation(setup.with_params(multipath=mode))
                    finally:
                        VisibilityOptions.cast = real_cast
                    files[mode] = ([x for x in res.obs_path.read_text().splitlines() if "RUN BY" not in x],
                                   res.fix_path.read_text())
                if best is None or res.wall_s < best[0].wall_s:
                    best = (res, count["cast_s"])
            res, cast_s = best
            n = res.epochs
            err = np.asarray(res.horizontal_error_m)
            same = "" if mode == "off" else ("yes" if files["auto"] == files["off"] else "no")
            print(f"{name:>10} {mode:>5} {res.wall_s / n * 1e3:9.2f} {cast_s / n * 1e3:14.3f} "
                  f"{100.0 * res.fixes / n:8.1f} {np.sqrt(np.mean(err ** 2)):12.2f} {same:>18}")
    if not DRIVE.is_dir() or not CITY.is_dir():
        print(f"city: needs {DRIVE} and {CITY}")
        return
    with tempfile.TemporaryDirectory() as tmp:
        scene = drive_check.city_scene(CITY, tmp)
        drive = drive_check.load_drive(DRIVE / "groundTruth_TST.csv", scene)
        nav = [str(DRIVE / "hksc1180.19n"), str(DRIVE / "hksc1180.19b")]
        prov, _ = open_ephemeris("broadcast", drive.t[0], epochs + 60.0, "GC", nav, check=False)
        n = min(epochs, len(drive.t))
        states = [prov.states(drive.t[i], systems="GC") for i in range(n)]
        t = time.perf_counter()
        walls = walls_of(scene)
        print(f"\ncity ({n} epochs of the drive, one antenna per call, best of {repeats}): {len(walls)} wall "
              f"triangles, wall test built in {(time.perf_counter() - t) * 1e3:.0f} ms; antennas with walls "
              f"within 100 m: {antennas_near_walls(scene, drive.antenna_world_m[:n], 100.0).mean():.2f}")
        ant = drive.antenna_world_m[:n]
        ms = min(_seconds(lambda: [antennas_near_walls(scene, a, 100.0) for a in ant]) for _ in range(repeats))
        print(f"  wall test alone: {ms / n * 1e3:.3f} ms/epoch")
        for mode in ("off", "auto", "full"):
            opt = VisibilityOptions(mask_deg=15.0, multipath=mode, multipath_range_m=100.0)
            ms = min(_seconds(lambda o=opt: [o.cast(scene, ant[i], states[i].pos_ecef_m) for i in range(n)])
                     for _ in range(repeats))
            print(f"  cast {mode:>4}: {ms / n * 1e3:.2f} ms/epoch")


def _seconds(f) -> float:
    t = time.perf_counter()
    f()
    return time.perf_counter() - t


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--epochs", type=int, default=120)
    ap.add_argument("--range", type=float, nargs="+", default=[50.0, 100.0, 200.0])
    ap.add_argument("--demo-only", action="store_true", help="only the demo courtyard")
    ap.add_argument("--quick", action="store_true", help="fewer epochs on the city (make bench)")
    ap.add_argument("--auto", action="store_true", help="only multipath auto against off (open field, "
                    "courtyard, city)")
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per figure of --auto, best kept")
    args = ap.parse_args()
    if args.auto:
        auto_figures(args.epochs, args.repeats)
        return 0
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
