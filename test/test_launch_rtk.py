"""launch_testing: `ros2 launch gnss_sim sim.launch.py rtk:=true` with the real launch tools.

    launch_test test/test_launch_rtk.py        # a ROS 2 install, or .venv-launch (make test)

Composed (the nodes as components of gnss_sim's container), on a simulated clock that the test
publishes 4x faster than real time along the demo path, with the RTK nodes: the base station
(gnss_sim_base_visibility, gnss_sim_base_receiver at base_position) and the rtk node (RTKLIB rtkrcv
under libfaketime).  Checked: every node active, /gnss/rtcm and /gnss/base/rtcm flowing, /gnss/rtk/fix
on the 1 s grid for >= 90 % of the epochs of the first 30 s (open ground), RTK (GBAS) status on >= 90 %
of them; then SIGINT: every process exits 0 without a traceback, no rtkrcv left.

Under plain pytest (the main suite) this module is skipped: launch tests run with `launch_test`.
"""
import os
import subprocess
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
import numpy as np  # noqa: E402
from launch_helpers import NODES, ExitsCleanly, Probe, sim_launch_description, stamp_s  # noqa: E402
from sensor_msgs.msg import NavSatFix, NavSatStatus  # noqa: E402
from std_msgs.msg import UInt8MultiArray  # noqa: E402
from test_rtk_engine import rtkrcv_and_faketime  # noqa: E402

from gnss_sim_ros2 import graph  # noqa: E402

SPEED = 4.0                     # simulated seconds per wall second
OPEN_S = 30.0                   # demo path: open ground south of the block up to here
RTK_NODES = tuple(s.name for s in graph.rtk_nodes())
OUT = Path(tempfile.mkdtemp(prefix="gnss_sim_launch_rtk_"))
HAVE_RTKRCV = rtkrcv_and_faketime()   # the rtk node runs rtkrcv under faketime
RTKRCV_PIDS = set()             # rtkrcv processes the rtk node of this launch started


def _rtkrcv_children_of_the_container() -> set[int]:
    rows = [ln.split(None, 2) for ln in subprocess.run(["ps", "-eo", "pid=,ppid=,args="], capture_output=True,
                                                       text=True).stdout.splitlines()]
    args = {int(r[0]): r[2] if len(r) > 2 else "" for r in rows}
    return {int(r[0]) for r in rows if len(r) > 2 and "gnss_sim_rtkrcv.conf" in r[2]
            and "__node:=gnss_sim_container" in args.get(int(r[1]), "")}


@pytest.mark.launch_test
def generate_test_description():
    return sim_launch_description(OUT, {"/**": {"rate_hz": 1.0, "marker_name": "LTRK"}}, {"rtk": "true"})


class TestRtkLaunch(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.probe = Probe(SPEED)
        cls.lock = threading.Lock()
        cls.rtk, cls.rtcm = [], {"rover": 0, "base": 0}
        node = cls.probe.node
        node.create_subscription(NavSatFix, "/gnss/rtk/fix", cls._on_rtk, 1000)
        node.create_subscription(UInt8MultiArray, "/gnss/rtcm", lambda m: cls._count("rover"), 1000)
        node.create_subscription(UInt8MultiArray, "/gnss/base/rtcm", lambda m: cls._count("base"), 1000)

    @classmethod
    def _on_rtk(cls, msg):
        with cls.lock:
            cls.rtk.append(msg)

    @classmethod
    def _count(cls, which):
        with cls.lock:
            cls.rtcm[which] += 1

    @classmethod
    def tearDownClass(cls):
        cls.probe.close()

    def test_1_every_node_active(self):
        if not HAVE_RTKRCV:
            self.skipTest("RTKLIB rtkrcv and libfaketime are not installed (apt-get install rtklib faketime)")
        probe = self.probe
        names = NODES + RTK_NODES
        ok = probe.wait_for(lambda: all(probe.state_or_none(n) == "active" for n in names), 120.0)
        self.assertTrue(ok, {n: probe.state_or_none(n) for n in names})
        probe.start_clock()

    def test_2_rtk_fixes_on_open_ground(self):
        if not HAVE_RTKRCV:
            self.skipTest("RTKLIB rtkrcv and libfaketime are not installed (apt-get install rtklib faketime)")

        def copy():
            with self.lock:
                return list(self.rtk)

        got = self.probe.wait_for(lambda: (f := copy()) and stamp_s(f[-1].header.stamp) >= OPEN_S,
                                  OPEN_S / SPEED + 60.0)
        fixes = [f for f in copy() if stamp_s(f.header.stamp) <= OPEN_S]
        self.assertTrue(got, f"{len(fixes)} RTK fixes, rtcm messages {self.rtcm}")
        t = np.array([stamp_s(f.header.stamp) for f in fixes])
        self.assertTrue(np.allclose(t, np.round(t), atol=0.01), "RTK fixes off the 1 s epoch grid")
        self.assertGreaterEqual(len(set(np.round(t))), 0.9 * (OPEN_S + 1))
        gbas = sum(f.status.status == NavSatStatus.STATUS_GBAS_FIX for f in fixes)
        self.assertGreaterEqual(gbas, 0.9 * len(fixes), f"{gbas} of {len(fixes)} RTK (GBAS) fixes")
        self.assertGreater(self.rtcm["base"], 0.9 * OPEN_S)
        self.assertGreater(self.rtcm["rover"], 0.9 * OPEN_S)
        RTKRCV_PIDS.update(_rtkrcv_children_of_the_container())
        self.assertTrue(RTKRCV_PIDS, "no rtkrcv process under the component container")


@launch_testing.post_shutdown_test()
class TestAfterSigint(ExitsCleanly, unittest.TestCase):
    def test_no_rtkrcv_left(self):
        """The rtkrcv the rtk node started ends with the container."""
        for pid in RTKRCV_PIDS:
            self.assertFalse(Path(f"/proc/{pid}").exists(), f"rtkrcv {pid} still runs")
