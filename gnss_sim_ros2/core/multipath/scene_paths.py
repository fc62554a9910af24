"""Reflected paths of one cast: the bridge between VisibilityOptions.cast and core/multipath/reflections.py.

Uses only the Scene's public members (``world``, ``rays``, ``spherical``, ``antenna_ecef``); the facets of
a scene are built once and kept on the Scene object.  Satellite directions in the world frame: the
ECEF line of sight rotated by the world's fixed rotation (``spherical.rotation_world_from_ecef``).
"""
from __future__ import annotations

import numpy as np

from ..constants import C_MPS, F_L1_HZ
from ..vocabulary import MULTIPATH_MODES, VisibilityState
from .diffraction import MAX_LOSS_DB, edge_loss_db
from .reflections import Facets, ScenePaths, find_paths
from .scattering import scatter_paths

L1_WAVELENGTH_M = C_MPS / F_L1_HZ

_ATTR = "_multipath_facets"


def facets_of(scene) -> Facets:
    """The scene's facets (cached on the scene)."""
    f = scene.__dict__.get(_ATTR)
    if f is None:
        f = Facets(scene.world)
        setattr(scene, _ATTR, f)
    return f


def world_directions(scene, antenna_world_m, sat_ecef_m) -> np.ndarray:
    """(M, N, 3) unit satellite directions in the world frame from antennas (M, 3) and satellites (N|M,N, 3)."""
    a = np.asarray(antenna_world_m, dtype=np.float64).reshape(-1, 3)
    rx = scene.antenna_ecef(a)
    sat = np.asarray(sat_ecef_m, dtype=np.float64)
    if sat.ndim == 2:
        sat = np.broadcast_to(sat, (len(a),) + sat.shape)
    d = sat - rx[:, None, :]
    d = d @ scene.spherical.world_from_ecef_t()
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def cast_paths(options, scene, antenna_world_m, sat_ecef_m, v, state, antennas=None):
    """Attach ``v.paths`` (ScenePaths, (M, N, K) or (N, K) for one antenna: the specular paths, then with
    ``multipath_scattering`` the scattered ones, scattering.py); returns (state, extra loss dB).

    Blocked satellites: knife-edge diffraction over the nearest edge (diffraction.py); below
    MAX_LOSS_DB the satellite is ATTENUATED by that loss (a weakened direct signal), else it stays
    blocked; with a reflected path it is REFLECTED_ONLY (or ATTENUATED with reflections on top).

    ``antennas``: (M,) bool, the antennas whose reflections are modelled (mode "auto": those with walls within
    ``multipath_range_m``, wall_proximity.py; they are modelled as "full"); the others keep their state, no
    path and no extra loss, as with "off", and cost nothing here.  None: every antenna."""
    mode = options.multipath
    if mode not in MULTIPATH_MODES:
        raise ValueError(f"visibility: parameter 'multipath' = {mode!r} (one of {', '.join(MULTIPATH_MODES)})")
    a = np.asarray(antenna_world_m, dtype=np.float64)
    single = a.ndim == 1
    a2 = a.reshape(-1, 3)
    st = np.atleast_2d(state).copy()
    el = np.atleast_2d(v.el_deg)
    m, n = st.shape
    extra_db = np.zeros(st.shape)
    rows = np.arange(m) if antennas is None else np.flatnonzero(antennas)
    if len(rows) == m:
        paths, st, extra_db = _modelled(options, "full" if mode == "auto" else mode, scene, a2, sat_ecef_m, el, st)
    else:
        paths = ScenePaths.empty(m, n, options.multipath_max_paths)
        if len(rows):
            sat = np.asarray(sat_ecef_m, dtype=np.float64)
            sub, st[rows], extra_db[rows] = _modelled(options, "full", scene, a2[rows],
                                                      sat if sat.ndim == 2 else sat[rows], el[rows], st[rows])
            width = sub.excess_m.shape[-1]
            if width != paths.excess_m.shape[-1]:
                paths = ScenePaths.empty(m, n, width)
            for f in ("excess_m", "gamma_co", "gamma_cross", "arrival_el_deg"):
                getattr(paths, f)[rows] = getattr(sub, f)
            paths.rays_cast = sub.rays_cast
    has = paths.valid.any(axis=-1)
    shortest = np.where(has, np.nanmin(np.where(paths.valid, paths.excess_m, np.inf), axis=-1), 0.0)
    if single:
        paths = ScenePaths(paths.excess_m[0], paths.gamma_co[0], paths.gamma_cross[0], paths.arrival_el_deg[0],
                           paths.rays_cast)
        st, shortest, extra_db = st[0], shortest[0], extra_db[0]
    v.extra_path_m = shortest
    v.paths = paths
    return st.astype(np.int64), extra_db


def _modelled(options, mode, scene, a, sat_ecef_m, el, st):
    """(ScenePaths (M, N, K'), state (M, N), extra loss dB (M, N)) of antennas ``a`` (M, 3) in mode "nlos" or
    "full", from their satellites' elevations and line-of-sight states (M, N)."""
    st = st.copy()
    cast = el >= options.mask_deg
    blocked = st == int(VisibilityState.BLOCKED)
    only = cast & blocked if mode == "nlos" else cast
    facets = facets_of(scene)
    dirs = world_directions(scene, a, sat_ecef_m) if (only.any() or (cast & blocked).any()) else None
    if only.any() and len(facets):
        paths = find_paths(scene, facets, a, dirs,
                           max_range_m=options.multipath_range_m, max_paths=options.multipath_max_paths, only=only,
                           bounces=options.multipath_bounces)
    else:
        paths = ScenePaths.empty(st.shape[0], st.shape[1], options.multipath_max_paths)
    if options.multipath_scattering and only.any() and len(facets):
        sc = scatter_paths(scene, facets, a, dirs, L1_WAVELENGTH_M,
                           max_range_m=options.multipath_range_m, paths=options.multipath_max_paths, only=only)
        paths = ScenePaths(*(np.concatenate([getattr(paths, f), getattr(sc, f)], axis=-1)
                             for f in ("excess_m", "gamma_co", "gamma_cross", "arrival_el_deg")),
                           paths.rays_cast + sc.rays_cast)
    extra_db = np.zeros(st.shape)
    for i in np.flatnonzero((cast & blocked).any(axis=1) if options.multipath_diffraction else []):
        j = np.flatnonzero(cast[i] & blocked[i])
        loss, _, n_rays = edge_loss_db(scene.rays, a[i], dirs[i, j], L1_WAVELENGTH_M)
        paths.rays_cast += n_rays
        weak = np.isfinite(loss) & (loss <= MAX_LOSS_DB)
        extra_db[i, j[weak]] = loss[weak]
        st[i, j[weak]] = int(VisibilityState.ATTENUATED)
    has = paths.valid.any(axis=-1)
    st = np.where(blocked & has & (st == int(VisibilityState.BLOCKED)), int(VisibilityState.REFLECTED_ONLY), st)
    return paths, st, extra_db
