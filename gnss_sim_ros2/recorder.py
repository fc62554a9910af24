"""Record topics into a rosbag2 bag (MCAP) where ``ros2 bag`` does not exist.

rclpy subscriptions with ``raw=True`` hand over the CDR bytes as they travel;
the rosbags library writes them unchanged into a rosbag2 folder
(``metadata.yaml`` + ``.mcap``), the layout ``ros2 bag play/info`` read on a
ROS 2 install.  Message definitions of the standard types come from rosbags'
Kilted type store; gnss_sim_msgs and tf2_msgs are registered from their .msg
files.  On a ROS install, ``ros2 bag record`` does the same job; gnss-sim run
uses this recorder in both worlds so that a run records the same way.

A bag survives SIGKILL as rosbag2's split files do (``ros2 bag record
--max-bag-duration``): messages go into a split (``bag_<i>.mcap``) that is
closed every ``split_s`` seconds of wall time, and ``metadata.yaml`` is
rewritten (atomically) after each closed split, listing the closed splits.
A killed recorder thus leaves a bag that rosbags (and ``ros2 bag``) read up
to its last closed split; the split being written when the process died
stays in a hidden ``.open_split`` folder, outside the bag.

Closing a split (MCAP summary, metadata.yaml) takes 40-100 ms of the thread
that spins the recorder, which in ``gnss-sim run`` is the nodes' executor: a
due split is closed right after the receivers' last message of an epoch
(``rotate_after``, EPOCH_LAST_TOPIC: once every robot's has come, nothing of
the chain waits then), or by the timer when they have not come for another
``split_s``.
"""
from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

import yaml
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from gnss_sim_ros2.graph import RECORDED, TOPIC_NAMESPACE

