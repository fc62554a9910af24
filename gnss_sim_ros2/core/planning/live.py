"""The planner at one instant and along a path: what the quality_map node (Nav2's GNSS-quality layer and its
path service) asks, computed by the planner's own functions (quality_block, path_quality) on a scene, a grid
over the world's bounds and an ephemeris provider opened once.

``QualityModel.grid(t)``: the FIELDS of every grid cell at GNSS time ``t`` (the RTK indicator's continuity
over ``continuity_s`` before it); ``QualityModel.path(xy, times)``: the FIELDS per pose of a path at the times
the robot is there (continuity from one pose to the next).  ROS-free: the node only turns these into messages.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene.world_mesh import world_bounds_xy
from ..time import GnssTime
from .area import PlanArea, grid_area, ground_z_m
from .predicted_cn0 import predictor_from_profile
from .quality import PlanInputs, path_quality, quality_block
from .ranging import budget_from_profile, tracked_systems
from .rtk_rule import RtkRule
from .runner import SceneSpec
from .sky import plan_sky


def poses_times(xy_m, start: GnssTime, speed_mps: float) -> tuple[np.ndarray, GnssTime]:
    """(distance along the path [m] (P,), the time each pose is reached (P,)) for a robot leaving pose 0 at
    ``start`` at ``speed_mps`` (> 0: ValueError naming speed_mps)."""
    xy = np.asarray(xy_m, float).reshape(-1, 2)
    if not (np.isfinite(speed_mps) and speed_mps > 0):
        raise ValueError(f"speed_mps is {speed_mps}: a speed > 0 m/s is needed")
    if len(xy) == 0:
        raise ValueError("the path has no pose")
    if not np.all(np.isfinite(xy)):
        raise ValueError("a pose of the path has a coordinate that is not finite")
    dist = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
    return dist, GnssTime.stack([start + float(d / speed_mps) for d in dist])


@dataclass
class QualityModel:
    """A scene, its grid and a provider: see the module doc.  Build it with :meth:`open`."""

    scene: object
    area: PlanArea
    ground_m: np.ndarray          # (C,) ground under each cell
    height_m: float
    provider: object
    systems: str
    excluded_svs: str
    inputs: PlanInputs            # sat positions filled per call
    vis: object                   # VisibilityOptions
    continuity_s: float

    @classmethod
    def open(cls, spec: SceneSpec, step_m: float, height_m: float, profile: str, systems: str, mask_deg: float,
             provider, continuity_s: float) -> QualityModel:
        from ..receiver.config import ReceiverConfig
        from ..visibility import VisibilityOptions

        scene = spec.load()
        if scene.spherical is None:
            raise ValueError(f"{spec.world or spec.mesh}: no geodetic origin (<spherical_coordinates>): satellites "
                             f"cannot be placed")
        bounds = world_bounds_xy(scene)
        if bounds is None:
            raise ValueError("the scene has no bounds (a sky mask): a quality map needs a world or a mesh")
        area = grid_area(step_m, bounds, step_name="parameter 'grid_step_m'")
        ground = ground_z_m(scene, area.x_m, area.y_m)
        systems = tracked_systems(profile, systems)
        inp = PlanInputs(np.zeros((0, 0, 3)), np.array([]), budget_from_profile(profile, systems), RtkRule(),
                         cn0=predictor_from_profile(profile, systems))
        return cls(scene, area, ground, float(height_m), provider, systems,
                   ReceiverConfig(profile=profile).excluded_svs or "", inp,
                   VisibilityOptions(mask_deg=float(mask_deg), multipath="off"), float(continuity_s))

    def _inputs(self, times: GnssTime):
        """(PlanInputs with the satellites of ``times``, their PlanSky)."""
        sky = plan_sky(self.provider, times, self.systems, self.excluded_svs)
        i = self.inputs
        return PlanInputs(sky.pos_ecef_m, sky.system, i.budget, i.rule, i.max_rays, i.cn0, i.good_cn0_dbhz,
                          sky.t_s), sky

    def grid(self, t: GnssTime) -> dict:
        """{field: (C,)} of every cell at ``t``: the cells' quality at ``t`` (the RTK arc since t - continuity_s)."""
        inp, _ = self._inputs(GnssTime.stack([t - self.continuity_s, t]))
        ant = np.stack([self.area.x_m, self.area.y_m, self.ground_m + self.height_m], axis=1)
        out = quality_block(self.scene, self.vis, ant, inp)
        return {k: v[:, -1] for k, v in out.items()}

    def path(self, xy_m, times: GnssTime) -> dict:
        """{field: (P,)} per pose (x, y) [m] at the time it is reached; the antenna ``height_m`` above its ground."""
        xy = np.asarray(xy_m, float).reshape(-1, 2)
        ant = np.stack([xy[:, 0], xy[:, 1], ground_z_m(self.scene, xy[:, 0], xy[:, 1]) + self.height_m], axis=1)
        inp, sky = self._inputs(times)
        return path_quality(self.scene, self.vis, ant, sky.pos_ecef_m, sky.system, inp, t_s=sky.t_s)
