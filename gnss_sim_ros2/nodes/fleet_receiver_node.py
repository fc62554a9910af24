"""Fleet receiver lifecycle node: every robot's receiver chain in one node (the fleet layout, graph.py).

``fleet_robots`` receivers, robot k's with the parameters its own receiver node has in the per-robot layouts
(graph_params.robot_node_params: seed + k, RINEX in output_dir/robot<k>, frames robot<k>/...; one robot: the
node's own), each its own core/receiver/chain.ReceiverChain (noise streams, clock, tracking state, RINEX file),
publishing on its own topics (/robot<k>/gnss/observations, fix, vel, status, nmea, ...).  One subscription to
``satellite_states`` serves all, and each message is decoded once for every robot (``decoded_states``: the robots
read the same arrays); robot k's ``visibility`` (the fleet visibility node's, one per robot) pairs with it by
stamp in robot k's core/receiver/epoch_pairing.EpochPairing.  A fleet visibility node of the same process and
executor hands robot k's epoch over directly instead (nodes/in_process.py: the visibility as its decode gives it,
with the states it cast, decoded), and robot k's visibility topic then has no middleware subscription here.
Each robot is a nodes/receiver_session.ReceiverSession, the object a receiver node holds one of (configure, the
observations then the fix of an epoch, the threat services, cleanup), here publishing on robot k's topics and
serving ~/robot<k>/threats/..., so a fleet's robot k gives what robot k's own receiver node gives, byte for byte
(test_fleet_layout).

The robots' observables are one numpy pass over robots x satellites x signals: a robot's paired epoch waits in its
session (ReceiverSession.paired) and the first one queues an executor task (``observe_robots``) behind the
visibility callbacks already waiting, which takes the epoch paired at every robot and computes their observables in
one core/receiver/batch_observe.observe_receivers (each robot's noise streams, clock, tracking state its own; each
robot's bits those it gets alone; robots whose settings cannot share the pass -- threats, the LMS layer, reflected
paths, another configuration -- are observed alone), publishes each robot's observations, then queues their fix
half.  Their position fixes are one solve: the first fix task
(``finish_robots``) takes the epoch waiting at every robot and solves them in one solver.solve_pvt_many
(core/receiver/batch_fix.py: each robot's smoothing filter, last fix, RAIM exclusions and SolverConfig its own;
each epoch's bits those it gets alone), then writes each robot's NMEA, RINEX and messages.  So the robots'
observations of an epoch go out before their fixes when the executor holds them together (4 robots: robot 0's
fix after robot 3's observations at the median).  What the fleet pays once: the states' decoding, the visibility
cast, the observables' stages without memory, the fix's iterations, the executor's and the middleware's per-node
work; per robot it still pays its clock, tracking and noise draws, its messages encoded and published, and its
visibility decoded when it comes through the middleware (docs/BENCHMARKS.md, fleet figures).
"""
from __future__ import annotations

import sys

