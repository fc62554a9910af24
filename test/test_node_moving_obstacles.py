"""The visibility node's moving obstacles: a Gazebo-style model whose poses come on a tf2_msgs/TFMessage topic
blocks the satellite behind it in the node's published visibility while it is there and not after it has gone;
another robot's body (its frame in TF, obstacle_frames) blocks too, the robot's own body is left out.  The
expected blocking is plain geometry: a bus 10 m long, 3 m high, its near face 4.75 m north of a rooftop antenna,
hides a satellite due north at 15 deg elevation (the ray reaches it 1.27 m above the antenna, under its roof);
robot1, a 1 x 1 x 2 m body 2 m south of the antenna (near face 1.5 m away, top 1.5 m above the antenna: 45 deg)
hides the satellite due south at 15 deg."""
from __future__ import annotations

import numpy as np
from rclpy.parameter import Parameter
from ros_helpers import ros  # noqa: F401  (fixture)

from gnss_sim_ros2.core import frames
from gnss_sim_ros2.core.ephemeris.states import SatelliteStates
from gnss_sim_ros2.core.time import GnssTime
from gnss_sim_ros2.core.vocabulary import VisibilityState

ROOF_M = np.array([0.0, 21.0, 25.5])      # open sky on the demo courtyard's north wing (the default base position)
TOPIC = "/world/demo/dynamic_pose/info"


def _states(scene, az_deg, el_deg, t):
    rx = scene.antenna_ecef(ROOF_M)
    lat, lon, _ = frames.ecef_to_geodetic(*rx)
    pos = rx + 2.0e7 * frames.enu_unit_from_az_el(np.asarray(az_deg, float), np.asarray(el_deg, float)) @ \
        frames.enu_rotation(lat, lon)
    n = len(pos)
    st = SatelliteStates.empty(t, "synthetic")
    z = np.zeros(n)
    return SatelliteStates(t=t, sv=np.array([f"G{i + 1:02d}" for i in range(n)]), pos_ecef_m=pos,
                           vel_ecef_mps=np.zeros((n, 3)), acc_ecef_mps2=np.zeros((n, 3)), clock_bias_s=z,
                           clock_drift_sps=z, relativistic_s=z, tgd_s=z, health=np.zeros(n, np.int64),
                           iode=np.zeros(n, np.int64), age_s=z, glo_channel=np.zeros(n, np.int64), source=st.source)


def _pose(sec, x, y, z, child="bus"):
    from geometry_msgs.msg import TransformStamped

    tf = TransformStamped()
    tf.header.stamp.sec = sec
    tf.header.frame_id = "world"
    tf.child_frame_id = child
    tf.transform.translation.x, tf.transform.translation.y, tf.transform.translation.z = x, y, z
    tf.transform.rotation.w = 1.0
    return tf


def test_model_on_the_pose_topic_blocks_the_satellite_behind_it_while_there(ros):  # noqa: F811
    from builtin_interfaces.msg import Time
    from gnss_sim_msgs.msg import Visibility
    from tf2_msgs.msg import TFMessage

    from gnss_sim_ros2.messages.conversions import encode_states, visibility_from_cdr
    from gnss_sim_ros2.nodes.visibility_node import VisibilityNode

    params = {"antenna_position": [float(v) for v in ROOF_M], "obstacle_models": ["bus"],
              "obstacle_pose_topic": TOPIC, "obstacle_model_size_m": [10.0, 2.5, 3.0],
              "obstacle_box_size_m": [1.0, 1.0, 2.0],
              "multipath": "off",             # the preset's nlos would find the wings' reflections of a hidden one
              "antenna_frame": "robot0/gnss_antenna", "obstacle_frames": ["robot0/base_link", "robot1/base_link"]}
    node = ros.add(VisibilityNode(node_name="gnss_sim_visibility", context=ros.context,
                                  parameter_overrides=[Parameter(k, value=v) for k, v in params.items()]))
    node.trigger_configure()
    assert node._state_machine.current_state[1] == "inactive", node.last_error
    assert node.obstacle_frames == ["robot1/base_link"]          # robot0's own body left out
    node.trigger_activate()
    got = []
    ros.helper.create_subscription(Visibility, "/visibility", got.append, 10, raw=True)
    pub = ros.helper.create_publisher(TFMessage, TOPIC, 10)
    tf_pub = ros.helper.create_publisher(TFMessage, "/tf", 10)
    # the bus stands 6 m north of the antenna (its base level with the roof) from 0 to 10 s, then 200 m east
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0 and tf_pub.get_subscription_count() > 0, 5.0)
    tf_pub.publish(TFMessage(transforms=[_pose(0, 0.0, 19.0, 25.0, "robot1/base_link"),
                                         _pose(20, 0.0, 19.0, 25.0, "robot1/base_link")]))
    pub.publish(TFMessage(transforms=[_pose(0, 0.0, 27.0, 25.0), _pose(10, 0.0, 27.0, 25.0),
                                      _pose(11, 200.0, 27.0, 25.0)]))
    assert ros.spin_until(lambda: "bus" in node.model_poses.frames() and node.tf.can_transform(
        "world", "robot1/base_link", Time(sec=12)), 5.0)
    t0 = GnssTime.from_iso("2025-06-01T10:00:00")
    for sec in (5, 12):
        st = _states(node.scene, [0.0, 180.0], [15.0, 15.0], t0 + sec)
        node.process(encode_states(st, t0 + sec, Time(sec=sec), "world"), ROOF_M)
    assert ros.spin_until(lambda: len(got) == 2, 5.0)
    during, after = (visibility_from_cdr(d) for d in got)
    blocked, visible = int(VisibilityState.BLOCKED), int(VisibilityState.VISIBLE)
    assert during["satellites"][1]["state"].tolist() == [blocked, blocked]
    assert after["satellites"][1]["state"].tolist() == [visible, blocked]
    assert node.obstacles_missing == 0
    node.trigger_deactivate()
    node.trigger_cleanup()
