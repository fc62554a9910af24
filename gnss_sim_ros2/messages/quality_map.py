"""The planner's quality as ROS messages: the nav_msgs/OccupancyGrid of the quality_map node and the response of
its gnss_sim_msgs/srv/PathQuality service."""
from __future__ import annotations

import numpy as np


def occupancy_grid(area, data, stamp, frame_id: str):
    """nav_msgs/OccupancyGrid over a grid PlanArea (core/planning/area.py): origin the lower-left corner of cell
    (0, 0) in ``frame_id``, ``resolution`` the grid step, ``data`` (ny * nx,) int8 row-major from there
    (core/planning/costmap.grid_cells)."""
    from nav_msgs.msg import OccupancyGrid

    msg = OccupancyGrid()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.info.map_load_time = stamp
    msg.info.resolution = float(area.step_m)
    msg.info.height, msg.info.width = (int(n) for n in area.shape)
    msg.info.origin.position.x = float(area.x0_m)
    msg.info.origin.position.y = float(area.y0_m)
    msg.info.origin.orientation.w = 1.0
    msg.data = np.asarray(data, np.int8).tolist()
    return msg


def path_xy(path) -> np.ndarray:
    """(P, 2) x, y [m] of a nav_msgs/Path's poses."""
    return np.array([[p.pose.position.x, p.pose.position.y] for p in path.poses], float).reshape(-1, 2)


def fill_path_quality(response, fields: dict, stamps_ns) -> None:
    """A PathQuality response from the planner's per-pose fields (quality.FIELDS, (P,) each) and the ROS times
    [ns] (P,) the poses are reached."""
    from builtin_interfaces.msg import Time

    response.stamps = [Time(sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000)) for ns in stamps_ns]
    for name in ("n_los", "n_attenuated", "n_blocked", "n_rtk"):
        setattr(response, name, np.asarray(fields[name]).astype(np.uint16).tolist())
    for name in ("pdop", "hdop", "h_acc_m"):
        setattr(response, name, np.asarray(fields[name], np.float32).tolist())
    response.rtk = [bool(v) for v in fields["rtk"]]
    response.success = True
    response.message = f"{len(response.stamps)} poses, RTK indicator on {int(np.sum(fields['rtk']))}"
