"""The reflected paths cross the Visibility message unchanged (conversions.reflections_to_msgs / paths_from_msg)."""
from __future__ import annotations

import numpy as np

from gnss_sim_ros2.core.multipath.reflections import ScenePaths
from gnss_sim_ros2.messages.conversions import paths_from_msg, reflections_to_msgs


def test_paths_cross_the_message_bit_for_bit():
    from gnss_sim_msgs.msg import SatelliteVisibility
    from rclpy.serialization import deserialize_message, serialize_message

    rng = np.random.default_rng(3)
    p = ScenePaths.empty(1, 3, 4).take(0)
    p.excess_m[0, :2] = [12.5, 40.25]                 # satellite 0: two paths, satellite 1: none, 2: one
    p.excess_m[2, 3] = 3.0                            # a path in the last slot (scattered paths come after)
    for i, k in ((0, 0), (0, 1), (2, 3)):
        p.gamma_co[i, k], p.gamma_cross[i, k] = rng.normal(size=2) + 1j * rng.normal(size=2)
        p.arrival_el_deg[i, k] = rng.uniform(-30, 60)
    svs = ["G01", "G02", "C11"]
    by_sv = {}
    for i, sv in enumerate(svs):
        msg = SatelliteVisibility(sv=sv, reflections=reflections_to_msgs(p, i))
        by_sv[sv] = deserialize_message(serialize_message(msg), SatelliteVisibility)
    assert [len(by_sv[s].reflections) for s in svs] == [2, 0, 1]
    back = paths_from_msg(by_sv, ["C11", "G01", "G09", "G02"])      # the receiver's row order; G09 not seen
    assert back.excess_m.shape == (4, 2)
    np.testing.assert_array_equal(back.excess_m[1], p.excess_m[0, :2])
    np.testing.assert_array_equal(back.gamma_co[1], p.gamma_co[0, :2])
    np.testing.assert_array_equal(back.gamma_cross[1], p.gamma_cross[0, :2])
    np.testing.assert_array_equal(back.arrival_el_deg[1], p.arrival_el_deg[0, :2])
    assert back.excess_m[0, 0] == 3.0 and back.gamma_co[0, 0] == p.gamma_co[2, 3]
    assert np.isnan(back.excess_m[0, 1]) and not back.valid[2].any() and not back.valid[3].any()
    # no reflection anywhere: None, what the chain takes without multipath
    assert paths_from_msg({"G01": SatelliteVisibility(sv="G01")}, ["G01"]) is None
    assert reflections_to_msgs(None, 0) == []
