"""The gnss_sim node graph, described once.

``launch/sim.launch.py`` (a ROS 2 install) and ``gnss-sim run`` (anywhere)
both build the same nodes from this table, with the same parameters (one
parameter file, see parameters.py) and the same remappings.  ROS-free.
"""
from __future__ import annotations

from dataclasses import dataclass

from gnss_sim_ros2.graph_params import INSTANCE_NODE_NAMES, instance_params, robot_namespace, robot_params
from gnss_sim_ros2.parameters import NODE_NAMES, param, validate_node

#: the ROS package, and the scheme of Python classes in its component index (nodes/components.py)
PACKAGE = "gnss_sim"
PYTHON_TARGET_PREFIX = "python:"


@dataclass(frozen=True)
class NodeSpec:
    key: str          # parameters.NODE_PARAMS key
    executable: str   # console script (setup.py) = `ros2 run gnss_sim <executable>`
    module: str       # python module (``python -m``)
    cls: str          # node class (composition in one process)
    #: "" for the rover's chain and the rtk node; "base", "antenna2", "heading": an RTK run's other instances
    #: of the class (graph_params.INSTANCE_NODE_NAMES)
    instance: str = ""
    #: ROS namespace without slashes: "" (the root) or "robot<k>" (a run with several robots)
    namespace: str = ""
    #: the robot of a run with several robots (its number k), -1: the node is not a robot's own
    robot: int = -1

    @property
    def name(self) -> str:
        if self.instance == FLEET_INSTANCE:
            return FLEET_NODE_NAMES[self.key]
        return INSTANCE_NODE_NAMES[(self.instance, self.key)] if self.instance else NODE_NAMES[self.key]

    @property
    def path(self) -> str:
        """The node's name under its namespace ("robot1/gnss_sim_receiver"; the name in the root namespace):
        what the lifecycle manager drives (``/<path>/change_state``)."""
        return f"{self.namespace}/{self.name}" if self.namespace else self.name

    @property
    def plugin(self) -> str:
        """Component name (``ros2 component types``, ``ComposableNode(plugin=...)``)."""
        return f"{PACKAGE}::{self.cls}"

    @property
    def target(self) -> str:
        """Where the class is (second field of the rclcpp_components index line)."""
        return f"{PYTHON_TARGET_PREFIX}{self.module}:{self.cls}"


#: the fleet layout's nodes (LAYOUTS "fleet"): one trajectory player moving every robot (one TFMessage per tick), one
#: visibility node casting every robot's antenna in one call per epoch and one receiver node running every robot's
#: chain (nodes/trajectory_player.py with fleet_robots, nodes/fleet_visibility_node.py, nodes/fleet_receiver_node.py)
FLEET_INSTANCE = "fleet"
FLEET_NODE_NAMES = {"trajectory": "gnss_sim_fleet_trajectory_player", "visibility": "gnss_sim_fleet_visibility",
                    "receiver": "gnss_sim_fleet_receiver"}
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
    ("threats_active", f"{TOPIC_NAMESPACE}/threats/active"),
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
    (f"{TOPIC_NAMESPACE}/threats/active", "std_msgs/msg/String"),      # with a scenario: its truth labels
    ("/tf", "tf2_msgs/msg/TFMessage"),
    ("/tf_static", "tf2_msgs/msg/TFMessage"),
    ("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray"),
)
RECORDED_TOPICS = tuple(t for t, _ in RECORDED)


