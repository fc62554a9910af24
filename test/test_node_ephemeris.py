"""Ephemeris lifecycle node: parameters validated on configure, one message per epoch on simulated time."""
from __future__ import annotations

import numpy as np
import pytest
from rclpy.parameter import Parameter
from ros_helpers import ros  # noqa: F401  (fixture)

from gnss_sim_ros2.core.ephemeris.broadcast import BroadcastEphemeris
from gnss_sim_ros2.core.time import GnssTime
from gnss_sim_ros2.messages.conversions import iono_from_msg, states_from_msg, states_to_msg
from gnss_sim_ros2.nodes.ephemeris_node import EphemerisNode


def _node(ros, tmp_path, **params):  # noqa: F811
    params.setdefault("output_dir", str(tmp_path))  # the navigation file goes there, never into the work tree
    overrides = [Parameter("use_sim_time", value=True)] + [Parameter(k, value=v) for k, v in params.items()]
    return ros.add(EphemerisNode(parameter_overrides=overrides, context=ros.context))


def test_states_every_epoch_on_sim_time(ros, opec_dir, tmp_path):  # noqa: F811
    from gnss_sim_msgs.msg import SatelliteStates

    nav = str(opec_dir / "OPEC00NOR_S_20220010000_01D_GN.rnx")
    node = _node(ros, tmp_path, source="broadcast", nav_files=[nav], systems="G", start_time="2022-01-01T01:00:00",
                 rate_hz=2.0, duration_s=60.0)
    got = []
    ros.helper.create_subscription(SatelliteStates, "satellite_states", got.append, 100)
    ros.set_clock(0)
    ros.spin_until(lambda: False, 0.3)
    node.trigger_configure()
    assert node._state_machine.current_state[1] == "inactive", node.last_error
    node.trigger_activate()
    for s in range(1, 6):  # 5 s of simulated time
        ros.set_clock(s)
        ros.spin_until(lambda s=s: len(got) >= 2 * s + 1, 5.0)
    assert len(got) >= 11
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in got]
    np.testing.assert_allclose(stamps[:11], np.arange(11) * 0.5, atol=1e-9)  # no epoch skipped, in order
    # content equals the core's states at that epoch
    t, st = states_from_msg(got[4])
    assert t == GnssTime.from_iso("2022-01-01T01:00:02")
    ref = BroadcastEphemeris.from_files([nav]).states(t, systems="G")
    assert list(st.sv) == list(ref.sv) and len(st) >= 8
    np.testing.assert_allclose(st.pos_ecef_m, ref.pos_ecef_m, atol=1e-6)
    # the GPS file's Klobuchar coefficients travel with the states (no Galileo file: no NeQuick-G)
    iono = iono_from_msg(got[4])
    assert set(iono) == {"GPSA", "GPSB"} and len(iono["GPSA"]) == 4
    # deactivate stops publishing; cleanup frees; configure again works
    node.trigger_deactivate()
    n = len(got)
    ros.set_clock(10)
    ros.spin_until(lambda: False, 0.3)
    assert len(got) == n
    node.trigger_cleanup()
    assert node.provider is None


@pytest.mark.parametrize("params, message", [
    ({"source": "broadcast", "nav_files": ["/nonexistent/brdc.rnx"]}, "navigation file /nonexistent/brdc.rnx"),
    ({"source": "broadcast"}, "needs nav_files"),
    ({"systems": "GXZ"}, "parameter 'systems'"),
    ({"rate_hz": -1.0}, "rate_hz"),
])
def test_bad_parameters_refuse_configure(ros, params, message, tmp_path):  # noqa: F811
    node = _node(ros, tmp_path, **params)
    node.trigger_configure()
    assert node._state_machine.current_state[1] == "unconfigured"
    assert message in node.last_error


def test_ionosphere_coefficients_round_trip(opec_dir):
    """states_to_msg -> iono_from_msg keeps Klobuchar and NeQuick-G coefficients (the receiver node's input)."""
    from std_msgs.msg import Header

    from gnss_sim_ros2.core.rinex.nav import read_nav_files

    nav = read_nav_files([str(opec_dir / f"OPEC00NOR_S_20220010000_01D_{s}N.rnx") for s in "GE"])
    eph = BroadcastEphemeris(nav)
    t = GnssTime.from_iso("2022-01-01T01:00:00")
    msg = states_to_msg(eph.states(t, systems="GE"), t, Header(), nav.iono)
    iono = iono_from_msg(msg)
    assert iono["GAL"] == pytest.approx([87.75, 0.41797, -0.010742])
    assert iono["GPSA"] == pytest.approx(nav.iono["GPSA"]) and iono["GPSB"] == pytest.approx(nav.iono["GPSB"])
    empty = states_to_msg(eph.states(t, systems="GE"), t, Header(), None)
    assert iono_from_msg(empty) is None
