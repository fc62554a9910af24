"""Fleet receiver lifecycle node: every robot's receiver chain in one node (the fleet layout, graph.py).

``fleet_robots`` receivers, robot k's with the parameters its own receiver node has in the per-robot layouts
(graph_params.robot_node_params: seed + k, RINEX in output_dir/robot<k>, frames robot<k>/...; one robot: the
node's own), each its own core/receiver/chain.ReceiverChain (noise streams, clock, tracking state, RINEX file),
publishing on its own topics (/robot<k>/gnss/observations, fix, vel, status, nmea, ...).  One subscription to
``satellite_states`` serves all, and each message is decoded once for every robot (``decoded_states``: the robots
read the same arrays); robot k's ``visibility`` (the fleet visibility node's, one per robot) pairs with it by
stamp in robot k's core/receiver/epoch_pairing.EpochPairing.  Each robot is a nodes/receiver_session.ReceiverSession,
the object a receiver node holds one of (configure, the observations then the fix of an epoch, the threat
services, cleanup), here publishing on robot k's topics and serving ~/robot<k>/threats/..., so a fleet's robot k
gives what robot k's own receiver node gives, byte for byte (test_fleet_layout).

The robots' observables are computed one robot after the other (a loop over robots, not yet one numpy step over
robots x satellites x signals); their position fixes are one solve: a robot's fix half is an executor task
(ReceiverSession.process) queued behind the visibility callbacks already waiting, and the first of those tasks
(``finish_robots``) takes the epoch waiting at every robot and solves them in one solver.solve_pvt_many
(core/receiver/batch_fix.py: each robot's smoothing filter, last fix, RAIM exclusions and SolverConfig its own;
each epoch's bits those it gets alone), then writes each robot's NMEA, RINEX and messages.  So the robots'
observations of an epoch go out before their fixes when the executor holds them together (4 robots: robot 0's
fix after robot 3's observations at the median).  What the fleet pays once: the states' decoding, the visibility
cast, the fix's iterations, the executor's and the middleware's per-node work; per robot it still pays the
observables, its visibility decoded, its messages encoded and published (docs/BENCHMARKS.md, fleet figures).
"""
from __future__ import annotations

import sys

from gnss_sim_ros2.core.receiver.batch_fix import solve_receivers_fixes
from gnss_sim_ros2.graph import FLEET_NODE_NAMES, fleet_topic
from gnss_sim_ros2.graph_params import fleet_robot_params, robot_namespace
from gnss_sim_ros2.messages.conversions import states_from_cdr
from gnss_sim_ros2.nodes.common import GnssSimNode, run_node
from gnss_sim_ros2.nodes.receiver_session import ReceiverSession

#: SatelliteStates messages kept decoded: epochs whose robots' visibility is still awaited (a late robot's TF)
DECODED_KEPT = 8


class FleetReceiverNode(GnssSimNode):
    PARAMS_KEY = "receiver"

    def __init__(self, node_name: str | None = None, **kwargs):
        super().__init__(node_name=node_name or FLEET_NODE_NAMES["receiver"], **kwargs)
        self.robots: list[ReceiverSession] = []
        self._shared: dict = {}
        #: the last SatelliteStates messages decoded (id -> (bytes, states_from_cdr)): one decode for every robot
        self._decoded: dict = {}

    def decoded_states(self, data: bytes):
        """states_from_cdr of ``data`` (the one message object every robot's pairing holds), decoded once: the
        robots read the same arrays (the chain does not write into the states)."""
        hit = self._decoded.get(id(data))
        if hit is None or hit[0] is not data:
            hit = self._decoded[id(data)] = (data, states_from_cdr(data))
            while len(self._decoded) > DECODED_KEPT:
                del self._decoded[next(iter(self._decoded))]
        return hit[1]

    def finish_robots(self):
        """The fix half of every robot's epochs observed and not yet finished, in rounds: the first waiting
        epoch of each robot (a robot's next epoch starts at this one's fix), their fixes in one solve
        (core/receiver/batch_fix.solve_receivers_fixes: each robot's bits as alone), then each robot's
        products and messages (ReceiverSession.publish_fix: NMEA, RINEX, fix, vel, status, nmea)."""
        for r in self.robots:
            if r.chain is None:
                r.unfinished.clear()
        while True:
            due = [r for r in self.robots if r.unfinished]
            if not due:
                return
            epochs = [r.unfinished.pop(0) for r in due]
            sols = solve_receivers_fixes([r.chain for r in due], [e[4] for e in epochs])
            for r, e, sol in zip(due, epochs, sols):
                r.publish_fix(*e, sol=sol)

    def shared_publisher(self, msg_type, topic: str, qos):
        if topic not in self._shared:
            self._shared[topic] = self.lifecycle_publisher(msg_type, topic, qos)
        return self._shared[topic]

    def robot_session(self, k: int, robots: int) -> ReceiverSession:
        """Robot k's receiver: its topics (graph.fleet_topic; /diagnostics one for every robot), its services
        (~/robot<k>/threats/start; one robot: the node's own names), the states decoded once for every robot,
        its fixes solved with the other robots' (finish_robots)."""
        def publisher(msg_type, topic: str, qos):
            if topic.startswith("/"):
                return self.shared_publisher(msg_type, topic, qos)
            return self.lifecycle_publisher(msg_type, fleet_topic(k, robots, topic), qos)

        def service(name: str) -> str:
            return f"~/{robot_namespace(k)}/{name[2:]}" if robots > 1 and name.startswith("~/") else name

        return ReceiverSession(self, label=f"{self.get_name()} ({robot_namespace(k)})", publisher=publisher,
                               service=service, decode_states=self.decoded_states, finish=self.finish_robots)

    def configure(self, p):
        n = p["fleet_robots"]
        self.robots = [self.robot_session(k, n) for k in range(n)]
        for k, r in enumerate(self.robots):
            r.configure(fleet_robot_params(p, k, "receiver"))

    def activate(self):
        from gnss_sim_msgs.msg import SatelliteStates, Visibility

        self.active_subscription(SatelliteStates, "satellite_states", self._on_states, 100, raw=True)
        n = len(self.robots)
        for k, r in enumerate(self.robots):
            self.active_subscription(Visibility, fleet_topic(k, n, "visibility"), r.on_visibility, 100, raw=True)

    def _on_states(self, data: bytes):
        for r in self.robots:
            r.on_states(data)

    def deactivate(self):
        for r in self.robots:
            r.deactivate()

    def cleanup(self):
        for r in self.robots:
            r.cleanup()
        self.robots = []
        self._shared = {}
        self._decoded = {}


def main(args=None):
    return run_node(FleetReceiverNode, args)


if __name__ == "__main__":
    sys.exit(main())
