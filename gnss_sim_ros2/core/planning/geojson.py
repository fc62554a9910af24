"""The plan's cells as GeoJSON (RFC 7946: WGS 84 longitude, latitude [, ellipsoidal height], counter-clockwise
outer rings), georeferenced through the world's ``spherical_coordinates`` (scene/georeference.py), so a GIS
tool opens them at the right place.  Each cell is a Polygon (its square, at its ground height) with the
per-cell summary as properties."""
from __future__ import annotations

import json

import numpy as np

from .. import frames


def world_to_lonlath(spherical, pos_world_m) -> np.ndarray:
    """World points (..., 3) [m] -> (..., 3) longitude [deg], latitude [deg], ellipsoidal height [m]."""
    ecef = spherical.world_to_ecef(np.asarray(pos_world_m, float))
    lat, lon, h = frames.ecef_to_geodetic(ecef[..., 0], ecef[..., 1], ecef[..., 2])
    return np.stack([lon, lat, h], axis=-1)


def lonlath_to_world(spherical, lonlath) -> np.ndarray:
    """The inverse of :func:`world_to_lonlath`."""
    a = np.asarray(lonlath, float)
    ecef = frames.geodetic_to_ecef(a[..., 1], a[..., 0], a[..., 2])
    return spherical.ecef_to_world(np.stack(ecef, axis=-1) if isinstance(ecef, tuple) else ecef)


def cells_feature_collection(spherical, corners_xy, ground_z_m, properties: dict) -> dict:
    """FeatureCollection of the cells: ``corners_xy`` (C, 5, 2) closed rings in world x, y, at ``ground_z_m``
    (C,); ``properties``: name -> (C,) values (NaN written as null)."""
    if spherical is None:
        raise ValueError("GeoJSON: the world has no spherical_coordinates (geodetic origin): cells cannot be "
                         "placed on the Earth")
    ring = np.concatenate([corners_xy, np.broadcast_to(np.asarray(ground_z_m, float)[:, None, None],
                                                       corners_xy.shape[:2] + (1,))], axis=-1)
    llh = world_to_lonlath(spherical, ring)
    # the world frame's x, y rings are counter-clockwise (area.py) and the heading only rotates them: they stay so
    names = list(properties)
    cols = [np.asarray(properties[n]) for n in names]
    feats = []
    for i in range(len(llh)):
        props = {}
        for n, col in zip(names, cols):
            val = col[i].item() if hasattr(col[i], "item") else col[i]
            props[n] = None if isinstance(val, float) and not np.isfinite(val) else val
        feats.append({"type": "Feature", "geometry": {"type": "Polygon", "coordinates": [
            [[round(float(p[0]), 9), round(float(p[1]), 9), round(float(p[2]), 3)] for p in llh[i]]]},
            "properties": props})
    return {"type": "FeatureCollection", "features": feats}


def write_geojson(path, collection: dict) -> None:
    with open(path, "w") as fh:
        json.dump(collection, fh, separators=(",", ":"))
