"""BagRecorder's splits: a due split closes after every robot's last message of an epoch, not before.

The recorder runs on a stand-in node (the subscriptions' callbacks called by the test, a fixed clock) and
writes a real bag with rosbags; the monotonic clock the split age is read from is advanced by the test.
"""
from __future__ import annotations

import pytest

pytest.importorskip("rclpy", reason="rclpy is not installed (run make test, or source ROS 2)")
pytest.importorskip("gnss_sim_msgs", reason="gnss_sim_msgs is not built (run make test)")

from gnss_sim_ros2 import graph, recorder  # noqa: E402


class _Clock:
    class _Now:
        nanoseconds = 1_000_000_000

    def now(self):
        return self._Now()


class _Node:
    """What BagRecorder asks of its node: subscriptions (callbacks kept by topic), a timer, a clock."""

    def __init__(self):
        self.callbacks = {}

    def create_subscription(self, cls, topic, cb, qos, raw=False):
        self.callbacks[topic] = cb
        return topic

    def create_timer(self, period, cb, clock=None):
        return cb

    def get_clock(self):
        return _Clock()

    def destroy_timer(self, timer):
        pass

    def destroy_subscription(self, sub):
        pass


#: bytes of a message: the recorder writes what came without reading it
_MSG = b"\x00\x01\x00\x00" + bytes(12)
STATES = f"{graph.TOPIC_NAMESPACE}/satellite_states"


def _recorder(tmp_path, monkeypatch, topics):
    """(BagRecorder of ``topics`` on a stand-in node, its callbacks by topic, the monotonic clock {"s": ...})."""
    now = {"s": 100.0}
    monkeypatch.setattr(recorder.time, "monotonic", lambda: now["s"])
    node = _Node()
    rec = recorder.BagRecorder(node, tmp_path / "bag", topics, split_s=5.0)
    return rec, node.callbacks, now


def _nmea(k, robots):
    return graph.robot_topic(k, recorder.EPOCH_LAST_TOPIC) if robots > 1 else recorder.EPOCH_LAST_TOPIC


@pytest.mark.parametrize("robots", [1, 3])
def test_a_due_split_waits_for_every_robots_last_message(tmp_path, monkeypatch, robots):
    rec, cb, now = _recorder(tmp_path, monkeypatch, graph.recorded(robots))
    nmea = [_nmea(k, robots) for k in range(robots)]
    assert rec.rotate_after == frozenset(nmea)
    cb[STATES](_MSG)
    now["s"] += 6.0                                   # the split is due from here
    cb[STATES](_MSG)
    assert rec._splits == []                          # not after the states: the robots' epochs are running
    for topic in nmea[:-1]:
        cb[topic](_MSG)
        assert rec._splits == []                      # not before the last robot's
    cb[nmea[-1]](_MSG)
    assert len(rec._splits) == 1 and (tmp_path / "bag" / "bag_0.mcap").is_file()
    # the next split starts afresh: its own age, its own robots' messages
    cb[nmea[0]](_MSG)
    now["s"] += 6.0
    assert len(rec._splits) == 1
    rec.close()
    assert len(rec._splits) == 2


def test_without_the_epochs_last_topic_a_due_split_closes_after_any_message(tmp_path, monkeypatch):
    topics = tuple(t for t in graph.recorded(1) if not t[0].endswith(recorder.EPOCH_LAST_TOPIC))
    rec, cb, now = _recorder(tmp_path, monkeypatch, topics)
    assert rec.rotate_after == frozenset()
    cb[STATES](_MSG)
    now["s"] += 6.0
    cb[STATES](_MSG)
    assert len(rec._splits) == 1
    rec.close()
