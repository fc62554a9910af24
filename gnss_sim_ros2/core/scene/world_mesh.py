"""The loaded scene: triangles in the Gazebo world frame with a material class per triangle."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .georeference import SphericalCoordinates
from .materials import MaterialTable


@dataclass
class WorldMesh:
    """Triangles of a world in the Gazebo world frame [m] with a material class per triangle."""

    vertices_m: np.ndarray            # (V, 3) float64, world frame
    triangles: np.ndarray             # (T, 3) int64
    material: np.ndarray              # (T,) int16 index into materials.classes
    materials: MaterialTable
    spherical_coordinates: SphericalCoordinates | None = None
    parts: list[dict] = field(default_factory=list)   # {name, class, triangles}
    source: str = ""
    report: dict = field(default_factory=dict)        # scene report of the loader (scene_report.py)

    def class_counts(self) -> dict[str, int]:
        counts = np.bincount(self.material.astype(np.int64), minlength=len(self.materials.classes))
        return {c.name: int(n) for c, n in zip(self.materials.classes, counts)}


#: how far from its origin a world's geometry may lie [m]: the world frame is east, north, up at the origin; 1000 km
#: away the Earth's surface is d**2 / 2R = 78 km below that plane (R = 6371 km), no longer a local scene
WORLD_EXTENT_M = 1.0e6


def check_world_extent(vertices_m: np.ndarray, where: str) -> None:
    """ValueError naming ``where`` for a vertex that is not finite or lies beyond WORLD_EXTENT_M of the origin (a
    mesh with NaN vertices, or a model posed 1e12 m away, was loaded without a word)."""
    v = np.asarray(vertices_m, dtype=np.float64).reshape(-1, 3)
    bad = ~np.all(np.isfinite(v), axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"{where}: vertex {i + 1} is {v[i].tolist()}: a vertex needs 3 finite coordinates [m]")
    far = np.max(np.abs(v), axis=1) > WORLD_EXTENT_M if len(v) else np.zeros(0, bool)
    if far.any():
        i = int(np.argmax(far))
        raise ValueError(f"{where}: vertex {i + 1} at {', '.join(f'{c:.6g}' for c in v[i])} m lies more than "
                         f"{WORLD_EXTENT_M / 1e3:.0f} km from the world's origin: a world is a local scene "
                         f"(east, north, up at its spherical_coordinates)")


def world_bounds_xy(scene):
    """(xmin, ymin, xmax, ymax) of the scene's vertices [m], or None (a sky mask)."""
    world = getattr(scene, "world", None)
    if world is None or len(world.vertices_m) == 0:
        return None
    v = world.vertices_m[np.all(np.isfinite(world.vertices_m), axis=1)]
    return float(v[:, 0].min()), float(v[:, 1].min()), float(v[:, 0].max()), float(v[:, 1].max())