from gnss_sim_ros2.core.receiver.batch_fix import solve_receivers_fixes
from gnss_sim_ros2.core.receiver.batch_observe import observe_receivers
from gnss_sim_ros2.graph import FLEET_NODE_NAMES, fleet_topic
from gnss_sim_ros2.graph_params import fleet_robot_params, robot_namespace
from gnss_sim_ros2.messages.conversions import states_from_cdr
from gnss_sim_ros2.nodes.common import GnssSimNode, run_node
from gnss_sim_ros2.nodes.in_process import Taker, subscription_switch
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
        #: an observe_robots task is queued and has not run yet
        self._observe_queued = False
        #: robot k's visibility taken in-process (nodes/in_process.py; activate .. deactivate)
        self._takers: list[Taker] = []

    def decoded_states(self, data: bytes, decoded=None):
        """states_from_cdr of ``data`` (the one message object every robot's pairing holds), decoded once: the
        robots read the same arrays (the chain does not write into the states); ``decoded``: its decode handed
        with it (kept for the robots), None: decoded here if not kept yet."""
        hit = self._decoded.get(id(data))
        if hit is None or hit[0] is not data:
            hit = self._decoded[id(data)] = (data, decoded if decoded is not None else states_from_cdr(data))
            while len(self._decoded) > DECODED_KEPT:
                del self._decoded[next(iter(self._decoded))]
        return hit[1]

    def observe_due(self):
        """A robot's epoch is paired: observe it with the other robots' paired by then, in a task queued behind the
        callbacks already waiting (their visibility messages), or at once without an executor or once every
        robot's epoch is paired (the visibility handed in-process: the last robot's hand-over completes the round;
        a task would only add the executor's dispatch to the latency)."""
        if self.executor is None or all(r.paired for r in self.robots if r.chain is not None):
            self.observe_robots()
            return
        if self._observe_queued:
            return
        self._observe_queued = True
        self.executor.create_task(self.observe_robots)

    def observe_robots(self):
        """The observables of every robot's paired epochs, in rounds (a robot's next epoch after this one): the
        fixes still due first (each chain's halves in order), the first paired epoch of each robot observed in
        one pass (core/receiver/batch_observe.observe_receivers: each robot's bits as alone), each robot's
        observations published; then their fix half queued (finish_robots)."""
        self._observe_queued = False
        for r in self.robots:
            if r.chain is None:
                r.paired.clear()
        observed = False
        while True:
            due = [r for r in self.robots if r.paired]
            if not due:
                break
            self.finish_robots()
            inputs = [r.epoch_inputs(*r.paired.pop(0)) for r in due]
            got = observe_receivers([r.chain for r in due], [e for _, e in inputs])
            for r, (stamp, e), obs in zip(due, inputs, got):
                r.observed(stamp, e, obs)
            observed = True
        if observed:
            if self.executor is not None:
                self.executor.create_task(self.finish_robots)
            else:
                self.finish_robots()

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
                               service=service, decode_states=self.decoded_states, finish=self.finish_robots,
                               observe=self.observe_due)

    def configure(self, p):
        n = p["fleet_robots"]
        self.robots = [self.robot_session(k, n) for k in range(n)]
        for k, r in enumerate(self.robots):
            r.configure(fleet_robot_params(p, k, "receiver"))

    def activate(self):
        from gnss_sim_msgs.msg import SatelliteStates, Visibility

        self.active_subscription(SatelliteStates, "satellite_states", self._on_states, 100, raw=True)
        n = len(self.robots)
        self._takers = [self._take_visibility(k, fleet_topic(k, n, "visibility"), Visibility) for k in range(n)]

    def _take_visibility(self, k: int, topic: str, msg_type) -> Taker:
        """Robot k's visibility: handed by a fleet visibility node of this process (nodes/in_process.py), else
        from the middleware (a raw subscription)."""
        r = self.robots[k]
        over_middleware = subscription_switch(
            lambda: self.active_subscription(msg_type, topic, r.on_visibility, 100, raw=True), self.drop_active)
        return Taker(self, topic, self.speaking(lambda handed: self._handed(r, *handed)), over_middleware)

    def _handed(self, r: ReceiverSession, stamp, columns: dict, states_data: bytes, states_decoded):
        """Robot ``r``'s epoch handed by the fleet visibility node: its visibility decoded (the columns the
        message's decode gives) and the SatelliteStates it cast (its bytes and their decode: every robot's, decoded
        once), paired at once (the middleware's copy of the states then comes after its epoch: dropped)."""
        self.decoded_states(states_data, states_decoded)
        r.on_states(states_data)
        r.on_visibility(columns, stamp)

    def _on_states(self, data: bytes):
        for r in self.robots:
            r.on_states(data)

    def deactivate(self):
        for t in self._takers:
            t.close()
        self._takers = []
        self.observe_robots()            # the epochs paired, while the publishers are on
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
