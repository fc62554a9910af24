"""How the scene is cast for one epoch: :class:`VisibilityOptions`, from the visibility node's parameters
(``parameters.py``) and the preset (``core/presets.py``); the visibility node and the offline loop call
:meth:`VisibilityOptions.cast`."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..multipath.scene_paths import cast_paths
from ..multipath.wall_proximity import antennas_near_walls
from ..presets import preset as preset_switches
from ..vocabulary import VisibilityState
from .moving_obstacles import block_by_obstacles


@dataclass(frozen=True)
class VisibilityOptions:
    """How the scene is cast for one epoch (visibility node and offline loop alike)."""

    mask_deg: float = 10.0
    fresnel_rays: int = 0
    foliage: str = "path"
    use_visuals: bool = False
    #: world loading: non-static models kept as obstacles; unloadable parts an error (parameter strict_world)
    keep_dynamic: bool = False
    strict_world: bool = True
    #: reflections from the scene (core/multipath): "off", "nlos" (blocked satellites only), "full", or "auto"
    #: ("full" for the antennas with walls within multipath_range_m, "off" for the others: core/presets.py)
    multipath: str = "off"
    multipath_range_m: float = 100.0
    multipath_max_paths: int = 3
    #: knife-edge diffraction of blocked satellites over the nearest edge (multipath modes only)
    multipath_diffraction: bool = False
    #: 1: single bounces; 2: also double bounces between facing walls
    multipath_bounces: int = 2
    #: diffuse scattering from the walls (core/multipath/scattering.py) on top of the specular paths
    multipath_scattering: bool = False

    @classmethod
    def from_params(cls, p: dict, switches: dict | None = None) -> VisibilityOptions:
        """From the visibility node's parameters (shared ones included) and the preset's switches."""
        sw = switches if switches is not None else preset_switches(p["preset"])
        fresnel = p.get("fresnel_rays", -1)
        return cls(mask_deg=float(p["elevation_mask_deg"]),
                   fresnel_rays=int(fresnel if fresnel >= 0 else sw["fresnel_rays"]),
                   foliage=sw["foliage"], use_visuals=bool(p.get("use_visuals", False)),
                   keep_dynamic=bool(p.get("keep_dynamic_models", False)),
                   strict_world=bool(p.get("strict_world", True)),
                   multipath=_multipath_mode(p, sw),
                   multipath_range_m=float(p.get("multipath_range_m", 100.0)),
                   multipath_max_paths=int(p.get("multipath_max_paths", 3)),
                   multipath_diffraction=bool(p.get("multipath_diffraction", False)),
                   multipath_bounces=int(p.get("multipath_bounces", 2)),
                   multipath_scattering=bool(p.get("multipath_scattering", False)))

    def cast(self, scene, antenna_world_m, sat_ecef_m, obstacles=None, azimuth: bool = True):
        """(state, attenuation_db, VisibilityResult) of satellites (N, 3) or (M, N, 3) seen from the antenna(s).

        ``state`` uses VisibilityState; satellites below the mask are not cast and count as visible (the
        receiver does not track them).  With ``multipath`` on (``auto``: for the antennas with walls in range
        only; when none has, nothing beyond that test is computed and no ``v.paths`` is attached), ``v.paths``
        holds the reflected paths (core/multipath/scene_paths.py), blocked satellites diffracted over an edge
        with a loss below 40 dB are ATTENUATED by it, those with a reflected path REFLECTED_ONLY, and
        ``v.extra_path_m`` is the shortest path's excess.  ``obstacles``: moving boxes
        (core/visibility/moving_obstacles.py ``MovingBoxes``, one row per antenna) that block on top of the
        static scene, before the reflections are sought.  ``azimuth`` False: ``v.az_deg`` may be None (a caller
        that reads only the elevations, the planner; states and rays unchanged); kept with multipath or obstacles."""
        bare = self.multipath == "off" and obstacles is None
        v = scene.visibility_ecef(antenna_world_m, sat_ecef_m, mask_deg=self.mask_deg,
                                  fresnel_rays=self.fresnel_rays, foliage=self.foliage, azimuth=azimuth or not bare)
        # below the mask (-1, the only negative state) -> VISIBLE (0): the larger of the two
        state = np.maximum(v.state, int(VisibilityState.VISIBLE), dtype=np.int64)
        if obstacles is not None:
            state = block_by_obstacles(scene, antenna_world_m, sat_ecef_m, v, state, self.mask_deg, obstacles)
        att = v.attenuation_db + v.diffraction_db
        if self.multipath == "auto":
            near = antennas_near_walls(scene, antenna_world_m, self.multipath_range_m)
            if near.any():
                state, edge_db = cast_paths(self, scene, antenna_world_m, sat_ecef_m, v, state, antennas=near)
                att = att + edge_db
        elif self.multipath != "off":
            state, edge_db = cast_paths(self, scene, antenna_world_m, sat_ecef_m, v, state)
            att = att + edge_db
        return state, att, v


def _multipath_mode(p: dict, switches: dict) -> str:
    """Parameter multipath, else the preset's; ``auto`` (the scene decides) is off on a sky mask (parameter
    sky_mask_csv), which has no walls: one rule for the visibility node and the offline run."""
    mode = p.get("multipath") or switches.get("multipath", "off")
    return "off" if mode == "auto" and p.get("sky_mask_csv") else mode
