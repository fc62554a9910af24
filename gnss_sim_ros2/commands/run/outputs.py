"""What ``gnss-sim run`` reads of its graph while it runs: per robot (RobotOutputs) the receiver's status and fix
and the visibility's true antenna position, the latencies (nodes/latency_probe.py), how far TF has come (the
missing-frame rule), and with --rtk rtkrcv's fixes, headings and their quality."""
from __future__ import annotations

import time
from itertools import islice

import numpy as np

from gnss_sim_ros2 import graph
from gnss_sim_ros2.core.frames import ecef_to_enu, ecef_to_geodetic, geodetic_to_ecef
from gnss_sim_ros2.graph_params import robot_namespace
from gnss_sim_ros2.messages.conversions import stamp_of, visibility_antenna
from gnss_sim_ros2.nodes.in_process import Taker, subscription_switch


class RunOutputs:
    """The run's subscriptions on its node ``driver``: ``robots`` (RobotOutputs; robot 0's ``status``, ``fix``
    and ``truth`` are the run's), ``tf_wait``, ``probe`` (latencies), and with --rtk ``rtk_fix``, ``rtk_quality``,
    ``rtk_latency_s`` (wall time from the rover's status to its RTK solution, clock.ClockDriver.wait_rtk) and,
    with a second antenna, ``heading``, ``heading_quality``, ``truth2``."""

    def __init__(self, driver, cfg, args):
        from gnss_sim_msgs.msg import Observations, SatelliteStates
        from sensor_msgs.msg import NavSatFix

        from gnss_sim_ros2.nodes.latency_probe import LatencyProbe
        from gnss_sim_ros2.nodes.tf_stream import TfStream
        from gnss_sim_ros2.tf_tree import FrameWait

        self.driver, self.cfg = driver, cfg
        self._subs = []
        n = args.robots
        self.robots = [RobotOutputs(driver, k if n > 1 else -1) for k in range(n)]
        # how far TF has come: the missing-frame rule of the wait for an epoch's visibility (tf_tree.FrameWait; a
        # second later than the visibility node's own, whose error comes first)
        self.tf_wait = FrameWait(cfg.node("visibility")["tf_timeout_s"] + 1.0)
        self.tf_stream = TfStream(driver, lambda m: self.tf_wait.seen_transforms(m.transforms, time.monotonic()))
        r0 = self.robots[0]              # one robot: the run's outputs (the RTK figures use its truth)
        self.status, self.fix, self.truth = r0.status, r0.fix, r0.truth
        # latency: the states published -> each robot's observations published (the middleware's publication
        # times, read by a node of its own)
        self.probe = LatencyProbe(driver.context, ("/gnss/satellite_states", SatelliteStates),
                                  [(r.topic(name), msg_type) for r in self.robots
                                   for name, msg_type in (("observations", Observations), ("fix", NavSatFix))])
        self.rtk_latency_s: list[float] = []
        if args.rtk:
            self._subscribe_rtk()

    @property
    def last_vis(self):
        """Robot 0's last gnss_sim_msgs/Visibility (kept serialised during the run)."""
        return self.robots[0].last_vis_msg()

    def _subscribe_rtk(self):
        from diagnostic_msgs.msg import DiagnosticStatus
        from sensor_msgs.msg import NavSatFix

        self.rtk_fix, self.rtk_quality = {}, {}

        def on_fix(m):
            self.rtk_fix[m.header.stamp.sec + m.header.stamp.nanosec * 1e-9] = m

        def on_status(m):
            v = {kv.key: kv.value for kv in m.values}
            if v.get("stamp"):
                self.rtk_quality[round(float(v["stamp"]) * 1e6)] = v["quality"]   # [us]: the fix's stamp

        self._subs += [self.driver.create_subscription(NavSatFix, "/gnss/rtk/fix", on_fix, 1000),
                       self.driver.create_subscription(DiagnosticStatus, "/gnss/rtk/status", on_status, 1000)]
        if self.cfg.node("receiver")["antenna2_frame"]:
            self._subscribe_heading()

    def _subscribe_heading(self):
        """The moving baseline: rtkrcv's headings, their quality, and the second antenna's true position."""
        from diagnostic_msgs.msg import DiagnosticStatus
        from gnss_sim_msgs.msg import Visibility
        from sensor_msgs.msg import Imu

        self.heading, self.heading_quality, self.truth2 = {}, {}, {}

        def stamp(m):
            return m.header.stamp.sec + m.header.stamp.nanosec * 1e-9

        def on_heading(m):
            self.heading[stamp(m)] = m

        def on_status(m):
            v = {kv.key: kv.value for kv in m.values}
            if v.get("stamp"):
                self.heading_quality[round(float(v["stamp"]) * 1e6)] = v["quality"]

        def on_vis(m):
            self.truth2[stamp(m)] = np.array([m.antenna_ecef_m.x, m.antenna_ecef_m.y, m.antenna_ecef_m.z])

        d = self.driver
        self._subs += [d.create_subscription(Imu, "/gnss/rtk/heading", on_heading, 1000),
                       d.create_subscription(DiagnosticStatus, "/gnss/heading/status", on_status, 1000),
                       d.create_subscription(Visibility, "/gnss/antenna2/visibility", on_vis, 1000)]

    def close(self):
        self.tf_stream.close()
        for r in self.robots:
            for taker in r.takers:
                taker.close()
        self.probe.close()


