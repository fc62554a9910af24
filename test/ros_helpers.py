"""Helpers for in-process rclpy tests (a private ROS domain per test process)."""
from __future__ import annotations

import os
import time

import pytest

rclpy = pytest.importorskip("rclpy", reason="rclpy is not installed (run make test, or source ROS 2)")
pytest.importorskip("gnss_sim_msgs", reason="gnss_sim_msgs is not built (run make test)")

from rclpy.executors import SingleThreadedExecutor  # noqa: E402

os.environ.setdefault("ROS_DOMAIN_ID", str(os.getpid() % 100 + 101))


class RosFixture:
    """rclpy context + executor + a helper node publishing /clock."""

    def __init__(self):
        from rclpy.context import Context

        self.context = Context()
        rclpy.init(context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.helper = rclpy.create_node("gnss_sim_test_helper", context=self.context)
        from rosgraph_msgs.msg import Clock

        self.clock_pub = self.helper.create_publisher(Clock, "/clock", 10)
        self.executor.add_node(self.helper)
        self.nodes = [self.helper]

    def add(self, node):
        self.executor.add_node(node)
        self.nodes.append(node)
        return node

    def set_clock(self, sec: int, nanosec: int = 0):
        from builtin_interfaces.msg import Time
        from rosgraph_msgs.msg import Clock

        self.clock_pub.publish(Clock(clock=Time(sec=sec, nanosec=nanosec)))

    def spin_until(self, predicate, timeout_s: float = 10.0) -> bool:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.02)
            if predicate():
                return True
        return predicate()

    def close(self):
        for n in self.nodes:
            self.executor.remove_node(n)
            n.destroy_node()
        self.executor.shutdown()
        rclpy.shutdown(context=self.context)


@pytest.fixture
def ros():
    r = RosFixture()
    yield r
    r.close()
