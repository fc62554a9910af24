"""Specular single-bounce reflections of satellite signals on the planar facets of a scene.

Image method (e.g. Hannah 2001, ch. 4; Hsu, GPS Solutions 22:7, 2018, for one wall): a facet is a plane
with unit normal n through a point v0; an antenna A in front of it (h = (A - v0).n > 0) and a satellite
at infinity in the unit direction u with c = u.n > 0 (the facet faces the satellite) give the
reflection point

    R = A - 2 h n + (h / c) u        (the line from the image A' = A - 2 h n towards the satellite)

and the excess path over the direct signal  delta = 2 h c  (= 2 h sin(grazing angle)).  The signal
arrives at A from the direction of R, at incidence angle theta = arccos(c) from the facet's normal.

A path counts when R lies inside the triangle (barycentric test, numpy) and two casts through Open3D
(core/scene/raycast.py, in the scene's float-safe shifted frame) are clear: antenna -> R (the first hit
is the facet itself, at |R - A|) and R -> satellite (no hit).  Facets are the scene's triangles; those
closer to a vertical plane than 60 deg take the material of their class name (fresnel.NAME_HINTS,
default concrete), those facing up (|n_z| > 0.9) are ground (P.2040 medium dry ground) unless their
class names a material.  Triangles repeated in the mesh (the same three vertices) are used once.

Only facets whose plane lies within ``max_range_m`` of the antenna and whose triangle comes within
that distance are tried: a scene without facets in range costs one vectorised distance test.  Per
satellite the ``max_paths`` strongest candidates by |R_co|^2 + |R_cross|^2 are kept.

Double bounces between two facing walls within DOUBLE_RANGE_M (``bounces=2``, :func:`_double_paths`).
Not modelled: other double and higher-order bounces, diffuse scattering and surface roughness, the
frequency dependence of the coefficients across bands (L1 values used), moving reflectors.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..constants import F_L1_HZ
from . import fresnel

#: offset of the second cast's origin off the facet [m] (float32 scene: ~1e-5 m resolution near the centre)
SURFACE_OFFSET_M = 0.02
#: the antenna -> R cast must reach within this of |R - A| [m]
REACH_TOLERANCE_M = 0.05
#: scenes with this many facets or more find those near an antenna through a KD-tree of their centres
TREE_MIN_FACETS = 2000


@dataclass
class ScenePaths:
    """Reflected paths per (antenna, satellite, k); k < max_paths, invalid slots have excess_m = NaN."""

    excess_m: np.ndarray          # (M, N, K) extra path over the direct signal [m]
    gamma_co: np.ndarray          # (M, N, K) complex RHCP -> RHCP coefficient
    gamma_cross: np.ndarray       # (M, N, K) complex RHCP -> LHCP coefficient
    arrival_el_deg: np.ndarray    # (M, N, K) elevation of the arriving reflected ray (local up)
    rays_cast: int = 0            # Open3D rays spent on these paths

    @property
    def valid(self) -> np.ndarray:
        return np.isfinite(self.excess_m)

    def take(self, rows):
        """The paths of one antenna's satellite rows (``rows`` indexes axis 1 after selecting an antenna)."""
        return ScenePaths(self.excess_m[rows], self.gamma_co[rows], self.gamma_cross[rows],
                          self.arrival_el_deg[rows], 0)

    @classmethod
    def empty(cls, m: int, n: int, k: int) -> ScenePaths:
        z = np.full((m, n, k), np.nan)
        return cls(z, np.zeros((m, n, k), complex), np.zeros((m, n, k), complex), z.copy(), 0)