def nodes(with_trajectory_player: bool = True, robots: int = 1, fleet: bool = False) -> list[NodeSpec]:
    """The nodes of a run; without the player when Gazebo (ros_gz_bridge) publishes the robot's TF.

    ``robots`` > 1: one ephemeris node and, per robot k, a trajectory player, a visibility and a receiver node
    in the namespace ``robot<k>`` (ROBOT_KEYS); the players first, then the chain upstream -> downstream.
    ``fleet``: FLEET_NODES' player (every robot's TF), the ephemeris node, then FLEET_NODES' visibility and
    receiver node (serving every robot)."""
    if fleet:
        return [n for n in FLEET_NODES if n.key == "trajectory" and with_trajectory_player] + \
            [n for n in NODES if n.key == "ephemeris"] + [n for n in FLEET_NODES if n.key != "trajectory"]
    if robots == 1:
        return [n for n in NODES if with_trajectory_player or n.key != "trajectory"]
    by_key = {n.key: n for n in NODES}
    players = [robot_spec(by_key["trajectory"], k) for k in range(robots)] if with_trajectory_player else []
    chains = [robot_spec(by_key[key], k) for k in range(robots) for key in ("visibility", "receiver")]
    return players + [by_key["ephemeris"]] + chains


#: the nodes each robot of a run with several robots has of its own (the ephemeris node is shared)
ROBOT_KEYS = ("trajectory", "visibility", "receiver")


#: process layouts (gnss-sim run --layout, the launch file's composed:=): every node in one process
#: ("composed"), one process per robot (its player, visibility and receiver; the shared nodes, ephemeris and
#: RTK, in the main one: "robot"), one process per node ("node"), every node in one process with one visibility
#: and one receiver node serving all the robots ("fleet": FLEET_NODES)
LAYOUTS = ("composed", "robot", "node", "fleet")
#: the component container of a robot in the "robot" layout (in the robot's namespace: /robot<k>/...)
ROBOT_CONTAINER = "gnss_sim_robot_container"


def robot_of(spec: NodeSpec) -> int | None:
    """The robot whose process holds the node in the "robot" layout: k for robot k's nodes (0 for the player,
    visibility and receiver of a one-robot run), None for the shared ones (ephemeris, the RTK nodes)."""
    if spec.robot >= 0:
        return spec.robot
    return 0 if spec.key in ROBOT_KEYS and not spec.instance else None


def robot_groups(specs) -> dict[int, list[NodeSpec]]:
    """{robot k: its nodes of ``specs``, in their order} (the "robot" layout's processes beside the main one)."""
    out: dict[int, list[NodeSpec]] = {}
    for s in specs:
        k = robot_of(s)
        if k is not None:
            out.setdefault(k, []).append(s)
    return out


def robot_container_namespace(k: int, robots: int) -> str:
    """The namespace of robot k's container: robot<k>, the root for the one robot of a run."""
    return robot_namespace(k) if robots > 1 else ""


def robot_spec(spec: NodeSpec, k: int) -> NodeSpec:
    from dataclasses import replace

    return replace(spec, namespace=robot_namespace(k), robot=k)


def robot_topic(k: int, topic: str) -> str:
    """Robot k's name of a public topic of REMAPPINGS ("/gnss/fix" -> "/robot<k>/gnss/fix"; one robot: the
    topic itself); /gnss/satellite_states is every robot's."""
    return topic if k < 0 or topic == f"{TOPIC_NAMESPACE}/satellite_states" else f"/{robot_namespace(k)}{topic}"


def fleet_topic(k: int, robots: int, name: str) -> str:
    """Robot k's topic ``name`` (a REMAPPINGS source: "fix", "visibility") as a fleet node of ``robots`` robots
    publishes it: the per-robot layout's (/robot<k>/gnss/fix; one robot: /gnss/fix)."""
    return robot_topic(k if robots > 1 else -1, dict(REMAPPINGS)[name])


def robot_topics(robots: int) -> list[list[str]]:
    """Per robot, its public topics (REMAPPINGS' targets; /gnss/satellite_states is shared)."""
    return [[robot_topic(k if robots > 1 else -1, t) for _, t in REMAPPINGS] for k in range(robots)]


