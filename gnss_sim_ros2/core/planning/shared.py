"""What a satellite looks like from a tile of cells: per (time, satellite) quantities computed once at the tile's
centre and shared by its cells, with the per-cell masks (the real casts' states) applied on top.

A GNSS satellite (range >= 19,000 km) is seen from every cell of a tile whose cells lie within d metres of its
centre in a direction that differs by less than d / (range - d) rad (the parallax) and at a range that differs by
less than d; a cell's local vertical turns by less than d / 6,300 km (the smallest radius of curvature of the
WGS 84 ellipsoid is 6,335 km, at the equator).  So, per (tile, time, satellite):

- the unit line of sight in ECEF: a cell's DOP moments (solver.dop_moments: count, sums and products of the
  used satellites' lines of sight per clock group) are mask (cells x satellites) @ per-satellite terms, one matrix
  product per time, then turned into the cell's own ENU axes (linear, so the vertical's turn costs nothing): only
  the parallax remains;
- the UERE's variance at the centre's elevation (ranging.py): its sum over a cell's used satellites is one more
  column of the same product; an attenuated satellite adds its thermal-noise difference, a reflected-only one its
  excess path, per entry as before;
- the unobstructed C/N0 at the centre's range and elevation (predicted_cn0.py): a cell's is that less the cast's
  attenuation.  The C/N0 is only compared with thresholds (good, tracking); an entry within ``cn0_margin_db`` of
  one (a bound on the sharing's error: the link budget's largest slopes in elevation and range times the largest
  changes above) is computed per entry exactly as the per-cell planner does, so the counts and the RTK candidates
  are those of the per-cell computation.

The tile's size (``PlanInputs.share_tile_m``) bounds d; docs/PLANNING.md gives the measured differences.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .predicted_cn0 import RANGE_SLOPE_DB
from .sight_lines import AntennaAxes

#: smallest radius of curvature of the WGS 84 ellipsoid [m] (the meridian's at the equator, 6,335,439 m), rounded
#: down: a cell's vertical turns by at most distance / this [rad] from the tile centre's
MIN_CURVATURE_RADIUS_M = 6.3e6
#: the clock groups' count, the sums of the lines of sight per group, the 6 products, the UERE variance
_PAIRS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


@dataclass
class Tiles:
    """The block's cells in square tiles of the world's x, y: each cell's tile, and per tile its cells, its centre
    (ECEF point, ENU axes) and the largest distance of a cell from it [m]."""

    index: np.ndarray           # (C,)
    cells: list                 # per tile: the cells' indices, ascending
    centre: AntennaAxes         # (n,)
    radius_m: np.ndarray        # (n,)

    @classmethod
    def of(cls, scene, antenna_world_m, cell_axes: AntennaAxes, tile_m: float) -> Tiles:
        ant = np.asarray(antenna_world_m, float).reshape(-1, 3)
        key = np.floor((ant[:, :2] - ant[:, :2].min(axis=0)) / float(tile_m)).astype(np.int64)
        _, index = np.unique(key, axis=0, return_inverse=True)
        index = index.reshape(-1)
        order = np.argsort(index, kind="stable")                           # each tile's cells ascending
        cells = np.split(order, np.flatnonzero(np.diff(index[order])) + 1)
        mid = np.array([0.5 * (ant[c].min(axis=0) + ant[c].max(axis=0)) for c in cells])
        centre = AntennaAxes.of(scene, mid)
        radius = np.array([np.max(np.linalg.norm(cell_axes.ecef_m[c] - centre.ecef_m[j], axis=1))
                           for j, c in enumerate(cells)])
        return cls(index, cells, centre, radius)

    def sky(self, sat_ecef_m):
        """(unit lines of sight in ECEF (n, T, S, 3), ranges [m] (n, T, S), sines of the elevations (n, T, S)) of
        satellites ``sat_ecef_m`` (T, S, 3) (finite) from each tile's centre."""
        d = np.asarray(sat_ecef_m, float)[None] - self.centre.ecef_m[:, None, None, :]
        rng = np.sqrt(np.einsum("ntsi,ntsi->nts", d, d))
        u = d / rng[..., None]
        sin_el = np.einsum("ntsi,ni->nts", u, self.centre.enu_rows[:, 2])
        return u, rng, sin_el

    def broadcast(self, x) -> np.ndarray:
        """Per-tile values ``x`` (n, ...) as per-cell values (C, ...) (a view for one tile)."""
        if len(self.cells) == 1:
            return np.broadcast_to(x[0], (len(self.index),) + x.shape[1:])
        return x[self.index]

    def rows(self, x) -> np.ndarray:
        """Per (tile, time, satellite) values ``x`` (n, T, S) as rows cell * T + time (C x T, S)."""
        return self.broadcast(x).reshape(-1, x.shape[-1])

    def elevation_change_deg(self, min_range_m: float) -> np.ndarray:
        """(n,) bound on |a cell's elevation of a satellite - the centre's| [deg]: the vertical's turn plus the
        parallax (module doc)."""
        d = self.radius_m
        return np.degrees(d / MIN_CURVATURE_RADIUS_M + d / max(min_range_m - d.max(), 1.0))

    def cn0_margin_db(self, predictor, systems, min_range_m: float) -> np.ndarray:
        """(n, S) bound on |a cell's open-sky C/N0 - the centre's| [dB] of satellites of ``systems`` (S,) at least
        ``min_range_m`` from the centres: the link budget's elevation slope x :meth:`elevation_change_deg` + its
        range slope (predicted_cn0.RANGE_SLOPE_DB / range) x the tile's radius."""
        slope = np.array([predictor.elevation_slope_db_per_deg(s) for s in np.asarray(systems).tolist()])
        r_min = max(min_range_m - float(self.radius_m.max()), 1.0)
        return (slope[None, :] * self.elevation_change_deg(min_range_m)[:, None]
                + RANGE_SLOPE_DB * self.radius_m[:, None] / r_min)


