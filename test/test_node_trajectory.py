"""Trajectory player + TF source: the antenna pose at a stamp equals the path plus the lever arm."""
from __future__ import annotations

import numpy as np
from rclpy.parameter import Parameter
from ros_helpers import ros  # noqa: F401  (fixture)

from gnss_sim_ros2.core.trajectory import demo_trajectory
from gnss_sim_ros2.nodes.tf_source import TfSource
from gnss_sim_ros2.nodes.trajectory_player import TrajectoryPlayer


def test_antenna_pose_follows_path_on_sim_time(ros):  # noqa: F811
    from builtin_interfaces.msg import Time

    player = ros.add(TrajectoryPlayer(parameter_overrides=[
        Parameter("use_sim_time", value=True), Parameter("publish_rate_hz", value=10.0),
        Parameter("antenna_offset_m", value=[0.2, 0.0, 0.5])], context=ros.context))
    tf = TfSource(ros.helper, prefer_tf2_ros=False)
    ros.set_clock(0)
    ros.spin_until(lambda: False, 0.3)
    player.trigger_configure()
    player.trigger_activate()
    ros.set_clock(0, 100_000_000)
    ros.spin_until(lambda: tf.latest_s.get("base_link", -1) >= 0.1, 5)
    ros.set_clock(37)  # a jump: every 0.1 s tick in between gets a sample
    assert ros.spin_until(lambda: tf.latest_s.get("base_link", -1) >= 37.0, 5)
    path = demo_trajectory()
    for t in (12.3, 29.95, 36.0):
        stamp = Time(sec=int(t), nanosec=int(round((t % 1) * 1e9)))
        tr, rot = tf.lookup("world", "gnss_antenna", stamp)
        yaw = np.radians(path.yaw(t))
        expected = path.position(t) + np.array([0.2 * np.cos(yaw), 0.2 * np.sin(yaw), 0.5])
        np.testing.assert_allclose(tr, expected, atol=1e-3)
    player.trigger_deactivate()
    player.trigger_cleanup()
    tf.close()


def test_non_world_path_refuses_configure(ros, tmp_path):  # noqa: F811
    f = tmp_path / "geo.csv"
    f.write_text("t_s,lat_deg,lon_deg,h_m\n0,50,14,250\n10,50.001,14,250\n")
    player = ros.add(TrajectoryPlayer(parameter_overrides=[Parameter("trajectory_file", value=str(f))],
                                      context=ros.context))
    player.trigger_configure()
    assert player._state_machine.current_state[1] == "unconfigured"
    assert "geodetic" in player.last_error and str(f) in player.last_error
