"""Georeference of a Gazebo world: ``<spherical_coordinates>``.

``latitude_deg``, ``longitude_deg``, ``elevation`` (WGS 84 ellipsoidal height [m]) and
``heading_deg`` place the Gazebo world frame.  Only ``world_frame_orientation`` ENU (the default)
and ``surface_model`` EARTH_WGS84 are accepted.

Heading convention, as gz-math ``SphericalCoordinates`` implements it (the ECEF -> LOCAL transform
used by gz-sim's NavSat sensor): with h = heading_deg, ``world_xy = Rz(-h) enu_xy``, i.e.
``enu = Rz(+h) world``.  The world +x axis points h degrees counter-clockwise from east (compass
azimuth 90 - h); heading_deg = 90 makes world +x point north and +y west.  z is up at the origin.
The world frame is a flat (tangent-plane) frame: away from the origin geodetic up tilts away from
world z (about 0.9 deg at 100 km), which the visibility code accounts for.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import frames
from ..memo import read_only
from .sdf_xml import SdfError, child, floats, where


def _rz(angle_rad: float) -> np.ndarray:
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass
class SphericalCoordinates:
    """Geodetic origin of the Gazebo world frame (see the module docstring for the heading)."""

    latitude_deg: float
    longitude_deg: float
    elevation_m: float = 0.0
    heading_deg: float = 0.0
    surface_model: str = "EARTH_WGS84"

    def rotation_enu0_from_world(self) -> np.ndarray:
        """3x3: ENU at the origin = R @ world (gz-math: enu = Rz(+heading) world)."""
        return _rz(math.radians(self.heading_deg))

    def rotation_world_from_ecef(self) -> np.ndarray:
        """3x3: world vector = R @ ECEF vector."""
        return self.rotation_enu0_from_world().T @ frames.enu_rotation(self.latitude_deg, self.longitude_deg)

    def _terms(self):
        """(Rz(heading).T, ENU rotation at the origin, origin ECEF [m], rotation_world_from_ecef().T) of the present
        field values, computed once per value and read-only (world_to_ecef and the cast's frames run every epoch;
        the same products in the same order as frames.enu_to_ecef and rotation_world_from_ecef)."""
        key = (self.latitude_deg, self.longitude_deg, self.elevation_m, self.heading_deg)
        cached = self.__dict__.get("_kept_terms")
        if cached is None or cached[0] != key:
            heading_t = self.rotation_enu0_from_world().T
            enu_rot = frames.enu_rotation(self.latitude_deg, self.longitude_deg)
            origin = np.array(frames.geodetic_to_ecef(self.latitude_deg, self.longitude_deg, self.elevation_m))
            terms = read_only((heading_t, enu_rot, origin, (heading_t @ enu_rot).T))
            cached = self.__dict__["_kept_terms"] = (key, *terms)
        return cached[1:]

    def world_from_ecef_t(self) -> np.ndarray:
        """rotation_world_from_ecef().T (read-only, kept per field values): ECEF vectors (..., 3) @ it -> world."""
        return self._terms()[3]

    def world_to_ecef(self, pos_world_m) -> np.ndarray:
        """World points [..., 3] -> ECEF [..., 3] (float64)."""
        heading_t, enu_rot, origin, _ = self._terms()
        enu = np.asarray(pos_world_m, dtype=np.float64) @ heading_t
        return enu @ enu_rot + origin

    def ecef_to_world(self, pos_ecef_m) -> np.ndarray:
        """ECEF points [..., 3] -> world [..., 3] (float64)."""
        enu = frames.ecef_to_enu(pos_ecef_m, self.latitude_deg, self.longitude_deg, self.elevation_m)
        return enu @ self.rotation_enu0_from_world()

    def to_dict(self) -> dict:
        return {"latitude_deg": float(self.latitude_deg), "longitude_deg": float(self.longitude_deg),
                "elevation_m": float(self.elevation_m), "heading_deg": float(self.heading_deg),
                "surface_model": self.surface_model}

    @classmethod
    def from_dict(cls, d: dict, where: str = "spherical_coordinates") -> SphericalCoordinates:
        try:
            return cls(float(d["latitude_deg"]), float(d["longitude_deg"]), float(d.get("elevation_m", 0.0)),
                       float(d.get("heading_deg", 0.0)), str(d.get("surface_model", "EARTH_WGS84")))
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{where}: needs numeric latitude_deg, longitude_deg[, elevation_m, heading_deg]: "
                             f"{exc}") from exc


def spherical_from_sdf(world_el, file) -> SphericalCoordinates | None:
    """``<spherical_coordinates>`` of a ``<world>`` element (None when absent)."""
    sc = child(world_el, "spherical_coordinates")
    if sc is None:
        return None
    orient = child(sc, "world_frame_orientation")
    if orient is not None and (orient.text or "").strip().upper() not in ("", "ENU"):
        raise SdfError(f"{where(orient, file)}: world_frame_orientation {orient.text.strip()!r} is not supported "
                       f"(only ENU)")
    surf = child(sc, "surface_model")
    surface = (surf.text or "EARTH_WGS84").strip() if surf is not None else "EARTH_WGS84"
    if surface != "EARTH_WGS84":
        raise SdfError(f"{where(surf, file)}: surface_model {surface!r} is not supported (only EARTH_WGS84)")

    def val(tag, default=0.0):
        c = child(sc, tag)
        return floats(c, file, 1)[0] if c is not None else default

    lat = val("latitude_deg")
    if not -90.0 <= lat <= 90.0:
        raise SdfError(f"{where(sc, file)}: latitude_deg {lat} outside [-90, 90]")
    lon, h = val("longitude_deg"), val("elevation")      # longitude 400 or an origin 1e9 m up were taken
    try:
        frames.check_receiver_position([lat, lon, h], "geodetic", where(sc, file))
    except ValueError as exc:
        raise SdfError(str(exc)) from None
    return SphericalCoordinates(lat, lon, h, val("heading_deg"), surface)


def spherical_of_world_file(sdf_path) -> SphericalCoordinates | None:
    """``<spherical_coordinates>`` of an SDF world file, without loading its geometry (None when absent)."""
    from pathlib import Path

    from .sdf_xml import parse_xml

    world = child(parse_xml(Path(sdf_path)), "world")
    return spherical_from_sdf(world, sdf_path) if world is not None else None