def recorded(robots: int = 1) -> tuple:
    """What a run with ``robots`` records: RECORDED, with every robot's topics under its namespace."""
    if robots == 1:
        return RECORDED
    shared = f"{TOPIC_NAMESPACE}/satellite_states"
    own = [(t, ty) for t, ty in RECORDED if t.startswith(f"{TOPIC_NAMESPACE}/") and t != shared]
    rest = [(t, ty) for t, ty in RECORDED if (t, ty) not in own]
    return tuple(rest[:1] + [(robot_topic(k, t), ty) for k in range(robots) for t, ty in own] + rest[1:])


def ros_args(spec: NodeSpec, params_file: str | None, use_sim_time: bool) -> list[str]:
    """``--ros-args`` of one node run as its own process."""
    args = ["--ros-args", "-r", f"__node:={spec.name}"]
    if spec.namespace:
        args += ["-r", f"__ns:=/{spec.namespace}"]
    for a, b in remappings_of(spec):
        args += ["-r", f"{a}:={b}"]
    if params_file:
        args += ["--params-file", params_file]
    args += ["-p", f"use_sim_time:={'true' if use_sim_time else 'false'}"]
    return args


# ---------------------------------------------------------------------------- RTK (gnss-sim run --rtk, rtk:=true)
#: the base station (the rover's visibility and receiver classes at a static antenna, graph_params.base_station_params)
#: and the rtk node (rtkrcv on the rover's and the base's RTCM3), started after the rover's chain
RTK_NODES = (
    NodeSpec("visibility", "visibility_node", "gnss_sim_ros2.nodes.visibility_node", "VisibilityNode", "base"),
    NodeSpec("receiver", "receiver_node", "gnss_sim_ros2.nodes.receiver_node", "ReceiverNode", "base"),
    NodeSpec("rtk", "rtk_node", "gnss_sim_ros2.nodes.rtk_node", "RtkNode"),
)
#: with antenna2_frame: the second antenna's receiver and rtkrcv in moving-base mode (antenna 1 the moving base)
HEADING_NODES = (
    NodeSpec("visibility", "visibility_node", "gnss_sim_ros2.nodes.visibility_node", "VisibilityNode", "antenna2"),
    NodeSpec("receiver", "receiver_node", "gnss_sim_ros2.nodes.receiver_node", "ReceiverNode", "antenna2"),
    NodeSpec("rtk", "rtk_node", "gnss_sim_ros2.nodes.rtk_node", "RtkNode", "heading"),
)
FLEET_NODES = (
    NodeSpec("trajectory", "trajectory_player", "gnss_sim_ros2.nodes.trajectory_player", "TrajectoryPlayer",
             FLEET_INSTANCE),
    NodeSpec("visibility", "fleet_visibility_node", "gnss_sim_ros2.nodes.fleet_visibility_node",
             "FleetVisibilityNode", FLEET_INSTANCE),
    NodeSpec("receiver", "fleet_receiver_node", "gnss_sim_ros2.nodes.fleet_receiver_node", "FleetReceiverNode",
             FLEET_INSTANCE),
)
#: the GNSS-quality layer for Nav2 (launch argument quality_map:=true; its remappings and parameters below)
QUALITY_MAP_NODE = NodeSpec("quality_map", "quality_map_node", "gnss_sim_ros2.nodes.quality_map_node", "QualityMapNode")
#: one line per class in the component index (nodes/components.py)
COMPONENT_NODES = NODES + (RTK_NODES[2],) + FLEET_NODES[1:] + (QUALITY_MAP_NODE,)   # the fleet's player: NODES' class
BASE_NAMESPACE = f"{TOPIC_NAMESPACE}/base"
BASE_REMAPPINGS = (("satellite_states", f"{TOPIC_NAMESPACE}/satellite_states"),) + tuple(
    (a, f"{BASE_NAMESPACE}/{a}") for a, _ in REMAPPINGS if a != "satellite_states")