class Facets:
    """Unique triangles of a scene's world mesh with plane, edges and complex permittivity."""

    def __init__(self, world, f_hz: float = F_L1_HZ):
        v = np.asarray(world.vertices_m, dtype=np.float64)
        tri = np.asarray(world.triangles, dtype=np.int64)
        mat = np.asarray(world.material, dtype=np.int64)
        opaque = np.array([c.opaque for c in world.materials.classes], dtype=bool)
        keep = opaque[mat] if len(mat) else np.zeros(0, bool)
        tri, mat = tri[keep], mat[keep]
        p = v[tri]                                                     # (T, 3, 3)
        # the same triangle twice (meshes exported with both copies of a wall): once
        seen, first = set(), []
        for q, tri_m in enumerate(np.round(p, 3).tolist()):
            key = tuple(sorted(map(tuple, tri_m)))
            if key not in seen:
                seen.add(key)
                first.append(q)
        first = np.asarray(first, dtype=np.int64)
        p, mat = p[first], mat[first]
        e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        n = np.cross(e1, e2)
        area2 = np.linalg.norm(n, axis=1)
        ok = area2 > 1e-9
        p, mat, e1, e2, n, area2 = p[ok], mat[ok], e1[ok], e2[ok], n[ok], area2[ok]
        self.v0, self.e1, self.e2 = p[:, 0], e1, e2
        self.normal = n / area2[:, None]
        self.centroid = p.mean(axis=1)
        self.radius = np.max(np.linalg.norm(p - self.centroid[:, None], axis=2), axis=1) if len(p) else np.zeros(0)
        # barycentric solve: R - v0 = s e1 + t e2 (Gram matrix)
        d00, d01, d11 = (np.einsum("ij,ij->i", e1, e1), np.einsum("ij,ij->i", e1, e2), np.einsum("ij,ij->i", e2, e2))
        self._gram = (d00, d01, d11, d00 * d11 - d01 * d01)
        self._plane_offset = np.einsum("ij,ij->i", self.normal, self.v0)          # n . v0 per facet
        self._tree = None                                                         # KD-tree of the centres (near)
        names = [c.name for c in world.materials.classes]
        named = {i: fresnel.material_for_class(nm) for i, nm in enumerate(names)}
        explicit = {i: any(h in nm.lower() for h, _ in fresnel.NAME_HINTS) for i, nm in enumerate(names)}
        horiz = np.abs(self.normal[:, 2]) > 0.9
        mats = [named[int(m_)] if (explicit[int(m_)] or not h) else "ground" for m_, h in zip(mat, horiz)]
        perm = {nm: fresnel.material(nm).permittivity(f_hz) for nm in set(mats)}
        self.material_name = np.array(mats, dtype=object)
        self.eta = np.array([perm[nm] for nm in mats], dtype=np.complex128)

    def __len__(self) -> int:
        return len(self.v0)

    def inside(self, fi, r) -> np.ndarray:
        """(K,) bool: do the points ``r`` (K, 3) on the planes of facets ``fi`` (K,) lie inside the triangles?"""
        w = r - self.v0[fi]
        d00, d01, d11, den = (g[fi] for g in self._gram)
        d20 = np.einsum("ij,ij->i", w, self.e1[fi])
        d21 = np.einsum("ij,ij->i", w, self.e2[fi])
        bs = (d11 * d20 - d01 * d21) / den
        bt = (d00 * d21 - d01 * d20) / den
        return (bs >= 0) & (bt >= 0) & (bs + bt <= 1)

    def may_reach(self, fi, origin, u) -> np.ndarray:
        """(S, F) bool: may the rays from ``origin`` (F, 3) along the unit directions ``u`` (S, 3) meet the
        facets ``fi`` (F,)?  False only where a ray's line misses the facet's bounding sphere grown by 1 mm
        (angle to the centre above asin(radius / distance)): a conservative filter, the candidates it keeps
        go through the exact test (:meth:`inside`) as before."""
        w = self.centroid[fi] - origin
        dist = np.linalg.norm(w, axis=1)
        rad = self.radius[fi] * (1.0 + 1e-6) + 1e-3
        around = dist <= rad                                   # origin within the sphere: every direction
        cos_min = np.sqrt(np.maximum(0.0, 1.0 - (rad / np.where(around, 1.0, dist)) ** 2))
        return (u @ w.T >= (cos_min * dist)[None, :]) | around[None, :]

    def near(self, antenna_m, max_range_m: float) -> np.ndarray:
        """Indices of the facets that come within ``max_range_m`` of the antenna (3,): in front of it (plane
        distance h in (0.05, range]) and their bounding sphere within range.  A scene of many facets first takes
        the candidates from a KD-tree of the centres (within range + the largest radius + 1 um), then the same
        test on those only."""
        a = np.asarray(antenna_m, dtype=np.float64)
        if len(self) < TREE_MIN_FACETS:
            cand = slice(None)
        else:
            if self._tree is None:
                from scipy.spatial import cKDTree
                self._tree = cKDTree(self.centroid)
            reach = max_range_m + float(np.max(self.radius)) + 1e-6
            cand = np.sort(np.asarray(self._tree.query_ball_point(a, reach), dtype=np.int64))
        h = np.einsum("ij,j->i", self.normal[cand], a) - self._plane_offset[cand]
        dist = np.linalg.norm(self.centroid[cand] - a, axis=1) - self.radius[cand]
        keep = np.flatnonzero((h > 0.05) & (h <= max_range_m) & (dist <= max_range_m))
        return keep if isinstance(cand, slice) else cand[keep]


