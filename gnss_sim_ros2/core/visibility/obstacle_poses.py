"""Where the moving obstacles are at an epoch: timed poses as they arrive (a Gazebo pose topic, ros_gz_bridge's
tf2_msgs/TFMessage of /world/<name>/dynamic_pose/info) and the rule that leaves a robot's own body out.

:class:`PoseBuffer` keeps each named obstacle's recent poses (world frame: position, quaternion x, y, z, w) and
answers :meth:`PoseBuffer.at` for a stamp: the position linear between the two poses around it, the rotation of
the nearer one (a model moves little between two pose messages), the last pose held after it; a name without a
pose at or before the stamp is absent from the answer (an obstacle that has not appeared yet blocks nothing).
"""
from __future__ import annotations

import bisect

import numpy as np

#: poses older than this behind the newest one are dropped [s]
KEEP_S = 30.0


def quaternion_matrix(q_xyzw) -> np.ndarray:
    """(3, 3) rotation of a unit quaternion (x, y, z, w) (normalised here; Hamilton convention as ROS)."""
    x, y, z, w = np.asarray(q_xyzw, dtype=np.float64) / np.linalg.norm(q_xyzw)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


class PoseBuffer:
    """Recent poses of the obstacles ``names`` (module docstring); others are ignored."""

    def __init__(self, names):
        self._t: dict[str, list] = {n: [] for n in names}
        self._pose: dict[str, list] = {n: [] for n in names}

    def add(self, name: str, t_s: float, pos_world_m, q_xyzw) -> None:
        """One pose of ``name`` at ``t_s`` (a pose out of order is put in its place; one at a stamp already held
        replaces it)."""
        ts = self._t.get(name)
        if ts is None:
            return
        poses = self._pose[name]
        i = bisect.bisect_left(ts, t_s)
        pose = (np.asarray(pos_world_m, dtype=np.float64), quaternion_matrix(q_xyzw))
        if i < len(ts) and ts[i] == t_s:
            poses[i] = pose
        else:
            ts.insert(i, t_s)
            poses.insert(i, pose)
        drop = bisect.bisect_left(ts, ts[-1] - KEEP_S)
        if drop:
            del ts[:drop], poses[:drop]

    def at(self, t_s: float) -> dict:
        """{name: (base position (3,), rotation (3, 3))} of the obstacles known at ``t_s``."""
        out = {}
        for name, ts in self._t.items():
            i = bisect.bisect_right(ts, t_s)
            if i == 0:
                continue
            p0, r0 = self._pose[name][i - 1]
            if i == len(ts):
                out[name] = (p0, r0)
                continue
            p1, r1 = self._pose[name][i]
            f = (t_s - ts[i - 1]) / (ts[i] - ts[i - 1])
            out[name] = (p0 + f * (p1 - p0), r0 if f < 0.5 else r1)
        return out


def own_body(frame: str, antenna_frame: str) -> bool:
    """Whether obstacle ``frame`` is the body of the robot that carries ``antenna_frame``: both under the same TF
    prefix (``robot2/base_link`` and ``robot2/gnss_antenna``); frames without a prefix are never one's own."""
    prefix = antenna_frame.rpartition("/")[0]
    return bool(prefix) and frame.rpartition("/")[0] == prefix
