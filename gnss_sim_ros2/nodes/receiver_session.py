"""One robot's receiver inside a receiver node: its chain, pairing, unfinished epochs, publishers and services.

ReceiverNode (nodes/receiver_node.py) holds one ReceiverSession, FleetReceiverNode
(nodes/fleet_receiver_node.py) one per robot; the session is the receiver's work between the ROS messages
and the core, the node says where it lives in the graph (``publisher``: a topic name to a publisher of the
node; ``service``: a service name to the node's name for it; ``label``: how errors and diagnostics name it),
how the satellite states are decoded (``decode_states``: the fleet node decodes a message once for every robot),
who observes its epochs (``observe``: None, the session at once; or the fleet node's call that takes the session's
``paired`` epochs later, every robot's in one core/receiver/batch_observe pass) and who finishes them (``finish``:
the session alone, or the fleet node solving every robot's fix at once).
The physics is the core's (core/receiver/chain.ReceiverChain, core/receiver/epoch_pairing.EpochPairing,
core/threats/live.py); every message is built and read in gnss_sim_ros2/messages/.
"""
from __future__ import annotations

from collections.abc import Callable

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TwistWithCovarianceStamped
from sensor_msgs.msg import NavSatFix
from std_msgs.msg import Header, String

from gnss_sim_ros2.core.receiver.batch_observe import ReceiverEpoch
from gnss_sim_ros2.core.receiver.epoch_pairing import EpochPairing
from gnss_sim_ros2.messages.conversions import (
    chain_inputs_from_visibility,
    encode_observations,
    stamp_of,
    states_from_cdr,
    visibility_from_cdr,
)
from gnss_sim_ros2.messages.diagnostics import diagnostic_array, diagnostic_status
from gnss_sim_ros2.messages.solution import fix_to_msg, status_to_msg, vel_to_msg
from gnss_sim_ros2.messages.streams import nmea_to_msg, rtcm_to_msg
from gnss_sim_ros2.nodes.in_process import Offer

#: the publishers whose messages are also handed in-process (nodes/in_process.py): gnss-sim run's driver takes
#: every robot's fix and status
HANDED = ("fix", "status")


