"""Moving obstacles: boxes (robot bodies, Gazebo's moving models) that block satellites on top of the static scene.

The static scene's Open3D structure is built once (core/scene/raycast.py) and never rebuilt for a moving part:
each epoch's rays are tested against the boxes separately, here, and combined per ray with the static result
(blocked if either blocks).  The test is the slab method (Kay and Kajiya, "Ray tracing complex scenes",
SIGGRAPH 1986; Williams et al., "An efficient and robust ray-box intersection algorithm", JGT 2005) in numpy,
float64, in each box's own frame: the ray origin is taken relative to the box centre before anything else, so
the far-from-origin float32 loss of the Open3D scene (raycast.py) never arises.  Rays are culled first by each
box's bounding sphere, so an epoch costs one dot product per ray and box plus the slab test of the few pairs
left.  ``bench/bench_moving_obstacles.py`` measured (demo world, 40 satellites, 2 cores at load 6.7, median /
best): the obstacles' part of a cast 0.07 / 0.07 ms for 1 box, 0.15 / 0.08 ms for 16, 0.24 / 0.13 ms for 64;
the alternative, a small Open3D scene of only the boxes built and cast every epoch, 0.18 / 0.14, 0.21 / 0.16
and 0.51 / 0.33 ms, and it cannot leave out each antenna's own body in one cast.  One batched cast of 32
robots (each seeing the 31 other bodies) 10 / 1.5 ms against 98 / 55 ms for 32 separate casts.

A box stands on its frame: ``size_m`` = (length along the frame's x, width along y, height along z), its base
centred on the frame's origin (a robot's ``base_link``, a Gazebo model's origin on the ground).  Boxes are given
per antenna row (``MovingBoxes``, (M, B)): offline M is the block's epochs (each epoch its own poses); in a fleet
M is the robots, and ``active`` leaves out each robot's own body (:func:`fleet_bodies`).  Obstacles block only:
they do not reflect (the static scene's facets still do, core/multipath) and a reflected path is not checked
against them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..multipath.scene_paths import world_directions
from ..vocabulary import VisibilityState

#: rays start this far from the antenna (as Scene.visibility's tnear_m): a box touching the antenna does not block
TNEAR_M = 1e-3


def own_body(frame: str, antenna_frame: str) -> bool:
    """Whether obstacle ``frame`` is the body of the robot that carries ``antenna_frame``: both under the same TF
    prefix (``robot2/base_link`` and ``robot2/gnss_antenna``); frames without a prefix are never one's own."""
    prefix = antenna_frame.rpartition("/")[0]
    return bool(prefix) and frame.rpartition("/")[0] == prefix


def yaw_rotations(yaw_deg) -> np.ndarray:
    """(..., 3, 3) world-from-box rotations about world up by ``yaw_deg`` (from +x counter-clockwise, REP-103)."""
    y = np.radians(np.asarray(yaw_deg, dtype=np.float64))
    c, s = np.cos(y), np.sin(y)
    r = np.zeros(y.shape + (3, 3))
    r[..., 0, 0], r[..., 0, 1], r[..., 1, 0], r[..., 1, 1], r[..., 2, 2] = c, -s, s, c, 1.0
    return r


@dataclass(frozen=True)
class MovingBoxes:
    """B boxes as seen from each of M antenna rows (module docstring); arrays (M, B, ...)."""

    center_world_m: np.ndarray       # (M, B, 3) box centre, world frame
    rot_world_from_box: np.ndarray   # (M, B, 3, 3)
    half_size_m: np.ndarray          # (M, B, 3) half length, width, height
    active: np.ndarray               # (M, B) bool: False where antenna row m does not see box b (its own body)

    @classmethod
    def from_bases(cls, base_world_m, rot_world_from_box, size_m, active=None) -> MovingBoxes:
        """Boxes standing on frames at ``base_world_m`` (M, B, 3) with rotations (M, B, 3, 3) and ``size_m``
        (3,) or (B, 3) or (M, B, 3); ``active`` (M, B) bool, default all."""
        base = np.asarray(base_world_m, dtype=np.float64)
        if base.ndim != 3 or base.shape[-1] != 3:
            raise ValueError(f"MovingBoxes: base_world_m must be (M, B, 3), got {base.shape}")
        rot = np.broadcast_to(np.asarray(rot_world_from_box, dtype=np.float64), base.shape + (3,))
        half = np.broadcast_to(0.5 * np.asarray(size_m, dtype=np.float64), base.shape)
        # the box's centre: half its height up the frame's z from the base
        center = base + rot[..., :, 2] * half[..., 2:3]
        act = np.ones(base.shape[:2], bool) if active is None else np.asarray(active, bool).reshape(base.shape[:2])
        return cls(center, rot, half, act)

    @property
    def count(self) -> int:
        return int(self.center_world_m.shape[1])

    def rows(self, index) -> MovingBoxes:
        """The boxes as seen from the antenna rows ``index`` (a slice or indices)."""
        return MovingBoxes(*(getattr(self, f)[index] for f in _FIELDS))

    def repeat_rows(self, m: int) -> MovingBoxes:
        """Boxes of one antenna row seen alike from ``m`` rows (a model every robot of a fleet sees)."""
        if self.active.shape[0] != 1:
            raise ValueError(f"MovingBoxes.repeat_rows: boxes of one antenna row expected, got {self.active.shape[0]}")
        return MovingBoxes(*(np.repeat(getattr(self, f), m, axis=0) for f in _FIELDS))

    def concat(self, other: MovingBoxes) -> MovingBoxes:
        """These boxes and ``other``'s (same antenna rows) together."""
        return MovingBoxes(*(np.concatenate([getattr(self, f), getattr(other, f)], axis=1) for f in _FIELDS))


