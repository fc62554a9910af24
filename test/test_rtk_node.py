"""The rtk lifecycle node: rtkrcv fed from /gnss/rtcm and /gnss/base/rtcm, its fixes published;
start/stop/restart services; a user's rtkrcv .conf; a clear error where rtkrcv is missing."""
from __future__ import annotations

import os

import numpy as np
import pynmea2
import pytest
from rclpy.parameter import Parameter
from ros_helpers import ros  # noqa: F401  (fixture)
from test_rtk_engine import base_rover, rtkrcv_and_faketime, two_antennas  # noqa: F401  (fixtures: RTCM3)

from gnss_sim_ros2.core.frames import geodetic_to_ecef
from gnss_sim_ros2.core.rtk.solution import STATUS_GBAS_FIX

START = "2022-01-01T01:00:00"


def _node(ros, **params):  # noqa: F811
    from gnss_sim_ros2.nodes.rtk_node import RtkNode

    overrides = [Parameter("use_sim_time", value=True), Parameter("start_time", value=START),
                 Parameter("systems", value="GE")] + [Parameter(k, value=v) for k, v in params.items()]
    return ros.add(RtkNode(parameter_overrides=overrides, context=ros.context, namespace="gnss"))


def _state(node) -> str:
    return node._state_machine.current_state[1]


def test_rtkrcv_missing_refuses_configure(ros):  # noqa: F811
    node = _node(ros, rtkrcv_path="/no/such/rtkrcv")
    node.trigger_configure()
    assert _state(node) == "unconfigured"
    assert "rtkrcv not found '/no/such/rtkrcv'" in node.last_error and "apt-get install rtklib" in node.last_error


def test_bad_user_conf_refuses_configure(ros, tmp_path):  # noqa: F811
    conf = tmp_path / "bad.conf"
    conf.write_text("pos1-posmode=kinematic\nnot an option line\n")
    node = _node(ros, rtkrcv_conf=str(conf))
    node.trigger_configure()
    assert _state(node) == "unconfigured" and "bad.conf, line 2" in node.last_error


needs_rtkrcv = pytest.mark.skipif(not rtkrcv_and_faketime(), reason="RTKLIB rtkrcv and libfaketime are not "
                                  "installed (apt-get install rtklib faketime)")


@pytest.fixture(scope="module")
def streams(base_rover):  # noqa: F811
    return base_rover


def _call(ros, name: str):  # noqa: F811
    from std_srvs.srv import Trigger

    client = ros.helper.create_client(Trigger, f"/gnss/gnss_sim_rtk/{name}")
    assert client.wait_for_service(timeout_sec=5.0)
    fut = client.call_async(Trigger.Request())
    assert ros.spin_until(fut.done, 20.0)
    ros.helper.destroy_client(client)
    return fut.result()


def _feed(ros, streams, node, epochs):  # noqa: F811
    from std_msgs.msg import UInt8MultiArray

    pub_r = ros.helper.create_publisher(UInt8MultiArray, "/gnss/rtcm", 1000)
    pub_b = ros.helper.create_publisher(UInt8MultiArray, "/gnss/base/rtcm", 1000)
    ros.spin_until(lambda: pub_r.get_subscription_count() and pub_b.get_subscription_count(), 5.0)
    assert node.proc.wait_connected(15.0), node.proc.log_text()
    for b, r in list(zip(streams["base"], streams["rover"]))[:epochs]:
        pub_b.publish(UInt8MultiArray(data=b))
        pub_r.publish(UInt8MultiArray(data=r))
        ros.spin_until(lambda: False, 0.03)