def search_inputs(antenna_world_m, sat_dirs_world, k: int):
    """(antennas (M, 3), satellite directions (M, N, 3), empty ScenePaths (M, N, k)) of a path search."""
    a = np.asarray(antenna_world_m, dtype=np.float64).reshape(-1, 3)
    u_all = np.asarray(sat_dirs_world, dtype=np.float64)
    return a, u_all, ScenePaths.empty(u_all.shape[0], u_all.shape[1], k)


def find_paths(scene, facets: Facets, antenna_world_m, sat_dirs_world, *, max_range_m: float = 100.0,
               max_paths: int = 3, only=None, bounces: int = 1) -> ScenePaths:
    """Specular paths for antennas (M, 3) and satellite unit directions (M, N, 3), world frame.

    ``only``: optional (M, N) bool, the satellites for which paths are wanted (others stay empty);
    ``bounces``: 1, or 2 to add the double bounces between two facing walls (:func:`_double_paths`)."""
    if bounces not in (1, 2):
        raise ValueError(f"multipath: bounces = {bounces!r} must be 1 or 2")
    a, u_all, out = search_inputs(antenna_world_m, sat_dirs_world, max_paths)
    m, n = u_all.shape[:2]
    if len(facets) == 0 or n == 0:
        return out
    # candidates of every antenna, then one batch of casts for all of them
    cand = []                          # (antenna i, sat j, facet f, R (3,), excess, cos_inc)
    for i in range(m):
        sel = facets.near(a[i], max_range_m)
        if len(sel) == 0:
            continue
        sats = np.arange(n) if only is None else np.flatnonzero(only[i])
        if len(sats) == 0:
            continue
        nf = facets.normal[sel]                                     # (F, 3)
        h = nf @ a[i] - np.einsum("ij,ij->i", nf, facets.v0[sel])   # (F,)
        u = u_all[i, sats]                                           # (S, 3)
        c = u @ nf.T                                                 # (S, F)
        # R lies on the line from the antenna's image A - 2 h n along u: facets that line misses are dropped
        ok = (c > 1e-3) & facets.may_reach(sel, a[i] - 2.0 * h[:, None] * nf, u)
        s_idx, f_idx = np.nonzero(ok)
        if len(s_idx) == 0:
            continue
        cf = c[s_idx, f_idx]
        hf = h[f_idx]
        fi = sel[f_idx]
        r = a[i] - 2.0 * hf[:, None] * facets.normal[fi] + (hf / cf)[:, None] * u[s_idx]
        inside = facets.inside(fi, r)
        if not np.any(inside):
            continue
        k = np.flatnonzero(inside)
        cand.append((np.full(len(k), i), sats[s_idx[k]], fi[k], r[k], 2.0 * hf[k] * cf[k], cf[k]))
    doubles = _double_paths(scene, facets, a, u_all, max_range_m, only) if bounces == 2 else None
    if not cand and doubles is None:
        return out
    if not cand:
        ii, jj, excess, g_co, g_x, el_arr, rays = doubles
        out.rays_cast = rays
        _keep_strongest(out, ii, jj, excess, g_co, g_x, el_arr, max_paths)
        return out
    ii, jj, ff, rr, excess, cos_inc = (np.concatenate(x) for x in zip(*cand))
    # cast 1: antenna -> reflection point reaches the facet
    seg = rr - a[ii]
    dist = np.linalg.norm(seg, axis=1)
    dirs = seg / dist[:, None]
    t_hit = scene.rays.hit_distance(a[ii], dirs, tnear_m=1e-3)
    ok = t_hit >= dist - REACH_TOLERANCE_M
    # cast 2: reflection point -> satellite is clear
    sel = np.flatnonzero(ok)
    rays = len(ii) + len(sel)
    if len(sel):
        origin = rr[sel] + SURFACE_OFFSET_M * facets.normal[ff[sel]]
        clear = ~scene.rays.occluded(origin, u_all[ii[sel], jj[sel]], tnear_m=1e-3)
        ok[sel] &= clear
    good = np.flatnonzero(ok)
    ii, jj, ff, dirs, excess, cos_inc = ii[good], jj[good], ff[good], dirs[good], excess[good], cos_inc[good]
    inc_deg = np.degrees(np.arccos(np.clip(cos_inc, -1.0, 1.0)))
    g_co, g_x = fresnel.circular_coefficients(facets.eta[ff], inc_deg)
    el_arr = np.degrees(np.arcsin(np.clip(dirs[:, 2], -1.0, 1.0)))
    if doubles is not None:
        ii, jj, excess, g_co, g_x, el_arr = (np.concatenate([x, y]) for x, y in
                                             zip((ii, jj, excess, g_co, g_x, el_arr), doubles[:6]))
        rays += doubles[6]
    out.rays_cast = rays
    _keep_strongest(out, ii, jj, excess, g_co, g_x, el_arr, max_paths)
    return out