_FIELDS = ("center_world_m", "rot_world_from_box", "half_size_m", "active")


def fleet_bodies(base_world_m, yaw_deg, size_m) -> MovingBoxes:
    """The bodies of R robots as the obstacles of their R antennas: robot i's antenna sees every body but its own.

    ``base_world_m`` (R, 3), ``yaw_deg`` (R,), ``size_m`` (3,) or (R, 3)."""
    base = np.asarray(base_world_m, dtype=np.float64).reshape(-1, 3)
    r = len(base)
    rot = yaw_rotations(np.broadcast_to(np.asarray(yaw_deg, dtype=np.float64), (r,)))
    return MovingBoxes.from_bases(np.broadcast_to(base, (r, r, 3)), np.broadcast_to(rot, (r, r, 3, 3)),
                                  size_m, ~np.eye(r, dtype=bool))


def boxes_along_paths(paths, t_s, size_m) -> MovingBoxes | None:
    """Boxes of ``size_m`` standing on timed paths (core/trajectory.Trajectory in the world frame: ``position``,
    ``yaw``) at the times ``t_s`` (M,): one antenna row per time; None without paths."""
    if not paths:
        return None
    t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
    base = np.stack([np.asarray(p.position(t)).reshape(len(t), 3) for p in paths], axis=1)          # (M, B, 3)
    yaw = np.stack([np.broadcast_to(np.asarray(p.yaw(t), dtype=np.float64), t.shape) for p in paths], axis=1)
    return MovingBoxes.from_bases(base, yaw_rotations(yaw), size_m)


#: an obstacle path point farther than this outside the world's horizontal bounds is said (a path in another frame
#: or unit?): a box 2 m tall 1 km away rises 0.11 deg above the antenna's horizon, below any elevation mask
FAR_OUTSIDE_WORLD_M = 1000.0


def paths_far_from_world(paths, bounds_xy, option: str = "option --obstacle-path") -> list[str]:
    """One message per obstacle path (core/trajectory.Trajectory, world frame) whose farthest point lies more than
    FAR_OUTSIDE_WORLD_M outside the world's bounds ``bounds_xy`` (xmin, ymin, xmax, ymax; None: no check): such a
    box blocks nothing (the caller warns; a path leaving the world is legal)."""
    if bounds_xy is None:
        return []
    x0, y0, x1, y1 = bounds_xy
    out = []
    for p in paths:
        x, y = p.pos[:, 0], p.pos[:, 1]
        d_m = np.hypot(np.maximum(np.maximum(x0 - x, x - x1), 0.0), np.maximum(np.maximum(y0 - y, y - y1), 0.0))
        i = int(np.argmax(d_m))
        if d_m[i] > FAR_OUTSIDE_WORLD_M:
            at = p.source_lines[i] if p.source_lines else f", point {i + 1}"
            out.append(f"{option} {p.source}{at}: x {x[i]:g}, y {y[i]:g} m lies {d_m[i] / 1000.0:,.1f} km outside "
                       f"the world (x {x0:g}..{x1:g}, y {y0:g}..{y1:g} m): the obstacle there blocks nothing (a "
                       f"path in another frame or unit?)")
    return out