@needs_rtkrcv
def test_node_publishes_rtk_fixes_and_serves_start_stop_restart(ros, streams):  # noqa: F811
    from diagnostic_msgs.msg import DiagnosticStatus
    from geometry_msgs.msg import TwistWithCovarianceStamped
    from sensor_msgs.msg import NavSatFix
    from std_msgs.msg import String

    fixes, vels, nmea, status = [], [], [], []
    ros.helper.create_subscription(NavSatFix, "/gnss/rtk/fix", fixes.append, 1000)
    ros.helper.create_subscription(TwistWithCovarianceStamped, "/gnss/rtk/vel", vels.append, 1000)
    ros.helper.create_subscription(String, "/gnss/rtk/nmea", nmea.append, 1000)
    ros.helper.create_subscription(DiagnosticStatus, "/gnss/rtk/status", status.append, 1000)
    ros.set_clock(0)
    node = _node(ros)
    node.trigger_configure()
    assert _state(node) == "inactive", node.last_error
    assert not _call(ros, "start").success                # services act only while active
    node.trigger_activate()
    assert _state(node) == "active", node.last_error
    n = len(streams["rover"])
    _feed(ros, streams, node, n)
    # the node publishes each solution's fix, then its velocity: wait for both (a loaded machine delivers the last
    # velocity after the last fix)
    ros.spin_until(lambda: len(fixes) >= n and len(vels) >= len(fixes), 10.0)
    gbas = [f for f in fixes if f.status.status == STATUS_GBAS_FIX]
    err = np.array([np.linalg.norm(np.array(geodetic_to_ecef(f.latitude, f.longitude, f.altitude))
                                   - streams["rover_ecef"]) for f in gbas])
    fixed = int(status[-1].values[[v.key for v in status[-1].values].index("epochs_fixed")].value)
    print(f"\nrtk node: {len(fixes)} /gnss/rtk/fix for {n} epochs, {fixed} fixed, 3D error RMS "
          f"{np.sqrt(np.mean(err ** 2)) * 100:.2f} cm, {len(nmea)} NMEA sentences")
    assert len(fixes) >= 0.95 * n and fixed >= 0.9 * n
    assert np.sqrt(np.mean(err ** 2)) < 0.02
    f = fixes[-1]
    assert f.header.frame_id == "gnss_antenna" and f.position_covariance_type == NavSatFix.COVARIANCE_TYPE_KNOWN
    cov = np.array(f.position_covariance).reshape(3, 3)
    assert np.allclose(cov, cov.T) and 0 < cov[0, 0] < 1e-3
    # stamps: the solutions' GNSS times through time_mapping offset (ROS 0 = start_time)
    assert fixes[0].header.stamp.sec == 0 and fixes[-1].header.stamp.sec == n - 1
    assert len(vels) == len(fixes) and vels[-1].twist.covariance[0] > 0
    assert abs(vels[-1].twist.twist.linear.x) < 0.1              # a static rover
    gga = [pynmea2.parse(s.data) for s in nmea if s.data[3:6] == "GGA"]
    assert gga and sum(g.gps_qual == 4 for g in gga) >= 0.9 * n      # GGA quality 4: RTK fixed
    assert status[-1].level == DiagnosticStatus.OK and "fixed" in status[-1].message
    # services
    pid = node.proc.proc.pid
    r = _call(ros, "stop")
    assert r.success and "stopped" in r.message and node.proc is None
    with pytest.raises(ProcessLookupError):
        os.killpg(pid, 0)
    assert _call(ros, "stop").message == "rtkrcv is not running"
    r = _call(ros, "start")
    assert r.success and node.proc.running
    assert _call(ros, "start").message == "rtkrcv is already running"
    old = node.proc.proc.pid
    r = _call(ros, "restart")
    assert r.success and r.message.startswith("restarted") and node.proc.running and node.proc.proc.pid != old
    pid = node.proc.proc.pid
    node.trigger_deactivate()
    assert node.proc is None
    with pytest.raises(ProcessLookupError):
        os.killpg(pid, 0)
    assert not _call(ros, "start").success
    node.trigger_cleanup()
    assert _state(node) == "unconfigured"


@needs_rtkrcv
def test_node_runs_a_user_conf(ros, streams, tmp_path):  # noqa: F811
    from sensor_msgs.msg import NavSatFix

    conf = tmp_path / "mine.conf"
    conf.write_text("pos1-posmode=kinematic\npos1-frequency=l1+2\npos1-navsys=9\npos2-armode=fix-and-hold\n"
                    "pos2-arthres=2.0\nant2-postype=rtcm\ninpstr1-type=serial\ninpstr1-path=ttyUSB0:115200\n"
                    "outstr1-format=xyz\n")
    fixes = []
    ros.helper.create_subscription(NavSatFix, "/gnss/rtk/fix", fixes.append, 1000)
    ros.set_clock(0)
    node = _node(ros, rtkrcv_conf=str(conf))
    node.trigger_configure()
    node.trigger_activate()
    assert _state(node) == "active", node.last_error
    text = node.proc.conf_path.read_text()
    assert "pos2-armode       =fix-and-hold" in text and "inpstr1-type      =tcpcli" in text
    assert set(node.proc.replaced_options) == {"inpstr1-type", "inpstr1-path", "outstr1-format"}
    _feed(ros, streams, node, 40)
    ros.spin_until(lambda: len(fixes) >= 40, 10.0)
    assert sum(f.status.status == STATUS_GBAS_FIX for f in fixes) >= 36
    node.trigger_deactivate()
    node.trigger_cleanup()


