"""Trajectory player lifecycle node: the robot's TF along a path, where Gazebo does not move it.

Publishes ``/tf`` (world_frame -> base_frame) at ``publish_rate_hz`` of the ROS
clock and ``/tf_static`` (base_frame -> antenna_frame, the lever arm
``antenna_offset_m``; with ``antenna2_frame`` also base_frame -> antenna2_frame at
``antenna2_offset_m``).  With simulated time a clock that jumps forward gets a sample
for every tick it skipped, so a TF lookup at any epoch in between is interpolated
between true samples.  The path comes from ``trajectory_file`` (CSV), ``waypoints``
or the demo path through worlds/courtyard.sdf.

With ``fleet_robots`` N > 1 (the fleet layout's one player, graph.FLEET_NODES) it moves every robot k along its own
path (graph_params.fleet_robot_params: robot<k>/base_link, the convoy's offset or its own file), all of them in
one TFMessage per tick and one on /tf_static, as ros_gz_bridge publishes every model's pose in one message: one
timer, one message and one delivery per tick for the whole fleet instead of N players' (N nodes each woken by
every /clock message, N /tf messages each waking the fleet's visibility node). The transforms are those the N
per-robot players publish, so every robot's TF lookups give what they give.
"""
from __future__ import annotations

import sys

import numpy as np
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.time import Time

from gnss_sim_ros2.core.trajectory import Trajectory, robot_path
from gnss_sim_ros2.graph_params import fleet_robot_params
from gnss_sim_ros2.messages.tf import tf_message, transform_to_msg
from gnss_sim_ros2.nodes.common import GnssSimNode, run_node, run_origin_ns
from gnss_sim_ros2.nodes.in_process import Offer

STATIC_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)


def _tf_type():
    from tf2_msgs.msg import TFMessage

    return TFMessage


class TrajectoryPlayer(GnssSimNode):
    PARAMS_KEY = "trajectory"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.path: Trajectory | None = None
        #: (parameters, path) of each robot moved: the node's own, or the fleet's robots (fleet_robots)
        self.robots: list[tuple[dict, Trajectory]] = []
        self.tf_pub = self.static_pub = None
        self.tf_offer = None
        self.next_tick = None

    def configure(self, p):
        self.robots = []
        for k in range(p["fleet_robots"]):
            rp = fleet_robot_params(p, k, "trajectory")
            path = robot_path(rp, f"node {self.get_name()}")
            if path.frame != "world":
                raise ValueError(f"node {self.get_name()}: the trajectory player moves {rp['base_frame']} in the "
                                 f"world frame; {rp['trajectory_file']} is in {path.frame} coordinates (use "
                                 f"t_s,e_m,n_m,u_m)")
            self.robots.append((rp, path))
        self.path = self.robots[0][1]
        self.period_ns = int(round(1e9 / p["publish_rate_hz"]))
        self.tf_pub = self.lifecycle_publisher(_tf_type(), "/tf", 100)
        #: each /tf message handed to the TF listeners of this process too (nodes/in_process.py), after publishing
        self.tf_offer = Offer(self, self.tf_pub)
        self.static_pub = self.lifecycle_publisher(_tf_type(), "/tf_static", STATIC_QOS)

    def activate(self):
        self.origin_ns = run_origin_ns(self)  # path time 0: ROS time 0 (simulated clock) or now
        now = self.get_clock().now()
        self.next_tick = (now.nanoseconds // self.period_ns) * self.period_ns
        self.active_clock_timer(self.period_ns * 1e-9, self._tick)
        self._static_pending = True
        self._tick()  # a simulated clock may stand still until the first epoch is answered

    def cleanup(self):
        if self.tf_offer is not None:
            self.tf_offer.withdraw()
            self.tf_offer = None
        self.tf_pub = self.static_pub = None
        self.path = None
        self.robots = []

    def pose_at(self, t_s: float):
        return self.path.position(t_s), float(self.path.yaw(t_s))

    def _tick(self):
        now_ns = self.get_clock().now().nanoseconds
        if self._static_pending:
            stamp = Time(nanoseconds=now_ns).to_msg()
            static = []
            for p, _ in self.robots:
                static.append(transform_to_msg(p["base_frame"], p["antenna_frame"], stamp, p["antenna_offset_m"]))
                if p["antenna2_frame"]:          # the second antenna of a moving baseline (heading)
                    static.append(transform_to_msg(p["base_frame"], p["antenna2_frame"], stamp,
                                                   p["antenna2_offset_m"]))
            self.static_pub.publish(tf_message(static))
            self._static_pending = False
        ticks = []
        while self.next_tick <= now_ns:
            ticks.append(self.next_tick)
            self.next_tick += self.period_ns
        if not ticks:
            return
        ts = np.array(ticks, dtype=np.int64)
        stamps = [Time(nanoseconds=int(t)).to_msg() for t in ts]
        msgs = []
        for p, path in self.robots:
            pos = path.position((ts - self.origin_ns) * 1e-9)
            yaw = path.yaw((ts - self.origin_ns) * 1e-9)
            msgs += [transform_to_msg(p["world_frame"], p["base_frame"], stamp, pos[i], float(yaw[i]))
                     for i, stamp in enumerate(stamps)]
        msg = tf_message(msgs)
        takers = self.tf_offer.takers()
        if takers:       # handed with its bytes as published: a taker drops the middleware's copy (tf_stream.py)
            from rclpy.serialization import serialize_message

            data = serialize_message(msg)
            self.tf_pub.publish(data)
            for deliver in takers:
                deliver((msg, data))
        else:
            self.tf_pub.publish(msg)


def main(args=None):
    return run_node(TrajectoryPlayer, args)


if __name__ == "__main__":
    sys.exit(main())
