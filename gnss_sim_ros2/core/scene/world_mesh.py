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


def world_bounds_xy(scene):
    """(xmin, ymin, xmax, ymax) of the scene's vertices [m], or None (a sky mask)."""
    world = getattr(scene, "world", None)
    if world is None or len(world.vertices_m) == 0:
        return None
    v = world.vertices_m[np.all(np.isfinite(world.vertices_m), axis=1)]
    return float(v[:, 0].min()), float(v[:, 1].min()), float(v[:, 0].max()), float(v[:, 1].max())