def _keep_strongest(out: ScenePaths, ii, jj, excess, g_co, g_x, el_arr, max_paths: int) -> None:
    """The strongest ``max_paths`` per (antenna, satellite) into ``out``; the same path from a duplicated plane
    once."""
    strength = np.abs(g_co) ** 2 + np.abs(g_x) ** 2
    order = np.lexsort((-strength, jj, ii))
    slot = {}
    seen = set()
    for q in order:
        key = (int(ii[q]), int(jj[q]))
        dup = (key, round(float(excess[q]), 2))
        if dup in seen:
            continue
        seen.add(dup)
        s = slot.get(key, 0)
        if s >= max_paths:
            continue
        slot[key] = s + 1
        out.excess_m[key[0], key[1], s] = excess[q]
        out.gamma_co[key[0], key[1], s] = g_co[q]
        out.gamma_cross[key[0], key[1], s] = g_x[q]
        out.arrival_el_deg[key[0], key[1], s] = el_arr[q]


#: facing walls: vertical facets (|n_z| below this) whose normals are opposite within this cosine
_WALL_NZ_MAX = 0.3
_FACING_COS = -0.95
#: walls farther than this [m] take no part in double bounces (the pairs grow as the square of the facets in
#: range; street canyons are 10-60 m wide)
DOUBLE_RANGE_M = 60.0


def _reaches(scene, origin, target):
    """(K,) bool: a ray from ``origin`` towards ``target`` (K, 3) meets nothing before it (within tolerance)."""
    seg = target - origin
    dist = np.linalg.norm(seg, axis=1)
    t_hit = scene.rays.hit_distance(origin, seg / dist[:, None], tnear_m=1e-3)
    return t_hit >= dist - REACH_TOLERANCE_M


