"""Record topics into a rosbag2 bag (MCAP) where ``ros2 bag`` does not exist.

rclpy subscriptions with ``raw=True`` hand over the CDR bytes as they travel;
the rosbags library writes them unchanged into a rosbag2 folder
(``metadata.yaml`` + ``.mcap``), the layout ``ros2 bag play/info`` read on a
ROS 2 install.  Message definitions of the standard types come from rosbags'
Kilted type store; gnss_sim_msgs and tf2_msgs are registered from their .msg
files.  On a ROS install, ``ros2 bag record`` does the same job; gnss-sim run
uses this recorder in both worlds so that a run records the same way.
"""
from __future__ import annotations

import time
from pathlib import Path

from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from gnss_sim_ros2.graph import RECORDED


def _msg_dir() -> Path:
    """Folder of gnss_sim_msgs' .msg files (source tree or installed share)."""
    here = Path(__file__).resolve().parents[1] / "msg_pkg" / "msg"
    if here.is_dir():
        return here
    from ament_index_python.packages import get_package_share_directory

    return Path(get_package_share_directory("gnss_sim_msgs")) / "msg"


def typestore():
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_KILTED)
    add = {}
    for f in sorted(_msg_dir().glob("*.msg")):
        add.update(get_types_from_msg(f.read_text(), f"gnss_sim_msgs/msg/{f.stem}"))
    store.register(add)
    return store


class BagRecorder:
    """Subscribe to ``topics`` on ``node`` and write every message into ``bag_dir``."""

    def __init__(self, node, bag_dir: Path, topics=RECORDED):
        from rosbags.rosbag2 import StoragePlugin, Writer

        self.node = node
        self.store = typestore()
        self.bag_dir = Path(bag_dir)
        if self.bag_dir.exists():
            raise ValueError(f"bag folder {self.bag_dir} exists already (rosbag2 does not overwrite)")
        self.writer = Writer(self.bag_dir, version=8, storage_plugin=StoragePlugin.MCAP)
        self.writer.open()
        self.counts: dict[str, int] = {}
        self.connections = {}
        self.subs = []
        self.closed = False
        for topic, ros_type in topics:  # before any node publishes: the first epoch is recorded too
            self._subscribe(topic, ros_type)

    def _subscribe(self, topic: str, ros_type: str):
        import importlib

        pkg, _, name = ros_type.split("/")
        cls = getattr(importlib.import_module(f"{pkg}.msg"), name)
        static = topic == "/tf_static"
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL if static else DurabilityPolicy.VOLATILE)
        conn = self.writer.add_connection(topic, ros_type, typestore=self.store)
        self.connections[topic] = conn
        self.counts[topic] = 0

        def cb(data, topic=topic, conn=conn):
            if self.closed:
                return
            self.writer.write(conn, self.node.get_clock().now().nanoseconds or time.time_ns(), data)
            self.counts[topic] += 1

        self.subs.append(self.node.create_subscription(cls, topic, cb, qos, raw=True))

    def close(self):
        if self.closed:
            return
        self.closed = True
        for s in self.subs:
            self.node.destroy_subscription(s)
        self.writer.close()


def count_messages(bag_dir) -> dict[str, int]:
    """Messages per topic of a bag, read back with rosbags (an independent reader of what was written)."""
    from rosbags.highlevel import AnyReader

    out: dict[str, int] = {}
    with AnyReader([Path(bag_dir)], default_typestore=typestore()) as reader:
        for conn, _, _ in reader.messages():
            out[conn.topic] = out.get(conn.topic, 0) + 1
    return out
