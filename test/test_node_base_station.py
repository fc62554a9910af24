"""The base station's node features: a VisibilityNode with a static antenna (world, LLH, ECEF; no TF),
and a ReceiverNode serving its RTCM3 on a TCP port (rtcm_tcp_port) while configured."""
from __future__ import annotations

import socket

import numpy as np
import pytest
from rclpy.parameter import Parameter
from ros_helpers import ros  # noqa: F401  (fixture)

from gnss_sim_ros2.core.frames import ecef_to_geodetic
from gnss_sim_ros2.core.scene.demo_world import demo_world_path

ROOF_M = np.array([0.0, 21.0, 25.5])      # the default base_position (world)


def _state(node) -> str:
    return node._state_machine.current_state[1]


def _visibility(ros, **params):  # noqa: F811
    from gnss_sim_ros2.nodes.visibility_node import VisibilityNode

    overrides = [Parameter("use_sim_time", value=True)] + [Parameter(k, value=v) for k, v in params.items()]
    return ros.add(VisibilityNode(node_name="gnss_sim_base_visibility", parameter_overrides=overrides,
                                  context=ros.context))


@pytest.mark.parametrize("kind", ["world", "llh", "ecef"])
def test_static_antenna_in_every_form_lands_on_the_roof(ros, kind):  # noqa: F811
    from gnss_sim_ros2.core.scene.loader import load_sdf_world

    ecef = load_sdf_world(str(demo_world_path())).spherical_coordinates.world_to_ecef(ROOF_M)
    pos = {"world": list(ROOF_M), "ecef": list(ecef), "llh": list(ecef_to_geodetic(*ecef))}[kind]
    node = _visibility(ros, antenna_position=[float(v) for v in pos], antenna_position_type=kind)
    node.trigger_configure()
    assert _state(node) == "inactive", node.last_error
    assert np.allclose(node.fixed_world_m, ROOF_M, atol=1e-3)
    node.trigger_cleanup()


def test_static_antenna_far_from_the_world_is_refused(ros):  # noqa: F811
    node = _visibility(ros, antenna_position=[10.0, 10.0, 100.0], antenna_position_type="llh")
    node.trigger_configure()
    assert _state(node) == "unconfigured"
    assert "parameter 'antenna_position'" in node.last_error and "km from the world's origin" in node.last_error


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_receiver_serves_rtcm_on_its_tcp_port_while_configured(ros, tmp_path):  # noqa: F811
    from gnss_sim_ros2.nodes.receiver_node import ReceiverNode

    port = _free_port()
    overrides = [Parameter("rtcm", value=True), Parameter("rtcm_tcp_port", value=port),
                 Parameter("output_dir", value=str(tmp_path))]
    node = ros.add(ReceiverNode(node_name="gnss_sim_base_receiver", parameter_overrides=overrides,
                                context=ros.context))
    node.trigger_configure()
    assert _state(node) == "inactive", node.last_error
    with socket.create_connection(("127.0.0.1", port), timeout=2.0) as c:
        assert ros.spin_until(lambda: node.tcp.clients == 1, 3.0)
        node.tcp.write(b"\xd3\x00\x00\x47\xea\x4b")       # what process() forwards, byte for byte
        assert c.recv(16) == b"\xd3\x00\x00\x47\xea\x4b"
    node.trigger_cleanup()
    assert node.tcp is None
    with pytest.raises(OSError):
        socket.create_connection(("127.0.0.1", port), timeout=1.0).close()
    # a port another program holds: configure fails naming the parameter
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        node.set_parameters([Parameter("rtcm_tcp_port", value=busy.getsockname()[1])])
        node.trigger_configure()
        assert _state(node) == "unconfigured" and "parameter rtcm_tcp_port" in node.last_error


def test_world_offset_moves_the_georeference_and_a_static_llh_antenna_moves_against_it(ros):  # noqa: F811
    """Issue 27: world_offset_enu_m in the visibility node: the world's georeference moved (the shared scene left
    alone), an antenna given in LLH sits at its world position minus the offset."""
    from gnss_sim_ros2.core.scene.loader import load_sdf_world

    ecef = load_sdf_world(str(demo_world_path())).spherical_coordinates.world_to_ecef(ROOF_M)
    llh = [float(v) for v in ecef_to_geodetic(*ecef)]
    node = _visibility(ros, antenna_position=llh, antenna_position_type="llh", world_offset_enu_m=[1.5, -2.0, 0.5])
    node.trigger_configure()
    assert _state(node) == "inactive", node.last_error
    assert np.allclose(node.fixed_world_m, ROOF_M - np.array([1.5, -2.0, 0.5]), atol=1e-3)
    node.trigger_cleanup()
