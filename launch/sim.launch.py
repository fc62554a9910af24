"""ros2 launch gnss_sim sim.launch.py [world:=...] [config:=...] [composed:=true|false|robot] ...

The same node graph as `gnss-sim run` (gnss_sim_ros2/graph.py), with the
parameters of one file (config:=, default the package's config/gnss_sim.yaml)
merged with these launch arguments by gnss_sim_ros2.config_file.load_config.

Arguments:
  world:=FILE.sdf | mesh:=FILE.ply   scene (default: the demo courtyard)
  config:=FILE.yaml                  gnss_sim parameter file
  composed:=true|false|robot|fleet   the nodes as components of one container (gnss_sim's Python
                                     container, composition_interfaces), one process per node (false), or
                                     one container per robot (robot: /robot<k>/gnss_sim_robot_container with
                                     the robot's player, visibility and receiver; /gnss_sim_robot_container
                                     for one robot) beside /gnss_sim_container with the shared nodes
                                     (ephemeris, RTK), or one container whose one visibility node
                                     (gnss_sim_fleet_visibility) casts every robot's antenna per epoch and one
                                     receiver node (gnss_sim_fleet_receiver) steps every robot's chain, each
                                     robot's outputs on /robot<k>/gnss/... (fleet: up to 64 robots) [true]
  use_sim_time:=true|false           follow /clock (Gazebo) [true]
  trajectory_player:=true|false      move the robot along a path here; false when Gazebo publishes TF [true]
  record:=true|false                 record the gnss_sim topics into output_dir/bag (MCAP): `ros2 bag record`
                                     where it exists, else gnss_sim's recorder node [false]
  output_dir:=DIR                    RINEX files (and the bag) [gnss_sim_output]
  antenna_frame:=FRAME               TF frame of the antenna [from config]
  autostart:=true|false              configure and activate the nodes (lifecycle manager) [true]
  rtk:=true|false                    RTK: the base station (gnss_sim_base_visibility, gnss_sim_base_receiver at
                                     base_position) and the rtk node (RTKLIB rtkrcv): /gnss/rtk/fix [false]
  quality_map:=true|false            the GNSS-quality layer for Nav2 (gnss_sim_quality_map): the planner's
                                     quality over the world as nav_msgs/OccupancyGrid on /gnss/quality_map
                                     (transient_local; 0 RTK expected .. 100 no fix) and the service
                                     /gnss/path_quality (gnss_sim_msgs/srv/PathQuality) [false]
  profile:=NAME|FILE                 receiver profile: a built-in name (`gnss-sim profile list`) or a profile
                                     YAML file, relative to the launch's working directory [from config]
  scenario:=FILE                     threat scenario (docs/SCENARIOS.md): jammers, spoofers, receiver faults;
                                     truth labels on /gnss/threats/active [from config: none]
  strict_world:=true|false          stop when the world loses geometry it names (a model:// not found) or load
                                     the rest with a warning [from config: true]
  robots:=N                          N robots (1..16): each its trajectory player, visibility and receiver node in
                                     namespace robot<k> (/robot<k>/gnss/fix, TF frames robot<k>/..., RINEX in
                                     output_dir/robot<k>), a convoy convoy_spacing_s apart along the path (or
                                     robot_trajectory_files); one ephemeris node (/gnss/satellite_states) [1]

Every node is a lifecycle node driven by the `lifecycle_manager` process, in
both modes; `ros2 lifecycle set /gnss_sim_receiver ...` works on each, and
`ros2 component load /gnss_sim_container gnss_sim gnss_sim::ReceiverNode -n NAME`
adds a node to the running container.
"""
import importlib.util
import os
import shutil
import tempfile

import yaml
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, ExecuteProcess, OpaqueFunction, RegisterEventHandler
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import ComposableNodeContainer, LifecycleNode, Node
from launch_ros.descriptions import ComposableNode

from gnss_sim_ros2 import graph
from gnss_sim_ros2.config_file import load_config
from gnss_sim_ros2.core.receiver.profile_file import builtin_names
from gnss_sim_ros2.graph_params import LAUNCH_FALSE, LAUNCH_TRUE, check_robot_config, check_robots, launch_flag

