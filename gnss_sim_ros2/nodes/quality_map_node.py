"""GNSS-quality layer lifecycle node for Nav2: the planner's quality over the world as an OccupancyGrid, and the
predicted quality along a path as a service.

configure: validates parameters, loads the scene (world_file / mesh_file; the demo courtyard by default), lays
the grid over the world's bounds (grid_step_m) and opens the ephemeris source (core/planning/live.py); the
latched publisher ``quality_map`` (nav_msgs/OccupancyGrid, transient_local like a map server's /map).
activate: the grid of the clock's time + lookahead_s is published at once and again whenever the (ROS) clock has
moved refresh_period_s; the service ``path_quality`` (gnss_sim_msgs/srv/PathQuality) answers per pose of a
nav_msgs/Path. Values 0-100 as core/planning/costmap.py maps them (RTK indicator 0, no fix 100). The node
computes nothing itself: core/planning does (the planner of `gnss-sim plan`, the simulator's own casts).
"""
from __future__ import annotations

import sys

import numpy as np

from gnss_sim_ros2.messages.quality_map import fill_path_quality, occupancy_grid, path_xy
from gnss_sim_ros2.nodes.common import GnssSimNode, TimeMapping, run_node, run_origin_ns


class QualityMapNode(GnssSimNode):
    PARAMS_KEY = "quality_map"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.model = None
        self.mapping = None
        self.pub = None
        self.service = None
        self.last_grid_ns = None       # ROS time [ns] of the last grid published
        self.published = 0

    def configure(self, p):
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
        from gnss_sim_ros2.core.planning.live import QualityModel
        from gnss_sim_ros2.core.planning.runner import SceneSpec
        from gnss_sim_ros2.core.scene.demo_world import demo_world_path

        self.mapping = TimeMapping(p["start_time"], p["time_mapping"])
        world = p["world_file"] if p["world_file"] or p["mesh_file"] else str(demo_world_path())
        spec = SceneSpec(world=world if not p["mesh_file"] else "", mesh=p["mesh_file"],
                         materials=p["materials_file"], strict_world=p["strict_world"],
                         keep_dynamic=p["keep_dynamic_models"])
        # the window: the run's span, the look-ahead and a day of paths beyond it
        provider, _ = open_ephemeris(p["source"], self.mapping.start - p["refresh_period_s"],
                                     p["duration_s"] + p["lookahead_s"] + p["refresh_period_s"] + 86400.0,
                                     p["systems"], p["nav_files"], p["sp3_files"], p["clk_files"],
                                     cache_dir=p["download_cache_dir"] or None)
        self.model = QualityModel.open(spec, p["grid_step_m"], p["antenna_height_m"], p["profile"], p["systems"],
                                       p["elevation_mask_deg"], provider, p["refresh_period_s"])
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                             reliability=ReliabilityPolicy.RELIABLE)
        self.pub = self.lifecycle_publisher(_grid_type(), "quality_map", latched)
        self.last_grid_ns = None

    def activate(self):
        from gnss_sim_msgs.srv import PathQuality

        self.mapping.origin_ns = run_origin_ns(self)
        self.service = self.create_service(PathQuality, "path_quality", self.speaking(self._on_path))
        self.active_clock_timer(min(1.0, self.params["refresh_period_s"]), self._tick)
        self._tick()

    def deactivate(self):
        if self.service is not None:
            self.destroy_service(self.service)
            self.service = None

    def cleanup(self):
        self.model = self.mapping = self.pub = None

    # ------------------------------------------------------------------ the grid
    def _tick(self):
        now_ns = self.get_clock().now().nanoseconds
        period_ns = int(self.params["refresh_period_s"] * 1e9)
        if self.last_grid_ns is not None and now_ns - self.last_grid_ns < period_ns:
            return
        self.last_grid_ns = now_ns
        self.publish_grid(self.get_clock().now().to_msg())

    def publish_grid(self, stamp):
        from gnss_sim_ros2.core.planning.costmap import grid_cells, quality_cost

        t = self.mapping.to_gnss(stamp) + self.params["lookahead_s"]
        fields = self.model.grid(t)
        cost = quality_cost(fields, self.params["max_accuracy_m"])
        self.pub.publish(occupancy_grid(self.model.area, grid_cells(self.model.area, cost), stamp,
                                   self.params["world_frame"]))
        self.published += 1

    # ------------------------------------------------------------------ the path service
    def _on_path(self, request, response):
        from gnss_sim_ros2.core.planning.live import poses_times

        try:
            xy = path_xy(request.path)
            start = request.start_time
            if start.sec == 0 and start.nanosec == 0:
                start = self.get_clock().now().to_msg()
            _, times = poses_times(xy, self.mapping.to_gnss(start), float(request.speed_mps))
            fields = self.model.path(xy, times)
        except ValueError as exc:
            response.success, response.message = False, f"path_quality: {exc}"
            return response
        t0_ns = start.sec * 1_000_000_000 + start.nanosec
        fill_path_quality(response, fields, t0_ns + np.rint(np.asarray(times - times[0], float) * 1e9).astype(np.int64))
        return response


def _grid_type():
    from nav_msgs.msg import OccupancyGrid

    return OccupancyGrid


def main(args=None):
    return run_node(QualityMapNode, args)


if __name__ == "__main__":
    sys.exit(main())
