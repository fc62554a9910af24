"""nodes/receiver_session.ReceiverSession in the fleet receiver node: each robot its own receiver (chain, threat
services under ~/robot<k>/, topics under /robot<k>/gnss/), none sharing another's state (issue 31: the robots were
once ReceiverNode's methods rebound onto a proxy, which broke when the threat services were added)."""
from __future__ import annotations

from rclpy.parameter import Parameter
from ros_helpers import ros  # noqa: F401  (fixture)

FAULT = "{type: fault, kind: clock_jump_s, jump_s: 1.0e-3}"


def _call(ros, srv_type, name, request):  # noqa: F811
    client = ros.helper.create_client(srv_type, name)
    assert client.wait_for_service(timeout_sec=5.0), name
    fut = client.call_async(request)
    assert ros.spin_until(fut.done, 5.0), name
    return fut.result()


def test_fleet_robots_each_serve_their_own_threats(ros, tmp_path):  # noqa: F811
    from gnss_sim_msgs.srv import StartThreat, StopThreat

    from gnss_sim_ros2.nodes.fleet_receiver_node import FleetReceiverNode

    scenario = tmp_path / "none.yaml"
    scenario.write_text("version: 1\nevents: []\n")
    overrides = [Parameter("fleet_robots", value=2), Parameter("output_dir", value=str(tmp_path / "out")),
                 Parameter("scenario", value=str(scenario))]
    node = ros.add(FleetReceiverNode(parameter_overrides=overrides, context=ros.context))
    node.trigger_configure()
    assert node._state_machine.current_state[1] == "inactive", node.last_error
    r0, r1 = node.robots
    assert r0.chain is not r1.chain and r0.pairing is not r1.pairing and r0.chain.threats is not r1.chain.threats
    assert r0.pubs["fix"].topic_name == "/robot0/gnss/fix" and r1.pubs["fix"].topic_name == "/robot1/gnss/fix"
    assert r0.pubs["diag"] is r1.pubs["diag"]          # /diagnostics: one publisher for every robot

    base = f"/{node.get_name()}"
    started = _call(ros, StartThreat, f"{base}/robot1/threats/start", StartThreat.Request(event_yaml=FAULT))
    assert started.success and started.id, started.message
    # the event is robot 1's only: robot 0 does not know it, robot 1 stops it
    other = _call(ros, StopThreat, f"{base}/robot0/threats/stop", StopThreat.Request(id=started.id))
    assert not other.success and started.id in other.message
    mine = _call(ros, StopThreat, f"{base}/robot1/threats/stop", StopThreat.Request(id=started.id))
    assert mine.success, mine.message
    node.trigger_cleanup()
    assert node.robots == [] and r0.chain is None and r1.threat_services == []
