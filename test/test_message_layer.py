"""The message layer's builders (gnss_sim_ros2/messages: solution, rtk, diagnostics, images) and the sky view
picture (core/scene/sky_view.py): each message read back gives the core values it was built from."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("rclpy", reason="rclpy is not installed (run make test, or source ROS 2)")

from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from sensor_msgs.msg import NavSatFix, NavSatStatus  # noqa: E402
from std_msgs.msg import Header  # noqa: E402

from gnss_sim_ros2.core.rtk.solution import Q_FIX, Q_SINGLE, RtkBaseline, RtkSolution  # noqa: E402
from gnss_sim_ros2.core.scene.sky_view import (  # noqa: E402
    BELOW_HORIZON_RGB,
    OPAQUE_RGB,
    STATE_RGB,
    sky_view_rgb,
)
from gnss_sim_ros2.core.time import GnssTime  # noqa: E402
from gnss_sim_ros2.core.vocabulary import VisibilityState  # noqa: E402
from gnss_sim_ros2.messages.diagnostics import diagnostic_array, diagnostic_status  # noqa: E402
from gnss_sim_ros2.messages.images import rgb8_image  # noqa: E402
from gnss_sim_ros2.messages.rtk import heading_to_msg, rtk_fix_to_msg, rtk_status_to_msg, rtk_vel_to_msg  # noqa: E402
from gnss_sim_ros2.messages.solution import navsatfix_service, status_to_msg, vel_to_msg  # noqa: E402

T0 = GnssTime.from_iso("2022-01-01T01:00:00")
HEADER = Header(frame_id="gnss_antenna")


def _twist(msg):
    lin = msg.twist.twist.linear
    return np.array([lin.x, lin.y, lin.z]), np.array(msg.twist.covariance).reshape(6, 6)


def test_velocity_of_a_fix_and_of_none():
    cov = np.array([[0.04, 0.01, 0.0], [0.01, 0.05, 0.0], [0.0, 0.0, 0.09]])
    sol = SimpleNamespace(vel_status="fix", vel_enu_mps=np.array([1.5, -0.25, 0.125]), cov_vel_enu_m2ps2=cov)
    v, c = _twist(vel_to_msg(HEADER, sol))
    assert np.array_equal(v, sol.vel_enu_mps) and np.array_equal(c[:3, :3], cov)
    assert list(np.diag(c)[3:]) == [-1.0] * 3 and not np.any(c[:3, 3:]) and not np.any(c[3:, :3])
    for bad in (SimpleNamespace(vel_status="none", vel_enu_mps=np.ones(3), cov_vel_enu_m2ps2=cov),
                SimpleNamespace(vel_status="fix", vel_enu_mps=np.array([np.nan, 0.0, 0.0]), cov_vel_enu_m2ps2=cov)):
        v, c = _twist(vel_to_msg(HEADER, bad))
        assert not np.any(v) and c.ravel()[0] == -1.0 and not np.any(c.ravel()[1:])


def test_receiver_status_counts_and_solution_type():
    from gnss_sim_msgs.msg import ReceiverStatus

    obs = SimpleNamespace(sat_el_deg=np.array([3.0, 20.0, 45.0, 80.0]), sat_vis_state=np.array([0, 1, 0, 2]),
                          n_tracked_sats=3, clock_bias_s=1e-4, clock_drift_sps=2e-9)
    fix = SimpleNamespace(is_fix=True, n_used=3, sv_used=["G01", "E11", "G07"], gdop=2.0, pdop=1.8, hdop=1.0,
                          vdop=1.5, tdop=0.9, reason="")
    msg = status_to_msg(HEADER, obs, fix, elevation_mask_deg=10.0)
    assert (msg.satellites_visible, msg.satellites_tracked, msg.satellites_used) == (2, 3, 3)
    assert list(msg.systems_used) == ["E", "G"] and msg.solution_type == ReceiverStatus.SOLUTION_SINGLE
    assert (msg.hdop, msg.clock_bias_s, msg.reason) == (1.0, 1e-4, "")
    none = status_to_msg(HEADER, obs, SimpleNamespace(**{**vars(fix), "is_fix": False, "reason": "3 satellites"}),
                         elevation_mask_deg=50.0)
    assert none.satellites_visible == 1 and none.solution_type == ReceiverStatus.SOLUTION_NONE
    assert none.reason == "3 satellites"


def _rtk(q=Q_FIX, vel_cov=None):
    return RtkSolution(t=T0, lat_deg=22.3, lon_deg=114.17, h_m=40.5, q=q, ns=14,
                       cov_enu_m2=np.diag([1e-4, 2e-4, 9e-4]), age_s=1.0, ratio=12.5,
                       vel_enu_mps=np.array([0.5, 0.0, -0.1]),
                       cov_vel_enu_m2ps2=np.zeros((3, 3)) if vel_cov is None else vel_cov)


def test_rtk_fix_and_velocity():
    sol = _rtk()
    service = navsatfix_service("GE")
    assert service == NavSatStatus.SERVICE_GPS | NavSatStatus.SERVICE_GALILEO
    fix = rtk_fix_to_msg(HEADER, sol, service)
    assert (fix.latitude, fix.longitude, fix.altitude) == (22.3, 114.17, 40.5)
    assert fix.status.status == sol.status and fix.status.service == service
    assert np.array_equal(np.array(fix.position_covariance).reshape(3, 3), sol.cov_enu_m2)
    assert fix.position_covariance_type == NavSatFix.COVARIANCE_TYPE_KNOWN
    v, c = _twist(rtk_vel_to_msg(HEADER, sol))           # rtkrcv wrote no velocity covariance
    assert np.array_equal(v, sol.vel_enu_mps) and c[0, 0] == -1.0 and not np.any(c[:3, :3].ravel()[1:])
    cov = np.diag([0.01, 0.02, 0.03])
    v, c = _twist(rtk_vel_to_msg(HEADER, _rtk(vel_cov=cov)))
    assert np.array_equal(c[:3, :3], cov) and list(np.diag(c)[3:]) == [-1.0] * 3


@pytest.mark.parametrize("enu", [(1.0, 0.0, 0.0), (0.0, -2.0, 0.1), (-0.6, 0.8, 0.0)])
def test_heading_round_trip(enu):
    """The yaw the Imu carries gives back the baseline's heading as `gnss-sim run` reads it (90 - yaw)."""
    b = RtkBaseline(t=T0, enu_m=np.array(enu), q=Q_FIX, ns=12, cov_enu_m2=np.diag([1e-4, 4e-4, 1e-3]), age_s=0.0,
                    ratio=20.0)
    msg = heading_to_msg(HEADER, b)
    yaw_deg = np.degrees(2.0 * np.arctan2(msg.orientation.z, msg.orientation.w))
    assert (90.0 - yaw_deg) % 360.0 == pytest.approx(b.heading_deg, abs=1e-9)
    assert np.degrees(np.sqrt(msg.orientation_covariance[8])) == pytest.approx(b.heading_sd_deg)
    assert msg.angular_velocity_covariance[0] == -1.0 and msg.linear_acceleration_covariance[0] == -1.0