def _double_paths(scene, facets: Facets, a, u_all, max_range_m, only):
    """Double bounces satellite -> wall 2 -> facing wall 1 -> antenna (two facing, near-parallel walls of a
    street canyon).  Image of the antenna in wall 1 (A1), of A1 in wall 2 (A12); the line from A12 towards the
    satellite meets wall 2 at R2, the line R2 -> A1 meets wall 1 at R1; excess = |A R1| + |R1 R2| + (A - R2).u.
    Polarisation after two bounces: RHCP = co2 co1 + x2 x1, LHCP = co2 x1 + x2 co1 (the circular
    coefficients are the same for both handednesses).  Casts: A -> R1, R1 -> R2 and R2 -> satellite.
    Returns (i, j, excess, gamma_co, gamma_cross, arrival_el_deg, rays) or None."""
    m, n = u_all.shape[:2]
    rows = []
    for i in range(m):
        sel = facets.near(a[i], min(max_range_m, DOUBLE_RANGE_M))
        sel = sel[np.abs(facets.normal[sel, 2]) < _WALL_NZ_MAX]
        sats = np.arange(n) if only is None else np.flatnonzero(only[i])
        if len(sel) < 2 or len(sats) == 0:
            continue
        nrm = facets.normal[sel]
        p1, p2 = np.nonzero(nrm @ nrm.T < _FACING_COS)
        if len(p1) == 0:
            continue
        f1, f2 = sel[p1], sel[p2]
        n1, n2 = facets.normal[f1], facets.normal[f2]
        h1 = np.einsum("ij,ij->i", n1, a[i] - facets.v0[f1])
        a1 = a[i] - 2 * h1[:, None] * n1
        h12 = np.einsum("ij,ij->i", n2, a1 - facets.v0[f2])
        a12 = a1 - 2 * h12[:, None] * n2
        u = u_all[i, sats]
        c2 = u @ n2.T                                            # (S, P): wall 2 faces the satellite
        s_idx, q = np.nonzero((c2 > 1e-3) & facets.may_reach(f2, a12, u))       # R2 on the line A12 + t u
        if len(q) == 0:
            continue
        r2 = a12[q] + (h12[q] / c2[s_idx, q])[:, None] * u[s_idx]      # A12 lies h12 behind wall 2
        keep = facets.inside(f2[q], r2)
        s_idx, q, r2 = s_idx[keep], q[keep], r2[keep]
        d = a1[q] - r2
        den = np.einsum("ij,ij->i", d, n1[q])
        t = np.einsum("ij,ij->i", facets.v0[f1[q]] - r2, n1[q]) / np.where(den == 0, np.nan, den)
        r1 = r2 + t[:, None] * d
        keep = np.isfinite(t) & (t > 0) & (t < 1) & facets.inside(f1[q], r1)
        if not keep.any():
            continue
        s_idx, q, r2, r1 = s_idx[keep], q[keep], r2[keep], r1[keep]
        rows.append((np.full(len(q), i), sats[s_idx], f1[q], f2[q], r1, r2))
    if not rows:
        return None
    ii, jj, f1, f2, r1, r2 = (np.concatenate(x) for x in zip(*rows))
    ok = _reaches(scene, a[ii], r1)
    rays = len(ii)
    sel = np.flatnonzero(ok)
    if len(sel):
        ok[sel] &= _reaches(scene, r1[sel] + SURFACE_OFFSET_M * facets.normal[f1[sel]], r2[sel])
        rays += len(sel)
    sel = np.flatnonzero(ok)
    if len(sel):
        origin = r2[sel] + SURFACE_OFFSET_M * facets.normal[f2[sel]]
        ok[sel] &= ~scene.rays.occluded(origin, u_all[ii[sel], jj[sel]], tnear_m=1e-3)
        rays += len(sel)
    g = np.flatnonzero(ok)
    if len(g) == 0:
        return None
    ii, jj, f1, f2, r1, r2 = ii[g], jj[g], f1[g], f2[g], r1[g], r2[g]
    u = u_all[ii, jj]
    excess = np.linalg.norm(r1 - a[ii], axis=1) + np.linalg.norm(r2 - r1, axis=1) + np.einsum(
        "ij,ij->i", a[ii] - r2, u)
    inc2 = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", u, facets.normal[f2]), -1.0, 1.0)))
    d12 = (r1 - r2) / np.linalg.norm(r1 - r2, axis=1)[:, None]
    inc1 = np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", d12, facets.normal[f1])), -1.0, 1.0)))
    co2, x2 = fresnel.circular_coefficients(facets.eta[f2], inc2)
    co1, x1 = fresnel.circular_coefficients(facets.eta[f1], inc1)
    arrive = (r1 - a[ii]) / np.linalg.norm(r1 - a[ii], axis=1)[:, None]
    el_arr = np.degrees(np.arcsin(np.clip(arrive[:, 2], -1.0, 1.0)))
    return ii, jj, excess, co2 * co1 + x2 * x1, co2 * x1 + x2 * co1, el_arr, rays