RTK_TOPICS = ("rtk/fix", "rtk/vel", "rtk/nmea", "rtk/status", "rtk/heading")
RTK_REMAPPINGS = (("rtcm", f"{TOPIC_NAMESPACE}/rtcm"), ("base/rtcm", f"{BASE_NAMESPACE}/rtcm")) + tuple(
    (a, f"{TOPIC_NAMESPACE}/{a}") for a in RTK_TOPICS)
ANTENNA2_NAMESPACE = f"{TOPIC_NAMESPACE}/antenna2"
ANTENNA2_REMAPPINGS = (("satellite_states", f"{TOPIC_NAMESPACE}/satellite_states"),) + tuple(
    (a, f"{ANTENNA2_NAMESPACE}/{a}") for a, _ in REMAPPINGS if a != "satellite_states")
#: moving base: the "base" stream is the first antenna's, the "rover" stream the second's
HEADING_REMAPPINGS = (("rtcm", f"{ANTENNA2_NAMESPACE}/rtcm"), ("base/rtcm", f"{TOPIC_NAMESPACE}/rtcm"),
                      ("rtk/heading", f"{TOPIC_NAMESPACE}/rtk/heading"),
                      ("rtk/status", f"{TOPIC_NAMESPACE}/heading/status"),
                      ("rtk/nmea", f"{TOPIC_NAMESPACE}/heading/nmea"))
#: what an RTK run records on top of RECORDED
RECORDED_RTK = (
    (f"{TOPIC_NAMESPACE}/rtk/fix", "sensor_msgs/msg/NavSatFix"),
    (f"{TOPIC_NAMESPACE}/rtk/vel", "geometry_msgs/msg/TwistWithCovarianceStamped"),
    (f"{TOPIC_NAMESPACE}/rtk/status", "diagnostic_msgs/msg/DiagnosticStatus"),
    (f"{TOPIC_NAMESPACE}/rtk/nmea", "std_msgs/msg/String"),
    (f"{TOPIC_NAMESPACE}/rtcm", "std_msgs/msg/UInt8MultiArray"),
    (f"{BASE_NAMESPACE}/rtcm", "std_msgs/msg/UInt8MultiArray"),
    (f"{BASE_NAMESPACE}/fix", "sensor_msgs/msg/NavSatFix"),
    (f"{TOPIC_NAMESPACE}/rtk/heading", "sensor_msgs/msg/Imu"),
    (f"{TOPIC_NAMESPACE}/heading/status", "diagnostic_msgs/msg/DiagnosticStatus"),
)


# -------------------------------------------------------------------------- the GNSS-quality layer (quality_map:=true)
#: the planner's grid for Nav2 (nav_msgs/OccupancyGrid on /gnss/quality_map) and its path service
#: (/gnss/path_quality, gnss_sim_msgs/srv/PathQuality); started after the chain
QUALITY_MAP_REMAPPINGS = (("quality_map", f"{TOPIC_NAMESPACE}/quality_map"),
                          ("path_quality", f"{TOPIC_NAMESPACE}/path_quality"))
#: the quality map's parameters taken from other nodes' sections unless its own section sets them (one setting:
#: parameters.NODE_PARAMS["quality_map"])
QUALITY_MAP_FROM = {"visibility": ("world_file", "mesh_file", "materials_file", "keep_dynamic_models", "strict_world"),
                    "receiver": ("profile",),
                    "ephemeris": ("source", "nav_files", "sp3_files", "clk_files", "download_cache_dir",
                                  "time_mapping", "duration_s")}


def quality_map_parameter_sections(cfg) -> dict:
    """The quality map's section of a ROS parameter file ({node name: {"ros__parameters": ...}})."""
    return {QUALITY_MAP_NODE.name: {"ros__parameters": node_parameters(cfg, QUALITY_MAP_NODE)}}


