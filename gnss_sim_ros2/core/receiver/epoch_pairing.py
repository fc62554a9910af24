"""Pairing of one receiver's inputs by epoch: the satellite states and the visibility of the same stamp.

The receiver node (nodes/receiver_node.py) and each robot of the fleet receiver node (nodes/fleet_receiver_node.py)
get the two messages on separate subscriptions, in either order; an epoch is stepped once both of its stamp are in,
in stamp order, and never again nor older than the last one stepped (a late or repeated message is dropped).
ROS-free: the owner gives each message's stamp key (any ordered value, e.g. (sec, nanosec)) and its payload.
"""
from __future__ import annotations


class EpochPairing:
    """States and visibility payloads waiting for their partner, by stamp key; ``last_stamp``: the last paired."""

    def __init__(self):
        self.states: dict = {}
        self.vis: dict = {}
        self.last_stamp = None

    def add_states(self, key, payload) -> list[tuple]:
        """The (states, visibility) pairs now complete, oldest first, after the states of ``key`` came."""
        self.states[key] = payload
        return self._pairs()

    def add_visibility(self, key, payload) -> list[tuple]:
        """The (states, visibility) pairs now complete, oldest first, after the visibility of ``key`` came."""
        self.vis[key] = payload
        return self._pairs()

    def clear(self):
        """Forget what waits (a deactivated node); the last stamp paired is kept."""
        self.states.clear()
        self.vis.clear()

    def reset(self):
        """Forget everything (a node cleaned up starts again at any stamp)."""
        self.clear()
        self.last_stamp = None

    def _pairs(self) -> list[tuple]:
        out = []
        for key in sorted(self.states.keys() & self.vis.keys()):
            s, v = self.states.pop(key), self.vis.pop(key)
            if self.last_stamp is not None and key <= self.last_stamp:
                continue
            self.last_stamp = key
            out.append((s, v))
        if self.last_stamp is not None:     # anything not newer than the last epoch paired will never pair
            for d in (self.states, self.vis):
                for key in [k for k in d if k <= self.last_stamp]:
                    del d[key]
        return out
