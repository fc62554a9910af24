"""Benchmark of the visibility core: satellite-rays per second.

For the demo world (worlds/courtyard.sdf) and a generated ~250,000-triangle city (boxes + tree crowns),
times Scene.visibility (M antenna epochs x N satellites per call, local ENU directions rotated to the
world frame, mask, states) for
  * the LOS query   (the same scene with foliage made opaque -> only test_occlusions), and
  * the foliage query (opaque test_occlusions + foliage test_occlusions + list_intersections on the
    rays that touch foliage),
next to Open3D's raw test_occlusions on exactly the same rays (float32 tensor prepared beforehand).

    .venv/bin/python bench/bench_visibility.py [--epochs 2000] [--sats 40] [--repeat 3]
"""
from __future__ import annotations

import argparse
import copy
import time
from pathlib import Path

import numpy as np

from gnss_sim_ros2.core.scene.sdf_world import (
    MaterialClass,
    MaterialTable,
    SphericalCoordinates,
    WorldMesh,
    load_sdf_world,
)
from gnss_sim_ros2.core.scene.visibility import Scene

REPO = Path(__file__).resolve().parents[1]


def synthetic_city(n_boxes=15_000, n_trees=875, seed=1) -> WorldMesh:
    """Blocks of boxes on a 2 km grid with streets, plus icosphere tree crowns: ~250k triangles."""
    import trimesh

    rng = np.random.default_rng(seed)
    box = trimesh.creation.box(extents=(1, 1, 1))
    bv, bf = np.asarray(box.vertices), np.asarray(box.faces)
    side = int(np.ceil(np.sqrt(n_boxes)))
    pitch = 2000.0 / side
    ij = np.array([(i, j) for i in range(side) for j in range(side)][:n_boxes], float)
    centers = (ij + 0.5) * pitch - 1000.0
    size = np.c_[rng.uniform(0.4, 0.8, (n_boxes, 2)) * pitch, rng.uniform(5, 40, n_boxes)]
    verts = [(bv[None] * size[:, None, :] + np.c_[centers, size[:, 2] / 2][:, None, :]).reshape(-1, 3)]
    faces = [(bf[None] + 8 * np.arange(n_boxes)[:, None, None]).reshape(-1, 3)]
    mats = [np.zeros(len(faces[0]), np.int16)]
    crown = trimesh.creation.icosphere(subdivisions=1, radius=1.0)
    cv, cf = np.asarray(crown.vertices), np.asarray(crown.faces)
    # trees on the street corners (between blocks)
    tij = rng.integers(0, side, (n_trees, 2)).astype(float)
    tc = np.c_[tij * pitch - 1000.0, np.full(n_trees, 6.0)]
    r = rng.uniform(2.0, 4.0, n_trees)
    off = 8 * n_boxes
    verts.append((cv[None] * r[:, None, None] + tc[:, None, :]).reshape(-1, 3))
    faces.append((cf[None] + off + len(cv) * np.arange(n_trees)[:, None, None]).reshape(-1, 3))
    mats.append(np.ones(n_trees * len(cf), np.int16))
    return WorldMesh(np.vstack(verts), np.vstack(faces), np.concatenate(mats), MaterialTable(),
                     SphericalCoordinates(50.0764, 14.4179, 250.0, 0.0), [], "synthetic city"), pitch


def opaque_copy(world: WorldMesh) -> WorldMesh:
    w = copy.copy(world)
    w.materials = MaterialTable(classes=[MaterialClass(c.name, None) for c in world.materials.classes])
    return w


def timeit(fn, repeat):
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def run_case(name, world, antennas, n_sats, repeat, rng):
    m = len(antennas)
    az = rng.uniform(0, 360, (m, n_sats))
    el = rng.uniform(10, 85, (m, n_sats))
    full = Scene(world)
    los = Scene(opaque_copy(world))
    n_rays = m * n_sats
    # the exact rays our query casts (world frame, shifted by the scene centre), for the raw Open3D figure
    R = los.world_from_local_enu(antennas)
    from gnss_sim_ros2.core import frames

    d = np.einsum("mij,mnj->mni", R, frames.enu_unit_from_az_el(az, el)).reshape(-1, 3)
    o = np.repeat(antennas, n_sats, axis=0)
    rays = los.rays._rays(o, d)
    raw_los = timeit(lambda: los.rays._opaque.test_occlusions(rays), repeat)
    raw_full = timeit(lambda: full.rays._opaque.test_occlusions(rays), repeat)
    t_los = timeit(lambda: los.visibility(antennas, az_deg=az, el_deg=el, mask_deg=5.0), repeat)
    t_full = timeit(lambda: full.visibility(antennas, az_deg=az, el_deg=el, mask_deg=5.0), repeat)
    res = full.visibility(antennas, az_deg=az, el_deg=el, mask_deg=5.0)
    frac_att = float(np.mean(res.state == 2))
    frac_blk = float(np.mean(res.state == 1))
    print(f"\n{name}: {len(world.triangles):,} triangles ({world.class_counts()}), {m} epochs x {n_sats} satellites "
          f"= {n_rays:,} satellite-rays per call; blocked {frac_blk:.0%}, attenuated {frac_att:.1%}")
    print(f"  raw Open3D test_occlusions, all-opaque scene : {n_rays / raw_los / 1e6:7.2f} M rays/s")
    print(f"  Scene.visibility LOS query (no foliage)      : {n_rays / t_los / 1e6:7.2f} M rays/s "
          f"({raw_los / t_los:.0%} of raw)")
    print(f"  raw Open3D test_occlusions, opaque part      : {n_rays / raw_full / 1e6:7.2f} M rays/s")
    print(f"  Scene.visibility foliage query               : {n_rays / t_full / 1e6:7.2f} M rays/s "
          f"({raw_full / t_full:.0%} of raw)")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--epochs", type=int, default=2000)
    ap.add_argument("--sats", type=int, default=40)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    rng = np.random.default_rng(7)
    demo = load_sdf_world(REPO / "worlds" / "courtyard.sdf")
    # antenna path from open ground through the gate into the courtyard
    t = np.linspace(0, 1, args.epochs)
    ants = np.c_[np.interp(t, [0, 0.5, 1], [0, 0, -8.5]), np.interp(t, [0, 0.5, 1], [-70, 0, 5]), np.full_like(t, 1.0)]
    run_case("demo world (courtyard.sdf)", demo, ants, args.sats, args.repeat, rng)
    city, pitch = synthetic_city()
    # antennas in the streets (on block corners, between buildings), 1.5 m up
    k = rng.integers(1, int(2000 / pitch) - 1, (args.epochs, 2))
    ants = np.c_[k * pitch - 1000.0 + rng.uniform(-0.1, 0.1, (args.epochs, 2)) * pitch, np.full(args.epochs, 1.5)]
    run_case("synthetic city", city, ants, args.sats, args.repeat, rng)


if __name__ == "__main__":
    main()