@needs_rtkrcv
def test_node_moving_base_publishes_heading(ros, two_antennas):  # noqa: F811
    from sensor_msgs.msg import Imu

    heads = []
    ros.helper.create_subscription(Imu, "/gnss/rtk/heading", heads.append, 1000)
    ros.set_clock(0)
    node = _node(ros, rtk_mode="movingbase")
    node.trigger_configure()
    node.trigger_activate()
    assert _state(node) == "active", node.last_error
    assert "rtk/fix" not in str(node.pubs) and "fix" not in node.pubs
    n = len(two_antennas["rover"])
    _feed(ros, two_antennas, node, n)
    ros.spin_until(lambda: len(heads) >= n, 10.0)
    yaw = np.degrees([2 * np.arctan2(m.orientation.z, m.orientation.w) for m in heads])
    sd = np.degrees(np.sqrt([m.orientation_covariance[8] for m in heads]))
    print(f"\nrtk node movingbase: {len(heads)} headings, ENU yaw {yaw.mean():.3f} deg (truth 60), sd {sd.mean():.3f}")
    assert len(heads) >= 0.9 * n
    assert np.median(np.abs(yaw - 60.0)) < 0.2 and np.all(sd < 1.0)
    assert heads[-1].orientation_covariance[0] == 1e6 and heads[-1].angular_velocity_covariance[0] == -1.0
    node.trigger_deactivate()
    node.trigger_cleanup()


@needs_rtkrcv
def test_node_sends_nav_files_to_streams_without_ephemerides(ros, base_rover):  # noqa: F811
    """Base and rover RTCM3 with observations only: rtkrcv solves nothing alone, and fixes with the
    ephemerides of the run's RINEX navigation file sent by the node (parameter nav_files)."""
    from sensor_msgs.msg import NavSatFix
    from test_rtcm_rtklib import BASE_ECEF_M, simulate_to_rtcm

    from gnss_sim_ros2.core.rtcm.frame import epochs_of, message_number, split_frames

    out = base_rover["out"] / "bare"
    kw = dict(systems="GE", duration_s=40.0, interval_s=1.0, with_navigation=False)
    base = simulate_to_rtcm(out / "base", BASE_ECEF_M, seed=11, marker="BASE", **kw)
    rover = simulate_to_rtcm(out / "rover", base_rover["rover_ecef"], seed=22, marker="ROVR", **kw)
    bare = {"base": epochs_of(base["rtcm"].read_bytes()), "rover": epochs_of(rover["rtcm"].read_bytes())}
    assert not {1019, 1046} & {message_number(f) for f in split_frames(base["rtcm"].read_bytes())[0]}
    counts = []
    for nav_files in ([], [str(base["nav"])]):
        fixes = []
        sub = ros.helper.create_subscription(NavSatFix, "/gnss/rtk/fix", fixes.append, 1000)
        ros.set_clock(0)
        node = _node(ros, **({"nav_files": nav_files} if nav_files else {}))
        node.trigger_configure()
        node.trigger_activate()
        assert _state(node) == "active", node.last_error
        _feed(ros, bare, node, len(bare["rover"]))
        ros.spin_until(lambda fixes=fixes: len(fixes) >= len(bare["rover"]), 5.0)
        counts.append(sum(f.status.status == STATUS_GBAS_FIX for f in fixes))
        node.trigger_deactivate()
        node.trigger_cleanup()
        ros.helper.destroy_subscription(sub)
    print(f"\nRTCM3 without ephemerides: {counts[0]} RTK fixes alone, {counts[1]} with nav_files")
    assert counts[0] == 0 and counts[1] >= 0.9 * len(bare["rover"])
