"""In-process hand-over of a topic between nodes of one process, ROS context and executor.

rclcpp hands a message from a publisher to a subscription of its own process without the middleware
(intra-process communication); rclpy has no such transport, so a message between two nodes of one process is
serialised, goes through DDS and comes back as another callback (the fleet layout's Visibility messages: about
0.9 ms each, docs/BENCHMARKS.md "Where the latency goes").  Here a node that *offers* a topic (:class:`Offer`,
made with its publisher) hands what it publishes, as a subscriber would decode it, to every node that *takes*
the topic in the same process, context and executor (:class:`Taker`), and a taker has no middleware subscription
to the topic while such a publisher is there (no message taken twice; a topic with a publisher in this process
is taken from it alone).  The publisher still publishes on the topic for every other subscriber (recorder,
users).  Nodes in different processes or contexts are never linked: their messages go through the middleware as
before.  Used where the nodes share a process: nodes/ephemeris_node.py offers the satellite states, which the
visibility nodes take; nodes/fleet_visibility_node.py offers each robot's visibility, nodes/fleet_receiver_node.py
and gnss-sim run's driver (commands/run/outputs.py) take them; each receiver (nodes/receiver_session.py) offers its
fix and status, which the driver takes; nodes/trajectory_player.py offers /tf, which nodes/tf_stream.py (the TF tree
and the driver's missing-frame rule) takes beside its middleware subscription (/tf has many publishers: a message
handed is used at once, the middleware's copy of it dropped undecoded).  So in the fleet layout one epoch runs from
the states published to every robot's observations published in one callback, with no middleware hop in between.
``GNSS_SIM_IN_PROCESS=off`` turns the hand-over off (every message through the middleware).

The registry is keyed by (context, executor, resolved topic name); the context by its rcl handle, new at every
rclpy.init (a process that runs the graph twice, e.g. tests, never links a node of the first run); the executor
the node's when the offer or taker is made (nodes spun by different executors are never linked, and a
MultiThreadedExecutor, which may run a taker's callbacks beside the hand-over, links nothing).  Lifecycle: an offer
from configure to cleanup, a taker from activate to deactivate (the driver's: the run).
"""
from __future__ import annotations

import os
import threading
from collections.abc import Callable

#: environment variable: "off" sends every message through the middleware (default "on")
IN_PROCESS_ENV = "GNSS_SIM_IN_PROCESS"

_LOCK = threading.Lock()
_LINKS: dict = {}          # (context, executor, topic) -> _Link


class _Link:
    __slots__ = ("offers", "takers")

    def __init__(self):
        self.offers = 0
        self.takers: list[Taker] = []


def enabled() -> bool:
    """Whether in-process hand-overs are on (environment variable GNSS_SIM_IN_PROCESS: on, the default, or off)."""
    value = os.environ.get(IN_PROCESS_ENV, "on")
    if value not in ("on", "off"):
        raise ValueError(f"environment variable {IN_PROCESS_ENV} is {value!r}: one of on, off")
    return value == "on"


def _changed(link: _Link, key) -> tuple[list, bool]:
    """(the takers of ``link``, linked: an offer is there); an empty link leaves the registry."""
    if not link.offers and not link.takers:
        _LINKS.pop(key, None)
    return list(link.takers), link.offers > 0


def _follow(takers, linked: bool):
    for taker in takers:
        taker.set_linked(linked)


def _concurrent(executor) -> bool:
    """Whether ``executor`` may run two callbacks at once (rclpy's MultiThreadedExecutor): a hand-over would then
    run the taker's code beside its own callbacks, so its messages go through the middleware instead."""
    from rclpy.executors import MultiThreadedExecutor

    return isinstance(executor, MultiThreadedExecutor)


class Offer:
    """``node``'s publisher ``publisher`` handing its messages to the takers of the same process (:meth:`takers`)."""

    def __init__(self, node, publisher):
        self.node = node
        self.key = (node.context.handle, node.executor, publisher.topic_name)
        self._link = None
        if not enabled() or _concurrent(node.executor):
            return
        with _LOCK:
            link = self._link = _LINKS.setdefault(self.key, _Link())
            link.offers += 1
            takers, linked = _changed(link, self.key)
        _follow(takers, linked)

    def takers(self) -> list[Callable]:
        """The ``deliver`` of each taker of the topic in this process, context and executor (none: publish only)."""
        link = self._link
        if link is None:
            return []
        return [t.deliver for t in link.takers]

    def withdraw(self):
        """No more hand-overs (idempotent); takers left without an offer subscribe through the middleware."""
        link, self._link = self._link, None
        if link is None:
            return
        with _LOCK:
            link.offers -= 1
            takers, linked = _changed(link, self.key)
        _follow(takers, linked)


def subscription_switch(make: Callable[[], object], drop: Callable[[object], None]) -> Callable[[bool], None]:
    """A taker's ``over_middleware``: the subscription ``make()`` returns while on, ``drop(subscription)`` when off."""
    held: list = []

    def switch(on: bool):
        if on and not held:
            held.append(make())
        elif not on and held:
            drop(held.pop())
    return switch


class Taker:
    """``node`` taking ``topic`` in-process: ``deliver(payload)`` gets what an :class:`Offer` hands;
    ``over_middleware(on)`` makes (True) or drops (False) the node's middleware subscription to the topic: on
    while no publisher of this process offers the topic."""

    def __init__(self, node, topic: str, deliver: Callable, over_middleware: Callable[[bool], None]):
        self.node = node
        self.key = (node.context.handle, node.executor, node.resolve_topic_name(topic))
        self.deliver = deliver
        self._over_middleware = over_middleware
        self._registered = False
        linked = False
        if enabled() and not _concurrent(node.executor):
            with _LOCK:
                link = _LINKS.setdefault(self.key, _Link())
                link.takers.append(self)
                self._registered = True
                _, linked = _changed(link, self.key)
        self.linked = not linked      # set_linked acts on a change
        self.set_linked(linked)

    def set_linked(self, linked: bool):
        if linked != self.linked:
            self.linked = linked
            self._over_middleware(not linked)

    def close(self):
        """Out of the registry (idempotent); the middleware subscription is the node's to drop."""
        if not self._registered:
            return
        self._registered = False
        with _LOCK:
            link = _LINKS.get(self.key)
            if link is not None and self in link.takers:
                link.takers.remove(self)
                _changed(link, self.key)
