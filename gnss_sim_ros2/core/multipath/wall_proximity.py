"""Which antennas have walls within reach: the one test multipath mode ``auto`` pays where a scene has none.

A wall is an opaque facet of the world mesh that is not horizontal (|n_z| <= GROUND_NZ, the threshold
reflections.Facets uses to call a facet ground): facades, fences, slanted roofs.  The ground alone does not
ask for the reflection model: open-sky multipath (ground and antenna surroundings) is the receiver's own
statistical code multipath (receiver/code_multipath.py).  An antenna has walls within ``range_m`` when one
wall triangle's bounding sphere (centroid, farthest vertex) and its plane both come that close -- the tests
``Facets.near`` applies, so where this one says no, ``find_paths`` would find no wall facet either (both are
necessary conditions: a triangle they pass may still lie a little farther).

Built once per scene (numpy over the triangles, no per-triangle Python loop), kept on the Scene object; per
call a KD-tree query of the antennas against the wall centroids (scipy cKDTree): an antenna whose nearest
centroid lies within ``range_m`` is near, one farther than ``range_m`` + the largest radius is not, and only
those in between are tested against every wall.  A scene without walls (an open field, a sky mask) answers
without any arithmetic.  Cost: bench/bench_multipath.py ``--auto`` (docs/BENCHMARKS.md).
"""
from __future__ import annotations

import numpy as np

#: facets whose unit normal has |z| above this are ground or flat roofs (reflections.Facets' ground class)
GROUND_NZ = 0.9

_ATTR = "_multipath_walls"


class WallProximity:
    """Centroids and bounding radii of a world's wall triangles; :meth:`near` per antenna."""

    def __init__(self, world):
        v = np.asarray(world.vertices_m, dtype=np.float64)
        tri = np.asarray(world.triangles, dtype=np.int64).reshape(-1, 3)
        mat = np.asarray(world.material, dtype=np.int64)
        opaque = np.array([c.opaque for c in world.materials.classes], dtype=bool)
        tri = tri[opaque[mat]] if len(mat) else tri[:0]
        p = v[tri]                                                        # (T, 3, 3)
        n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        norm = np.linalg.norm(n, axis=1)
        wall = (norm > 1e-9) & (np.abs(n[:, 2]) <= GROUND_NZ * np.maximum(norm, 1e-300))
        p = p[wall]
        self.centroid_m = p.mean(axis=1)
        self.radius_m = (np.max(np.linalg.norm(p - self.centroid_m[:, None], axis=2), axis=1) if len(p)
                         else np.zeros(0))
        self.max_radius_m = float(self.radius_m.max()) if len(p) else 0.0
        self.normal = n[wall] / norm[wall][:, None]
        self.offset_m = np.einsum("ij,ij->i", self.normal, p[:, 0]) if len(p) else np.zeros(0)
        self._tree = None

    def __len__(self) -> int:
        return len(self.centroid_m)

    def near(self, antenna_world_m, range_m: float) -> np.ndarray:
        """(M,) bool: does a wall triangle come within ``range_m`` of each antenna (M, 3) (or (3,))?"""
        a = np.asarray(antenna_world_m, dtype=np.float64).reshape(-1, 3)
        out = np.zeros(len(a), dtype=bool)
        if len(self) == 0 or len(a) == 0:
            return out
        if self._tree is None:
            from scipy.spatial import cKDTree  # scipy: imported only where a scene has walls

            self._tree = cKDTree(self.centroid_m)
        d_nearest, _ = self._tree.query(a, k=1)
        out[d_nearest <= range_m] = True
        unsure = np.flatnonzero((d_nearest > range_m) & (d_nearest - self.max_radius_m <= range_m))
        for i in unsure:
            sphere = np.linalg.norm(self.centroid_m - a[i], axis=1) - self.radius_m <= range_m
            plane = np.abs(self.normal @ a[i] - self.offset_m) <= range_m
            out[i] = bool(np.any(sphere & plane))
        return out


def walls_of(scene) -> WallProximity | None:
    """The scene's WallProximity (built once, kept on the scene); None for a scene without a world mesh
    (a sky mask)."""
    w = scene.__dict__.get(_ATTR)
    if w is None:
        world = getattr(scene, "world", None)
        if world is None:
            return None
        w = WallProximity(world)
        setattr(scene, _ATTR, w)
    return w


def antennas_near_walls(scene, antenna_world_m, range_m: float) -> np.ndarray:
    """(M,) bool for antennas (M, 3) or (3,): walls of ``scene`` within ``range_m`` (module doc)."""
    w = walls_of(scene)
    if w is None:
        return np.zeros(np.asarray(antenna_world_m).reshape(-1, 3).shape[0], dtype=bool)
    return w.near(antenna_world_m, range_m)
