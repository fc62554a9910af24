"""A known georeference error applied explicitly: the visibility parameter ``world_offset_enu_m``.

The world (its buildings and its world frame) is moved by (east, north, up) [m] in the local ENU of its origin
against the Earth: its ``spherical_coordinates`` origin moves there (heading kept).  What is placed in ECEF or
geodetic coordinates (a static antenna, a geodetic or ECEF trajectory, a real drive's truth) then sits at its
world position minus the offset; what is placed in the world frame (world-frame trajectories, waypoints) moves
with the world.  ``gnss-sim compare --fit-offset`` (core/comparison/registration.py) reports the offset to add to
the antenna's placement in the world, (e, n): it is applied as ``world_offset_enu_m: [-e, -n, 0]``.

Never applied silently: the visibility node logs it and ``gnss-sim simulate`` prints it when it is not zero.
"""
from __future__ import annotations

import copy

import numpy as np

from .. import frames
from ..scene.georeference import SphericalCoordinates


def offset_note(offset_enu_m) -> str:
    """The line a front end prints or logs for a non-zero offset."""
    e, n, u = (float(v) for v in offset_enu_m)
    return (f"world_offset_enu_m = [{e:+.2f}, {n:+.2f}, {u:+.2f}] m: the world's georeference is moved by "
            f"{np.hypot(e, n):.2f} m horizontally and {u:+.2f} m up (a registration applied on purpose)")


def is_zero(offset_enu_m) -> bool:
    return len(offset_enu_m) == 0 or not np.any(np.asarray(offset_enu_m, dtype=np.float64))


def shifted_scene(scene, offset_enu_m, where: str = "parameter 'world_offset_enu_m'"):
    """``scene`` with its georeference moved by ``offset_enu_m`` (module docstring): a shallow copy (a scene
    shared with other robots is left as it is); ``scene`` itself for a zero or empty offset."""
    if scene is None or is_zero(offset_enu_m):
        return scene
    sc = getattr(scene, "spherical", None)
    if sc is None:
        raise ValueError(f"{where}: the scene has no spherical_coordinates (no georeference) to move")
    d = np.asarray(offset_enu_m, dtype=np.float64).reshape(3)
    origin = frames.enu_to_ecef(d, sc.latitude_deg, sc.longitude_deg, sc.elevation_m)
    lat, lon, h = frames.ecef_to_geodetic(*np.asarray(origin, dtype=np.float64).reshape(3))
    out = copy.copy(scene)
    out.spherical = SphericalCoordinates(float(lat), float(lon), float(h), sc.heading_deg, sc.surface_model)
    return out
