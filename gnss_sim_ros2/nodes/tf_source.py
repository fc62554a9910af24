"""Antenna pose from TF: tf2_ros on a ROS install, the compact tree here.

Both take the same standard topics (``/tf``, ``/tf_static``, tf2_msgs/TFMessage)
and answer ``lookup(target, source, stamp)`` -> (translation (3,), scipy Rotation)
at the stamp (interpolated), or raise ``TransformError``.
"""
from __future__ import annotations

import time

import numpy as np
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from scipy.spatial.transform import Rotation

from gnss_sim_ros2.nodes.tf_stream import TfStream
from gnss_sim_ros2.tf_tree import FrameWait, TransformError, TransformTree

try:  # a ROS 2 install
    import tf2_ros  # type: ignore

    HAVE_TF2_ROS = True
except ImportError:  # PyPI wheels: tf2_ros does not exist there
    HAVE_TF2_ROS = False


class TfSource:
    def __init__(self, node, cache_time_s: float = 30.0, prefer_tf2_ros: bool = True, on_update=None,
                 timeout_s: float = 5.0):
        self.node = node
        self.on_update = on_update     # called after each /tf message (compact backend): a waiting lookup retries
        self.backend = "tf2_ros" if (HAVE_TF2_ROS and prefer_tf2_ros) else "compact"
        self._subs = []
        self._stream = None
        #: how far TF has come per frame group: the missing-frame rule (frame_missing)
        self.wait = FrameWait(timeout_s)
        if self.backend == "tf2_ros":
            from rclpy.duration import Duration
            from tf2_msgs.msg import TFMessage

            self.buffer = tf2_ros.Buffer(cache_time=Duration(seconds=cache_time_s))
            self.listener = tf2_ros.TransformListener(self.buffer, node, spin_thread=False)
            self._subs = [node.create_subscription(TFMessage, "/tf", self._progress, 100)]
        else:
            from tf2_msgs.msg import TFMessage

            self.tree = TransformTree(cache_time_s=cache_time_s)
            static_qos = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                                    reliability=ReliabilityPolicy.RELIABLE)
            self._subs = [
                node.create_subscription(TFMessage, "/tf_static", lambda m: self._feed(m, True), static_qos)]
            # /tf: a trajectory player of this process hands its messages at once (nodes/tf_stream.py), the
            # others' come through the middleware
            self._stream = TfStream(node, lambda m: self._feed(m, False))
        #: newest dynamic stamp seen per child frame [s] (compact backend)
        self.latest_s: dict[str, float] = {}

    def _progress(self, msg):
        self.wait.seen_transforms(msg.transforms, time.monotonic())

    def _feed(self, msg, static: bool):
        if not static:
            self._progress(msg)
        for tf in msg.transforms:
            t = tf.header.stamp.sec + tf.header.stamp.nanosec * 1e-9
            tr, q = tf.transform.translation, tf.transform.rotation
            self.tree.set_transform(tf.header.frame_id, tf.child_frame_id, t, (tr.x, tr.y, tr.z),
                                    (q.x, q.y, q.z, q.w), static=static)
            if not static:
                self.latest_s[tf.child_frame_id] = max(t, self.latest_s.get(tf.child_frame_id, -np.inf))
        if self.on_update is not None:
            self.on_update()

    def lookup(self, target: str, source: str, stamp):
        """Pose of ``source`` in ``target`` at ``stamp`` (builtin_interfaces/Time)."""
        if self.backend == "tf2_ros":
            from rclpy.time import Time

            try:
                tf = self.buffer.lookup_transform(target, source, Time.from_msg(stamp))
            except (tf2_ros.LookupException, tf2_ros.ExtrapolationException,
                    tf2_ros.ConnectivityException) as exc:
                raise TransformError(str(exc)) from None
            tr, q = tf.transform.translation, tf.transform.rotation
            return np.array([tr.x, tr.y, tr.z]), Rotation.from_quat([q.x, q.y, q.z, q.w])
        return self.tree.lookup(target, source, stamp.sec + stamp.nanosec * 1e-9)

    def position(self, target: str, source: str, stamp) -> np.ndarray:
        """``lookup(...)[0]`` (the compact tree: the same bits, the rotation not composed)."""
        if self.backend == "tf2_ros":
            return self.lookup(target, source, stamp)[0]
        return self.tree.position(target, source, stamp.sec + stamp.nanosec * 1e-9)

    def frame_missing(self, frame: str, stamp, waiting_since_s: float) -> bool:
        """Whether an epoch at ``stamp`` that waits since ``waiting_since_s`` (time.monotonic()) for the transform
        of ``frame`` misses it: tf_tree.FrameWait's rule, with the /tf publishers alive in the graph."""
        return self.wait.missing(frame, stamp.sec + stamp.nanosec * 1e-9, waiting_since_s, time.monotonic(),
                                 self.node.count_publishers("/tf"))

    def can_transform(self, target: str, source: str, stamp) -> bool:
        try:
            self.lookup(target, source, stamp)
            return True
        except TransformError:
            return False

    def close(self):
        if self._stream is not None:
            self._stream.close()
            self._stream = None
        for s in self._subs:
            self.node.destroy_subscription(s)
        self._subs = []
