"""Benchmark of the visibility core: satellite-rays per second.

For the demo world (worlds/courtyard.sdf) and a generated ~250,000-triangle city (boxes + tree crowns),
times Scene.visibility (M antenna epochs x N satellites per call, local ENU directions rotated to the
world frame, mask, states) for
  * the LOS query   (the same scene with foliage made opaque -> only test_occlusions),
  * the LOS query on a sky with about half of the satellites below the mask (those are never cast:
    rays/s counts the cast rays only, and the raw figure is over those rays),
  * the foliage query (opaque test_occlusions + foliage test_occlusions on the rays that are not blocked +
    list_intersections on the rays that touch foliage) and its foliage="touch" variant (no
    list_intersections),
next to Open3D's raw calls on exactly the same rays (float32 tensors prepared beforehand, same tnear):
  * "raw opaque": test_occlusions on the opaque part only (the issue's yardstick; the foliage query
    necessarily does more than this),
  * "raw foliage pipeline": the same Open3D calls the foliage query makes (opaque test on all rays, foliage
    test on the unblocked rays, list_intersections on the touching rays), each on tensors prepared
    beforehand -- the fair floor of the foliage query.
Raw and our query are timed interleaved, best of --repeat, so machine load hits both alike.

    .venv/bin/python bench/bench_visibility.py [--epochs 2000] [--sats 40] [--repeat 7]
"""
from __future__ import annotations

import argparse
import copy
import inspect
import time
from pathlib import Path

import numpy as np
import open3d as o3d

from gnss_sim_ros2.core.scene.georeference import SphericalCoordinates
from gnss_sim_ros2.core.scene.loader import load_sdf_world
from gnss_sim_ros2.core.scene.materials import MaterialClass, MaterialTable
from gnss_sim_ros2.core.scene.visibility import Scene
from gnss_sim_ros2.core.scene.world_mesh import WorldMesh

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


TNEAR_M = 1e-3   # Scene.visibility's default tnear_m


def timeit_interleaved(fns: dict, repeat: int) -> dict:
    """Best wall time [s] of each function, the functions run in turn ``repeat`` times."""
    best = dict.fromkeys(fns, np.inf)
    for _ in range(repeat):
        for key, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            best[key] = min(best[key], time.perf_counter() - t0)
    return best


def world_rays(scene, antennas, az, el):
    """The float32 ray tensor our query casts (world frame, shifted by the scene centre)."""
    from gnss_sim_ros2.core import frames

    R = scene.world_from_local_enu(antennas)
    d = np.einsum("mij,mnj->mni", R, frames.enu_unit_from_az_el(az, el)).reshape(-1, 3)
    o = np.repeat(antennas, az.shape[1], axis=0)
    return scene.rays._rays(o, d)


def run_case(name, world, antennas, n_sats, repeat, rng, scene_cls=Scene):
    m = len(antennas)
    az = rng.uniform(0, 360, (m, n_sats))
    el = rng.uniform(10, 85, (m, n_sats))
    full = scene_cls(world)
    los = scene_cls(opaque_copy(world))
    n_rays = m * n_sats
    rays = world_rays(los, antennas, az, el)
    # the foliage query's Open3D calls, on tensors prepared beforehand from the same rays
    op, pen = full.rays._opaque, full.rays._pen
    blocked = op.test_occlusions(rays, tnear=TNEAR_M).numpy()
    clear = o3d.core.Tensor(np.ascontiguousarray(rays.numpy()[~blocked]))
    touching = o3d.core.Tensor(np.ascontiguousarray(clear.numpy()[pen.test_occlusions(clear).numpy()]))
    # a sky with about half of the satellites below the 5-degree mask: raw over the cast rays only
    # (own generator: ``rng`` draws exactly what it drew before this case existed)
    el_sky = np.random.default_rng(99).uniform(-85, 85, (m, n_sats))
    cast = el_sky >= 5.0
    rays_sky = o3d.core.Tensor(np.ascontiguousarray(world_rays(los, antennas, az, el_sky).numpy()[cast.ravel()]))
    n_sky = int(cast.sum())

    def raw_pipeline(lists=True):
        op.test_occlusions(rays, tnear=TNEAR_M)
        pen.test_occlusions(clear)
        if lists:
            pen.list_intersections(touching)

    fns = {
        "raw_los": lambda: los.rays._opaque.test_occlusions(rays, tnear=TNEAR_M),
        "los": lambda: los.visibility(antennas, az_deg=az, el_deg=el, mask_deg=5.0),
        "raw_sky": lambda: los.rays._opaque.test_occlusions(rays_sky, tnear=TNEAR_M),
        "sky": lambda: los.visibility(antennas, az_deg=az, el_deg=el_sky, mask_deg=5.0),
        "raw_opaque": lambda: op.test_occlusions(rays, tnear=TNEAR_M),
        "raw_pipeline": raw_pipeline,
        "full": lambda: full.visibility(antennas, az_deg=az, el_deg=el, mask_deg=5.0),
        "raw_touch": lambda: raw_pipeline(lists=False),
        "touch": lambda: full.visibility(antennas, az_deg=az, el_deg=el, mask_deg=5.0, foliage="touch"),
    }
    if "foliage" not in inspect.signature(scene_cls.visibility).parameters:     # an implementation without it
        del fns["raw_touch"], fns["touch"]
    best = timeit_interleaved(fns, repeat)
    res = full.visibility(antennas, az_deg=az, el_deg=el, mask_deg=5.0)
    frac_att = float(np.mean(res.state == 2))
    frac_blk = float(np.mean(res.state == 1))

    def rate(key, n=n_rays):
        return f"{n / best[key] / 1e6:7.2f} M rays/s"

    def pct(key, ref):
        return f"{best[ref] / best[key]:.0%} of {ref.replace('_', ' ')}"

    print(f"\n{name}: {len(world.triangles):,} triangles ({world.class_counts()}), {m} epochs x {n_sats} satellites "
          f"= {n_rays:,} satellite-rays per call; blocked {frac_blk:.0%}, attenuated {frac_att:.1%} "
          f"(unblocked {len(clear.numpy()):,}, touching foliage {len(touching.numpy()):,})")
    print(f"  raw Open3D test_occlusions, all-opaque scene : {rate('raw_los')}")
    print(f"  Scene.visibility LOS query (no foliage)      : {rate('los')} ({pct('los', 'raw_los')})")
    print(f"  raw, all-opaque, {n_sky:,} cast rays of a half-masked sky: {rate('raw_sky', n_sky)}")
    print(f"  Scene.visibility LOS query, half-masked sky  : {rate('sky', n_sky)} per cast ray "
          f"({pct('sky', 'raw_sky')})")
    print(f"  raw Open3D test_occlusions, opaque part      : {rate('raw_opaque')}")
    print(f"  raw Open3D foliage pipeline (same calls)     : {rate('raw_pipeline')}")
    print(f"  Scene.visibility foliage query               : {rate('full')} ({pct('full', 'raw_opaque')}, "
          f"{pct('full', 'raw_pipeline')})")
    if "touch" in best:
        print(f"  raw Open3D touch pipeline (no lists)         : {rate('raw_touch')}")
        print(f"  Scene.visibility foliage='touch' query       : {rate('touch')} ({pct('touch', 'raw_opaque')}, "
              f"{pct('touch', 'raw_touch')})")
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--epochs", type=int, default=2000)
    ap.add_argument("--sats", type=int, default=40)
    ap.add_argument("--repeat", type=int, default=7)
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
