"""launch_testing: `ros2 launch gnss_sim sim.launch.py robots:=2 composed:=robot`, one container per robot.

    launch_test test/test_launch_robot_layout.py     # a ROS 2 install, or .venv-launch (make test)

Each robot's trajectory player, visibility and receiver are components of a container of its own
(/robot<k>/gnss_sim_robot_container, one process per robot), the shared ephemeris node of
/gnss_sim_container; on a simulated clock the test publishes 4x faster than real time.  Checked: each
container lists exactly its nodes (composition_interfaces ListNodes), every node active, fixes on
/robot0/gnss/fix and /robot1/gnss/fix on the epoch grid; then SIGINT: every process exits 0 without a
traceback and each robot's RINEX is in output_dir/robot<k>.

Under plain pytest (the main suite) this module is skipped: launch tests run with `launch_test`.
"""
import os
import sys
import tempfile
import unittest
from pathlib import Path

import pytest

pytest.importorskip("launch_testing", reason="launch_testing is not installed here: `make test` runs this file "
                    "with launch_test in .venv-launch (../shared/ros2-tools); on a ROS install: launch_test FILE")
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # launch_helpers (launch_test adds no path)
import launch_testing  # noqa: E402
from composition_interfaces.srv import ListNodes  # noqa: E402
from launch_helpers import ExitsCleanly, RobotLaunchCase, check_robot_rinex, sim_launch_description  # noqa: E402

from gnss_sim_ros2 import graph  # noqa: E402

ROBOTS = 2
SPEED = 4.0                     # simulated seconds per wall second
RUN_S = 12.0
SPECS = graph.nodes(True, ROBOTS)
NODE_PATHS = tuple(s.path for s in SPECS)
OUT = Path(tempfile.mkdtemp(prefix="gnss_sim_launch_robot_layout_"))
MARKER = "LTRL"


@pytest.mark.launch_test
def generate_test_description():
    return sim_launch_description(OUT, {"/**": {"rate_hz": 1.0, "marker_name": MARKER, "systems": "GE"}},
                                  {"robots": str(ROBOTS), "composed": "robot"})


class TestRobotLayout(RobotLaunchCase, unittest.TestCase):
    SPEED, ROBOTS = SPEED, ROBOTS

    def test_1_each_container_its_nodes_every_node_active(self):
        probe = self.probe
        self.assert_all_active(NODE_PATHS)
        expected = {"/gnss_sim_container": {"/gnss_sim_ephemeris"}}
        for k in range(ROBOTS):
            expected[f"/robot{k}/{graph.ROBOT_CONTAINER}"] = {f"/{s.path}" for s in SPECS if s.robot == k}
        for container, nodes in expected.items():
            listed = probe.call(ListNodes, f"{container}/_container/list_nodes", ListNodes.Request())
            self.assertEqual(set(listed.full_node_names), nodes, container)
        self.assertEqual(len(expected[f"/robot1/{graph.ROBOT_CONTAINER}"]), 3)
        probe.start_clock()

    def test_2_each_robot_its_fixes(self):
        self.robot_fixes_until(RUN_S, RUN_S / SPEED + 90.0)


@launch_testing.post_shutdown_test()
class TestAfterSigint(ExitsCleanly, unittest.TestCase):
    def test_rinex_per_robot(self):
        check_robot_rinex(self, OUT / "out", ROBOTS, MARKER, 5)
