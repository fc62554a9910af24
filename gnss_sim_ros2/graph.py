"""The gnss_sim node graph, described once.

``launch/sim.launch.py`` (a ROS 2 install) and ``gnss-sim run`` (anywhere)
both build the same nodes from this table, with the same parameters (one
parameter file, see parameters.py) and the same remappings.  ROS-free.
"""
from __future__ import annotations

from dataclasses import dataclass

from gnss_sim_ros2.parameters import NODE_NAMES

#: the ROS package, and the scheme of Python classes in its component index (nodes/components.py)
PACKAGE = "gnss_sim"
PYTHON_TARGET_PREFIX = "python:"


@dataclass(frozen=True)
class NodeSpec:
    key: str          # parameters.NODE_PARAMS key
    executable: str   # console script (setup.py) = `ros2 run gnss_sim <executable>`
    module: str       # python module (``python -m``)
    cls: str          # node class (composition in one process)

    @property
    def name(self) -> str:
        return NODE_NAMES[self.key]

    @property
    def plugin(self) -> str:
        """Component name (``ros2 component types``, ``ComposableNode(plugin=...)``)."""
        return f"{PACKAGE}::{self.cls}"

    @property
    def target(self) -> str:
        """Where the class is (second field of the rclcpp_components index line)."""
        return f"{PYTHON_TARGET_PREFIX}{self.module}:{self.cls}"


#: start order: TF first, then the chain upstream -> downstream
NODES = (
    NodeSpec("trajectory", "trajectory_player", "gnss_sim_ros2.nodes.trajectory_player", "TrajectoryPlayer"),
    NodeSpec("ephemeris", "ephemeris_node", "gnss_sim_ros2.nodes.ephemeris_node", "EphemerisNode"),
    NodeSpec("visibility", "visibility_node", "gnss_sim_ros2.nodes.visibility_node", "VisibilityNode"),
    NodeSpec("receiver", "receiver_node", "gnss_sim_ros2.nodes.receiver_node", "ReceiverNode"),
)

#: the public topics, under /gnss like a GNSS driver (nmea_navsat_driver, ublox publish fix/vel)
TOPIC_NAMESPACE = "/gnss"
REMAPPINGS = (
    ("satellite_states", f"{TOPIC_NAMESPACE}/satellite_states"),
    ("visibility", f"{TOPIC_NAMESPACE}/visibility"),
    ("sky_view", f"{TOPIC_NAMESPACE}/sky_view"),
    ("observations", f"{TOPIC_NAMESPACE}/observations"),
    ("fix", f"{TOPIC_NAMESPACE}/fix"),
    ("vel", f"{TOPIC_NAMESPACE}/vel"),
    ("status", f"{TOPIC_NAMESPACE}/status"),
    ("nmea", f"{TOPIC_NAMESPACE}/nmea"),
    ("rtcm", f"{TOPIC_NAMESPACE}/rtcm"),
)

#: topics a run records (rosbag2) with their types; the sky view images are left out (bulky)
RECORDED = (
    (f"{TOPIC_NAMESPACE}/satellite_states", "gnss_sim_msgs/msg/SatelliteStates"),
    (f"{TOPIC_NAMESPACE}/visibility", "gnss_sim_msgs/msg/Visibility"),
    (f"{TOPIC_NAMESPACE}/observations", "gnss_sim_msgs/msg/Observations"),
    (f"{TOPIC_NAMESPACE}/fix", "sensor_msgs/msg/NavSatFix"),
    (f"{TOPIC_NAMESPACE}/vel", "geometry_msgs/msg/TwistWithCovarianceStamped"),
    (f"{TOPIC_NAMESPACE}/status", "gnss_sim_msgs/msg/ReceiverStatus"),
    (f"{TOPIC_NAMESPACE}/nmea", "std_msgs/msg/String"),
    ("/tf", "tf2_msgs/msg/TFMessage"),
    ("/tf_static", "tf2_msgs/msg/TFMessage"),
    ("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray"),
)
RECORDED_TOPICS = tuple(t for t, _ in RECORDED)


def nodes(with_trajectory_player: bool = True) -> list[NodeSpec]:
    """The nodes of a run; without the player when Gazebo (ros_gz_bridge) publishes the robot's TF."""
    return [n for n in NODES if with_trajectory_player or n.key != "trajectory"]


def ros_args(spec: NodeSpec, params_file: str | None, use_sim_time: bool) -> list[str]:
    """``--ros-args`` of one node run as its own process."""
    args = ["--ros-args", "-r", f"__node:={spec.name}"]
    for a, b in REMAPPINGS:
        args += ["-r", f"{a}:={b}"]
    if params_file:
        args += ["--params-file", params_file]
    args += ["-p", f"use_sim_time:={'true' if use_sim_time else 'false'}"]
    return args
