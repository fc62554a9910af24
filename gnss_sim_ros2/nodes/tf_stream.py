"""``/tf`` as one stream of tf2_msgs/TFMessage, each message once: those a trajectory player of this process hands
(nodes/in_process.py: the message with its serialised bytes) at once, every other publisher's through the
middleware.  /tf has many publishers, so the middleware subscription stays while a player hands its messages; the
middleware's copy of a message handed (the same bytes) is dropped before it is decoded.  Used by the compact TF
tree (nodes/tf_source.py) and gnss-sim run's missing-frame rule (commands/run/outputs.py)."""
from __future__ import annotations

import collections
from collections.abc import Callable

from gnss_sim_ros2.nodes.in_process import Taker


class TfStream:
    """``on_message(msg)`` for every /tf message ``node`` receives, once."""

    def __init__(self, node, on_message: Callable, depth: int = 100):
        from tf2_msgs.msg import TFMessage

        self.on_message = on_message
        self._type = TFMessage
        #: the serialised bytes of the messages handed whose middleware copy has not come yet
        self._handed: collections.deque = collections.deque(maxlen=256)
        self.node = node
        self._sub = node.create_subscription(TFMessage, "/tf", self.from_middleware, depth, raw=True)
        self._taker = Taker(node, "/tf", self.from_process, lambda on: None)

    def from_process(self, handed):
        """A message handed in-process: (TFMessage, its serialised bytes as published)."""
        msg, data = handed
        self._handed.append(data)
        self.on_message(msg)

    def from_middleware(self, data: bytes):
        """A serialised message of the middleware: dropped if it is the copy of one handed, else decoded."""
        if data in self._handed:
            self._handed.remove(data)
            return
        from rclpy.serialization import deserialize_message

        self.on_message(deserialize_message(data, self._type))

    def close(self):
        self._taker.close()
        if self._sub is not None:
            self.node.destroy_subscription(self._sub)
            self._sub = None
