"""Diffuse scattering of satellite signals from building walls (effective roughness model, Lambertian lobe).

Real facades are not mirrors: windows, ledges and masonry scatter part of the incident power in every
direction.  The effective roughness model (V. Degli-Esposti, F. Fuschini, E. M. Vitucci, G. Falciasecca,
"Measurement and modelling of scattering from buildings", IEEE Trans. Antennas Propag. 55(1), 143-153,
2007) gives a wall element dS lit by a plane wave the scattered share S^2 of the power it intercepts,
radiated with a Lambertian pattern (their best fit for rough facades, S about 0.4 at 1.3 GHz).  With the
satellite at infinity the element's power at the antenna relative to an unobstructed line of sight is

    p = S^2 cos(theta_i) cos(theta_s) dS / (pi r^2)

(theta_i: the satellite's direction from the wall's normal, theta_s: the antenna's, r: element to antenna);
over a whole lit wall seen as a half-space this integrates to 2 S^2 cos(theta_i) (the Lambertian lobe over
the hemisphere).  The excess path of the element at P is |P - A| - (P - A).u (u: unit vector to the
satellite).

Sampling: the walls (|n_z| < 0.3) within ``max_range_m`` are cut into tiles of about ``TILE_ANGLE`` radians
seen from the antenna (at least TILE_MIN_M), each tile a point of a low-discrepancy sequence on its
triangle; the ``MAX_TILES`` tiles of largest cos(theta_s) dS / r^2 are cast from the antenna (visible?),
then towards each satellite (lit?).  The tiles of a satellite are summed coherently (phase 2 pi
excess / lambda, no random draw: one geometry, one answer) in bins of ``BIN_M`` of excess delay; the
``paths`` bins of largest power become paths with that complex amplitude split evenly between RHCP and
LHCP (a rough surface depolarises).  Not modelled: the specular share's reduction by (1 - S^2) (0.8 dB),
scattering from the ground, the roofs and by vegetation, tiles shadowed only in part.
"""
from __future__ import annotations

import numpy as np

from .reflections import REACH_TOLERANCE_M, SURFACE_OFFSET_M, Facets, ScenePaths, search_inputs

#: scattering coefficient S of building walls (Degli-Esposti et al. 2007, Lambertian fit, ~0.4)
S_WALL = 0.4
#: tile size: this angle seen from the antenna [rad], at least TILE_MIN_M [m]
TILE_ANGLE = 0.1
TILE_MIN_M = 1.0
#: tiles per triangle at most, tiles cast per antenna at most
MAX_TILES_PER_FACET = 400
MAX_TILES = 600
#: width of the excess-delay bins a satellite's tiles are summed in [m]
BIN_M = 15.0
_WALL_NZ_MAX = 0.3


def _triangle_points(n: int):
    """(n, 2) barycentric (s, t), s + t <= 1, spread over a triangle (Kronecker sequence, folded)."""
    k = np.arange(n) + 0.5
    s = (k * 0.7548776662466927) % 1.0          # plastic-number sequence (R2)
    t = (k * 0.5698402909980532) % 1.0
    fold = s + t > 1.0
    return np.column_stack([np.where(fold, 1.0 - s, s), np.where(fold, 1.0 - t, t)])


def _tiles(facets: Facets, sel, antenna_m):
    """Tile centres (T, 3), areas (T,), facet indices (T,) of the facets ``sel`` seen from the antenna."""
    area = 0.5 * np.linalg.norm(np.cross(facets.e1[sel], facets.e2[sel]), axis=1)
    dist = np.maximum(np.linalg.norm(facets.centroid[sel] - antenna_m, axis=1), 1.0)
    tile = np.maximum(TILE_MIN_M, TILE_ANGLE * dist)
    n = np.clip(np.ceil(area / tile ** 2).astype(np.int64), 1, MAX_TILES_PER_FACET)
    pts, dA, fi = [], [], []
    for f, a_f, n_f in zip(sel, area, n):
        st = _triangle_points(int(n_f))
        pts.append(facets.v0[f] + st[:, :1] * facets.e1[f] + st[:, 1:] * facets.e2[f])
        dA.append(np.full(int(n_f), a_f / n_f))
        fi.append(np.full(int(n_f), f))
    if not pts:
        return np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int64)
    return np.vstack(pts), np.concatenate(dA), np.concatenate(fi)