def test_rtk_status():
    from builtin_interfaces.msg import Time

    none = rtk_status_to_msg("rtk: rtkrcv", None, None, False, {}, {"rover": 0, "base": 0}, 0)
    assert none.level == DiagnosticStatus.WARN and none.message == "no solution yet"
    sol = _rtk()
    msg = rtk_status_to_msg("rtk: rtkrcv", sol, Time(sec=12, nanosec=5_000_000), True, {Q_FIX: 3, Q_SINGLE: 0},
                            {"rover": 100, "base": 90}, 2)
    values = {kv.key: kv.value for kv in msg.values}
    assert msg.level == DiagnosticStatus.OK and msg.hardware_id == "rtkrcv"
    assert values["stamp"] == "12.005000000" and values["quality"] == sol.quality and values["running"] == "true"
    assert values["epochs_fixed"] == "3" and "epochs_single" not in values
    assert (values["rover_bytes"], values["rover_epochs_without_base"]) == ("100", "2")


def test_diagnostics():
    from builtin_interfaces.msg import Time

    st = diagnostic_status("n: receiver", "fix, 9 satellites tracked", {"epochs": 11, "hdop": "0.90"})
    assert st.level == DiagnosticStatus.OK and st.hardware_id == "gnss_sim"
    assert [(kv.key, kv.value) for kv in st.values] == [("epochs", "11"), ("hdop", "0.90")]
    assert diagnostic_status("n", "m", {}, warn=True).level == DiagnosticStatus.WARN
    arr = diagnostic_array(Time(sec=3), st)
    assert arr.header.stamp.sec == 3 and list(arr.status) == [st]


