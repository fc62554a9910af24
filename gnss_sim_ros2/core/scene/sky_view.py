"""The sky view picture of the visibility node's ``sky_view`` topic: a polar sky plot as an RGB raster.

North up, zenith at the centre, horizon at the rim (radius = 90 - elevation); the scene as the casts over the
whole sky find it (``Scene.sky_grid``: blocked sky grey, foliage pale green, open sky under an overhang white),
outside the horizon dark; satellites as squares coloured by their line-of-sight state (VisibilityState: green
visible, red blocked, yellow attenuated, blue reflection only). The PNG plot of a run is core/skyplot.py.
"""
from __future__ import annotations

import numpy as np

from gnss_sim_ros2.core.vocabulary import VisibilityState

#: RGB of each satellite state; black for another value
STATE_RGB = {VisibilityState.VISIBLE: (0, 170, 0), VisibilityState.BLOCKED: (200, 0, 0),
             VisibilityState.ATTENUATED: (230, 170, 0), VisibilityState.REFLECTED_ONLY: (0, 0, 200)}
OPAQUE_RGB, FOLIAGE_RGB, BELOW_HORIZON_RGB = (170, 170, 170), (200, 230, 200), (40, 40, 40)
#: the sky grid is cast again when the antenna has moved more than this [m]
RECAST_DISTANCE_M = 1.0


def sky_view_rgb(az_deg, el_deg, state, sky, size_px: int = 241) -> np.ndarray:
    """(size_px, size_px, 3) uint8 picture of the satellites (az_deg, el_deg, state: arrays over satellites)
    over ``sky`` = Scene.sky_grid(antenna) (az_edges_deg, el_edges_deg, opaque, foliage)."""
    img = np.full((size_px, size_px, 3), 255, dtype=np.uint8)
    c = size_px // 2
    yy, xx = np.mgrid[0:size_px, 0:size_px]
    dx, dy = xx - c, c - yy
    r = np.hypot(dx, dy) / c  # 0 at zenith, 1 at the horizon
    az = np.degrees(np.arctan2(dx, dy)) % 360.0
    az_e, el_e, opaque, foliage = sky
    el_px = 90.0 * (1.0 - r)
    inside = r <= 1.0
    ia = np.clip(np.searchsorted(az_e, az, side="right") - 1, 0, opaque.shape[0] - 1)
    ie = np.clip(np.searchsorted(el_e, el_px, side="right") - 1, 0, opaque.shape[1] - 1)
    img[inside & opaque[ia, ie]] = OPAQUE_RGB
    img[inside & foliage[ia, ie] & ~opaque[ia, ie]] = FOLIAGE_RGB
    img[(r > 1.0)] = BELOW_HORIZON_RGB
    for a, e, st in zip(np.asarray(az_deg, dtype=float), np.asarray(el_deg, dtype=float), np.asarray(state)):
        rr = (90.0 - e) / 90.0 * c
        x = int(round(c + rr * np.sin(np.radians(a))))
        y = int(round(c - rr * np.cos(np.radians(a))))
        img[max(0, y - 3):y + 4, max(0, x - 3):x + 4] = STATE_RGB.get(int(st), (0, 0, 0))
    return img


class SkyView:
    """Sky view pictures of one scene; the sky grid cast again only when the antenna moved more than
    RECAST_DISTANCE_M (open sky under an overhang stays open)."""

    def __init__(self, scene):
        self.scene = scene
        self._at = None
        self._sky = None

    def rgb(self, antenna_world_m, az_deg, el_deg, state, size_px: int = 241) -> np.ndarray:
        if self._sky is None or np.linalg.norm(self._at - antenna_world_m) > RECAST_DISTANCE_M:
            self._at = np.array(antenna_world_m)
            self._sky = self.scene.sky_grid(antenna_world_m, az_step_deg=2.0)
        return sky_view_rgb(az_deg, el_deg, state, self._sky, size_px)
