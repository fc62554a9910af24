"""Publish-to-publish latency between two topics, from the middleware's own publication timestamps.

A small node of its own (no publishers, no parameter services), spun by a SingleThreadedExecutor in a
background thread, subscribes raw to both topics with the message info: ``source_timestamp`` is the
system time [ns] at which the publisher handed the message to DDS (Fast DDS stamps each sample in its
write call), so ``last - first`` of one header stamp is the time from the first message published to the
second one published, whatever the executors of the nodes in between do and however late this probe's
own callbacks run. (rclpy's EventsExecutor does not hand the message info to callbacks: hence this
probe's own executor.) Both stamps come from one machine's clock.
"""
from __future__ import annotations

import threading

from gnss_sim_ros2.messages.conversions import stamp_of


class LatencyProbe:
    def __init__(self, context, first: tuple[str, type], lasts: list[tuple[str, type]],
                 name: str = "gnss_sim_latency_probe"):
        """``first``: (topic, type) the latency starts at; ``lasts``: [(topic, type)] it ends at (one figure
        each: every robot's observations)."""
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        self.node = rclpy.create_node(name, context=context, start_parameter_services=False, enable_rosout=False)
        self.first_ns: dict[tuple[int, int], int] = {}     # header stamp -> source timestamp [ns]
        self.last_ns: dict[str, dict[tuple[int, int], int]] = {topic: {} for topic, _ in lasts}

        def on_first(data, info):
            self.first_ns[stamp_of(data)] = info["source_timestamp"]

        def on_last(got: dict):
            def callback(data, info):
                got[stamp_of(data)] = info["source_timestamp"]
            return callback

        self.node.create_subscription(first[1], first[0], on_first, 1000, raw=True)
        for topic, msg_type in lasts:
            self.node.create_subscription(msg_type, topic, on_last(self.last_ns[topic]), 1000, raw=True)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, name=name, daemon=True)
        self._thread.start()

    def _spin(self):
        while not self._stop.is_set() and self.executor.context.ok():
            self.executor.spin_once(timeout_sec=0.05)

    def latencies_ms(self, topic: str) -> list[float]:
        """One latency per stamp the first topic and ``topic`` both carried [ms]."""
        first = dict(self.first_ns)
        return [1e-6 * (ns - first[k]) for k, ns in list(self.last_ns[topic].items()) if k in first]

    def close(self):
        if self._thread is None:
            return
        self._stop.set()
        self._thread.join(timeout=2.0)
        self._thread = None
        self.executor.remove_node(self.node)
        self.node.destroy_node()
        self.executor.shutdown()
