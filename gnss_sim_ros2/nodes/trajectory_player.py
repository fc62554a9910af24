"""Trajectory player lifecycle node: the robot's TF along a path, where Gazebo does not move it.

Publishes ``/tf`` (world_frame -> base_frame) at ``publish_rate_hz`` of the ROS
clock and ``/tf_static`` (base_frame -> antenna_frame, the lever arm
``antenna_offset_m``; with ``antenna2_frame`` also base_frame -> antenna2_frame at
``antenna2_offset_m``).  With simulated time a clock that jumps forward gets a sample
for every tick it skipped, so a TF lookup at any epoch in between is interpolated
between true samples.  The path comes from ``trajectory_file`` (CSV), ``waypoints``
or the demo path through worlds/courtyard.sdf.
"""
from __future__ import annotations

import sys

import numpy as np
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.time import Time

from gnss_sim_ros2.core.trajectory import Trajectory, robot_path
from gnss_sim_ros2.messages.tf import tf_message, transform_to_msg
from gnss_sim_ros2.nodes.common import GnssSimNode, run_node, run_origin_ns

STATIC_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)


def _tf_type():
    from tf2_msgs.msg import TFMessage

    return TFMessage


class TrajectoryPlayer(GnssSimNode):
    PARAMS_KEY = "trajectory"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.path: Trajectory | None = None
        self.tf_pub = self.static_pub = None
        self.next_tick = None

    def configure(self, p):
        self.path = robot_path(p, f"node {self.get_name()}")
        if self.path.frame != "world":
            raise ValueError(f"node {self.get_name()}: the trajectory player moves {p['base_frame']} in the world "
                             f"frame; {p['trajectory_file']} is in {self.path.frame} coordinates (use t_s,e_m,n_m,u_m)")
        self.period_ns = int(round(1e9 / p["publish_rate_hz"]))
        self.tf_pub = self.lifecycle_publisher(_tf_type(), "/tf", 100)
        self.static_pub = self.lifecycle_publisher(_tf_type(), "/tf_static", STATIC_QOS)

    def activate(self):
        self.origin_ns = run_origin_ns(self)  # path time 0: ROS time 0 (simulated clock) or now
        now = self.get_clock().now()
        self.next_tick = (now.nanoseconds // self.period_ns) * self.period_ns
        self.active_clock_timer(self.period_ns * 1e-9, self._tick)
        self._static_pending = True
        self._tick()  # a simulated clock may stand still until the first epoch is answered

    def cleanup(self):
        self.tf_pub = self.static_pub = None
        self.path = None

    def pose_at(self, t_s: float):
        return self.path.position(t_s), float(self.path.yaw(t_s))

    def _tick(self):
        p = self.params
        now_ns = self.get_clock().now().nanoseconds
        if self._static_pending:
            stamp = Time(nanoseconds=now_ns).to_msg()
            static = [transform_to_msg(p["base_frame"], p["antenna_frame"], stamp, p["antenna_offset_m"])]
            if p["antenna2_frame"]:          # the second antenna of a moving baseline (heading)
                static.append(transform_to_msg(p["base_frame"], p["antenna2_frame"], stamp, p["antenna2_offset_m"]))
            self.static_pub.publish(tf_message(static))
            self._static_pending = False
        ticks = []
        while self.next_tick <= now_ns:
            ticks.append(self.next_tick)
            self.next_tick += self.period_ns
        if not ticks:
            return
        ts = np.array(ticks, dtype=np.int64)
        pos = self.path.position((ts - self.origin_ns) * 1e-9)
        yaw = self.path.yaw((ts - self.origin_ns) * 1e-9)
        msgs = [transform_to_msg(p["world_frame"], p["base_frame"], Time(nanoseconds=int(t)).to_msg(), pos[i],
                                 float(yaw[i])) for i, t in enumerate(ts)]
        self.tf_pub.publish(tf_message(msgs))


def main(args=None):
    return run_node(TrajectoryPlayer, args)


if __name__ == "__main__":
    sys.exit(main())
