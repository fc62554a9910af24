"""A compact transform buffer: what tf2 does for gnss_sim, where tf2_ros is missing.

Holds time-stamped transforms parent -> child (as ``/tf`` and ``/tf_static``
carry them: the child frame's pose in the parent frame), finds the chain
between two frames through their common ancestor, and interpolates each
dynamic edge at the requested time (linear translation, slerp rotation, as
tf2 does).  Static edges hold for every time.  ROS-free: the nodes feed it
from their subscriptions (``gnss_sim_ros2/nodes/tf_source.py``).

Quaternions are (x, y, z, w) as in geometry_msgs.
"""
from __future__ import annotations

import bisect
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation, Slerp


class TransformError(LookupError):
    """A transform cannot be computed (unknown frame, no common tree, time out of the buffer)."""


@dataclass
class _Edge:
    parent: str
    static: bool
    times: list = field(default_factory=list)  # float seconds, sorted
    trans: list = field(default_factory=list)  # np (3,)
    quats: list = field(default_factory=list)  # np (4,) xyzw

    def at(self, t_s: float | None, tolerance_s: float) -> tuple[np.ndarray, Rotation]:
        if self.static or t_s is None:
            return self.trans[-1], Rotation.from_quat(self.quats[-1])
        i = bisect.bisect_left(self.times, t_s)
        if i < len(self.times) and abs(self.times[i] - t_s) <= 1e-9:
            return self.trans[i], Rotation.from_quat(self.quats[i])
        if i == 0 or i == len(self.times):
            nearest = 0 if i == 0 else len(self.times) - 1
            if abs(self.times[nearest] - t_s) <= tolerance_s:
                return self.trans[nearest], Rotation.from_quat(self.quats[nearest])
            raise TransformError(
                f"time {t_s:.6f} s is outside the buffer of frame edge {self.parent}: "
                f"[{self.times[0]:.6f}, {self.times[-1]:.6f}] s"
            )
        t0, t1 = self.times[i - 1], self.times[i]
        a = (t_s - t0) / (t1 - t0)
        trans = (1 - a) * self.trans[i - 1] + a * self.trans[i]
        rot = Slerp([0.0, 1.0], Rotation.from_quat([self.quats[i - 1], self.quats[i]]))([a])[0]
        return trans, rot


class TransformTree:
    """Time-stamped frame tree with lookups like ``tf2::BufferCore::lookupTransform``."""

    def __init__(self, cache_time_s: float = 10.0, tolerance_s: float = 0.0):
        self.cache_time_s = cache_time_s
        #: a lookup slightly beyond the newest (or before the oldest) sample is allowed by this much
        self.tolerance_s = tolerance_s
        self._edges: dict[str, _Edge] = {}  # child -> edge to its parent

    def set_transform(self, parent: str, child: str, t_s: float, translation, quaternion_xyzw, static: bool = False):
        """Add one transform: pose of ``child`` in ``parent`` at time ``t_s`` (seconds)."""
        parent, child = parent.lstrip("/"), child.lstrip("/")
        if parent == child:
            raise ValueError(f"transform from frame '{child}' to itself")
        edge = self._edges.get(child)
        if edge is None or edge.parent != parent or edge.static != static:
            edge = self._edges[child] = _Edge(parent, static)
        q = np.asarray(quaternion_xyzw, dtype=float)
        n = np.linalg.norm(q)
        if not np.isfinite(n) or n < 1e-9:
            raise ValueError(f"transform {parent} -> {child}: invalid quaternion {quaternion_xyzw}")
        tr = np.asarray(translation, dtype=float)
        if static:
            edge.times, edge.trans, edge.quats = [t_s], [tr], [q / n]
            return
        i = bisect.bisect_left(edge.times, t_s)
        if i < len(edge.times) and edge.times[i] == t_s:
            edge.trans[i], edge.quats[i] = tr, q / n
        else:
            edge.times.insert(i, t_s)
            edge.trans.insert(i, tr)
            edge.quats.insert(i, q / n)
        # drop what is older than the cache time
        cut = bisect.bisect_left(edge.times, edge.times[-1] - self.cache_time_s)
        if cut > 0:
            del edge.times[:cut], edge.trans[:cut], edge.quats[:cut]

    def frames(self) -> set[str]:
        return set(self._edges) | {e.parent for e in self._edges.values()}

    def _path_to_root(self, frame: str) -> list[str]:
        path = [frame]
        while path[-1] in self._edges:
            path.append(self._edges[path[-1]].parent)
            if len(path) > 1000:
                raise TransformError(f"loop in the frame tree at '{frame}'")
        return path

    def lookup(self, target: str, source: str, t_s: float | None = None):
        """Pose of ``source`` in ``target`` at ``t_s``: (translation (3,), Rotation).

        A point p in ``source`` maps to ``R.apply(p) + translation`` in ``target``
        (tf2's lookupTransform(target, source, time)).  ``t_s`` None: the latest.
        """
        target, source = target.lstrip("/"), source.lstrip("/")
        for f in (target, source):
            if f not in self.frames():
                raise TransformError(f"frame '{f}' does not exist (known: {sorted(self.frames())})")
        up_s = self._path_to_root(source)
        up_t = self._path_to_root(target)
        common = next((f for f in up_s if f in set(up_t)), None)
        if common is None:
            raise TransformError(f"frames '{source}' and '{target}' are not connected")
        # source -> common
        tr_s, rot_s = np.zeros(3), Rotation.identity()
        for f in up_s[: up_s.index(common)]:
            tr, rot = self._edges[f].at(t_s, self.tolerance_s)
            tr_s, rot_s = rot.apply(tr_s) + tr, rot * rot_s
        tr_t, rot_t = np.zeros(3), Rotation.identity()
        for f in up_t[: up_t.index(common)]:
            tr, rot = self._edges[f].at(t_s, self.tolerance_s)
            tr_t, rot_t = rot.apply(tr_t) + tr, rot * rot_t
        inv_t = rot_t.inv()
        return inv_t.apply(tr_s - tr_t), inv_t * rot_s