def remappings_of(spec: NodeSpec) -> tuple:
    """The topic remappings of one node: the rover's chain under /gnss, the base station's under /gnss/base,
    robot k's under /robot<k>/gnss (the satellite states: /gnss/satellite_states, shared)."""
    if spec.robot >= 0:
        return tuple((a, robot_topic(spec.robot, b)) for a, b in REMAPPINGS)
    if spec.instance == FLEET_INSTANCE:     # each robot's topics are named by the node (fleet_topic)
        return REMAPPINGS[:1]
    if spec.instance == "base":
        return BASE_REMAPPINGS
    if spec.instance == "antenna2":
        return ANTENNA2_REMAPPINGS
    if spec.instance == "heading":
        return HEADING_REMAPPINGS
    if spec.key == "rtk":
        return RTK_REMAPPINGS
    if spec.key == "quality_map":
        return QUALITY_MAP_REMAPPINGS
    return REMAPPINGS


def rtk_nodes(cfg=None) -> list[NodeSpec]:
    """The nodes an RTK run adds to :func:`nodes`; with ``cfg`` (parameters.Config) naming an antenna2_frame,
    the moving baseline's too."""
    heading = cfg is not None and bool(cfg.node("receiver")["antenna2_frame"])
    return list(RTK_NODES) + (list(HEADING_NODES) if heading else [])


def node_parameters(cfg, spec: NodeSpec, robots: int = 1) -> dict:
    """The parameters of one node of the graph from the configuration (parameters.Config)."""
    if spec.robot >= 0:
        return robot_params(cfg, spec.robot, robots, spec.key)
    if spec.instance == FLEET_INSTANCE:
        return validate_node(spec.key, {**cfg.node(spec.key), "fleet_robots": robots},
                             f"{cfg.source}: {spec.name} (robots: {robots})")
    out = instance_params(cfg, spec.instance, spec.key) if spec.instance else cfg.node(spec.key)
    if spec.key == "rtk" and not out["nav_files"]:
        out["nav_files"] = [str(run_navigation_file(cfg))]
    if spec.key == "quality_map":     # the other node's value where the quality map's section leaves the default
        for key, names in QUALITY_MAP_FROM.items():
            out.update({n: cfg.node(key)[n] for n in names if out[n] == param("quality_map", n).default})
    return out


def run_navigation_file(cfg):
    """The RINEX navigation file the ephemeris node writes on configure: the ephemerides the rtk node sends
    rtkrcv (the simulated receivers' RTCM3 carry observations only: a node has no navigation records)."""
    from pathlib import Path

    from gnss_sim_ros2.core.receiver.outputs import rinex_name
    from gnss_sim_ros2.core.time import GnssTime

    eph = cfg.node("ephemeris")
    if not eph["output_dir"]:
        raise ValueError(f"{cfg.source}: an RTK run needs output_dir (parameter output_dir is empty): the rtk node "
                         f"sends rtkrcv the ephemerides of the run's navigation file written there (or give the "
                         f"rtk node nav_files)")
    name = rinex_name(eph["marker_name"], GnssTime.from_iso(eph["start_time"]), eph["duration_s"],
                      1.0 / eph["rate_hz"], "MN")
    return Path(eph["output_dir"]) / name


def rtk_parameter_sections(cfg) -> dict:
    """The RTK nodes' sections of a ROS parameter file ({node name: {"ros__parameters": ...}}): the base
    station's, and the rtk node's with the run's navigation file."""
    return {s.name: {"ros__parameters": node_parameters(cfg, s)} for s in rtk_nodes(cfg)}


def robot_parameter_sections(cfg, robots: int) -> dict:
    """With several robots, their nodes' sections of a ROS parameter file ({"/robot<k>/<node>":
    {"ros__parameters": ...}}; rcl matches a section by the node's full name); {} for one robot."""
    if robots == 1:
        return {}
    return {f"/{s.path}": {"ros__parameters": node_parameters(cfg, s, robots)}
            for s in nodes(True, robots) if s.robot >= 0}
