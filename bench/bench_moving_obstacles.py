"""Cost of moving obstacles and of robots as a batch axis in the visibility cast (printed figures).

On the demo world (worlds/courtyard.sdf), one antenna in the courtyard and ``--sats`` satellites above the mask:
  * per epoch, the static cast alone and with 1, 4, 16, 64 moving boxes (VisibilityOptions.cast(...,
    obstacles=): the slab test in numpy, core/visibility/moving_obstacles.py), and the alternative it was
    measured against: a small Open3D RaycastingScene of only the boxes built every epoch and cast (the
    static BVH is never rebuilt either way);
  * R = 1, 4, 32 robots (each body a box, each antenna seeing the others' bodies): one batched cast of the
    R antennas against R separate casts.
Times are the median / best of ``--repeat`` runs (wall clock, one process; Open3D uses every core), with the
load average printed beside them: on a shared machine the median moves with the load, the best much less.
"slab" is the obstacles' own part of the cast (block_by_obstacles: directions, cull, slab test, states).

    .venv/bin/python bench/bench_moving_obstacles.py [--sats 40] [--repeat 200]
"""
from __future__ import annotations

import argparse
import copy
import os
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from gnss_sim_ros2.benchmarks.timing import median_best_ms as timed_ms  # noqa: E402
from gnss_sim_ros2.core import frames  # noqa: E402
from gnss_sim_ros2.core.multipath.scene_paths import world_directions  # noqa: E402
from gnss_sim_ros2.core.scene.demo_world import demo_world_path  # noqa: E402
from gnss_sim_ros2.core.visibility import VisibilityOptions, load_scene  # noqa: E402
from gnss_sim_ros2.core.visibility.moving_obstacles import (  # noqa: E402
    MovingBoxes,
    block_by_obstacles,
    fleet_bodies,
    yaw_rotations,
)

ANTENNA_WORLD_M = np.array([0.0, 0.0, 1.5])
BOX_SIZE_M = np.array([4.5, 1.8, 1.5])


def fmt(t) -> str:
    return f"{t[0]:.3f} / {t[1]:.3f}"


def satellites(scene, n: int, rng) -> np.ndarray:
    rx = scene.antenna_ecef(ANTENNA_WORLD_M)
    lat, lon, _ = frames.ecef_to_geodetic(*rx)
    enu = frames.enu_unit_from_az_el(rng.uniform(0, 360, n), rng.uniform(11, 89, n))
    return rx + 2.0e7 * enu @ frames.enu_rotation(lat, lon)


def open3d_boxes_blocked(center, rot, half, origin, dirs):
    """The measured alternative: a RaycastingScene of the boxes (12 triangles each) built and cast per epoch,
    in a frame centred on the antenna (float32)."""
    import open3d as o3d

    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    tris = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],
                     [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    v = (corners[None] * half[:, None, :]) @ rot.transpose(0, 2, 1) + (center - origin)[:, None, :]
    f = (tris[None] + 8 * np.arange(len(center))[:, None, None]).reshape(-1, 3)
    sc = o3d.t.geometry.RaycastingScene()
    sc.add_triangles(o3d.core.Tensor(v.reshape(-1, 3).astype(np.float32)), o3d.core.Tensor(f.astype(np.uint32)))
    rays = np.zeros((len(dirs), 6), np.float32)
    rays[:, 3:] = dirs
    return sc.test_occlusions(o3d.core.Tensor(rays), tnear=1e-3).numpy()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sats", type=int, default=40)
    ap.add_argument("--repeat", type=int, default=200)
    a = ap.parse_args(argv)
    load0 = os.getloadavg()
    rng = np.random.default_rng(7)
    scene = load_scene(str(demo_world_path()))
    sat = satellites(scene, a.sats, rng)
    opts = VisibilityOptions(mask_deg=10.0)
    print(f"demo world, {a.sats} satellites, median / best of {a.repeat}; ms per epoch")
    static = timed_ms(lambda: opts.cast(scene, ANTENNA_WORLD_M, sat), a.repeat)
    print(f"static cast alone: {fmt(static)}")
    print(f"{'boxes':>6} {'cast with boxes':>16} {'slab part':>16} {'Open3D boxes scene':>19}")
    dirs = world_directions(scene, ANTENNA_WORLD_M, sat)[0]
    _, _, v0 = opts.cast(scene, ANTENNA_WORLD_M, sat)
    state0 = np.where(v0.state < 0, 0, v0.state).astype(np.int64)
    for b in (1, 4, 16, 64):
        base = np.c_[rng.uniform(-15, 15, (b, 2)), np.zeros(b)]
        yaw = rng.uniform(0, 360, b)
        boxes = MovingBoxes.from_bases(base[None], yaw_rotations(yaw)[None], BOX_SIZE_M)
        with_boxes = timed_ms(lambda bx=boxes: opts.cast(scene, ANTENNA_WORLD_M, sat, obstacles=bx), a.repeat)
        slab = timed_ms(lambda bx=boxes: block_by_obstacles(scene, ANTENNA_WORLD_M, sat, copy.copy(v0), state0,
                                                            opts.mask_deg, bx), a.repeat)
        o3d_ms = timed_ms(lambda bx=boxes: open3d_boxes_blocked(bx.center_world_m[0], bx.rot_world_from_box[0],
                                                                bx.half_size_m[0], ANTENNA_WORLD_M, dirs), a.repeat)
        print(f"{b:>6} {fmt(with_boxes):>16} {fmt(slab):>16} {fmt(o3d_ms):>19}")
    print(f"\n{'robots':>6} {'one batched cast':>17} {'R separate casts':>17} {'ratio (best)':>13}")
    for r in (1, 4, 32):
        base = np.c_[rng.uniform(-15, 15, (r, 2)), np.zeros(r)]
        yaw = rng.uniform(0, 360, r)
        ant = base + [0.0, 0.0, 1.0]
        bodies = fleet_bodies(base, yaw, [1.0, 0.7, 0.4])
        rep = max(5, a.repeat // r)
        batched = timed_ms(lambda an=ant, bo=bodies: opts.cast(scene, an, sat, obstacles=bo), rep)
        single = [bodies.rows(slice(i, i + 1)) for i in range(r)]
        separate = timed_ms(lambda an=ant, si=single: [opts.cast(scene, x, sat, obstacles=o) for x, o in zip(an, si)],
                            rep)
        print(f"{r:>6} {fmt(batched):>17} {fmt(separate):>17} {separate[1] / batched[1]:13.1f}")
    print(f"[bench_moving_obstacles] {os.cpu_count()} cores; load average before {load0[0]:.2f}, "
          f"after {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
