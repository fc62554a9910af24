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

#: the rotation of no turn (composed with a lookup's rotation as the general case composes it)
_IDENTITY = Rotation.identity()


class TransformError(LookupError):
    """A transform cannot be computed (unknown frame, no common tree, time out of the buffer)."""


@dataclass
class _Edge:
    parent: str
    static: bool
    times: list = field(default_factory=list)  # float seconds, sorted
    trans: list = field(default_factory=list)  # np (3,)
    quats: list = field(default_factory=list)  # np (4,) xyzw
    #: Rotation of a static edge's quaternion, made once (a lookup through the edge at every epoch)
    static_rot: Rotation | None = None

    def at(self, t_s: float | None, tolerance_s: float) -> tuple[np.ndarray, Rotation]:
        if self.static:
            if self.static_rot is None:
                self.static_rot = Rotation.from_quat(self.quats[-1])
            return self.trans[-1], self.static_rot
        if t_s is None:
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
            edge.static_rot = None
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
        return self._lookup(target, source, t_s, True)

    def position(self, target: str, source: str, t_s: float | None = None) -> np.ndarray:
        """``lookup(...)[0]``, the same bits, without composing the rotation when ``target`` is an ancestor of
        ``source`` (an antenna in the world: three scipy Rotation products less)."""
        return self._lookup(target, source, t_s, False)[0]

    def _lookup(self, target: str, source: str, t_s: float | None, rotation: bool):
        target, source = target.lstrip("/"), source.lstrip("/")
        known = self.frames()
        for f in (target, source):
            if f not in known:
                raise TransformError(f"frame '{f}' does not exist (known: {sorted(known)})")
        up_s = self._path_to_root(source)
        up_t = self._path_to_root(target)
        common = next((f for f in up_s if f in set(up_t)), None)
        if common is None:
            raise TransformError(f"frames '{source}' and '{target}' are not connected")
        # source -> common
        rotation = rotation or common != target       # the way back needs the source's rotation
        tr_s, rot_s = np.zeros(3), Rotation.identity()
        for f in up_s[: up_s.index(common)]:
            tr, rot = self._edges[f].at(t_s, self.tolerance_s)
            tr_s, rot_s = rot.apply(tr_s) + tr, rot * rot_s if rotation else None
        if common == target:      # the target is the source's ancestor (world -> a robot's antenna): no way back
            # what the product with the way back's inverse (identity) gives
            return tr_s, _IDENTITY * rot_s if rotation else None
        tr_t, rot_t = np.zeros(3), Rotation.identity()
        for f in up_t[: up_t.index(common)]:
            tr, rot = self._edges[f].at(t_s, self.tolerance_s)
            tr_t, rot_t = rot.apply(tr_t) + tr, rot * rot_t
        inv_t = rot_t.inv()
        return inv_t.apply(tr_s - tr_t), inv_t * rot_s


def frame_group(frame: str) -> str:
    """The namespace part of a frame id (``robot1/gnss_antenna`` -> ``robot1/``; ``gnss_antenna`` -> ``""``):
    the frames one source of TF publishes (one robot's)."""
    return frame[:frame.rfind("/") + 1]


def _stamp_of_step(step: tuple[float, float]) -> float:
    return step[0]


class FrameWait:
    """The missing-frame rule of an epoch that waits for its antenna's transform (issue 25: a loaded machine
    is the normal case, so wall time alone proves nothing). It keys on the data:

    - the source of TF has reached the epoch (a ``/tf`` transform of the antenna's frame group stamped at or
      after it came) and the transform still cannot be computed: the frame is missing once that has lasted
      ``timeout_s`` of wall time (late ``/tf_static`` and other publishers' frames get that grace);
    - TF has not reached the epoch: while a ``/tf`` publisher is alive the epoch waits (the source is behind,
      e.g. starved of CPU, not missing a frame); with no ``/tf`` publisher at all the frame is missing
      ``timeout_s`` of wall time after the epoch began to wait (nothing publishes the robot's TF).

    ROS-free: the owner feeds it each ``/tf`` message's (child frame, stamp [s]) through :meth:`seen` and asks
    :meth:`missing` with the wall times of ``time.monotonic()``.
    """

    def __init__(self, timeout_s: float, history: int = 4096):
        self.timeout_s = float(timeout_s)
        self.history = history
        #: per frame group: [(stamp_s, wall_s)], the wall time at which TF first reached each newer stamp
        self.reached: dict[str, list[tuple[float, float]]] = {}

    def seen(self, child_frame: str, stamp_s: float, wall_s: float) -> None:
        steps = self.reached.setdefault(frame_group(child_frame), [])
        if not steps or stamp_s > steps[-1][0]:
            steps.append((stamp_s, wall_s))
            if len(steps) > self.history:
                del steps[:len(steps) - self.history]

    def seen_transforms(self, transforms, wall_s: float) -> None:
        """:meth:`seen` of each geometry_msgs/TransformStamped of a ``/tf`` message."""
        for tf in transforms:
            self.seen(tf.child_frame_id, tf.header.stamp.sec + tf.header.stamp.nanosec * 1e-9, wall_s)

    def reached_at(self, frame: str, t_s: float) -> float | None:
        """Wall time at which TF of ``frame``'s group first reached ``t_s`` (1 ns tolerance); None: not yet."""
        steps = self.reached.get(frame_group(frame), [])
        i = bisect.bisect_left(steps, t_s - 1e-9, key=_stamp_of_step)   # O(log n): asked per robot per pass
        return steps[i][1] if i < len(steps) else None

    def missing(self, frame: str, t_s: float, waiting_since_s: float, now_s: float, tf_publishers: int) -> bool:
        """Whether the epoch at ``t_s`` (waiting since ``waiting_since_s``) misses the transform of ``frame``."""
        reached = self.reached_at(frame, t_s)
        if reached is not None:
            return now_s - max(reached, waiting_since_s) > self.timeout_s
        if tf_publishers > 0:
            return False
        return now_s - waiting_since_s > self.timeout_s
