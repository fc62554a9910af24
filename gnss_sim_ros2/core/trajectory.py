"""Antenna/robot paths: from a CSV file, from waypoints, or the demo path.

A path is a list of timed points in one frame, named by the CSV header:
- ``t_s,e_m,n_m,u_m[,yaw_deg]``: world frame (ENU at the world origin of the scene), m;
- ``t_s,lat_deg,lon_deg,h_m``: geodetic (WGS 84);
- ``t_s,x_m,y_m,z_m``: ECEF, m.
Positions are interpolated linearly in time; before the first point the path
holds its start, after the last its end (or it loops).
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .frames import check_receiver_position
from .input_file import read_utf8

FRAMES = {
    ("e_m", "n_m", "u_m"): "world",
    ("lat_deg", "lon_deg", "h_m"): "geodetic",
    ("x_m", "y_m", "z_m"): "ecef",
}


@dataclass
class Trajectory:
    t_s: np.ndarray          # (K,) seconds from the start of the run, increasing
    pos: np.ndarray          # (K, 3) in ``frame``
    frame: str               # "world" | "geodetic" | "ecef"
    yaw_deg: np.ndarray | None = None  # (K,) heading about world up, from east counter-clockwise (REP-103)
    loop: bool = False
    #: where the points come from (a CSV file) and each point's ":line" in it: errors name them
    source: str = field(default="", compare=False)
    source_lines: list | None = field(default=None, compare=False)

    def __post_init__(self):
        self.t_s = np.asarray(self.t_s, dtype=float)
        self.pos = np.asarray(self.pos, dtype=float).reshape(-1, 3)
        if len(self.t_s) == 0 or len(self.t_s) != len(self.pos):
            raise ValueError("a trajectory needs at least one point, with one time per point")
        if np.any(np.diff(self.t_s) <= 0):
            i = int(np.flatnonzero(np.diff(self.t_s) <= 0)[0]) + 1
            raise ValueError(f"trajectory times must increase: point {i + 1} has t={self.t_s[i]} "
                             f"after t={self.t_s[i - 1]}")
        #: yaw given per point (interpolated) or derived from travel (constant along each segment)
        self.yaw_given = self.yaw_deg is not None
        if self.yaw_deg is None:
            self.yaw_deg = _yaw_along(self.pos) if self.frame == "world" else np.zeros(len(self.t_s))

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0])

    def _wrap(self, t_s):
        t = np.asarray(t_s, dtype=float)
        if self.loop and self.duration_s > 0:
            t = self.t_s[0] + np.mod(t - self.t_s[0], self.duration_s)
        return t

    def position(self, t_s):
        """Position(s) at time(s) ``t_s`` (scalar -> (3,), array -> (N, 3))."""
        t = self._wrap(t_s)
        out = np.stack([np.interp(t, self.t_s, self.pos[:, i]) for i in range(3)], axis=-1)
        return out

    def yaw(self, t_s):
        """Heading [deg] at time(s) ``t_s``."""
        t = self._wrap(t_s)
        if not self.yaw_given:
            i = np.clip(np.searchsorted(self.t_s, t, side="right") - 1, 0, len(self.t_s) - 1)
            return self.yaw_deg[i]
        yaw = np.unwrap(np.radians(self.yaw_deg))
        return np.degrees(np.interp(t, self.t_s, yaw))

    @property
    def is_static(self) -> bool:
        return bool(np.all(self.pos == self.pos[0]))

    # ------------------------------------------------------------------ constructors
    @classmethod
    def static(cls, pos, frame: str, where: str = "static antenna position") -> Trajectory:
        """One position held for the whole run; a geodetic or ECEF one must be a receiver the simulator models
        (frames.check_receiver_position: ValueError naming ``where``, e.g. the option)."""
        if frame != "world":
            check_receiver_position(pos, frame, where)
        return cls(np.array([0.0]), np.asarray(pos, dtype=float).reshape(1, 3), frame)

    @classmethod
    def from_waypoints(cls, flat, loop: bool = False, where: str = "parameter 'waypoints'") -> Trajectory:
        """From a flat list t_s,e_m,n_m,u_m,... in the world frame."""
        flat = np.asarray(flat, dtype=float)
        if flat.size == 0 or flat.size % 4:
            raise ValueError(f"{where}: needs groups of 4 numbers t_s,e_m,n_m,u_m; got {flat.size} numbers")
        pts = flat.reshape(-1, 4)
        return cls(pts[:, 0], pts[:, 1:], "world", loop=loop)

    @classmethod
    def from_csv(cls, path, loop: bool = False) -> Trajectory:
        """Read a CSV path (header names the frame; see the module doc). Errors name file and line."""
        path = Path(path)
        try:
            text = read_utf8(path, f"trajectory file {path}")
        except OSError as exc:
            raise ValueError(f"trajectory file {path}: {exc.strerror}") from None
        rows = [r for r in csv.reader(text.splitlines())]
        first = next((i for i, r in enumerate(rows) if "".join(r).strip() and not r[0].lstrip().startswith("#")),
                     None)           # '#' comment lines before the header too, as between the rows
        if first is None:
            raise ValueError(f"{path}: empty trajectory file")
        header = [h.strip() for h in rows[first]]
        frame = None
        for cols, name in FRAMES.items():
            if header[:1] == ["t_s"] and tuple(header[1:4]) == cols:
                frame = name
        if frame is None:
            raise ValueError(f"{path}:{first + 1}: header must be t_s,e_m,n_m,u_m[,yaw_deg] or t_s,lat_deg,lon_deg,h_m "
                             f"or t_s,x_m,y_m,z_m; got {','.join(header)}")
        has_yaw = len(header) > 4 and header[4] == "yaw_deg"
        ts, pos, yaw, lines = [], [], [], []
        for lineno, row in enumerate(rows[first + 1:], start=first + 2):
            if not row or not "".join(row).strip() or row[0].lstrip().startswith("#"):
                continue
            if "".join(row[len(header):]).strip():      # a value no column names was dropped without a word
                raise ValueError(f"{path}:{lineno}: {len(row)} values under a header of {len(header)} columns "
                                 f"({','.join(header)}), got {','.join(row)}")
            try:
                vals = [float(v) for v in row[: 5 if has_yaw else 4]]
                if len(vals) < (5 if has_yaw else 4):
                    raise ValueError
            except ValueError:
                raise ValueError(f"{path}:{lineno}: expected {len(header)} numbers, got {','.join(row)}") from None
            if not all(np.isfinite(vals)):
                raise ValueError(f"{path}:{lineno}: every value must be a finite number, got {','.join(row)}")
            ts.append(vals[0])
            pos.append(vals[1:4])
            lines.append(f":{lineno}")
            if has_yaw:
                yaw.append(vals[4])
        if not ts:
            raise ValueError(f"{path}: no points after the header")
        if frame != "world":        # a world path is placed by its scene (core/simulation.py AntennaPath)
            check_receiver_position(np.array(pos), frame, str(path), labels=lines)
        try:
            out = cls(np.array(ts), np.array(pos), frame, np.array(yaw) if has_yaw else None, loop)
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from None
        out.source, out.source_lines = str(path), lines      # a world path is checked where a scene places it
        return out


def _yaw_along(pos: np.ndarray) -> np.ndarray:
    """Heading of travel [deg, from east counter-clockwise]; held where the robot stops."""
    d = np.diff(pos[:, :2], axis=0)
    yaw = np.degrees(np.arctan2(d[:, 1], d[:, 0])) if len(d) else np.zeros(0)
    moving = np.hypot(d[:, 0], d[:, 1]) > 1e-9 if len(d) else np.zeros(0, bool)
    out = np.zeros(len(pos))
    last = 90.0
    for i in range(len(d)):
        if moving[i]:
            last = yaw[i]
        out[i] = last
    if len(pos) > 1:
        out[-1] = last
    return out


#: The demo path through worlds/courtyard.sdf (world ENU, m; see worlds/README.md):
#: open ground south of the block -> through the gate -> into the courtyard ->
#: under a tree -> under the ledge -> back to the middle of the yard.
#: Waypoints t_s, e_m, n_m, u_m at about 1 m/s.
DEMO_WAYPOINTS = [
    0.0, 0.0, -60.0, 0.0,     # open ground south of the block
    30.0, 0.0, -30.0, 0.0,
    45.0, 0.0, -15.0, 0.0,    # through the gate
    60.0, 0.0, 0.0, 0.0,      # middle of the courtyard
    70.0, -8.5, 5.0, 0.0,     # under tree_1's crown, 1.5 m from its trunk
    100.0, -8.5, 5.0, 0.0,
    127.0, 17.0, -3.0, 0.0,   # under the ledge of building_east
    157.0, 17.0, -3.0, 0.0,
    175.0, 0.0, 0.0, 0.0,     # back to the middle of the yard
]


def demo_trajectory(loop: bool = False) -> Trajectory:
    return Trajectory.from_waypoints(DEMO_WAYPOINTS, loop=loop, where="demo path")


def robot_path(p: dict, where: str = "node gnss_sim_trajectory_player") -> Trajectory:
    """The robot's (base frame's) path from the trajectory player's parameters: ``trajectory_file``, else
    ``waypoints``, else the demo path; ``loop``; ``time_offset_s`` (the path time at run time 0: the robot
    starts that far along it, as a convoy's robots do)."""
    if p["trajectory_file"]:
        path = Trajectory.from_csv(p["trajectory_file"], loop=p["loop"])
    elif p["waypoints"]:
        path = Trajectory.from_waypoints(p["waypoints"], loop=p["loop"], where=f"{where}: parameter 'waypoints'")
    else:
        path = demo_trajectory(loop=p["loop"])
    offset_s = float(p.get("time_offset_s", 0.0))
    if offset_s:
        path.t_s = path.t_s - offset_s
    return path


def antenna_path(base: Trajectory, offset_m) -> Trajectory:
    """The antenna's path: ``offset_m`` (x forward, y left, z up in the base frame, REP-103) turned by the
    heading at each point of a world-frame path and added to it.  Exact for a vertical offset; a horizontal
    one is exact at the points and linear between them (as the TF player's samples are)."""
    off = np.asarray(offset_m, dtype=float).reshape(3)
    if base.frame != "world":
        if np.any(off):
            raise ValueError(f"an antenna offset {off.tolist()} needs a path in the world frame (t_s,e_m,n_m,u_m)")
        return base
    yaw = np.radians(base.yaw_deg)
    d = np.stack([np.cos(yaw) * off[0] - np.sin(yaw) * off[1], np.sin(yaw) * off[0] + np.cos(yaw) * off[1],
                  np.full(len(yaw), off[2])], axis=-1)
    out = Trajectory(base.t_s.copy(), base.pos + d, "world", base.yaw_deg.copy() if base.yaw_given else None,
                     base.loop)
    out.source, out.source_lines = base.source, base.source_lines
    return out
