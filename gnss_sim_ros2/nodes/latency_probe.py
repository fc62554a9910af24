"""Publish-to-publish latency between two topics, from the middleware's own publication timestamps.

A small node of its own (no publishers, no parameter services), spun by a wait loop of its own in a background
thread, subscribes raw to both topics with the message info: ``source_timestamp`` is the
system time [ns] at which the publisher handed the message to DDS (Fast DDS stamps each sample in its
write call), so ``last - first`` of one header stamp is the time from the first message published to the
second one published, whatever the executors of the nodes in between do and however late this probe's
own callbacks run. (rclpy's EventsExecutor does not hand the message info to callbacks: hence this
probe's own loop.) Both stamps come from one machine's clock.  The loop is rcl's wait set over the probe's
subscriptions, made once, each ready one emptied at every wake-up: rclpy's SingleThreadedExecutor rebuilds its
wait set in Python for every message, which with a fleet's 2 x 32 topics took a third of a core (32 robots at 10
Hz) and the GIL from the graph it measures.
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

        self.node = rclpy.create_node(name, context=context, start_parameter_services=False, enable_rosout=False)
        self.first_ns: dict[tuple[int, int], int] = {}     # header stamp -> source timestamp [ns]
        self.last_ns: dict[str, dict[tuple[int, int], int]] = {topic: {} for topic, _ in lasts}

        def on_first(data, info):
            self.first_ns[stamp_of(data)] = info["source_timestamp"]

        def on_last(got: dict):
            def callback(data, info):
                got[stamp_of(data)] = info["source_timestamp"]
            return callback

        self._subs = [(self.node.create_subscription(first[1], first[0], lambda *_: None, 1000, raw=True), on_first)]
        for topic, msg_type in lasts:
            self._subs.append((self.node.create_subscription(msg_type, topic, lambda *_: None, 1000, raw=True),
                               on_last(self.last_ns[topic])))
        self.context = context
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, name=name, daemon=True)
        self._thread.start()

    def _spin(self, timeout_ns: int = 50_000_000):
        from rclpy.exceptions import InvalidHandle
        from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

        try:
            with self.context.handle:
                wait_set = _rclpy.WaitSet(len(self._subs), 0, 0, 0, 0, 0, self.context.handle)
            while not self._stop.is_set() and self.context.ok():
                with self.context.handle:        # the context lives while the loop waits on it
                    wait_set.clear_entities()
                    for sub, _ in self._subs:
                        wait_set.add_subscription(sub.handle)
                    wait_set.wait(timeout_ns)
                ready = wait_set.get_ready_entities("subscription")
                for sub, callback in self._subs:
                    if sub.handle.pointer in ready:
                        while (got := sub.handle.take_message(sub.msg_type, True)) is not None:
                            callback(*got)       # (serialised message, message info)
        except (InvalidHandle, _rclpy.RCLError):  # the context shut down under the loop: the run is over
            pass

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
        self.node.destroy_node()