def lit_tiles(scene, facets: Facets, antenna_m, sat_dirs, *, max_range_m: float = 100.0, s_coef: float = S_WALL):
    """The wall tiles that scatter towards one antenna (3,) for satellite unit directions (S, 3), world frame:
    (satellite index (Q,), relative power p (Q,), excess path [m] (Q,), arrival elevation [deg] (Q,), rays cast)
    for every (satellite, tile) pair seen from the antenna and lit by the satellite (module docstring)."""
    a = np.asarray(antenna_m, dtype=np.float64).reshape(3)
    u = np.asarray(sat_dirs, dtype=np.float64).reshape(-1, 3)
    none = (np.zeros(0, np.int64), np.zeros(0), np.zeros(0), np.zeros(0))
    sel = facets.near(a, max_range_m)
    sel = sel[np.abs(facets.normal[sel, 2]) < _WALL_NZ_MAX]
    if len(sel) == 0 or len(u) == 0:
        return (*none, 0)
    p, dA, fi = _tiles(facets, sel, a)
    d = p - a
    r = np.linalg.norm(d, axis=1)
    nrm = facets.normal[fi]
    cos_s = -np.einsum("ij,ij->i", d, nrm) / r
    w = np.where((cos_s > 0) & (r <= max_range_m), cos_s * dA / (np.pi * r ** 2), 0.0)
    keep = np.argsort(-w)[:MAX_TILES]
    keep = keep[w[keep] > 0]
    if len(keep) == 0:
        return (*none, 0)
    p, d, r, nrm, w = p[keep], d[keep], r[keep], nrm[keep], w[keep]
    dirs = d / r[:, None]
    seen = scene.rays.hit_distance(np.broadcast_to(a, dirs.shape), dirs, tnear_m=1e-3) >= r - REACH_TOLERANCE_M
    rays = len(keep)
    p, d, r, nrm, w, dirs = p[seen], d[seen], r[seen], nrm[seen], w[seen], dirs[seen]
    cos_i = u @ nrm.T                                    # (S, T): the wall faces the satellite
    s_idx, t_idx = np.nonzero(cos_i > 1e-3)
    if len(s_idx) == 0:
        return (*none, rays)
    origin = p[t_idx] + SURFACE_OFFSET_M * nrm[t_idx]
    lit = ~scene.rays.occluded(origin, u[s_idx], tnear_m=1e-3)
    rays += len(s_idx)
    s_idx, t_idx = s_idx[lit], t_idx[lit]
    power = s_coef ** 2 * cos_i[s_idx, t_idx] * w[t_idx]
    excess = r[t_idx] - np.einsum("ij,ij->i", d[t_idx], u[s_idx])
    el = np.degrees(np.arcsin(np.clip(dirs[t_idx, 2], -1.0, 1.0)))
    return s_idx, power, excess, el, rays


def scatter_paths(scene, facets: Facets, antenna_world_m, sat_dirs_world, wavelength_m: float, *,
                  max_range_m: float = 100.0, paths: int = 3, only=None, s_coef: float = S_WALL) -> ScenePaths:
    """Diffusely scattered paths (module docstring) for antennas (M, 3) and satellite unit directions (M, N, 3),
    world frame; ``only``: (M, N) bool, the satellites wanted.  ScenePaths (M, N, ``paths``)."""
    a_all, u_all, out = search_inputs(antenna_world_m, sat_dirs_world, paths)
    m, n = u_all.shape[:2]
    if len(facets) == 0 or n == 0:
        return out
    for i in range(m):
        sats = np.arange(n) if only is None else np.flatnonzero(only[i])
        if len(sats) == 0:
            continue
        s_idx, power, excess, el, rays = lit_tiles(scene, facets, a_all[i], u_all[i, sats], max_range_m=max_range_m,
                                                   s_coef=s_coef)
        out.rays_cast += rays
        phasor = np.sqrt(power) * np.exp(2j * np.pi * excess / wavelength_m)
        b = np.floor(excess / BIN_M).astype(np.int64)
        for s in np.unique(s_idx):
            q = s_idx == s
            _, inv = np.unique(b[q], return_inverse=True)
            pw = np.bincount(inv, weights=power[q])
            amp = np.bincount(inv, weights=phasor[q].real) + 1j * np.bincount(inv, weights=phasor[q].imag)
            ex = np.bincount(inv, weights=power[q] * excess[q]) / pw
            ev = np.bincount(inv, weights=power[q] * el[q]) / pw
            j = sats[s]
            for k, g in enumerate(np.argsort(-pw)[:paths]):
                out.excess_m[i, j, k] = ex[g]
                out.gamma_co[i, j, k] = amp[g] / np.sqrt(2.0)
                out.gamma_cross[i, j, k] = amp[g] / np.sqrt(2.0)
                out.arrival_el_deg[i, j, k] = ev[g]
    return out
