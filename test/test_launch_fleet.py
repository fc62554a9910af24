"""launch_testing: `ros2 launch gnss_sim sim.launch.py robots:=4 composed:=fleet`, the fleet layout.

    launch_test test/test_launch_fleet.py     # a ROS 2 install, or .venv-launch (make test)

One container (/gnss_sim_container) holding the four robots' trajectory players, the ephemeris node, ONE visibility
node (gnss_sim_fleet_visibility: every robot's antenna in one cast per epoch) and ONE receiver node
(gnss_sim_fleet_receiver: every robot's chain), on a simulated clock the test publishes 4x faster than real
time.  Checked: the container lists exactly those nodes (composition_interfaces ListNodes), every node active,
fixes on every /robot<k>/gnss/fix on the epoch grid (none on /gnss/fix), the convoy's robots apart; then SIGINT:
every process exits 0 without a traceback and each robot's RINEX is in output_dir/robot<k>.

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
from composition_interfaces.srv import ListNodes  # noqa: E402
from launch_helpers import ExitsCleanly, RobotLaunchCase, check_robot_rinex, sim_launch_description, stamp_s  # noqa: E402,E501

from gnss_sim_ros2 import graph  # noqa: E402

ROBOTS = 4
SPEED = 4.0                     # simulated seconds per wall second
RUN_S = 12.0
SPACING_S = 3.0                 # convoy_spacing_s: 3 m apart on the demo path (1 m/s)
SPECS = graph.nodes(True, ROBOTS, fleet=True)
NODE_PATHS = tuple(s.path for s in SPECS)
OUT = Path(tempfile.mkdtemp(prefix="gnss_sim_launch_fleet_"))
MARKER = "LTFL"


@pytest.mark.launch_test
def generate_test_description():
    return sim_launch_description(OUT, {"/**": {"rate_hz": 1.0, "marker_name": MARKER, "systems": "GE"},
                                        "gnss_sim_trajectory_player": {"convoy_spacing_s": SPACING_S}},
                                  {"robots": str(ROBOTS), "composed": "fleet"})


class TestFleetLayout(RobotLaunchCase, unittest.TestCase):
    SPEED, ROBOTS = SPEED, ROBOTS

    def test_1_one_container_one_visibility_one_receiver_every_node_active(self):
        probe = self.probe
        self.assert_all_active(NODE_PATHS)
        listed = probe.call(ListNodes, "/gnss_sim_container/_container/list_nodes", ListNodes.Request())
        self.assertEqual(set(listed.full_node_names), {f"/{p}" for p in NODE_PATHS})
        self.assertEqual(sum(1 for n in NODE_PATHS if "visibility" in n), 1)
        self.assertEqual(sum(1 for n in NODE_PATHS if "receiver" in n), 1)
        probe.start_clock()

    def test_2_every_robot_its_fixes_on_the_epoch_grid(self):
        fixes = self.robot_fixes_until(RUN_S, RUN_S / SPEED + 120.0)
        last = {}
        for k in range(ROBOTS):
            t = np.array([stamp_s(f.header.stamp) for f in fixes[k]])
            self.assertTrue(np.allclose(t, np.round(t)), f"robot{k}: stamps off the 1 Hz grid {t}")
            last[k] = self.valid_fixes(fixes[k], k)[-1]
        # the convoy: robot k + 1 is SPACING_S metres from robot k (fixes good to a few metres)
        a, b = last[0], last[ROBOTS - 1]
        e, n, _ = pymap3d.geodetic2enu(b.latitude, b.longitude, b.altitude, a.latitude, a.longitude, a.altitude)
        self.assertAlmostEqual(float(np.hypot(e, n)), SPACING_S * (ROBOTS - 1), delta=4.0)


@launch_testing.post_shutdown_test()
class TestAfterSigint(ExitsCleanly, unittest.TestCase):
    def test_rinex_per_robot(self):
        check_robot_rinex(self, OUT / "out", ROBOTS, MARKER, 5)
