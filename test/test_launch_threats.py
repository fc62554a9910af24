"""launch_testing: a jammer started and stopped through the receiver's services while the graph runs.

    launch_test test/test_launch_threats.py        # a ROS 2 install, or .venv-launch (make test)

`ros2 launch gnss_sim sim.launch.py scenario:=<no event at the start>` (composed), on a simulated clock the test
publishes 4x faster than real time along the demo path (open ground south of the block for the first 30 s).
Checked: every node active and /gnss/fix a fix; ``/gnss_sim_receiver/threats/start`` refuses a bad event with
the scenario file's error text, then starts a multi-band noise jammer 15 m from the robot's path: /gnss/fix
turns to NO_FIX (no satellite left), /gnss/status reports the jamming indicator, /gnss/threats/active the
event; ``threats/stop`` ends it and the fix comes back with its satellites; then SIGINT: every process exits 0
without a traceback.

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
from gnss_sim_msgs.msg import ReceiverStatus  # noqa: E402
from gnss_sim_msgs.srv import StartThreat, StopThreat  # noqa: E402
from launch_helpers import NODES, ExitsCleanly, Probe, sim_launch_description, stamp_s  # noqa: E402
from sensor_msgs.msg import NavSatStatus  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from gnss_sim_ros2.messages.threats import threats_from_msg  # noqa: E402

SPEED = 4.0                     # simulated seconds per wall second
OUT = Path(tempfile.mkdtemp(prefix="gnss_sim_launch_threats_"))
START = "/gnss_sim_receiver/threats/start"
STOP = "/gnss_sim_receiver/threats/stop"
#: noise over 1155-1605 MHz (every band of the geodetic profile), 0 dBW, 1 m up, 15 m east of the demo path
JAMMER = ("{type: jammer, name: test_jammer, position: [15, -45, 1], position_type: world, eirp_dbw: 0.0, "
          "center_hz: 1380.0e6, bandwidth_hz: 450.0e6}")


@pytest.mark.launch_test
def generate_test_description():
    scenario = OUT / "no_event.yaml"
    scenario.write_text("version: 1\nevents: []\n")
    return sim_launch_description(OUT, {"/**": {"rate_hz": 1.0, "marker_name": "LTHR"}}, {"scenario": str(scenario)})


class TestThreatServices(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.probe = Probe(SPEED)
        cls.lock = threading.Lock()
        cls.status, cls.labels = [], []
        node = cls.probe.node
        node.create_subscription(ReceiverStatus, "/gnss/status", lambda m: cls._keep(cls.status, m), 1000)
        node.create_subscription(String, "/gnss/threats/active", lambda m: cls._keep(cls.labels, m), 1000)

    @classmethod
    def _keep(cls, into, msg):
        with cls.lock:
            into.append(msg)

    @classmethod
    def tearDownClass(cls):
        cls.probe.close()

    def _after(self, items, t_s):
        with self.lock:
            return [m for m in items if stamp_s(m.header.stamp) > t_s] if items is self.status else \
                [m for m in items if threats_from_msg(m)["stamp"][0] > t_s]

    def _fixes_after(self, t_s):
        return [f for f in self.probe.fixes_copy() if stamp_s(f.header.stamp) > t_s]

    def _last_fix_s(self):
        f = self.probe.fixes_copy()
        return stamp_s(f[-1].header.stamp) if f else -1.0

    def test_1_every_node_active(self):
        probe = self.probe
        ok = probe.wait_for(lambda: all(probe.state_or_none(n) == "active" for n in NODES), 120.0)
        self.assertTrue(ok, {n: probe.state_or_none(n) for n in NODES})
        probe.start_clock()

    def test_2_a_jammer_started_takes_the_fix_and_stopping_it_gives_it_back(self):
        probe = self.probe
        self.assertTrue(probe.wait_for(lambda: self._last_fix_s() >= 4.0, 60.0), "no fix stamped 4 s")
        before = [f for f in probe.fixes_copy() if stamp_s(f.header.stamp) >= 1.0]
        self.assertTrue(all(f.status.status >= NavSatStatus.STATUS_FIX for f in before), "no fix on open ground")

        bad = probe.call(StartThreat, START, StartThreat.Request(event_yaml="{type: jammer, power_w: 3}"))
        self.assertFalse(bad.success)
        self.assertIn("key 'events[0].power_w': unknown key 'power_w'", bad.message)

        started = probe.call(StartThreat, START, StartThreat.Request(event_yaml=JAMMER))
        self.assertTrue(started.success, started.message)
        self.assertEqual(started.id, "test_jammer")
        t_on = self._last_fix_s()
        self.assertTrue(probe.wait_for(lambda: any(f.status.status == NavSatStatus.STATUS_NO_FIX
                                                   for f in self._fixes_after(t_on)), 60.0),
                        "the fix did not go while the jammer was on")
        self.assertTrue(probe.wait_for(lambda: self._after(self.status, t_on + 1.0), 30.0))
        jammed = self._after(self.status, t_on + 1.0)
        self.assertTrue(any(s.satellites_tracked == 0 for s in jammed), [s.satellites_tracked for s in jammed])
        self.assertTrue(all("1" in s.jam_bands and max(s.jam_ind) > 100 for s in jammed),
                        [(list(s.jam_bands), list(s.jam_ind)) for s in jammed])
        on_labels = self._after(self.labels, t_on)
        self.assertTrue(on_labels and all(threats_from_msg(m)["active"] == ["test_jammer"] for m in on_labels))

        stopped = probe.call(StopThreat, STOP, StopThreat.Request(id="test_jammer"))
        self.assertTrue(stopped.success, stopped.message)
        again = probe.call(StopThreat, STOP, StopThreat.Request(id="test_jammer"))
        self.assertFalse(again.success)
        self.assertIn("over already", again.message)
        t_off = self._last_fix_s()
        # reacquisition takes a few epochs (the tracking thresholds): a fix again within 20 s of simulated time
        self.assertTrue(probe.wait_for(lambda: any(f.status.status >= NavSatStatus.STATUS_FIX
                                                   for f in self._fixes_after(t_off)), 60.0),
                        "the fix did not come back after the jammer stopped")
        self.assertLess(min(stamp_s(f.header.stamp) for f in self._fixes_after(t_off)
                            if f.status.status >= NavSatStatus.STATUS_FIX), t_off + 20.0)
        self.assertTrue(probe.wait_for(lambda: self._after(self.status, t_off + 10.0), 30.0))
        clear = self._after(self.status, t_off + 10.0)
        self.assertTrue(all(len(s.jam_bands) == 0 and s.satellites_used >= 4 for s in clear))
        off_labels = self._after(self.labels, t_off + 1.0)
        self.assertTrue(off_labels and all(threats_from_msg(m)["active"] == [] for m in off_labels))


@launch_testing.post_shutdown_test()
class TestAfterSigint(ExitsCleanly, unittest.TestCase):
    pass