def test_image_round_trip():
    rgb = np.random.default_rng(1).integers(0, 256, (5, 7, 3), dtype=np.uint8)
    msg = rgb8_image(HEADER, rgb)
    assert (msg.height, msg.width, msg.step, msg.encoding) == (5, 7, 21, "rgb8")
    assert np.array_equal(np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(5, 7, 3), rgb)


def test_sky_view_picture():
    """Blocked sky grey, open sky white, outside the horizon dark, a satellite in its state's colour."""
    az_e, el_e = np.arange(0.0, 361.0, 90.0), np.array([0.0, 30.0, 90.0])
    opaque = np.zeros((4, 2), dtype=bool)
    opaque[1, 0] = True                    # east, below 30 deg
    sky = (az_e, el_e, opaque, np.zeros_like(opaque))
    img = sky_view_rgb([0.0, 180.0], [90.0, 45.0], [VisibilityState.VISIBLE, VisibilityState.BLOCKED], sky, 101)
    c = 50
    assert tuple(img[c, c]) == STATE_RGB[VisibilityState.VISIBLE]             # zenith
    assert tuple(img[c + 25, c]) == STATE_RGB[VisibilityState.BLOCKED]        # south, 45 deg
    assert tuple(img[c, c + 45]) == OPAQUE_RGB                                  # east, 9 deg
    assert tuple(img[c, c - 45]) == (255, 255, 255)                             # west, 9 deg: open
    assert tuple(img[0, 0]) == BELOW_HORIZON_RGB


def test_transform_round_trip():
    from builtin_interfaces.msg import Time

    from gnss_sim_ros2.messages.tf import tf_message, transform_to_msg

    tf = transform_to_msg("world", "base_link", Time(sec=4, nanosec=7), [1.5, -2.0, 0.25], yaw_deg=-120.0)
    t = tf.transform
    assert (tf.header.frame_id, tf.child_frame_id, tf.header.stamp.nanosec) == ("world", "base_link", 7)
    assert (t.translation.x, t.translation.y, t.translation.z) == (1.5, -2.0, 0.25)
    assert np.degrees(2.0 * np.arctan2(t.rotation.z, t.rotation.w)) == pytest.approx(-120.0)
    assert t.rotation.x == t.rotation.y == 0.0 and np.hypot(t.rotation.z, t.rotation.w) == pytest.approx(1.0)
    assert list(tf_message([tf, tf]).transforms) == [tf, tf]


def test_streams_round_trip():
    from gnss_sim_ros2.messages.streams import nmea_to_msg, rtcm_from_msg, rtcm_to_msg

    frames = bytes([0xD3, 0x00, 0x13, 0x3E, 0xD0, 0x00, 0xFF])
    assert rtcm_from_msg(rtcm_to_msg(frames)) == frames
    text = "$GPGGA,...*47\r\n$GPRMC,...*11\r\n"
    assert nmea_to_msg(text).data == text