def rays_blocked_by_boxes(origins_world_m, dirs_world, boxes: MovingBoxes, tnear_m: float = TNEAR_M):
    """(M, N) bool: does the ray from antenna m (``origins_world_m`` (M, 3)) along unit ``dirs_world`` (M, N, 3)
    cross an active box of row m beyond ``tnear_m``?  Slab method in each box's frame (module docstring)."""
    o = np.asarray(origins_world_m, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(dirs_world, dtype=np.float64)
    m, n = d.shape[:2]
    out = np.zeros((m, n), bool)
    if boxes.count == 0 or n == 0:
        return out
    rows = np.flatnonzero(boxes.active.any(axis=1))
    if len(rows) == 0:
        return out
    # cull first: a ray that passes farther from a box's centre than its half diagonal, or that points away from
    # it, cannot touch it (one dot product per ray and box); the slab test runs only on the pairs left
    rel = boxes.center_world_m[rows] - o[rows, None, :]                   # (m', B, 3) antenna -> box centre
    radius = np.sqrt(np.einsum("mbi,mbi->mb", boxes.half_size_m[rows], boxes.half_size_m[rows]))
    dist2 = np.einsum("mbi,mbi->mb", rel, rel)
    proj = np.matmul(d[rows], rel.transpose(0, 2, 1))                     # (m', N, B): along the ray to the centre
    near = (dist2[:, None, :] - proj * proj <= (radius * radius)[:, None, :]) & (proj >= -radius[:, None, :])
    near &= boxes.active[rows][:, None, :]
    mm, nn, bb = np.nonzero(near)
    if len(mm) == 0:
        return out
    rot = boxes.rot_world_from_box[rows][mm, bb]                          # (K, 3, 3) of each pair left
    ob = -np.einsum("kji,kj->ki", rot, rel[mm, bb])                       # origin in the box's frame R^T (o - c)
    db = np.einsum("kji,kj->ki", rot, d[rows][mm, nn])                    # direction R^T d
    h = boxes.half_size_m[rows][mm, bb]
    # parallel to a slab: 1e-300 instead of 0, so (+-h - o) / d is -+huge inside the slab (no limit there) and of
    # one sign outside it (never inside): the slab rule without a special case
    db[db == 0.0] = 1e-300
    inv = 1.0 / db
    with np.errstate(over="ignore"):
        t1 = (-h - ob) * inv
        t2 = (h - ob) * inv
    lo, hi = np.minimum(t1, t2), np.maximum(t1, t2)
    t_in = np.maximum(np.maximum(lo[:, 0], lo[:, 1]), lo[:, 2])
    t_out = np.minimum(np.minimum(hi[:, 0], hi[:, 1]), hi[:, 2])
    hit = t_out >= np.maximum(t_in, tnear_m)
    out[rows[mm[hit]], nn[hit]] = True
    return out


def block_by_obstacles(scene, antenna_world_m, sat_ecef_m, v, state, mask_deg: float,
                       boxes: MovingBoxes) -> np.ndarray:
    """``state`` (N,) or (M, N) with the cast satellites (el >= ``mask_deg``) that a box hides made BLOCKED;
    ``v`` (the static VisibilityResult) follows: a newly blocked ray reports no foliage or diffraction loss and a
    blocked fraction 1, as a ray the static scene blocks.  Returns the new state."""
    a = np.asarray(antenna_world_m, dtype=np.float64)
    single = a.ndim == 1
    a2 = a.reshape(-1, 3)
    el = np.atleast_2d(v.el_deg)
    if len(a2) != boxes.active.shape[0]:
        raise ValueError(f"moving obstacles: boxes for {boxes.active.shape[0]} antenna rows, {len(a2)} antennas")
    dirs = world_directions(scene, a2, sat_ecef_m)
    hit = rays_blocked_by_boxes(a2, dirs, boxes) & (el >= mask_deg)
    st = np.atleast_2d(state)
    newly = hit & (st != int(VisibilityState.BLOCKED))
    if not newly.any():
        return state
    st = np.where(newly, int(VisibilityState.BLOCKED), st).astype(np.asarray(state).dtype)
    for name, value in (("state", int(VisibilityState.BLOCKED)), ("attenuation_db", 0.0),
                        ("path_in_foliage_m", 0.0), ("fraction_blocked", 1.0), ("diffraction_db", 0.0)):
        arr = np.array(getattr(v, name), copy=True)
        np.atleast_2d(arr)[newly] = value
        setattr(v, name, arr)
    return st[0] if single else st
