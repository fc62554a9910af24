"""A small lifecycle manager: configure, then activate, each node; stop at the first failure.

Nodes are given upstream first (TF player, ephemeris, visibility, receiver).
Configure and cleanup go in that order; activate goes downstream first (a
sink listens before its source publishes: no epoch is lost at the start) and
deactivate upstream first (sources stop before their sinks).

Nodes in this process are driven directly; nodes in other processes through
their standard ``<node>/change_state`` and ``<node>/get_state`` services
(lifecycle_msgs), as nav2_lifecycle_manager does.
"""
from __future__ import annotations

import time

from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState

TRANSITIONS = {
    "configure": (Transition.TRANSITION_CONFIGURE, "inactive"),
    "activate": (Transition.TRANSITION_ACTIVATE, "active"),
    "deactivate": (Transition.TRANSITION_DEACTIVATE, "inactive"),
    "cleanup": (Transition.TRANSITION_CLEANUP, "unconfigured"),
}


#: wall seconds a node in another process has to answer its first get_state (each try, and in all) once its
#: services are discovered: its service is discovered before its answers reach this process, and a
#: change_state whose answer is lost would wait for it for the transition's whole timeout
FIRST_ANSWER_S = (2.0, 30.0)


class TransitionFailed(RuntimeError):
    pass


class LocalNodes:
    """Nodes living in this process (composition)."""

    def __init__(self, nodes):
        self.nodes = list(nodes)

    def transition(self, name: str, spin=None):
        order = list(reversed(self.nodes)) if name == "activate" else self.nodes
        for node in order:
            getattr(node, f"trigger_{name}")()
            state = node._state_machine.current_state[1]
            if state != TRANSITIONS[name][1]:
                why = getattr(node, "last_error", "") or "(see the node's log)"
                raise TransitionFailed(f"{node.get_name()}: {name} failed: {why}")


class RemoteNodes:
    """Nodes in other processes, driven through their lifecycle services."""

    def __init__(self, client_node, names, executor, should_stop=None):
        self.node = client_node
        self.names = list(names)
        self.executor = executor
        self.should_stop = should_stop or (lambda: False)  # e.g. a signal: every wait ends early
        self.change = {n: client_node.create_client(ChangeState, f"/{n}/change_state") for n in self.names}
        self.get = {n: client_node.create_client(GetState, f"/{n}/get_state") for n in self.names}

    def _call(self, client, request, timeout_s: float):
        future = client.call_async(request)
        deadline = time.monotonic() + timeout_s
        while not future.done() and time.monotonic() < deadline and not self.should_stop():
            self.executor.spin_once(timeout_sec=0.05)
        return future.result() if future.done() else None

    def wait_for_services(self, timeout_s: float = 30.0):
        deadline = time.monotonic() + timeout_s
        for n in self.names:
            while not self.change[n].service_is_ready():
                if self.should_stop():
                    return
                if time.monotonic() > deadline:
                    raise TransitionFailed(f"{n}: its lifecycle services did not appear within {timeout_s:.0f} s "
                                           f"(did the process start? see its log)")
                self.executor.spin_once(timeout_sec=0.1)
        for n in self.names:
            end = time.monotonic() + FIRST_ANSWER_S[1]
            while self._call(self.get[n], GetState.Request(), FIRST_ANSWER_S[0]) is None:
                if self.should_stop():
                    return
                if time.monotonic() > end:
                    raise TransitionFailed(f"{n}: no answer to get_state within {FIRST_ANSWER_S[1]:g} s")

    def transition(self, name: str, timeout_s: float = 120.0):
        tid, goal = TRANSITIONS[name]
        order = list(reversed(self.names)) if name == "activate" else self.names
        for n in order:
            if self.should_stop():
                return
            req = ChangeState.Request()
            req.transition.id = tid
            res = self._call(self.change[n], req, timeout_s)
            state = self._call(self.get[n], GetState.Request(), 10.0)
            if self.should_stop():
                return
            label = state.current_state.label if state is not None else "?"
            # a change_state answer lost on the way (Fast DDS: "failed to send response (timeout)" while a busy
            # process's client is still being discovered) from a node in the goal state: the transition was made
            if label != goal or (res is not None and not res.success):
                raise TransitionFailed(f"{n}: {name} failed (state {label}; the node's error is in its log above)")


class OrderedNodes:
    """Nodes wherever each is (LocalNodes or RemoteNodes, one part per node, in the graph's order), driven
    like one manager: configure upstream first, activate downstream first."""

    def __init__(self, parts):
        self.parts = list(parts)

    def transition(self, name: str):
        for part in reversed(self.parts) if name == "activate" else self.parts:
            part.transition(name)