def moment_terms(u, clock, n_groups: int, extra=None) -> np.ndarray:
    """Per (tile, time, satellite) what a used satellite adds to solver.dop_moments (in ECEF): its group's count,
    its group's sums of the three components, the 6 products (order of solver's pairs), then ``extra`` (n, T, S)
    (a column summed alike, e.g. the UERE variance).  (n, T, S, K)."""
    n, t, s = u.shape[:3]
    g = n_groups
    k = 4 * g + 6 + (0 if extra is None else 1)
    terms = np.zeros((n, t, s, k))
    cols = np.arange(s)
    terms[:, :, cols, clock] = 1.0
    for i in range(3):
        terms[:, :, cols, g + i * g + clock] = u[..., i]
    for p, (i, j) in enumerate(_PAIRS):
        terms[..., 4 * g + p] = u[..., i] * u[..., j]
    if extra is not None:
        terms[..., -1] = extra
    return terms


#: multiply-adds of one matrix product of row_sums: OpenBLAS runs a product of at most 4 x 65,536 on one thread
#: (interface/gemm.c, GEMM_MULTITHREAD_THRESHOLD); larger ones start its threads, which then compete with Open3D's
#: on a busy machine (2,000 Hong Kong cells x 24 h: 0.44 s in the products against 0.04 s on one thread)
ONE_THREAD_PRODUCT = 1 << 17


def row_sums(mask, tiles: Tiles, terms) -> np.ndarray:
    """(C x T, K) sums of ``terms`` (n, T, S, K) over the True entries of ``mask`` (C x T, S) (rows cell * T +
    time): matrix products per tile and time, of at most ONE_THREAD_PRODUCT multiply-adds each."""
    n, t, s, k = terms.shape
    m3 = np.asarray(mask, bool).reshape(-1, t, s)
    out = np.empty((len(m3), t, k))
    per = max(1, ONE_THREAD_PRODUCT // max(1, s * k))                   # cells per product
    for j, cells in enumerate(tiles.cells):
        for i0 in range(0, len(cells), per):
            sel = slice(i0, i0 + per) if n == 1 else cells[i0:i0 + per]
            mf = m3[sel].astype(np.float64)
            out[sel] = np.matmul(mf.transpose(1, 0, 2), terms[j]).transpose(1, 0, 2)   # a product per time
    return out.reshape(-1, k)


def enu_moments(sums, cell_axes: AntennaAxes, n_times: int, n_groups: int):
    """solver.dop_moments' (count (G, M), sums (3, G, M), products (6, M)) in each cell's ENU axes, from
    :func:`row_sums` of :func:`moment_terms` (ECEF; rows cell * n_times + time): s' = R s and P' = R P R^T with R
    the cell's ENU rows (an exact change of axes), as products of 3 x 3 matrices per cell over all its times."""
    g, t = n_groups, n_times
    m = len(sums)
    c = m // t
    rot = cell_axes.enu_rows                                               # (C, 3, 3)
    cnt = sums[:, :g].T
    s1 = sums[:, g:4 * g].reshape(c, t, 3, g).transpose(0, 2, 1, 3).reshape(c, 3, t * g)
    s1_enu = np.matmul(rot, s1).reshape(c, 3, t, g).transpose(1, 3, 0, 2).reshape(3, g, m)
    p = sums[:, 4 * g:4 * g + 6].reshape(c, t, 6)
    full = np.empty((c, 3, t, 3))                                          # P[k, l] of each time, side by side
    for a in range(3):
        for b in range(3):
            full[:, a, :, b] = p[..., _PAIRS.index((min(a, b), max(a, b)))]
    rp = np.matmul(rot, full.reshape(c, 3, 3 * t)).reshape(c, 3, t, 3)    # (R P)[i, l]
    rprt = np.matmul(rp.transpose(0, 2, 1, 3).reshape(c, 3 * t, 3), rot.transpose(0, 2, 1)).reshape(c, t, 3, 3)
    s2 = np.stack([rprt[..., i, j] for i, j in _PAIRS]).reshape(6, m)     # (R P) R^T
    return cnt, s1_enu, s2
