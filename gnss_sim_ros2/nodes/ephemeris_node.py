"""Ephemeris provision lifecycle node: publishes the satellite states of every epoch.

configure: validates parameters, opens the ephemeris source for the span
(files checked and loaded here, diagnostics prepared); activate: a timer on
the ROS clock (simulated time works) publishes ``satellite_states`` for each
epoch of the grid start_time + k / rate_hz that the clock has reached, in
order, none skipped (a late timer catches up and counts the late epochs);
diagnostics report data problems (satellites without a valid ephemeris).
The message goes out as its CDR bytes, written from the arrays (gnss_sim_ros2/messages/cdr.py).
"""
from __future__ import annotations

import math
import sys
import tempfile

from diagnostic_msgs.msg import DiagnosticArray

from gnss_sim_ros2.core.time import GnssTime
from gnss_sim_ros2.messages.conversions import encode_states, states_as_decoded
from gnss_sim_ros2.messages.diagnostics import diagnostic_array, diagnostic_status
from gnss_sim_ros2.nodes.common import GnssSimNode, TimeMapping, run_node, run_origin_ns
from gnss_sim_ros2.nodes.in_process import Offer


class EphemerisNode(GnssSimNode):
    PARAMS_KEY = "ephemeris"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.provider = None
        self.pub = None
        self.offer = None
        self.diag_pub = None
        self.mapping = None
        self.next_k = 0
        self.published = 0
        self.late_epochs = 0
        self.period_s = 1.0
        self.nav_paths: list = []     # navigation files the provider read
        self.nav_path = None          # the RINEX navigation file written into output_dir
        self._tmp = None

    def configure(self, p):
        from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris

        self.next_k = self.published = self.late_epochs = 0   # a reconfigured node starts clean
        self.mapping = TimeMapping(p["start_time"], p["time_mapping"])
        self._tmp = tempfile.TemporaryDirectory(prefix="gnss_sim_eph_")
        self.provider, self.nav_paths = open_ephemeris(
            p["source"], self.mapping.start, p["duration_s"], p["systems"], p["nav_files"], p["sp3_files"],
            p["clk_files"], workdir=self._tmp.name, cache_dir=p["download_cache_dir"] or None)
        self.pub = self.lifecycle_publisher(_msg_type(), "satellite_states", 100)
        #: the states handed to the visibility nodes of this process too (nodes/in_process.py), after publishing
        self.offer = Offer(self, self.pub)
        self.diag_pub = self.lifecycle_publisher(DiagnosticArray, "/diagnostics", 10)
        self.period_s = 1.0 / p["rate_hz"]
        self.nav_path = None
        if p["output_dir"]:
            from pathlib import Path

            from gnss_sim_ros2.core.receiver.outputs import rinex_name, write_navigation

            out = Path(p["output_dir"])
            out.mkdir(parents=True, exist_ok=True)
            name = rinex_name(p["marker_name"], self.mapping.start, p["duration_s"], self.period_s, "MN")
            self.nav_path = write_navigation(out / name, self.provider, p["systems"])

    def activate(self):
        self.mapping.origin_ns = run_origin_ns(self)
        self.next_k = self._first_epoch_index()
        self.active_clock_timer(min(self.period_s, 0.05), self._tick)
        self._tick()  # the epoch the clock stands at now (a simulated clock may wait for it)

    def cleanup(self):
        if self.offer is not None:
            self.offer.withdraw()
            self.offer = None
        self.pub = self.diag_pub = None
        self.provider = self.mapping = self.nav_path = None
        self.nav_paths = []
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None

    # ------------------------------------------------------------------
    def _epoch(self, k: int) -> GnssTime:
        return self.mapping.start + k * self.period_s

    def _first_epoch_index(self) -> int:
        now = self.mapping.to_gnss(self.get_clock().now().to_msg())
        return max(0, math.ceil((now - self.mapping.start) / self.period_s - 1e-9))

    def _tick(self):
        now = self.mapping.to_gnss(self.get_clock().now().to_msg())
        due = []
        while self._epoch(self.next_k) - now <= 1e-9:
            due.append(self.next_k)
            self.next_k += 1
        if len(due) > 1:
            self.late_epochs += len(due) - 1
        for k in due:
            self.publish_epoch(self._epoch(k))

    def publish_epoch(self, t: GnssTime):
        states = self.provider.states(t, systems=self.params["systems"])
        # the serialised message straight from the arrays (cdr.py; what states_to_msg + rclpy would send)
        iono = getattr(self.provider, "iono", None)
        stamp = self.mapping.to_ros(t)
        data = encode_states(states, t, stamp, "earth", iono)
        self.pub.publish(data)             # first: the latency of what follows starts at this publication
        takers = self.offer.takers()
        if takers:                         # the message and its decode, built from the arrays (no parsing)
            handed = (data, states_as_decoded(states, t, stamp, iono))
            for deliver in takers:
                deliver(handed)
        self.published += 1
        if self.published % max(1, int(round(10.0 / self.period_s))) == 1:
            self._diagnose(t, len(states))

    def _diagnose(self, t: GnssTime, n: int):
        values = {"satellites": n, "epochs_published": self.published, "late_epochs": self.late_epochs}
        diag = getattr(self.provider, "diagnostics", None)
        problems = []
        if diag is not None:
            d = diag(t, systems=self.params["systems"])
            for name in ("gap", "unhealthy", "stale", "missing"):
                svs = getattr(d, name, None)
                if svs:
                    problems.append(f"{name}: {' '.join(map(str, svs))}")
                    values[name] = " ".join(map(str, svs))
        status = diagnostic_status(f"{self.get_name()}: ephemeris",
                                   "; ".join(problems) if problems else f"{n} satellites", values,
                                   warn=bool(problems) or n < 4)
        self.diag_pub.publish(diagnostic_array(self.get_clock().now().to_msg(), status))


def _msg_type():
    from gnss_sim_msgs.msg import SatelliteStates

    return SatelliteStates


def main(args=None):
    return run_node(EphemerisNode, args)


if __name__ == "__main__":
    sys.exit(main())
