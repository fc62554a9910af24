"""Lifecycle manager executable: configures, then activates, the named nodes at start.

Parameters: ``node_names`` (string array, upstream first; nodes in other
processes or in a component container alike, through their lifecycle
services), ``autostart`` (bool), ``service_timeout_s`` (how long to wait for
the nodes to appear: a container loads them one after the other).  A failing
transition is logged with the node's name and the process exits with code 3,
so ``ros2 launch`` shows the error.  SIGINT/SIGTERM end it with code 0.
"""
from __future__ import annotations

import sys

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter

from gnss_sim_ros2.nodes.common import close_ros, init_ros, spin_until_stopped
from gnss_sim_ros2.nodes.manager import RemoteNodes, TransitionFailed


def main(args=None) -> int:
    stop = init_ros(args)
    node = rclpy.create_node("gnss_sim_lifecycle_manager")
    names = node.declare_parameter("node_names", Parameter.Type.STRING_ARRAY).value or []
    autostart = node.declare_parameter("autostart", True).value
    timeout_s = node.declare_parameter("service_timeout_s", 120.0).value
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    code = 0
    try:
        if autostart and names:
            manager = RemoteNodes(node, names, executor, should_stop=lambda: stop.stopped)
            manager.wait_for_services(timeout_s)
            manager.transition("configure")
            manager.transition("activate")
            if not stop.stopped:
                node.get_logger().info(f"active: {', '.join(names)}")
        spin_until_stopped(executor, stop)
    except TransitionFailed as exc:
        node.get_logger().error(str(exc))
        code = 3
    finally:
        close_ros(executor, node)
    return code


if __name__ == "__main__":
    sys.exit(main())