#: the receiver's last message of an epoch (receiver_node.process publishes observations, fix, vel, status, nmea)
EPOCH_LAST_TOPIC = f"{TOPIC_NAMESPACE}/nmea"


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
    """Subscribe to ``topics`` on ``node`` and write every message into the rosbag2 folder ``bag_dir``,
    in splits of ``split_s`` seconds (wall time), each listed in metadata.yaml once closed."""

    def __init__(self, node, bag_dir: Path, topics=RECORDED, split_s: float = 5.0,
                 rotate_after: str | None = EPOCH_LAST_TOPIC):
        self.node = node
        self.store = typestore()
        self.bag_dir = Path(bag_dir)
        if self.bag_dir.exists():
            raise ValueError(f"bag folder {self.bag_dir} exists already (rosbag2 does not overwrite)")
        self.bag_dir.mkdir(parents=True)
        self.split_s = float(split_s)
        self.topics = list(topics)
        # a due split closes once every recorded topic named rotate_after, or ending in it (each robot's
        # /robotK/gnss/nmea), has come since it became due; without any such topic, after any message
        self.rotate_after = frozenset(t for t, _ in self.topics if rotate_after and t.endswith(rotate_after))
        self._due_seen: set = set()
        self.counts: dict[str, int] = {}
        self.subs = []
        self.closed = False
        self._splits: list[dict] = []      # metadata of the closed splits
        self._writer = None
        self._conns: dict = {}
        self._split_started = 0.0
        self._open_split()
        for topic, ros_type in self.topics:  # before any node publishes: the first epoch is recorded too
            self._subscribe(topic, ros_type)
        from rclpy.clock import Clock, ClockType

        # a split also closes when no message comes (a slow or stalled run loses at most split_s)
        self._timer = node.create_timer(min(1.0, self.split_s / 2), lambda: self._rotate_if_due(None),
                                        clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _rotate_if_due(self, topic: str | None = None):
        """Close the split when due: after a message of ``rotate_after`` (or of any topic without one); from
        the timer (``topic`` None) only once it is a further ``split_s`` overdue (that topic stopped)."""
        if self.closed or not self._split_messages:
            return
        age = time.monotonic() - self._split_started
        if topic is None:
            due = age >= (2.0 * self.split_s if self.rotate_after else self.split_s)
        elif age < self.split_s:
            return
        elif self.rotate_after:
            if topic in self.rotate_after:
                self._due_seen.add(topic)
            due = self._due_seen == self.rotate_after
        else:
            due = True
        if due:
            self._close_split()
            self._open_split()

    # ------------------------------------------------------------------ splits
    def _open_split(self):
        from rosbags.rosbag2 import StoragePlugin, Writer

        tmp = self.bag_dir / ".open_split"
        if tmp.exists():
            shutil.rmtree(tmp)
        self._writer = Writer(tmp, version=8, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        self._conns = {topic: self._writer.add_connection(topic, ros_type, typestore=self.store)
                       for topic, ros_type in self.topics}
        self._split_messages = 0
        self._split_started = time.monotonic()
        self._due_seen = set()

    def _close_split(self):
        """Close the open split, move its file into the bag and rewrite metadata.yaml."""
        self._writer.close()
        self._writer = None
        tmp = self.bag_dir / ".open_split"
        if self._split_messages:
            name = f"bag_{len(self._splits)}.mcap"
            os.replace(tmp / ".open_split.mcap", self.bag_dir / name)
            info = yaml.safe_load((tmp / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
            info["relative_file_paths"] = [name]
            for f in info["files"]:
                f["path"] = name
            self._splits.append(info)
            self._write_metadata()
        shutil.rmtree(tmp, ignore_errors=True)

    def _write_metadata(self):
        first = self._splits[0]
        topics: dict[str, dict] = {}
        for sp in self._splits:
            for t in sp["topics_with_message_count"]:
                name = t["topic_metadata"]["name"]
                if name in topics:
                    topics[name]["message_count"] += t["message_count"]
                else:
                    topics[name] = {"message_count": t["message_count"], "topic_metadata": t["topic_metadata"]}
        files = [f for sp in self._splits for f in sp["files"]]
        start = min(f["starting_time"]["nanoseconds_since_epoch"] for f in files)
        end = max(f["starting_time"]["nanoseconds_since_epoch"] + f["duration"]["nanoseconds"] for f in files)
        info = dict(first, relative_file_paths=[f["path"] for f in files], files=files,
                    message_count=sum(f["message_count"] for f in files), starting_time={
                        "nanoseconds_since_epoch": start}, duration={"nanoseconds": end - start},
                    topics_with_message_count=list(topics.values()))
        tmp = self.bag_dir / ".metadata.yaml.tmp"
        tmp.write_text(yaml.safe_dump({"rosbag2_bagfile_information": info}, sort_keys=False))
        os.replace(tmp, self.bag_dir / "metadata.yaml")   # a reader sees the old or the new list, never half

    # ------------------------------------------------------------------ recording
    def _subscribe(self, topic: str, ros_type: str):
        import importlib

        pkg, _, name = ros_type.split("/")
        cls = getattr(importlib.import_module(f"{pkg}.msg"), name)
        static = topic == "/tf_static"
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL if static else DurabilityPolicy.VOLATILE)
        self.counts[topic] = 0

        def cb(data, topic=topic):
            if self.closed:
                return
            self._writer.write(self._conns[topic], self.node.get_clock().now().nanoseconds or time.time_ns(), data)
            self._split_messages += 1
            self.counts[topic] += 1
            self._rotate_if_due(topic)

        self.subs.append(self.node.create_subscription(cls, topic, cb, qos, raw=True))

    def close(self):
        if self.closed:
            return
        self.closed = True
        self.node.destroy_timer(self._timer)
        for s in self.subs:
            self.node.destroy_subscription(s)
        self._close_split()
        if not self._splits:        # nothing recorded: still a valid, empty bag
            self._open_split()
            self._writer.close()
            tmp = self.bag_dir / ".open_split"
            os.replace(tmp / "metadata.yaml", self.bag_dir / "metadata.yaml")
            os.replace(tmp / ".open_split.mcap", self.bag_dir / "bag_0.mcap")
            meta = (self.bag_dir / "metadata.yaml").read_text().replace(".open_split.mcap", "bag_0.mcap")
            (self.bag_dir / "metadata.yaml").write_text(meta)
            shutil.rmtree(tmp, ignore_errors=True)


def count_messages(bag_dir) -> dict[str, int]:
    """Messages per topic of a bag, read back with rosbags (an independent reader of what was written)."""
    from rosbags.highlevel import AnyReader

    out: dict[str, int] = {}
    with AnyReader([Path(bag_dir)], default_typestore=typestore()) as reader:
        for conn, _, _ in reader.messages():
            out[conn.topic] = out.get(conn.topic, 0) + 1
    return out