#: launch argument -> (default, description): `ros2 launch gnss_sim sim.launch.py --show-args` prints them
ARGS = {
    "world": ("", "Gazebo world (SDF) for visibility; empty: the config's world_file (the demo courtyard)"),
    "mesh": ("", "scene mesh exported by `gnss-sim export-world` (instead of world)"),
    "config": ("", "gnss_sim parameter file (ROS 2 format); empty: the package's config/gnss_sim.yaml defaults"),
    "composed": ("true", "true: every node in one container; false: one process per node; robot: one container "
                         "per robot; fleet: one container, one visibility and one receiver node for every robot"),
    "use_sim_time": ("true", "follow /clock (Gazebo or the trajectory player)"),
    "trajectory_player": ("true", "move the robot along a path here; false when Gazebo publishes TF"),
    "record": ("false", "record the gnss_sim topics into output_dir/bag (MCAP)"),
    "output_dir": ("gnss_sim_output", "folder of the RINEX files (and the bag)"),
    "antenna_frame": ("", "TF frame of the antenna; empty: the config's antenna_frame"),
    "autostart": ("true", "configure and activate the nodes (lifecycle manager)"),
    "rtk": ("false", "RTK: a base station and the rtk node (RTKLIB rtkrcv) publishing /gnss/rtk/fix"),
    "quality_map": ("false", "the GNSS-quality layer for Nav2: the planner's quality over the world as an "
                             "OccupancyGrid on /gnss/quality_map (0: RTK expected .. 100: no fix; docs/PLANNING.md) "
                             "and the path service /gnss/path_quality"),
    "robots": ("1", "number of robots (1..16), each in namespace robot<k>"),
    "profile": ("", f"receiver profile: a built-in name ({', '.join(builtin_names())}) or a profile YAML file "
                    f"(docs/PROFILES.md), relative to the working directory; empty: the config's profile"),
    "scenario": ("", "threat scenario file (YAML, docs/SCENARIOS.md): timed jammers, spoofers and receiver faults, "
                     "relative to the working directory; empty: the config's scenario"),
    "strict_world": ("", "true: stop when the world loses geometry it names (a model:// not found, an unreadable "
                         "mesh); false: load the rest with a warning; empty: the config's strict_world"),
}
CONTAINER = "gnss_sim_container"




def _stop_launch_if_failed(action, what: str):
    """A recorder or container that exits with an error ends the launch (no run without the bag asked
    for; no lifecycle manager waiting for nodes that will never come)."""
    def on_exit(event, _context):
        if event.returncode != 0:
            return [EmitEvent(event=Shutdown(reason=f"{what} exited with code {event.returncode}"))]
        return None

    return RegisterEventHandler(OnProcessExit(target_action=action, on_exit=on_exit))


def _recorder(output_dir: str, rtk: bool = False, robots: int = 1) -> list:
    bag = os.path.join(output_dir, "bag")
    if os.path.exists(bag):
        raise ValueError(f"record:=true: the bag folder {bag} exists already (rosbag2 does not overwrite); "
                           "choose another output_dir:= or remove it")
    if shutil.which("ros2") and importlib.util.find_spec("ros2bag") is not None:
        topics = [*(t for t, _ in graph.recorded(robots)), *(t for t, _ in graph.RECORDED_RTK if rtk)]
        proc = ExecuteProcess(cmd=["ros2", "bag", "record", "-s", "mcap", "-o", bag, *topics],
                              output="screen")
        return [proc, _stop_launch_if_failed(proc, "ros2 bag record")]
    if importlib.util.find_spec("rosbags") is not None:
        proc = Node(package=graph.PACKAGE, executable="recorder", name="gnss_sim_recorder", output="screen",
                    parameters=[{"bag_dir": bag, "rtk": rtk, "robots": robots}])
        return [proc, _stop_launch_if_failed(proc, "the gnss_sim recorder")]
    raise RuntimeError("record:=true: nothing can record here: `ros2 bag` (rosbag2, e.g. ros-<distro>-rosbag2) is "
                       "not installed and neither is the Python package rosbags (pip install rosbags) that "
                       "gnss_sim's recorder uses")


def _write_params(params: dict, name: str) -> str:
    path = os.path.join(tempfile.mkdtemp(prefix="gnss_sim_launch_"), name)
    with open(path, "w") as f:
        yaml.safe_dump(params, f, sort_keys=False)
    return path


#: composed:= values -> process layout (gnss_sim_ros2.graph.LAYOUTS)
COMPOSED_LAYOUTS = {**dict.fromkeys(LAUNCH_TRUE, "composed"), **dict.fromkeys(LAUNCH_FALSE, "node"), "robot": "robot",
                    "fleet": "fleet"}
#: the true/false launch arguments (graph_params.launch_flag)
SWITCHES = ("use_sim_time", "trajectory_player", "record", "autostart", "rtk", "quality_map")


def layout_of(composed: str) -> str:
    """The process layout of the composed:= argument; ValueError naming it."""
    layout = COMPOSED_LAYOUTS.get(composed.strip().lower())
    if layout is None:
        raise ValueError(f"launch argument composed is {composed!r}; one of true (one container), false (one "
                         f"process per node), robot (one container per robot), fleet (one container, one "
                         f"visibility and one receiver node for every robot)")
    return layout


def _container(name: str, namespace: str, specs, params, sim_time: bool) -> list:
    container = ComposableNodeContainer(
        package=graph.PACKAGE, executable="container", name=name, namespace=namespace, output="screen",
        parameters=[{"use_sim_time": sim_time}],
        composable_node_descriptions=[
            ComposableNode(package=graph.PACKAGE, plugin=spec.plugin, name=spec.name, namespace=spec.namespace,
                           parameters=params, remappings=list(graph.remappings_of(spec)))
            for spec in specs])
    where = f"/{namespace}/{name}" if namespace else f"/{name}"
    return [container, _stop_launch_if_failed(container, f"the component container {where}")]