class ReceiverSession:
    """A receiver on the node ``node`` (a GnssSimNode: its executor, logger, clock and services), configured
    by ``configure(params)`` (the receiver node's parameters) until ``cleanup()``."""

    def __init__(self, node, *, label: str, publisher: Callable | None = None,
                 service: Callable[[str], str] = lambda name: name, decode_states: Callable = states_from_cdr,
                 finish: Callable[[], None] | None = None, observe: Callable[[], None] | None = None):
        self.node = node
        self.label = label                 # "gnss_sim_receiver", "gnss_sim_fleet_receiver (robot2)"
        self._publisher = publisher or node.lifecycle_publisher
        self._service = service
        self._decode_states = decode_states
        self._finish_due = finish or self.finish_alone
        self._observe_due = observe
        self.params: dict = {}
        self.chain = None                  # core.receiver.chain.ReceiverChain (configure .. cleanup)
        self.pubs: dict = {}
        self.offers: dict = {}             # HANDED's publishers handed in-process (configure .. cleanup)
        self.pairing = EpochPairing()      # the states and visibility bytes by stamp (sec, nanosec) until both came
        self.tcp = None                    # core.rtcm.tcp_server.RtcmTcpServer (configure .. cleanup)
        self.unfinished: list = []         # epochs observed and published, their fix not yet (process .. finish)
        self.paired: list = []             # (states, visibility bytes) paired, not yet observed (``observe`` given)
        self.threat_services: list = []    # ~/threats/start, ~/threats/stop (configure .. cleanup)
        self.last_t = None                 # GNSS time of the last epoch observed: "now" for the threat services

    # ------------------------------------------------------------------ lifecycle
    def configure(self, p: dict):
        from gnss_sim_msgs.msg import Observations, ReceiverStatus

        from gnss_sim_ros2.core.receiver.chain import ChainSettings, ReceiverChain

        self.params = p
        try:
            settings = ChainSettings.from_params(p)
        except ValueError as exc:
            raise ValueError(f"node {self.label}: {exc}") from None
        self.chain = ReceiverChain(settings, None, nmea=True, comment="gnss_sim receiver node",
                                   rtcm=True if p["rtcm"] else None)
        self.pairing.reset()
        pub = self._publisher
        self.pubs = {
            "obs": pub(Observations, "observations", 100),
            "fix": pub(NavSatFix, "fix", 100),
            "vel": pub(TwistWithCovarianceStamped, "vel", 100),
            "status": pub(ReceiverStatus, "status", 100),
            "nmea": pub(String, "nmea", 100),
            "diag": pub(DiagnosticArray, "/diagnostics", 10),
        }
        self.offers = {key: Offer(self.node, self.pubs[key]) for key in HANDED}
        if p["scenario"]:              # the scenario's events (core/threats) in the scene of scenario_world
            from gnss_sim_ros2.core.threats.runtime import ThreatRuntime
            from gnss_sim_ros2.core.threats.scenario import load_scenario
            from gnss_sim_ros2.core.time import GnssTime

            try:
                self.chain.threats = ThreatRuntime(load_scenario(p["scenario"]), self._scenario_scene(p),
                                                   start=GnssTime.from_iso(p["start_time"]))
            except ValueError as exc:
                raise ValueError(f"node {self.label}: {exc}") from None
            self.pubs["threats"] = pub(String, "threats_active", 100)
        from gnss_sim_msgs.srv import StartThreat, StopThreat

        self.threat_services = [
            self.node.create_service(StartThreat, self._service("~/threats/start"), self._srv_threat_start),
            self.node.create_service(StopThreat, self._service("~/threats/stop"), self._srv_threat_stop)]
        if p["rtcm"]:
            from std_msgs.msg import UInt8MultiArray

            self.pubs["rtcm"] = pub(UInt8MultiArray, "rtcm", 100)
            if p["rtcm_tcp_port"]:
                from gnss_sim_ros2.core.rtcm.tcp_server import RtcmTcpServer

                try:
                    self.tcp = RtcmTcpServer(p["rtcm_tcp_port"], p["rtcm_tcp_host"])
                except ValueError as exc:
                    raise ValueError(f"node {self.label}: {exc}") from None
                self.node.get_logger().info(f"RTCM3 served on tcp://{self.tcp.host}:{self.tcp.port}")

    def deactivate(self):
        self.finish()                  # the fix of an epoch whose observations went out, while publishers are on
        self.pairing.clear()

    def cleanup(self):
        self.finish()
        self.paired.clear()
        for offer in self.offers.values():
            offer.withdraw()
        self.offers = {}
        self.pubs = {}
        for srv in self.threat_services:
            self.node.destroy_service(srv)
        self.threat_services = []
        if self.tcp is not None:
            self.tcp.close()
            self.tcp = None
        if self.chain is not None:
            self.chain.close()       # RINEX closed with its last epoch
            self.chain = None
        self.pairing.reset()

    # ------------------------------------------------------------------ one epoch
    def on_states(self, data: bytes):
        for s, v in self.pairing.add_states(stamp_of(data), data):     # keyed by (sec, nanosec) of the stamp
            self.process(s, v)

    def on_visibility(self, data, stamp=None):
        """``data``: serialised Visibility, or its decode_visibility columns handed in-process with their ``stamp``
        (nodes/in_process.py)."""
        for s, v in self.pairing.add_visibility(stamp_of(data) if stamp is None else stamp, data):
            self.process(s, v)

    def process(self, states_data: bytes, vis_data: bytes):
        """One epoch from the serialised SatelliteStates and Visibility of one stamp (``observe`` given: queued
        in ``paired`` for the caller's pass over every robot, which then calls :meth:`epoch_inputs` and
        :meth:`observed`)."""
        if self._observe_due is not None:
            self.paired.append((states_data, vis_data))
            self._observe_due()
            return
        # the raw observations first, as a receiver outputs them before its fix (the latency ends here), then
        # the fix and the rest of the epoch: ReceiverChain.step in its two halves
        self.finish()                  # the chain's halves in order: the previous epoch's fix first
        stamp, e = self.epoch_inputs(states_data, vis_data)
        obs = self.chain.observe(e.t, e.antenna_ecef_m, e.states, e.vis_state, e.attenuation_db,
                                 multipath=e.multipath)
        self.observed(stamp, e, obs)
        # the fix after what is already waiting in the executor: several receivers in one process (robots
        # composed) publish every robot's observations before any of them computes its fix
        if self.node.executor is not None:
            self.node.executor.create_task(self.finish)
        else:
            self.finish()

    def epoch_inputs(self, states_data: bytes, vis_data: bytes):
        """(stamp, core ReceiverEpoch) of one epoch's serialised SatelliteStates and Visibility; the chain takes
        the navigation header's ionosphere coefficients; the epoch's time is "now" for the threat services."""
        stamp, t, states, iono = self._decode_states(states_data)
        self.chain.set_iono_coefficients(iono)
        # below the horizon = not in the visibility message: blocked, no attenuation
        vis = vis_data if isinstance(vis_data, dict) else visibility_from_cdr(vis_data)    # dict: handed decoded
        ecef, vis_state, att, paths = chain_inputs_from_visibility(vis, states.sv)
        self.last_t = t
        return stamp, ReceiverEpoch(t, ecef, states, vis_state, att, paths)

    def observed(self, stamp, e: ReceiverEpoch, obs):
        """Publish an epoch's observations (ReceiverChain.observe of :meth:`epoch_inputs`); its fix is due."""
        if self.wanted("obs"):
            self.pubs["obs"].publish(encode_observations(stamp, self.params["antenna_frame"], e.t, obs))
        self.unfinished.append((stamp, e.t, e.antenna_ecef_m, e.states, obs))

    def finish(self):
        """The fix half of the epochs observed and not finished, by whoever finishes this session's epochs
        (``finish`` of the constructor: the session alone, or the fleet node with every robot's)."""
        if self.unfinished:
            self._finish_due()

    def finish_alone(self):
        """The second half of the epochs observed (ReceiverChain.finish) and their messages, in order."""
        while self.unfinished and self.chain is not None:
            self.publish_fix(*self.unfinished.pop(0))
        self.unfinished.clear()

    def publish_fix(self, stamp, t, ecef, states, obs, sol=None):
        """The fix half of one epoch and its messages; ``sol``: its fix solved already (the fleet node's robots
        in one solve), None: solved by the chain."""
        nmea = self.wanted("nmea")
        ep = self.chain.finish(t, ecef, states, obs, sol, nmea=nmea)
        sol = ep.sol
        fix, status = self._receivers("fix"), self._receivers("status")
        vel = self.wanted("vel")
        if fix or vel or status:
            header = Header(stamp=Time(sec=stamp[0], nanosec=stamp[1]), frame_id=self.params["antenna_frame"])
            if fix:
                self._send("fix", fix_to_msg(header, sol), fix)
            if vel:
                self.pubs["vel"].publish(vel_to_msg(header, sol))
            if status:
                bands = self.chain.threats.status(t) if self.chain.threats is not None else None
                self._send("status", status_to_msg(header, obs, sol, self.chain.settings.receiver.elevation_mask_deg,
                                                   bands), status)
        if nmea:
            self.pubs["nmea"].publish(nmea_to_msg(ep.nmea))
        if "threats" in self.pubs and self.wanted("threats"):     # the epoch's truth labels (messages/threats.py)
            from gnss_sim_ros2.messages.threats import threats_to_msg

            th = self.chain.threats
            self.pubs["threats"].publish(threats_to_msg(stamp, th.labels(t), th.status(t)))
        if ep.rtcm:
            if self.wanted("rtcm"):
                self.pubs["rtcm"].publish(rtcm_to_msg(ep.rtcm))
            if self.tcp is not None:
                self.tcp.write(ep.rtcm)
        if self.chain.epochs % 10 == 1 and self.wanted("diag"):
            self._diagnose(obs, sol)

    def _receivers(self, key: str) -> tuple:
        """Who gets the message of publisher ``key`` (a HANDED one): (published: anyone subscribes, the takers of
        this process it is handed to); empty: nobody, no message built."""
        takers = self.offers[key].takers() if key in self.offers else []
        published = self.wanted(key)
        return (published, takers) if published or takers else ()

    def _send(self, key: str, msg, receivers: tuple):
        published, takers = receivers
        if published:
            self.pubs[key].publish(msg)
        for deliver in takers:
            deliver(msg)

    def wanted(self, key: str) -> bool:
        """Whether the message of publisher ``key`` has anyone to go to: a topic without subscribers gets no
        message built (its publishers are volatile: a message published before a subscriber matched is not
        delivered to it either), so a robot's products nobody listens to cost nothing (files are written
        regardless)."""
        return self.pubs[key].get_subscription_count() > 0

    # ------------------------------------------------------------------ threats started and stopped at run time
    def _scenario_scene(self, p):
        """The scene placing the scenario's world-frame events and attenuating jammers (parameter scenario_world:
        the visibility node's world, shared with it when composed), as ``gnss-sim simulate`` has it."""
        from gnss_sim_ros2.core.scene.demo_world import demo_world_path
        from gnss_sim_ros2.core.visibility import load_scene

        path = p["scenario_world"] or str(demo_world_path())
        world = path.lower().endswith((".sdf", ".world"))
        return load_scene(path if world else "", "" if world else path, shared=True)

    def _threat_now_s(self) -> float:
        """Run time [s] of the last epoch observed (0 before the first): an event started now acts from the next
        epoch on, one stopped now is over at the next."""
        th = self.chain.threats
        return 0.0 if self.last_t is None else float(th.t_rel(self.last_t)[0])

    def _threat_call(self, response, act):
        if self.chain is None or self.chain.threats is None:
            response.success, response.message = False, (
                f"node {self.label} runs without a threat scenario: give it one (parameter scenario, launch "
                f"argument scenario:=, gnss-sim run --scenario; 'version: 1' and 'events: []' for none at the start)")
            return response
        try:
            act()
            response.success = True
        except ValueError as exc:
            response.success, response.message = False, str(exc)
        return response

    def _srv_threat_start(self, request, response):
        from gnss_sim_ros2.core.threats.live import start_event

        def act():
            response.id = start_event(self.chain.threats, request.event_yaml, self._threat_now_s())
            response.message = f"threat event {response.id!r} started"
        return self._threat_call(response, act)

    def _srv_threat_stop(self, request, response):
        from gnss_sim_ros2.core.threats.live import stop_event

        def act():
            stop_event(self.chain.threats, request.id, self._threat_now_s())
            response.message = f"threat event {request.id!r} stopped"
        return self._threat_call(response, act)

    def _diagnose(self, obs, sol):
        status = diagnostic_status(f"{self.label}: receiver",
                                   f"{'fix' if sol.is_fix else 'no fix: ' + sol.reason}, "
                                   f"{obs.n_tracked_sats} satellites tracked",
                                   {"epochs": self.chain.epochs, "fixes": self.chain.fixes, "hdop": f"{sol.hdop:.2f}"},
                                   warn=not sol.is_fix)
        self.pubs["diag"].publish(diagnostic_array(self.node.get_clock().now().to_msg(), status))
