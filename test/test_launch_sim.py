"""launch_testing: `ros2 launch gnss_sim sim.launch.py` on a ROS 2 install.

Here (PyPI wheels, no launch/launch_testing on PyPI) this module is skipped;
the same scenarios run through pytest in test_run_graph.py.
On a ROS install: `launch_test test/test_launch_sim.py` (or colcon test).
"""
import os
import tempfile
import time
import unittest

import pytest

pytest.importorskip("launch_testing",
                    reason="launch_testing is not on PyPI: runs on a ROS 2 install (test_run_graph.py covers it here)")
import launch  # noqa: E402
import launch_testing.actions  # noqa: E402
import rclpy  # noqa: E402
from ament_index_python.packages import get_package_share_directory  # noqa: E402
from launch.launch_description_sources import PythonLaunchDescriptionSource  # noqa: E402

OUT = tempfile.mkdtemp(prefix="gnss_sim_launch_test_")


@pytest.mark.launch_test
def generate_test_description():
    sim = launch.actions.IncludeLaunchDescription(
        PythonLaunchDescriptionSource(os.path.join(get_package_share_directory("gnss_sim"), "launch",
                                                   "sim.launch.py")),
        launch_arguments={"output_dir": OUT, "use_sim_time": "false", "composed": "true"}.items())
    return launch.LaunchDescription([sim, launch_testing.actions.ReadyToTest()])


class TestFixFlows(unittest.TestCase):
    def test_fix_and_rinex(self):
        from sensor_msgs.msg import NavSatFix

        rclpy.init()
        node = rclpy.create_node("gnss_sim_launch_test")
        got = []
        node.create_subscription(NavSatFix, "/gnss/fix", got.append, 10)
        deadline = time.monotonic() + 60
        while len(got) < 3 and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
        node.destroy_node()
        rclpy.shutdown()
        self.assertGreaterEqual(len(got), 3)
        self.assertTrue(any(f.endswith("_MO.rnx") for f in os.listdir(OUT)))
