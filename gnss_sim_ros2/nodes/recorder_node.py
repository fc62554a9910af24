"""``ros2 run gnss_sim recorder --ros-args -p bag_dir:=DIR``: the project's rosbag2 (MCAP) recorder
(gnss_sim_ros2/recorder.py) as a node of a launch, where ``ros2 bag`` does not exist.

Records graph.recorded(robots) (every robot's topics, parameter ``robots``) until SIGINT/SIGTERM,
then closes the bag (exit 0).  A bag folder that exists already, or no ``bag_dir``, is an error (exit 2).
"""
from __future__ import annotations

import sys
from pathlib import Path

import rclpy

from gnss_sim_ros2.nodes.common import close_ros, init_ros, make_executor, spin_until_stopped


def main(args=None) -> int:
    stop = init_ros(args)
    node = rclpy.create_node("gnss_sim_recorder")
    bag_dir = node.declare_parameter("bag_dir", "").value
    rtk = node.declare_parameter("rtk", False).value        # also the RTK topics (graph.RECORDED_RTK)
    robots = node.declare_parameter("robots", 1).value      # every robot's topics (graph.recorded)
    executor = make_executor()
    executor.add_node(node)
    recorder = None
    try:
        if not bag_dir:
            raise ValueError("node gnss_sim_recorder: parameter 'bag_dir' is empty (the bag folder to write)")
        from gnss_sim_ros2.graph import RECORDED_RTK, recorded
        from gnss_sim_ros2.graph_params import check_robots
        from gnss_sim_ros2.recorder import BagRecorder

        topics = recorded(check_robots(robots, "node gnss_sim_recorder: parameter 'robots'"))
        recorder = BagRecorder(node, Path(bag_dir), topics + (RECORDED_RTK if rtk else ()))
        node.get_logger().info(f"recording into {bag_dir}")
        spin_until_stopped(executor, stop)
    except ValueError as exc:
        node.get_logger().error(str(exc))
        return 2
    finally:
        if recorder is not None:
            recorder.close()
        close_ros(executor, node)
    return 0


if __name__ == "__main__":
    sys.exit(main())
