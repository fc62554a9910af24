"""The cells of a plan: a regular grid over the world's bounds or a polygon (world x, y), or the points of a path.

A grid keeps its full (ny, nx) shape with ``inside`` marking the cells computed (polygon or bounds), so maps
and GeoJSON cells are plain array views.  Cell centres sit at ``x0 + (i + 0.5) step`` from the lower-left corner
of the box.  The antenna of a cell is ``height_m`` above its ground: the highest opaque surface under the cell
centre (one downward cast of the scene per cell; a roof where the cell lies on a building), or z = 0 where
nothing is under it (a sky mask or a mesh without ground).
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..input_file import read_utf8


@dataclass
class PlanArea:
    """Cells in the world frame [m]: ``x_m``, ``y_m`` (C,) of the computed cells; a grid also has its shape."""

    x_m: np.ndarray
    y_m: np.ndarray
    kind: str                                   # "grid" | "path"
    step_m: float = 0.0
    x0_m: float = 0.0                           # grid: lower-left corner of the box
    y0_m: float = 0.0
    shape: tuple = ()                           # grid: (ny, nx)
    inside: np.ndarray | None = None            # grid: (ny, nx) bool, the computed cells in row-major order

    @property
    def n_cells(self) -> int:
        return len(self.x_m)

    def corners_xy(self) -> np.ndarray:
        """(C, 5, 2) closed ring of each cell (grid: the square of side step; path: a step-sized square)."""
        h = 0.5 * (self.step_m if self.step_m > 0 else 1.0)
        dx = np.array([-h, h, h, -h, -h])
        dy = np.array([-h, -h, h, h, -h])
        return np.stack([self.x_m[:, None] + dx, self.y_m[:, None] + dy], axis=-1)

    def to_grid(self, values, fill=np.nan) -> np.ndarray:
        """Per-cell values (C, ...) as a (ny, nx, ...) grid (``fill`` outside); a grid area only."""
        if self.kind != "grid":
            raise ValueError("to_grid: the area is a path, not a grid")
        v = np.asarray(values)
        out = np.full(self.shape + v.shape[1:], fill, dtype=np.result_type(v.dtype, np.asarray(fill).dtype))
        out[self.inside] = v
        return out


#: the most cell-times one plan computes (cells x time steps): the fields take about 37 B a cell-time in memory
#: (quality.FIELDS: 6 int16, 6 float32, 1 bool) before the NetCDF / Parquet tables; 5e7 (about 1.9 GB) holds the
#: Hong Kong square kilometre at 2 m over 24 h at 10 min (250,000 cells x 145 steps = 3.6e7, docs/PLANNING.md)
MAX_CELL_TIMES = 50_000_000
#: the most time steps of one plan: each is one ephemeris evaluation and a time object before any cell is computed
#: (1.2e7 steps ran out of 4 GB); 1e5 is a month at 30 s, the longest window (MAX_DURATION_S) at 1 min takes 44,641
MAX_TIME_STEPS = 100_000


def check_plan_size(n_cells: int, n_times: int) -> None:
    """ValueError naming the options when ``n_times`` exceeds MAX_TIME_STEPS or ``n_cells`` x ``n_times``
    MAX_CELL_TIMES (a clear refusal
    instead of a MemoryError after minutes)."""
    if n_times > MAX_TIME_STEPS:
        raise ValueError(f"options --hours and --every-min give {n_times:,} time steps; a plan takes at most "
                         f"{MAX_TIME_STEPS:,} (MAX_TIME_STEPS in core/planning/area.py): a shorter --hours or a "
                         f"longer --every-min")
    if n_cells * n_times > MAX_CELL_TIMES:
        raise ValueError(f"{n_cells:,} cells x {n_times:,} time steps = {n_cells * n_times:.3g} cell-times; a plan "
                         f"takes at most {MAX_CELL_TIMES:.0e} (about 37 B of memory each, MAX_CELL_TIMES in "
                         f"core/planning/area.py): a larger --step-m, a smaller --polygon or --path, a shorter --hours "
                         f"or a longer --every-min")


def check_inside_bounds(x_m, y_m, bounds_xy, what) -> None:
    """ValueError naming ``what(i)`` (the option or file and row) for the first point outside the world's bounds
    (xmin, ymin, xmax, ymax); no check without bounds (a sky mask)."""
    if bounds_xy is None:
        return
    bx0, by0, bx1, by1 = bounds_xy
    x, y = np.atleast_1d(np.asarray(x_m, float)), np.atleast_1d(np.asarray(y_m, float))
    out = np.flatnonzero((x < bx0) | (x > bx1) | (y < by0) | (y > by1))
    if out.size:
        i = int(out[0])
        raise ValueError(f"{what(i)}: x {x[i]:g}, y {y[i]:g} m lies outside the world (x {bx0:g}..{bx1:g}, "
                         f"y {by0:g}..{by1:g} m)")


def check_step(step_m: float, option: str = "--step-m") -> float:
    step = float(step_m)
    if not (np.isfinite(step) and step > 0):
        raise ValueError(f"option {option} is {step_m}: a grid step > 0 m is needed")
    return step


def parse_polygon(text: str, option: str = "--polygon") -> np.ndarray:
    """``"x,y;x,y;x,y[;...]"`` (world metres) -> (P, 2); ValueError naming the option."""
    try:
        pts = np.array([[float(v) for v in p.split(",")] for p in text.replace(" ", "").strip(";").split(";")])
    except ValueError:
        pts = np.zeros((0, 0))
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 3 or not np.all(np.isfinite(pts)):
        raise ValueError(f"option {option} {text!r}: expected at least three x,y vertices in world metres, separated "
                         f"by ';', e.g. {option} '0,0;50,0;50,40;0,40'")
    if abs(_area(pts)) <= 0.0:
        raise ValueError(f"option {option} {text!r}: the vertices enclose no area")
    return pts


def _area(p):
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def inside_polygon(x, y, poly) -> np.ndarray:
    """Even-odd rule (W. R. Franklin's pnpoly crossing test), vectorised over points: (K,) bool."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    inside = np.zeros(x.shape, bool)
    px, py = poly[:, 0], poly[:, 1]
    j = len(poly) - 1
    for i in range(len(poly)):
        xi, yi, xj, yj = px[i], py[i], px[j], py[j]
        crosses = (yi > y) != (yj > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            xc = (xj - xi) * (y - yi) / (yj - yi) + xi
        inside ^= crosses & (x < xc)
        j = i
    return inside


def grid_area(step_m: float, bounds_xy=None, polygon=None, step_name: str = "option --step-m") -> PlanArea:
    """A grid over ``polygon`` (P, 2) (clipped to ``bounds_xy`` (xmin, ymin, xmax, ymax) when given) or over the
    bounds.  ValueError naming --polygon when it lies outside the world's bounds, ``step_name`` (the option or
    parameter of the step) when the grid would hold more than MAX_CELL_TIMES cells."""
    step = check_step(step_m)
    if polygon is not None:
        lo, hi = polygon.min(axis=0), polygon.max(axis=0)
        if bounds_xy is not None:
            bx0, by0, bx1, by1 = bounds_xy
            if hi[0] <= bx0 or lo[0] >= bx1 or hi[1] <= by0 or lo[1] >= by1:
                raise ValueError(f"option --polygon: x {lo[0]:g}..{hi[0]:g}, y {lo[1]:g}..{hi[1]:g} m lies outside "
                                 f"the world (x {bx0:g}..{bx1:g}, y {by0:g}..{by1:g} m)")
            lo = np.maximum(lo, [bx0, by0])
            hi = np.minimum(hi, [bx1, by1])
    elif bounds_xy is not None:
        lo, hi = np.array(bounds_xy[:2], float), np.array(bounds_xy[2:], float)
    else:
        raise ValueError("the area needs --polygon or --path (this world source has no bounds)")
    nx = max(1, int(np.ceil((hi[0] - lo[0]) / step - 1e-9)))
    ny = max(1, int(np.ceil((hi[1] - lo[1]) / step - 1e-9)))
    if nx * ny > MAX_CELL_TIMES:                     # before the (ny, nx) meshgrid: 2e5 x 2e5 would be 298 GiB
        raise ValueError(f"{step_name} {step:g}: a grid of {nx:,} x {ny:,} cells over x {lo[0]:g}..{hi[0]:g}, "
                         f"y {lo[1]:g}..{hi[1]:g} m; a plan takes at most {MAX_CELL_TIMES:.0e} cell-times "
                         f"(MAX_CELL_TIMES in core/planning/area.py): a larger step or a smaller area")
    xs = lo[0] + (np.arange(nx) + 0.5) * step
    ys = lo[1] + (np.arange(ny) + 0.5) * step
    gx, gy = np.meshgrid(xs, ys)                      # (ny, nx)
    inside = np.ones(gx.shape, bool) if polygon is None else inside_polygon(gx, gy, polygon)
    if not inside.any():
        raise ValueError(f"option --polygon: no cell centre of the {step:g} m grid falls inside the polygon "
                         f"(a smaller --step-m?)")
    return PlanArea(gx[inside], gy[inside], "grid", step, float(lo[0]), float(lo[1]), gx.shape, inside)


def read_path_csv(path) -> PlanArea:
    """A path CSV with columns x_m,y_m (or x,y), world metres, one row per point; ValueError naming file and line."""
    p = Path(path)
    try:
        rows = list(csv.reader(read_utf8(p, f"option --path {path}").splitlines()))    # binary, UTF-16, BOM
    except OSError as exc:
        raise ValueError(f"option --path {path}: cannot read ({exc.strerror})") from None
    rows = [r for r in rows if r and not r[0].lstrip().startswith("#")]
    if not rows:
        raise ValueError(f"{path}: empty (expected a header x_m,y_m and one row per point)")
    head = [h.strip() for h in rows[0]]
    cols = next(((head.index(a), head.index(b)) for a, b in (("x_m", "y_m"), ("x", "y")) if a in head and b in head),
                None)
    if cols is None:
        raise ValueError(f"{path}:1: header {','.join(head)!r} has no x_m,y_m (or x,y) columns")
    xy = []
    for n, r in enumerate(rows[1:], start=2):
        try:
            xy.append((float(r[cols[0]]), float(r[cols[1]])))
        except (ValueError, IndexError):
            raise ValueError(f"{path}:{n}: expected numbers in columns {head[cols[0]]},{head[cols[1]]}") from None
    if not xy:
        raise ValueError(f"{path}: no point after the header")
    a = np.array(xy)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{path}: a coordinate is not finite")
    return PlanArea(a[:, 0], a[:, 1], "path")


def ground_z_m(scene, x_m, y_m) -> np.ndarray:
    """The highest opaque surface under each (x, y) [m] (one downward cast each); 0 where nothing is under it
    or the scene has no surfaces (a sky mask)."""
    x, y = np.asarray(x_m, float), np.asarray(y_m, float)
    rays = getattr(scene, "rays", None)
    world = getattr(scene, "world", None)
    if rays is None or world is None or len(world.vertices_m) == 0:
        return np.zeros(x.shape)
    top = float(np.nanmax(world.vertices_m[:, 2])) + 10.0
    o = np.stack([x, y, np.full(x.shape, top)], axis=1)
    t = rays.hit_distance(o, np.array([[0.0, 0.0, -1.0]]))
    return np.where(np.isfinite(t), top - t, 0.0)
