"""ros2 launch gnss_sim sim.launch.py [world:=...] [config:=...] [composed:=true] ...

The same node graph as `gnss-sim run` (gnss_sim_ros2/graph.py), with the
parameters of one file (config:=, default the package's config/gnss_sim.yaml)
merged with these launch arguments by gnss_sim_ros2.parameters.load_config.

Arguments:
  world:=FILE.sdf | mesh:=FILE.ply   scene (default: the demo courtyard)
  config:=FILE.yaml                  gnss_sim parameter file
  composed:=true|false               all nodes in one process, or one process per node
  use_sim_time:=true|false           follow /clock (Gazebo) [true]
  trajectory_player:=true|false      move the robot along a path here; false when Gazebo publishes TF [true]
  record:=true|false                 ros2 bag record -s mcap of the gnss_sim topics [false]
  output_dir:=DIR                    RINEX files (and the bag) [gnss_sim_output]
  antenna_frame:=FRAME               TF frame of the antenna [from config]
  autostart:=true|false              configure and activate the nodes [true]
"""
import os
import tempfile

import yaml
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import LifecycleNode, Node

from gnss_sim_ros2 import graph
from gnss_sim_ros2.parameters import load_config

ARGS = {
    "world": "", "mesh": "", "config": "", "composed": "true", "use_sim_time": "true", "trajectory_player": "true",
    "record": "false", "output_dir": "gnss_sim_output", "antenna_frame": "", "autostart": "true",
}


def _true(v: str) -> bool:
    return v.lower() in ("true", "1", "yes", "on")


def _setup(context):
    a = {k: LaunchConfiguration(k).perform(context) for k in ARGS}
    shared = {"output_dir": os.path.abspath(a["output_dir"])}
    if a["antenna_frame"]:
        shared["antenna_frame"] = a["antenna_frame"]
    overrides = {"/**": shared}
    if a["world"]:
        overrides["visibility"] = {"world_file": os.path.abspath(a["world"]), "mesh_file": ""}
    if a["mesh"]:
        overrides["visibility"] = {"mesh_file": os.path.abspath(a["mesh"]), "world_file": ""}
    cfg = load_config(a["config"] or None, overrides)
    sim_time = _true(a["use_sim_time"])
    params = cfg.ros_parameter_file_dict()
    params["/**"] = {"ros__parameters": {"use_sim_time": sim_time}}  # every node, composed or not
    params_file = os.path.join(tempfile.mkdtemp(prefix="gnss_sim_launch_"), "params.yaml")
    with open(params_file, "w") as f:
        yaml.safe_dump(params, f, sort_keys=False)
    specs = graph.nodes(_true(a["trajectory_player"]))
    remaps = list(graph.REMAPPINGS)
    actions = []
    if _true(a["composed"]):
        actions.append(Node(package="gnss_sim", executable="container", name="gnss_sim_container", output="screen",
                            parameters=[params_file, {"use_sim_time": sim_time, "autostart": _true(a["autostart"]),
                                                      "trajectory_player": _true(a["trajectory_player"])}],
                            remappings=remaps))
    else:
        for spec in specs:
            actions.append(LifecycleNode(package="gnss_sim", executable=spec.executable, name=spec.name,
                                         namespace="", output="screen", remappings=remaps,
                                         parameters=[params_file, {"use_sim_time": sim_time}]))
        actions.append(Node(package="gnss_sim", executable="lifecycle_manager", name="gnss_sim_lifecycle_manager",
                            output="screen", parameters=[{"node_names": [s.name for s in specs],
                                                          "autostart": _true(a["autostart"]),
                                                          "use_sim_time": sim_time}]))
    if _true(a["record"]):
        bag = os.path.join(shared["output_dir"], "bag")
        actions.append(ExecuteProcess(cmd=["ros2", "bag", "record", "-s", "mcap", "-o", bag,
                                           *graph.RECORDED_TOPICS], output="screen"))
    return actions


def generate_launch_description():
    return LaunchDescription([DeclareLaunchArgument(k, default_value=v) for k, v in ARGS.items()]
                             + [OpaqueFunction(function=_setup)])