def _setup(context):
    a = {k: LaunchConfiguration(k).perform(context) for k in ARGS}
    if not a["output_dir"].strip():       # os.path.abspath('') is the working directory: a silent default
        raise ValueError("launch argument output_dir is empty: give the folder of the RINEX files (and the bag)")
    flag = {k: launch_flag(a[k], k) for k in SWITCHES}     # every switch checked before anything starts
    shared = {"output_dir": os.path.abspath(a["output_dir"])}
    if a["antenna_frame"]:
        shared["antenna_frame"] = a["antenna_frame"]
    overrides = {"/**": shared}
    if a["world"]:
        overrides["visibility"] = {"world_file": os.path.abspath(a["world"]), "mesh_file": ""}
    if a["mesh"]:
        overrides["visibility"] = {"mesh_file": os.path.abspath(a["mesh"]), "world_file": ""}
    if a["strict_world"]:     # checked by the parameter table (load_config) like the file's value
        overrides.setdefault("visibility", {})["strict_world"] = yaml.safe_load(a["strict_world"])
    if a["profile"]:          # loaded and checked by the table; a file kept as its absolute path
        overrides.setdefault("receiver", {})["profile"] = a["profile"]
    if a["scenario"]:         # read and checked by the table; kept as its absolute path
        overrides.setdefault("receiver", {})["scenario"] = a["scenario"]
    layout = layout_of(a["composed"])
    rtk = flag["rtk"]
    robots = check_robots(a["robots"], "launch argument robots", fleet=layout == "fleet")
    if rtk and robots > 1:
        raise ValueError(f"launch arguments rtk:=true and robots:={robots} do not go together: an RTK run has one "
                         f"rover (and its base station); use robots:=1 with rtk:=true")
    if rtk:
        overrides.setdefault("receiver", {})["rtcm"] = True      # the rover's RTCM3 for the rtk node
    cfg = load_config(a["config"] or None, overrides, {"strict_world": "strict_world:=", "profile": "profile:=",
                                                         "scenario": "scenario:="})
    check_robot_config(cfg, robots, "launch argument robots")
    sim_time = flag["use_sim_time"]
    quality_map = flag["quality_map"]
    params = {**cfg.ros_parameter_file_dict(), **(graph.rtk_parameter_sections(cfg) if rtk else {}),
              **(graph.quality_map_parameter_sections(cfg) if quality_map else {}),
              **graph.robot_parameter_sections(cfg, robots)}
    specs = graph.nodes(flag["trajectory_player"], robots, layout == "fleet") + \
        (graph.rtk_nodes(cfg) if rtk else []) + ([graph.QUALITY_MAP_NODE] if quality_map else [])
    # the fleet layout's visibility and receiver node: the configuration's, serving every robot (fleet_robots)
    params.update({s.name: {"ros__parameters": graph.node_parameters(cfg, s, robots)}
                   for s in specs if s.instance == graph.FLEET_INSTANCE})
    params["/**"] = {"ros__parameters": {"use_sim_time": sim_time}}  # every node, composed or not
    params_file = _write_params(params, "params.yaml")
    node_params = [params_file, {"use_sim_time": sim_time}]
    # launch_ros turns a composable node's parameter file into Parameter messages and rejects empty
    # lists; every list parameter whose value is empty has the empty list as its default: leave them out
    composable_params = [_write_params({node: {"ros__parameters": {k: v for k, v in sec["ros__parameters"].items()
                                                                  if v != []}}
                                        for node, sec in params.items()}, "composable_params.yaml"),
                         {"use_sim_time": sim_time}]
    actions = []
    if flag["record"]:  # first: a recorder that cannot start fails the launch before any node runs
        actions += _recorder(shared["output_dir"], rtk, robots)
    if layout in ("composed", "fleet"):
        actions += _container(CONTAINER, "", specs, composable_params, sim_time)
    elif layout == "robot":
        actions += _container(CONTAINER, "", [s for s in specs if graph.robot_of(s) is None], composable_params,
                              sim_time)
        for k, group in graph.robot_groups(specs).items():
            actions += _container(graph.ROBOT_CONTAINER, graph.robot_container_namespace(k, robots), group,
                                  composable_params, sim_time)
    else:
        for spec in specs:
            actions.append(LifecycleNode(package=graph.PACKAGE, executable=spec.executable, name=spec.name,
                                         namespace=spec.namespace, output="screen",
                                         remappings=list(graph.remappings_of(spec)),
                                         parameters=node_params))
    actions.append(Node(package=graph.PACKAGE, executable="lifecycle_manager", name="gnss_sim_lifecycle_manager",
                        output="screen", parameters=[{"node_names": [s.path for s in specs],
                                                      "autostart": flag["autostart"],
                                                      "use_sim_time": sim_time}]))
    return actions


def generate_launch_description():
    return LaunchDescription([DeclareLaunchArgument(k, default_value=v, description=d) for k, (v, d) in ARGS.items()]
                             + [OpaqueFunction(function=_setup)])
