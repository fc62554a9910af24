"""Small scenes for the multipath tests (imported by test_multipath_* and test_urban_*)."""
from __future__ import annotations

import numpy as np

from gnss_sim_ros2.core.scene.georeference import SphericalCoordinates
from gnss_sim_ros2.core.scene.materials import MaterialTable
from gnss_sim_ros2.core.scene.visibility import Scene
from gnss_sim_ros2.core.scene.world_mesh import WorldMesh


def _box(x0, x1, y0, y1, z0, z1):
    v = np.array([[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)], dtype=float)
    f = [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],
         [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]
    return v, np.array(f)


def canyon_scene(shift_x_m: float = 0.0, walls: bool = True, latitude_deg: float | None = None,
                 longitude_deg: float = 114.1788):
    """West wall face at x = -5 (20 m high), east wall face at x = +10 (10 m high), ground z = 0 (600 m square).

    ``shift_x_m``: both walls moved along x (the ground stays); ``walls=False``: the ground alone (an open
    field); ``latitude_deg``: georeferenced there (world origin on the ellipsoid), else no geodetic origin."""
    parts = [_box(-6.0 + shift_x_m, -5.0 + shift_x_m, -200, 200, 0, 20),
             _box(10.0 + shift_x_m, 11.0 + shift_x_m, -200, 200, 0, 10)] if walls else []
    verts, tris = [], []
    for v, f in parts:
        tris.append(f + sum(len(p) for p in verts))
        verts.append(v)
    g = np.array([[-300, -300, 0], [300, -300, 0], [300, 300, 0], [-300, 300, 0]], float)
    tris.append(np.array([[0, 1, 2], [0, 2, 3]]) + sum(len(p) for p in verts))
    verts.append(g)
    v, t = np.vstack(verts), np.vstack(tris)
    world = WorldMesh(v, t, np.zeros(len(t), np.int16), MaterialTable())
    if latitude_deg is not None:
        world = WorldMesh(v, t, world.material, world.materials,
                          spherical_coordinates=SphericalCoordinates(latitude_deg, longitude_deg, 0.0))
    return Scene(world)


def write_canyon_mesh(folder, latitude_deg: float = 22.2982, longitude_deg: float = 114.1788):
    """The canyon of :func:`canyon_scene`, georeferenced, as an exported mesh (PLY + sidecar) that the
    visibility node and ``gnss-sim simulate`` load (parameter mesh_file); returns the PLY path."""
    import dataclasses
    from pathlib import Path

    from gnss_sim_ros2.core.scene.mesh_io import write_scene

    world = dataclasses.replace(canyon_scene().world,
                                spherical_coordinates=SphericalCoordinates(latitude_deg, longitude_deg, 0.0))
    path = Path(folder) / "canyon.ply"
    write_scene(path, world)
    return path
