"""RTK lifecycle node: RTKLIB rtkrcv fed with the rover's and the base's RTCM3, its solutions published.

Subscribes ``rtcm`` (rover) and ``base/rtcm`` (base station): std_msgs/UInt8MultiArray,
the raw RTCM3 bytes of one epoch or any run of whole frames (rtcm_msgs and
mavros_msgs are not available as Kilted wheels on PyPI; UInt8MultiArray is
the standard raw-bytes message).  The messages go to rtkrcv through its TCP
inputs (core/rtk/process.py) synchronised by epoch (core/rtk/sync.py): a
rover epoch waits until the base epoch of the same time has been sent, so
rtkrcv pairs them even when the simulation runs many epochs per rtkrcv cycle.

Publishes (relative names: under the ``/gnss`` namespace they are
``/gnss/rtk/...``): ``rtk/fix`` (sensor_msgs/NavSatFix, status from the RTKLIB
quality as nmea_navsat_driver maps GGA: fixed and float -> STATUS_GBAS_FIX,
DGPS -> STATUS_SBAS_FIX, single -> STATUS_FIX, see core/rtk/solution.py;
covariance: rtkrcv's ENU covariance, COVARIANCE_TYPE_KNOWN), ``rtk/vel``
(geometry_msgs/TwistWithCovarianceStamped, ENU velocity of rtkrcv's
dynamics model with its covariance), ``rtk/nmea`` (std_msgs/String, one
sentence per message), ``rtk/status`` (diagnostic_msgs/DiagnosticStatus:
quality, ratio, satellites, age of the base data, counts).  With
``rtk_mode`` movingbase (the "base" stream is the robot's first antenna, the
rover stream its second): ``rtk/heading`` (sensor_msgs/Imu: orientation =
the yaw of the baseline first -> second antenna in ENU, REP-103; yaw
variance from rtkrcv's baseline covariance; roll and pitch unknown, 1e6 rad^2,
as the ublox driver's heading output; no angular velocity or acceleration:
-1 in element 0, REP-145) instead of rtk/fix and rtk/vel.

Services (std_srvs/Trigger): ``~/start``, ``~/stop``, ``~/restart`` of rtkrcv
while the node is active.  Lifecycle: configure checks rtkrcv (a clear error
when missing), reads a user's ``rtkrcv_conf``; activate starts rtkrcv
(``autostart``) and subscribes; deactivate and cleanup stop it (its whole
process group).  Ephemerides: those in the RTCM3 streams (1019-1046), and
with ``nav_files`` those of RINEX navigation files, sent at the simulated
time on rtkrcv's third input.  Message stamps: the solution's GNSS time through
``time_mapping`` (as the ephemeris node).
"""
from __future__ import annotations

import datetime as _dt
import os
import queue
import sys

from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import TwistWithCovarianceStamped
from rclpy.clock import Clock, ClockType
from sensor_msgs.msg import Imu, NavSatFix
from std_msgs.msg import Header, String, UInt8MultiArray

from gnss_sim_ros2.core.rtk.solution import QUALITY_NAMES, RtkBaseline, RtkSolution
from gnss_sim_ros2.messages.rtk import heading_to_msg, rtk_fix_to_msg, rtk_status_to_msg, rtk_vel_to_msg
from gnss_sim_ros2.messages.solution import navsatfix_service
from gnss_sim_ros2.messages.streams import nmea_to_msg, rtcm_from_msg
from gnss_sim_ros2.nodes.common import GnssSimNode, TimeMapping, run_node, run_origin_ns