def _stamp_s(m) -> float:
    return m.header.stamp.sec + m.header.stamp.nanosec * 1e-9


class RobotOutputs:
    """What the run reads of one robot's receiver chain: status, fix and the visibility's true antenna
    position (the latency: the run's LatencyProbe), on the robot's topics (graph.robot_topic: /robot<k>/gnss/...;
    ``k`` = -1: the one robot of a run, /gnss/...)."""

    def __init__(self, driver, k: int):
        from gnss_sim_msgs.msg import ReceiverStatus, Visibility
        from sensor_msgs.msg import NavSatFix

        self.k = k
        self.name = robot_namespace(max(k, 0))
        self.status, self.fix, self.truth = {}, {}, {}
        self.last_vis = None

        def on_status(m):
            self.status[_stamp_s(m)] = m

        def on_fix(m):
            self.fix[_stamp_s(m)] = m

        def on_vis(data):
            # raw: no message object per satellite in the chain's executor (the last one is read at the end)
            sec, nanosec = stamp_of(data)
            self.truth[sec + nanosec * 1e-9] = visibility_antenna(data)[1]
            self.last_vis = data

        def on_handed(handed):
            # handed by the fleet visibility node of this process (nodes/in_process.py): the message's columns
            (sec, nanosec), cols = handed[0], handed[1]
            self.truth[sec + nanosec * 1e-9] = np.array([cols[f"antenna_ecef_m.{a}"][0] for a in "xyz"])
            self.last_vis = cols

        topic = self.topic

        def taker(name, deliver, subscribe):
            """``name`` handed by a node of this process (nodes/in_process.py), else subscribed."""
            return Taker(driver, topic(name), deliver, subscription_switch(subscribe, driver.destroy_subscription))

        # the status and fix as the receiver hands them (the message objects: nothing serialised for the driver)
        self.takers = [
            taker("status", on_status, lambda: driver.create_subscription(ReceiverStatus, topic("status"),
                                                                           on_status, 100)),
            taker("fix", on_fix, lambda: driver.create_subscription(NavSatFix, topic("fix"), on_fix, 100)),
            taker("visibility", on_handed, lambda: driver.create_subscription(Visibility, topic("visibility"), on_vis,
                                                                              100, raw=True))]

    def topic(self, name: str) -> str:
        """This robot's topic ``name`` (/robot<k>/gnss/<name>, or /gnss/<name> for the one robot of a run)."""
        return graph.robot_topic(self.k, f"{graph.TOPIC_NAMESPACE}/{name}")

    def last_vis_msg(self):
        """The last gnss_sim_msgs/Visibility (kept serialised, or as its columns, during the run); None before the
        first."""
        if isinstance(self.last_vis, dict):      # handed in-process: the message's columns, written as the message
            from gnss_sim_ros2.messages.cdr import VISIBILITY_CODEC

            self.last_vis = VISIBILITY_CODEC.encode(self.last_vis)
        if isinstance(self.last_vis, bytes):
            from gnss_sim_msgs.msg import Visibility
            from rclpy.serialization import deserialize_message

            self.last_vis = deserialize_message(self.last_vis, Visibility)
        return self.last_vis

    def spec(self, key: str):
        """This robot's node of ``key`` (graph.ROBOT_KEYS)."""
        return graph.robot_spec(next(n for n in graph.NODES if n.key == key), self.k)

    def answered(self, t_s: float, every: bool = False) -> bool:
        """The receiver's status of the epoch at t_s came (``every``: searched among all, else the last 3)."""
        if any(abs(s - t_s) < 1e-6 for s in islice(reversed(self.status), 3)):  # not a copy of all: asked per pass
            return True
        # all only when the last 3 lack it: the driver asks every robot after each epoch (N x epochs a pass else)
        return every and any(abs(s - t_s) < 1e-6 for s in self.status)

    def cast(self, t_s: float) -> bool:
        """The visibility of the epoch at t_s came (the antenna's TF was there)."""
        return any(abs(s - t_s) < 1e-6 for s in islice(reversed(self.truth), 3))

    def epochs_answered(self, n_epochs: int, period: float) -> int:
        return len({int(round(t / period)) for t in self.status} & set(range(n_epochs)))

    def samples(self, probe) -> dict:
        """Per-epoch samples: satellites tracked, fixes, horizontal errors against the true antenna [m],
        latency states -> observations [ms]."""
        err = []
        for t, f in self.fix.items():
            if f.status.status < 0 or t not in self.truth:
                continue
            est = np.array(geodetic_to_ecef(f.latitude, f.longitude, f.altitude))
            lat, lon, h = ecef_to_geodetic(*self.truth[t])
            d = ecef_to_enu(est, lat, lon, h)
            err.append(float(np.hypot(d[0], d[1])))
        return {"tracked": [m.satellites_tracked for m in self.status.values()],
                "fixes": [1 for m in self.fix.values() if m.status.status >= 0], "err": err,
                "lat_ms": probe.latencies_ms(self.topic("observations")),
                "fix_lat_ms": probe.latencies_ms(self.topic("fix"))}
