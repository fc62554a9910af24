"""launch_testing: `ros2 launch gnss_sim sim.launch.py quality_map:=true` with the real launch tools.

    launch_test test/test_launch_quality_map.py     # a ROS 2 install, or .venv-launch (make test)

Composed, on a simulated clock the test publishes 4x faster than real time, with the GNSS-quality layer
(gnss_sim_quality_map). Checked: the node active beside the chain; a late subscriber (transient_local, as
Nav2's static layer subscribes to /map) receives a nav_msgs/OccupancyGrid in frame world whose origin and
resolution place it on the demo courtyard (its ground plane spans x, y -100..100 m: worlds/courtyard.sdf) at
the configured grid_step_m, values 0..100, 0 (RTK expected) on open ground far from the buildings; the service
/gnss/path_quality answers a path from the open ground into the yard pose by pose; then SIGINT: every process
exits 0 without a traceback.

Under plain pytest (the main suite) this module is skipped: launch tests run with `launch_test`.
"""
import os
import sys
import tempfile
import threading
import unittest
from pathlib import Path

import pytest

pytest.importorskip("launch_testing", reason="launch_testing is not installed here: `make test` runs this file "
                    "with launch_test in .venv-launch (../shared/ros2-tools); on a ROS install: launch_test FILE")
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # launch_helpers (launch_test adds no path)
import launch_testing  # noqa: E402
from geometry_msgs.msg import PoseStamped  # noqa: E402
from gnss_sim_msgs.srv import PathQuality  # noqa: E402
from launch_helpers import NODES, ExitsCleanly, Probe, sim_launch_description  # noqa: E402
from nav_msgs.msg import OccupancyGrid  # noqa: E402
from nav_msgs.msg import Path as NavPath  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402

from gnss_sim_ros2 import graph  # noqa: E402

SPEED = 4.0
STEP_M = 5.0
OUT = Path(tempfile.mkdtemp(prefix="gnss_sim_launch_quality_map_"))


@pytest.mark.launch_test
def generate_test_description():
    return sim_launch_description(OUT, {"/**": {"rate_hz": 1.0, "marker_name": "LQMP"},
                                        "gnss_sim_quality_map": {"grid_step_m": STEP_M}}, {"quality_map": "true"})


class TestQualityMapLaunch(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.probe = Probe(SPEED)
        cls.lock = threading.Lock()
        cls.grids = []

    @classmethod
    def tearDownClass(cls):
        cls.probe.close()

    def _on_grid(self, msg):
        with self.lock:
            self.grids.append(msg)

    def test_1_nodes_active(self):
        probe = self.probe
        names = NODES + (graph.QUALITY_MAP_NODE.name,)
        ok = probe.wait_for(lambda: all(probe.state_or_none(n) == "active" for n in names), 180.0)
        self.assertTrue(ok, {n: probe.state_or_none(n) for n in names})
        probe.start_clock()

    def test_2_latched_grid_on_the_world(self):
        qos = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
        self.probe.node.create_subscription(OccupancyGrid, "/gnss/quality_map", self._on_grid, qos)
        self.assertTrue(self.probe.wait_for(lambda: bool(self.grids), 60.0), "no grid on /gnss/quality_map")
        with self.lock:
            g = self.grids[-1]
        self.assertEqual(g.header.frame_id, "world")
        self.assertAlmostEqual(g.info.resolution, STEP_M, places=6)
        self.assertEqual((g.info.origin.position.x, g.info.origin.position.y), (-100.0, -100.0))
        self.assertEqual((g.info.width, g.info.height), (40, 40))
        data = list(g.data)
        self.assertEqual(len(data), 1600)
        self.assertTrue(all(0 <= v <= 100 for v in data))
        # open ground 70-90 m from the centre: RTK expected
        for x, y in ((-90.0, -90.0), (90.0, 90.0), (-90.0, 90.0), (85.0, -85.0)):
            i = int((x + 100.0) // STEP_M)
            j = int((y + 100.0) // STEP_M)
            self.assertEqual(data[j * 40 + i], 0, (x, y))

    def test_3_path_service(self):
        req = PathQuality.Request()
        req.path = NavPath()
        for y in (-60.0, -30.0, 0.0):
            p = PoseStamped()
            p.pose.position.y = y
            req.path.poses.append(p)
        req.start_time.sec = 10
        req.speed_mps = 1.5
        res = self.probe.call(PathQuality, "/gnss/path_quality", req, timeout_s=60.0)
        self.assertTrue(res.success, res.message)
        self.assertEqual([s.sec for s in res.stamps], [10, 30, 50])
        self.assertEqual(len(res.n_los), 3)
        self.assertTrue(res.rtk[0])
        self.assertLess(res.n_los[2], res.n_los[0])


@launch_testing.post_shutdown_test()
class TestAfterSigint(ExitsCleanly, unittest.TestCase):
    pass