class RtkNode(GnssSimNode):
    PARAMS_KEY = "rtk"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.proc = None
        self.pubs: dict = {}
        self.trigger_services: list = []
        self.mapping: TimeMapping | None = None
        self._solutions: queue.Queue = queue.Queue()
        self._nmea: queue.Queue = queue.Queue()
        self.counts = {q: 0 for q in QUALITY_NAMES}
        self.last: RtkSolution | None = None
        self.bytes_in = {"rover": 0, "base": 0}
        self.sync = None

    # ----------------------------------------------------------------------------- lifecycle
    def configure(self, p):
        from gnss_sim_ros2.core.rtk.config import default_options, read_conf
        from gnss_sim_ros2.core.rtk.process import find_faketime, find_rtkrcv

        where = f"node {self.get_name()}"
        try:
            find_rtkrcv(p["rtkrcv_path"])
            if p["rtkrcv_clock"] == "simulated":
                find_faketime()
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None
        systems = p["rtk_systems"] or p["systems"]
        self.options = None
        if p["rtkrcv_conf"]:
            read_conf(p["rtkrcv_conf"])             # its errors name the file and line, before anything starts
        else:
            try:
                self.options = default_options(systems, p["rtk_frequencies"], p["elevation_mask_deg"],
                                               p["rtk_ratio_threshold"], p["rtk_mode"])
            except ValueError as exc:
                raise ValueError(f"{where}: {exc}") from None
        self.schedule = None
        if p["nav_files"]:
            from gnss_sim_ros2.core.rinex.nav import read_nav_files, records_as_dicts
            from gnss_sim_ros2.core.rtcm.writer import EphemerisSchedule

            for f in p["nav_files"]:
                if not os.path.isfile(f):
                    raise ValueError(f"{where}: navigation file {f} does not exist (parameter nav_files)")
            self.schedule = EphemerisSchedule(records_as_dicts(read_nav_files(p["nav_files"]), systems), 30.0)
        self.service_flags = navsatfix_service(systems)
        self.mapping = TimeMapping(p["start_time"], p["time_mapping"])
        self.moving_base = p["rtk_mode"] == "movingbase"
        self.pubs = {
            "nmea": self.lifecycle_publisher(String, "rtk/nmea", 100),
            "status": self.lifecycle_publisher(DiagnosticStatus, "rtk/status", 100),
        }
        if self.moving_base:
            self.pubs["heading"] = self.lifecycle_publisher(Imu, "rtk/heading", 100)
        else:
            self.pubs["fix"] = self.lifecycle_publisher(NavSatFix, "rtk/fix", 100)
            self.pubs["vel"] = self.lifecycle_publisher(TwistWithCovarianceStamped, "rtk/vel", 100)
        from std_srvs.srv import Trigger

        self.trigger_services = [self.create_service(Trigger, f"~/{name}", getattr(self, f"_srv_{name}"))
                         for name in ("start", "stop", "restart")]

    def activate(self):
        from gnss_sim_ros2.core.rtk.sync import EpochSync

        self.mapping.origin_ns = run_origin_ns(self)
        self.sync = EpochSync()
        self.active_subscription(UInt8MultiArray, "rtcm", lambda m: self._feed("rover", m), 1000)
        self.active_subscription(UInt8MultiArray, "base/rtcm", lambda m: self._feed("base", m), 1000)
        # rtkrcv's output is drained on the steady clock: a simulated /clock may stand still
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.active_timer(0.02, self._drain, clock=steady)
        if self.schedule is not None:
            self.active_timer(1.0, self._send_ephemerides, clock=steady)
        if self.params["autostart"]:
            self.start_rtkrcv()

    def deactivate(self):
        self.stop_rtkrcv()

    def cleanup(self):
        self.stop_rtkrcv()
        for s in self.trigger_services:
            self.destroy_service(s)
        self.trigger_services = []
        self.pubs = {}

    # ----------------------------------------------------------------------------- rtkrcv
    def _clock_start_utc(self) -> _dt.datetime | None:
        mode = self.params["rtkrcv_clock"]
        if mode == "system":
            return None
        t = self.mapping.to_gnss(self.get_clock().now().to_msg())
        utc = t.to_datetime("UTC")
        now_utc = _dt.datetime.now(_dt.timezone.utc).replace(tzinfo=None)
        if mode == "auto" and abs((utc - now_utc).total_seconds()) < 3600.0:
            return None
        return utc

    def start_rtkrcv(self) -> str:
        """Start rtkrcv (no-op when running); a message for the service reply."""
        from gnss_sim_ros2.core.rtk.process import RtkrcvProcess

        if self.proc is not None and self.proc.running:
            return "rtkrcv is already running"
        p = self.params
        self.proc = RtkrcvProcess(options=self.options, user_conf=p["rtkrcv_conf"] or None,
                                  rtkrcv_path=p["rtkrcv_path"], on_solution=self._solutions.put,
                                  on_nmea=self._nmea.put, clock_start_utc=self._clock_start_utc(),
                                  solution_format="enu" if self.moving_base else "llh")
        self.proc.start()
        if self.schedule is not None:
            self.schedule.reset()
            self._send_ephemerides()
        if self.proc.replaced_options:
            self.get_logger().info(f"rtkrcv_conf: the node sets {', '.join(self.proc.replaced_options)}")
        return f"rtkrcv started ({self.proc.conf_path})"

    def stop_rtkrcv(self) -> str:
        if self.proc is None:
            return "rtkrcv is not running"
        rc = self.proc.stop()
        self.proc = None
        return f"rtkrcv stopped (exit {rc})"

    def _active(self) -> bool:
        return self._state_machine.current_state[1] == "active"

    def _srv_start(self, request, response):
        return self._reply(response, self.start_rtkrcv)

    def _srv_stop(self, request, response):
        return self._reply(response, self.stop_rtkrcv)

    def _srv_restart(self, request, response):
        def restart():
            self.stop_rtkrcv()
            return "restarted: " + self.start_rtkrcv()
        return self._reply(response, restart)

    def _reply(self, response, action):
        if not self._active():
            response.success, response.message = False, f"node {self.get_name()} is not active"
            return response
        try:
            response.message = action()
            response.success = True
        except (ValueError, OSError) as exc:
            response.success, response.message = False, str(exc)
            self.last_error = str(exc)
        return response

    # ----------------------------------------------------------------------------- data
    def _feed(self, which: str, msg) -> None:
        data = rtcm_from_msg(msg)
        self.bytes_in[which] += len(data)
        for to, chunk in self.sync.push(which, data):
            if self.proc is not None:
                (self.proc.feed_rover if to == "rover" else self.proc.feed_base)(chunk)

    def _send_ephemerides(self) -> None:
        """The ephemerides of nav_files due at the current simulated time, to rtkrcv's input stream 3."""
        if self.proc is None or self.schedule is None:
            return
        from gnss_sim_ros2.core.rtcm.frame import frame

        t = self.mapping.to_gnss(self.get_clock().now().to_msg())
        payloads = self.schedule.due(t)
        if payloads:
            self.proc.feed_nav(b"".join(frame(x) for x in payloads))

    def _drain(self) -> None:
        while True:
            try:
                line = self._nmea.get_nowait()
            except queue.Empty:
                break
            if self.pubs:
                self.pubs["nmea"].publish(nmea_to_msg(line))
        while True:
            try:
                sol = self._solutions.get_nowait()
            except queue.Empty:
                break
            self._publish(sol)

    def _publish(self, sol: RtkSolution | RtkBaseline) -> None:
        if not self.pubs:
            return
        self.counts[sol.q] = self.counts.get(sol.q, 0) + 1
        self.last = sol
        header = Header(stamp=self.mapping.to_ros(sol.t), frame_id=self.params["antenna_frame"])
        if isinstance(sol, RtkBaseline):
            self.pubs["heading"].publish(heading_to_msg(header, sol))
        else:
            self.pubs["fix"].publish(rtk_fix_to_msg(header, sol, self.service_flags))
            self.pubs["vel"].publish(rtk_vel_to_msg(header, sol))
        self.pubs["status"].publish(self.status_message(sol))

    def status_message(self, sol: RtkSolution | RtkBaseline | None) -> DiagnosticStatus:
        """The rtk/status message of the last solution (messages.rtk.rtk_status_to_msg)."""
        return rtk_status_to_msg(f"{self.get_name()}: rtkrcv", sol, self.mapping.to_ros(sol.t) if sol is not None
                                 else None, self.proc is not None and self.proc.running, self.counts, self.bytes_in,
                                 self.sync.released_unpaired if self.sync else 0)


def main(args=None):
    return run_node(RtkNode, args)


if __name__ == "__main__":
    sys.exit(main())
