"""Quality-map lifecycle node (Nav2's GNSS-quality layer): a latched OccupancyGrid placed on the world's grid,
refreshed as the clock moves refresh_period_s, and the path_quality service per pose."""
from __future__ import annotations

import math

import numpy as np
from rclpy.parameter import Parameter
from ros_helpers import ros  # noqa: F401  (fixture)

from gnss_sim_ros2.nodes.quality_map_node import QualityMapNode

STEP_M = 4.0


def _node(ros, **params):  # noqa: F811
    base = {"systems": "GREC", "profile": "ublox_f9p", "grid_step_m": STEP_M, "refresh_period_s": 60.0}
    base.update(params)
    overrides = [Parameter("use_sim_time", value=True)] + [Parameter(k, value=v) for k, v in base.items()]
    return ros.add(QualityMapNode(parameter_overrides=overrides, context=ros.context))


def _grid_qos():
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)


def _cell(grid, x, y) -> int:
    i = int((x - grid.info.origin.position.x) // grid.info.resolution)
    j = int((y - grid.info.origin.position.y) // grid.info.resolution)
    return grid.data[j * grid.info.width + i]


def test_grid_and_path_service(ros):  # noqa: F811
    from geometry_msgs.msg import PoseStamped
    from gnss_sim_msgs.srv import PathQuality
    from nav_msgs.msg import OccupancyGrid, Path

    node = _node(ros)
    ros.set_clock(0)
    ros.spin_until(lambda: False, 0.2)
    node.trigger_configure()
    assert node._state_machine.current_state[1] == "inactive", node.last_error
    node.trigger_activate()
    assert node._state_machine.current_state[1] == "active", node.last_error
    grids = []
    ros.helper.create_subscription(OccupancyGrid, "quality_map", grids.append, _grid_qos())   # a late joiner
    assert ros.spin_until(lambda: grids, 10.0), "no latched grid"
    g = grids[-1]
    # placed on the world: the demo courtyard's ground plane spans x, y -100..100 m (worlds/courtyard.sdf)
    assert g.header.frame_id == "world"
    assert g.info.resolution == STEP_M
    assert (g.info.origin.position.x, g.info.origin.position.y) == (-100.0, -100.0)
    assert (g.info.width, g.info.height) == (50, 50) and len(g.data) == 2500
    data = np.array(g.data)
    assert data.min() >= 0 and data.max() <= 100
    # open ground far from the buildings: RTK expected (0) everywhere; the inner yard is worse somewhere
    far = [_cell(g, x, y) for x in (-90.0, -70.0, 70.0, 90.0) for y in (-90.0, 0.0, 90.0)]
    assert far == [0] * len(far)
    yard = [_cell(g, x, y) for x in np.arange(-18.0, 19.0, STEP_M) for y in np.arange(-14.0, 15.0, STEP_M)]
    assert max(yard) > 0
    # refreshed only when the clock has moved refresh_period_s
    n0 = node.published
    ros.set_clock(30)
    ros.spin_until(lambda: False, 0.5)
    assert node.published == n0
    ros.set_clock(61)
    assert ros.spin_until(lambda: node.published == n0 + 1, 10.0)

    # the path service: from the open ground south into the yard at 2 m/s
    client = ros.helper.create_client(PathQuality, "path_quality")
    assert client.wait_for_service(timeout_sec=5.0)
    req = PathQuality.Request()
    req.path = Path()
    for y in (-60.0, -40.0, -10.0, 0.0):
        p = PoseStamped()
        p.pose.position.x, p.pose.position.y = 0.0, y
        req.path.poses.append(p)
    req.start_time.sec = 100
    req.speed_mps = 2.0
    fut = client.call_async(req)
    assert ros.spin_until(fut.done, 20.0)
    res = fut.result()
    assert res.success, res.message
    t = [s.sec + s.nanosec * 1e-9 for s in res.stamps]
    np.testing.assert_allclose(t, [100.0, 110.0, 125.0, 130.0], atol=1e-6)   # distance / speed
    assert len(res.n_los) == len(res.rtk) == len(res.hdop) == 4
    assert res.rtk[0] and res.n_los[0] >= 10                 # open sky
    assert res.n_los[3] < res.n_los[0]                       # the yard hides part of the sky
    assert all(math.isfinite(h) for h in res.h_acc_m[:2])
    # a bad request: an answer naming the problem, not an exception
    req.speed_mps = 0.0
    fut = client.call_async(req)
    assert ros.spin_until(fut.done, 10.0)
    assert not fut.result().success and "speed_mps" in fut.result().message
    node.trigger_deactivate()
    node.trigger_cleanup()
    assert node._state_machine.current_state[1] == "unconfigured"


def test_bad_parameter_fails_configure(ros):  # noqa: F811
    node = _node(ros, world_file="/nonexistent/world.sdf")
    node.trigger_configure()
    assert node._state_machine.current_state[1] == "unconfigured"
    assert "world.sdf" in node.last_error
