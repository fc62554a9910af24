"""Receiver lifecycle node: observables, fix, NMEA and RINEX from satellites + visibility.

For each epoch it pairs ``satellite_states`` and ``visibility`` with the same
stamp (the visibility message carries the antenna position that the
visibility node looked up in TF at that stamp, lever arm included: one TF
lookup serves both nodes), runs the receiver core and publishes:
``observations`` (gnss_sim_msgs/Observations), ``fix`` (sensor_msgs/NavSatFix,
messages.solution.fix_to_msg: the solver's ENU covariance, which it scaled by the a-posteriori variance factor),
``vel`` (geometry_msgs/TwistWithCovarianceStamped, ENU), ``status``
(gnss_sim_msgs/ReceiverStatus), ``nmea`` (std_msgs/String, one epoch's
sentences; nmea_msgs is not available on PyPI) and diagnostics; and writes
the RINEX observation file epoch by epoch into ``output_dir``.  With a threat scenario (parameter ``scenario``,
docs/SCENARIOS.md): its truth labels on ``threats_active``, the jamming indicator and AGC per band in ``status``,
and the services ``~/threats/start`` (gnss_sim_msgs/StartThreat: one event as YAML, its name back) and
``~/threats/stop`` (StopThreat: by name) to start and stop events while the run goes on (core/threats/live.py).
With ``rtcm``:
``rtcm`` (std_msgs/UInt8MultiArray, one epoch's RTCM3 messages), also served
on TCP port ``rtcm_tcp_port`` (core/rtcm/tcp_server.py) for outside tools.

The epoch's work is core/receiver/chain.py's ReceiverChain, the same object
``gnss-sim simulate`` steps, held with the pairing, the epochs awaiting their fix, the publishers and the
services by one nodes/receiver_session.ReceiverSession (the fleet receiver node holds one per robot): this node
only subscribes and drives the session through the lifecycle. The big messages
travel as CDR bytes read and written from arrays (gnss_sim_ros2/messages/cdr.py): the
states and visibility subscriptions are raw, ``observations`` is published
serialised; the others are small rclpy messages.  The node has
the states at the epoch, not the ephemeris: the chain goes back to the
transmit time with the second-order expansion (sub-millimetre over 0.07 s,
see test_propagation), whatever the preset says.
"""
from __future__ import annotations

import sys

from gnss_sim_ros2.nodes.common import GnssSimNode, run_node
from gnss_sim_ros2.nodes.receiver_session import ReceiverSession


class ReceiverNode(GnssSimNode):
    PARAMS_KEY = "receiver"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.session = ReceiverSession(self, label=self.get_name())   # the receiver (configure .. cleanup)

    # the session's state, read by tests and tools as the node's
    @property
    def chain(self):
        return self.session.chain

    @property
    def pubs(self) -> dict:
        return self.session.pubs

    @property
    def tcp(self):
        return self.session.tcp

    def process(self, states_data: bytes, vis_data: bytes):
        """One epoch from the serialised SatelliteStates and Visibility of one stamp (ReceiverSession.process)."""
        self.session.process(states_data, vis_data)

    def configure(self, p):
        self.session.configure(p)

    def activate(self):
        from gnss_sim_msgs.msg import SatelliteStates, Visibility

        self.active_subscription(SatelliteStates, "satellite_states", self.session.on_states, 100, raw=True)
        self.active_subscription(Visibility, "visibility", self.session.on_visibility, 100, raw=True)

    def deactivate(self):
        self.session.deactivate()

    def cleanup(self):
        self.session.cleanup()


def main(args=None):
    return run_node(ReceiverNode, args)


if __name__ == "__main__":
    sys.exit(main())
