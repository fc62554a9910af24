"""Lifecycle manager executable: configures, then activates, the named nodes at start.

Parameters: ``node_names`` (string array, upstream first), ``autostart``
(bool).  A failing transition is logged with the node's name and the process
exits with code 3, so ``ros2 launch`` shows the error and stops the start.
"""
from __future__ import annotations

import sys

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.parameter import Parameter

from gnss_sim_ros2.nodes.manager import RemoteNodes, TransitionFailed


def main(args=None) -> int:
    rclpy.init(args=args)
    node = rclpy.create_node("gnss_sim_lifecycle_manager")
    names = node.declare_parameter("node_names", Parameter.Type.STRING_ARRAY).value or []
    autostart = node.declare_parameter("autostart", True).value
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    code = 0
    try:
        if autostart and names:
            manager = RemoteNodes(node, names, executor)
            manager.wait_for_services()
            manager.transition("configure")
            manager.transition("activate")
            node.get_logger().info(f"active: {', '.join(names)}")
        executor.spin()
    except TransitionFailed as exc:
        node.get_logger().error(str(exc))
        code = 3
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return code


if __name__ == "__main__":
    sys.exit(main())
