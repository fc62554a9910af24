"""launch_testing: `ros2 launch gnss_sim sim.launch.py robots:=2 record:=true` with the real launch tools.

    launch_test test/test_launch_robots.py     # a ROS 2 install, or .venv-launch (make test)

Composed (the nodes as components of gnss_sim's container) on a simulated clock that the test
publishes 4x faster than real time, two robots in a convoy along the demo path.  Checked: every node
active (one ephemeris node; robot<k>/gnss_sim_trajectory_player, robot<k>/gnss_sim_visibility,
robot<k>/gnss_sim_receiver), fixes on /robot0/gnss/fix and /robot1/gnss/fix on the epoch grid, none on
/gnss/fix, the two robots' fixes apart by about the convoy spacing; then SIGINT: every process exits 0
without a traceback, each robot's RINEX in output_dir/robot<k>, the bag (recorder) holds both robots'
fixes and one /gnss/satellite_states.

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
import numpy as np  # noqa: E402
import pymap3d  # noqa: E402
import yaml  # noqa: E402
from launch_helpers import ExitsCleanly, RobotLaunchCase, check_robot_rinex, sim_launch_description, stamp_s  # noqa: E402,E501

from gnss_sim_ros2 import graph  # noqa: E402

ROBOTS = 2
SPEED = 4.0                     # simulated seconds per wall second
RUN_S = 25.0                    # demo path: open ground south of the block (1 m/s northwards) up to here
SPACING_S = 5.0                 # convoy_spacing_s of the test's configuration: 5 m apart on the demo path
NODE_PATHS = tuple(s.path for s in graph.nodes(True, ROBOTS))
OUT = Path(tempfile.mkdtemp(prefix="gnss_sim_launch_robots_"))
MARKER = "LTRB"


@pytest.mark.launch_test
def generate_test_description():
    return sim_launch_description(OUT, {"/**": {"rate_hz": 1.0, "marker_name": MARKER},
                                        "gnss_sim_trajectory_player": {"convoy_spacing_s": SPACING_S}},
                                  {"robots": str(ROBOTS), "record": "true"})


class TestRobotsLaunch(RobotLaunchCase, unittest.TestCase):
    SPEED, ROBOTS = SPEED, ROBOTS

    def test_1_every_node_active(self):
        self.assert_all_active(NODE_PATHS)
        self.assertEqual(sum(1 for n in NODE_PATHS if n.endswith("gnss_sim_ephemeris")), 1)
        self.probe.start_clock()

    def test_2_each_robot_its_fixes(self):
        fixes = self.robot_fixes_until(RUN_S, RUN_S / SPEED + 90.0)
        by_stamp = []
        for k in range(ROBOTS):
            by_stamp.append({round(stamp_s(f.header.stamp), 3): f for f in self.valid_fixes(fixes[k], k)})
        common = sorted(set(by_stamp[0]) & set(by_stamp[1]))
        self.assertGreater(len(common), 10)
        gaps = []
        for t in common:
            a, b = by_stamp[0][t], by_stamp[1][t]
            e, n, _ = pymap3d.geodetic2enu(b.latitude, b.longitude, b.altitude, a.latitude, a.longitude, a.altitude)
            gaps.append(float(np.hypot(e, n)))
        # 1 m/s on open ground: SPACING_S seconds apart is SPACING_S metres, the fixes good to a few metres
        self.assertAlmostEqual(float(np.median(gaps)), SPACING_S, delta=3.0, msg=f"gaps {np.round(gaps, 1)}")


@launch_testing.post_shutdown_test()
class TestAfterSigint(ExitsCleanly, unittest.TestCase):
    def test_rinex_per_robot(self):
        check_robot_rinex(self, OUT / "out", ROBOTS, MARKER, 10)

    def test_bag_has_both_robots(self):
        meta = yaml.safe_load((OUT / "out" / "bag" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        counts = {t["topic_metadata"]["name"]: t["message_count"] for t in meta["topics_with_message_count"]}
        for k in range(ROBOTS):
            self.assertGreater(counts.get(f"/robot{k}/gnss/fix", 0), 10, counts)
            self.assertGreater(counts.get(f"/robot{k}/gnss/observations", 0), 10, counts)
        self.assertGreater(counts.get("/gnss/satellite_states", 0), 10, counts)
        self.assertEqual(counts.get("/gnss/fix", 0), 0, counts)
