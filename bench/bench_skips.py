"""What each "model only what the scene requires" skip saves: ratios measured in one run (printed).

    python bench/bench_skips.py [--epochs 300]

Skips measured (each against the same work done without the skip, best of
``--repeats`` timings, on the demo scenario: courtyard world, synthetic GRECJI
constellation, demo path):

1. no foliage -> no multi-hit queries: the visibility query of a scene with and
   without its penetrable triangles, and foliage model "path" (list_intersections
   through every crown) against "touch" (one any-hit test);
2. satellites below the horizon are never cast: raycasting all satellites
   against only those above the mask, and the receiver fed every satellite
   against only those above the horizon (what run_simulation passes);
3. systems not tracked are never computed: GPS+Galileo against all six systems
   (ephemeris + receiver per epoch);
4. ephemerides loaded for the simulated span only: the OPEC daily navigation
   files (or a day of synthetic records) read for one hour against the day;
5. the mesh cut to what the robot can see (crop_world_mesh): a 4 km x 4 km
   city of 40,000 buildings (480,000 triangles), path in its middle:
   scene build and visibility queries with and without the crop;
6. batched epochs (one ephemeris call and one raycast per 300 epochs) against
   epoch by epoch: the whole run_simulation loop.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from gnss_sim_ros2.benchmarks.presets import shared_data_dir  # noqa: E402
from gnss_sim_ros2.benchmarks.timing import best_s  # noqa: E402
from gnss_sim_ros2.config_file import load_config  # noqa: E402
from gnss_sim_ros2.core.demo import DEMO_START  # noqa: E402
from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris  # noqa: E402
from gnss_sim_ros2.core.frames import az_el_from_ecef  # noqa: E402
from gnss_sim_ros2.core.receiver.config import ReceiverConfig  # noqa: E402
from gnss_sim_ros2.core.receiver.engine import Receiver  # noqa: E402
from gnss_sim_ros2.core.scene.demo_world import demo_world_path  # noqa: E402
from gnss_sim_ros2.core.scene.materials import MaterialTable  # noqa: E402
from gnss_sim_ros2.core.scene.visibility import Scene  # noqa: E402
from gnss_sim_ros2.core.scene.world_mesh import WorldMesh  # noqa: E402
from gnss_sim_ros2.core.simulation import (  # noqa: E402
    AntennaPath,
    crop_world_mesh,
    run_simulation,
    setup_from_config,
)
from gnss_sim_ros2.core.time import GnssTime  # noqa: E402
from gnss_sim_ros2.core.trajectory import demo_trajectory  # noqa: E402
from gnss_sim_ros2.core.visibility import load_scene  # noqa: E402

START = GnssTime.from_iso(DEMO_START)


def line(name, with_skip, without, unit="s"):
    print(f"  {name:58s} {without:9.4f} {unit} -> {with_skip:9.4f} {unit}   x{without / with_skip:6.2f}")


def city(n_side=200, pitch_m=20.0):
    """n_side^2 boxes (12 triangles each) on a grid centred on the origin, heights 6-30 m."""
    rng = np.random.default_rng(0)
    cx, cy = np.meshgrid((np.arange(n_side) - n_side / 2 + 0.5) * pitch_m,
                         (np.arange(n_side) - n_side / 2 + 0.5) * pitch_m, indexing="ij")
    cx, cy = cx.ravel(), cy.ravel()
    keep = np.hypot(cx, cy) > 40.0                       # an open square for the robot
    cx, cy = cx[keep], cy[keep]
    h = rng.uniform(6.0, 30.0, cx.size)
    half = 0.35 * pitch_m
    corners = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0], [-1, -1, 1], [1, -1, 1], [1, 1, 1],
                        [-1, 1, 1]], dtype=float)
    faces = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4], [1, 2, 6], [1, 6, 5],
                      [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
    v = np.empty((cx.size, 8, 3))
    v[..., 0] = cx[:, None] + half * corners[:, 0]
    v[..., 1] = cy[:, None] + half * corners[:, 1]
    v[..., 2] = h[:, None] * corners[:, 2]
    f = (faces[None, :, :] + 8 * np.arange(cx.size)[:, None, None]).reshape(-1, 3)
    base = load_scene(str(demo_world_path())).world      # for its geodetic origin and material table
    return WorldMesh(v.reshape(-1, 3), f, np.zeros(len(f), dtype=np.int16), MaterialTable(),
                     base.spherical_coordinates)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--epochs", type=int, default=300)
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args()
    n, rep = a.epochs, a.repeats
    work = Path(tempfile.mkdtemp(prefix="gnss_sim_skips_"))
    provider, _ = open_ephemeris("synthetic", START, float(n), "GRECJI", workdir=work / "eph")
    scene = load_scene(str(demo_world_path()))
    path = AntennaPath(demo_trajectory(loop=True), scene)
    t_rel = np.arange(n, dtype=float)
    ecef, world = path.at_many(t_rel)
    svs = np.asarray(provider.svs("GRECJI"))
    tt = START + t_rel
    st = provider.states_at(np.tile(svs, n), GnssTime(np.repeat(tt.sec, len(svs)), np.repeat(tt.frac, len(svs))))
    sat = st.pos_ecef_m.reshape(n, len(svs), 3)        # synthetic: every satellite has a record
    _, el, _ = az_el_from_ecef(ecef[:, None, :], sat)
    print(f"demo scenario: {n} epochs at 1 s, {len(svs)} satellites, {np.mean(el > 10):.0%} above the 10 deg "
          f"mask, {np.mean(el > 0):.0%} above the horizon; best of {rep}\n")
    print(f"  {'skip':58s} {'without':>11s}    {'with':>11s}   gain")

    # 1. foliage
    w = scene.world
    opaque = w.material == w.materials.index("opaque")
    bare = Scene(dataclasses.replace(w, triangles=w.triangles[opaque], material=w.material[opaque], parts=[]))
    t_fol = best_s(lambda: scene.visibility_ecef(world, sat, mask_deg=10.0), rep)
    t_bare = best_s(lambda: bare.visibility_ecef(world, sat, mask_deg=10.0), rep)
    t_touch = best_s(lambda: scene.visibility_ecef(world, sat, mask_deg=10.0, foliage="touch"), rep)
    print(f"1. foliage ({w.class_counts()})")
    line("scene without foliage: occlusion test only", t_bare, t_fol)
    line("foliage 'touch' (any-hit) instead of 'path' (multi-hit)", t_touch, t_fol)

    # 2. below the horizon / mask
    t_all = best_s(lambda: scene.visibility_ecef(world, sat, mask_deg=-90.0), rep)
    print("2. satellites below the mask / horizon")
    line("raycast only above the 10 deg mask (vs every satellite)", t_fol, t_all)
    cfg = ReceiverConfig(systems="GRECJI")
    per_epoch = [st.select(np.arange(k * len(svs), (k + 1) * len(svs))) for k in range(n)]
    above = [s.select(el[k] > -1.0) for k, s in enumerate(per_epoch)]

    def feed(states):
        rx = Receiver(cfg, provider, getattr(provider, "iono", None))
        for k in range(n):
            rx.epoch(tt[k], ecef[k], states[k])

    line("receiver fed satellites above the horizon (vs all)", best_s(lambda: feed(above), rep),
         best_s(lambda: feed(per_epoch), rep))

    # 3. systems
    def chain(systems):
        rx = Receiver(ReceiverConfig(systems=systems), provider, getattr(provider, "iono", None))
        for k in range(n):
            rx.epoch(tt[k], ecef[k], provider.states(tt[k], systems=systems))

    print("3. systems not tracked")
    line("GPS+Galileo only (vs GRECJI): states + receiver", best_s(lambda: chain("GE"), rep),
         best_s(lambda: chain("GRECJI"), rep))

    # 4. ephemeris span
    from gnss_sim_ros2.core.ephemeris.broadcast import BroadcastEphemeris

    opec = shared_data_dir() / "opec-2022-001"
    if opec.is_dir():
        files = [str(opec / f"OPEC00NOR_S_20220010000_01D_{s}N.rnx") for s in "GECR"]
        t0 = GnssTime.from_iso("2022-01-01T00:00:00")
        label = "OPEC daily GECR navigation files"
    else:
        files = [str(next((work / "eph").glob("*.rnx")))]
        t0 = START
        label = "synthetic navigation file"
    lo, hi = t0 - 4 * 3600.0, t0 + 3600.0 + 4 * 3600.0
    big = BroadcastEphemeris.from_files(files)
    small = BroadcastEphemeris.from_files(files, start=lo, end=hi)
    print(f"4. ephemeris span ({label}: {big.n_kep + len(big.glonass_rec['toe_sec'])} records, "
          f"{small.n_kep + len(small.glonass_rec['toe_sec'])} kept for 1 h + 4 h margins)")
    line("read for the span only (vs the whole file)", best_s(lambda: BroadcastEphemeris.from_files(
        files, start=lo, end=hi), rep), best_s(lambda: BroadcastEphemeris.from_files(files), rep))
    grid = t0 + np.arange(0.0, 3600.0, 1.0)

    def evaluate(p):
        for k in range(0, 3600, 10):
            p.states(grid[k])

    line("360 epochs of states from the span's records (vs all)", best_s(lambda: evaluate(small), rep),
         best_s(lambda: evaluate(big), rep))

    # 5. mesh crop
    c = city()
    a_world = demo_trajectory(loop=True).pos
    def build_and_query(mesh):
        sc = Scene(mesh)                  # Open3D builds its BVH at the first query: time both
        sc.visibility_ecef(world[:1], sat[:1], mask_deg=10.0)
        return sc

    t_build_full = best_s(lambda: build_and_query(c), rep)
    t_build_cut = best_s(lambda: build_and_query(crop_world_mesh(c, a_world, 10.0, 0.2)[0]), rep)
    cropped, dropped = crop_world_mesh(c, a_world, 10.0, 0.2)
    full, cut = Scene(c), Scene(cropped)
    print(f"5. mesh crop: city of {len(c.triangles)} triangles, {dropped} dropped "
          f"({len(cropped.triangles)} kept) for the demo path and a 10 deg mask")
    line("scene build + first query (crop included)", t_build_cut, t_build_full)
    tf = best_s(lambda: full.visibility_ecef(world, sat, mask_deg=10.0), rep)
    tc = best_s(lambda: cut.visibility_ecef(world, sat, mask_deg=10.0), rep)
    line(f"visibility of {n} epochs", tc, tf)
    same = np.array_equal(full.visibility_ecef(world, sat, mask_deg=10.0).state,
                          cut.visibility_ecef(world, sat, mask_deg=10.0).state)
    print(f"     same visibility states with and without the crop: {same}")

    # 6. batched epochs
    setup = setup_from_config(load_config(), work / "run", demo_trajectory(loop=True), start=START,
                              duration_s=float(n - 1), interval_s=1.0, scene=scene,
                              ephemeris={"synthetic": (provider, [])}).with_params(preset="balanced")
    print("6. batched precomputation in run_simulation (balanced preset)")
    t_b = min(run_simulation(setup).wall_s for _ in range(rep))
    t_1 = min(run_simulation(dataclasses.replace(setup, batch_epochs=1)).wall_s for _ in range(rep))
    line(f"{n} epochs in blocks of 300 (vs one by one)", t_b, t_1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
