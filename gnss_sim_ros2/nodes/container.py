"""All gnss_sim nodes in one process (``composed:=true`` of sim.launch.py).

rclpy has no component container for Python nodes, so this executable plays
that role: it builds every node of the graph (gnss_sim_ros2/graph.py) in one
process and spins them in one executor.  The global ``--ros-args`` of the
process (``--params-file``, remappings, ``use_sim_time``) reach every node, as
in a component container.  ``-p autostart:=true`` (the default) configures
and activates them; ``-p trajectory_player:=false`` leaves the robot's TF to
Gazebo.
"""
from __future__ import annotations

import importlib
import sys

import rclpy
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor

from gnss_sim_ros2 import graph
from gnss_sim_ros2.nodes.manager import LocalNodes, TransitionFailed


def main(args=None) -> int:
    rclpy.init(args=args)
    ctl = rclpy.create_node("gnss_sim_container")
    autostart = ctl.declare_parameter("autostart", True).value
    with_player = ctl.declare_parameter("trajectory_player", True).value
    nodes = []
    for spec in graph.nodes(with_player):
        cls = getattr(importlib.import_module(spec.module), spec.cls)
        nodes.append(cls())
    executor = MultiThreadedExecutor(num_threads=2)
    for n in [ctl] + nodes:
        executor.add_node(n)
    code = 0
    try:
        if autostart:
            manager = LocalNodes(nodes)
            manager.transition("configure")
            manager.transition("activate")
        executor.spin()
    except TransitionFailed as exc:
        ctl.get_logger().error(str(exc))
        code = 3
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        for n in nodes:
            n.release()
            n.destroy_node()
        ctl.destroy_node()
        rclpy.try_shutdown()
    return code


if __name__ == "__main__":
    sys.exit(main())
