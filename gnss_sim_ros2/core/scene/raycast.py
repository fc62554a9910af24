"""Open3D ray queries against a scene split into opaque and penetrable (foliage) triangles.

Open3D's ``RaycastingScene`` (Embree) works in float32: a 6.4e6 m ECEF
coordinate keeps about 0.5 m, a 100 km world coordinate about 8 mm.  So the
vertices are shifted by the scene's bounding-box centre (in float64) before the
float32 conversion, and every ray origin is shifted by the same centre; rays
are (origin, unit direction) with ``t`` in metres, never far end points.

* opaque triangles: one scene, ``test_occlusions`` (any hit) or ``cast_rays``
  (first hit distance);
* penetrable triangles (closed volumes such as tree crowns): a second scene;
  ``test_occlusions`` first finds the few rays that touch foliage at all, and
  only those go through ``list_intersections``.  The path length inside the
  volumes is  sum(t at exits) - sum(t at entries)  with entry/exit told by the
  sign of (ray direction . outward face normal); a ray starting inside a
  volume has one exit more than entries, which the sum handles.  Each hit is
  weighted by its triangle's attenuation [dB/m], so overlapping volumes of
  different classes add up.

Batched queries (``*_buffer`` methods) take a C-contiguous float32 (K, 6) ray
buffer (origin shifted by ``center_m``, unit direction), which is handed to
Open3D without a copy (``Tensor.from_numpy``); :meth:`RayScene.rays_buffer` and
:meth:`RayScene.rays_buffer_ragged` build one with the origins filled.  With
``scratch=True`` the buffer is a per-thread array kept from call to call: a
fresh multi-megabyte array per call costs more in page faults (the allocator
hands large blocks back to the system and takes them again) than the numpy
work that fills it.
"""
from __future__ import annotations

import math
import threading

import numpy as np
import open3d as o3d

#: scratch arrays above this many elements are not kept between calls (64 MB of float32)
SCRATCH_MAX_ELEMENTS = 1 << 24
#: nor those of up to this many (a fresh small array is cheaper than the look-up, and costs no page faults)
SCRATCH_MIN_ELEMENTS = 4096


def _tensor(a, dtype):
    return o3d.core.Tensor(np.ascontiguousarray(a, dtype=dtype))


class RayScene:
    """Ray queries in the world frame.  ``attenuation_db_per_m[t]`` per triangle: inf/NaN = opaque."""

    def __init__(self, vertices_m, triangles, attenuation_db_per_m, nthreads: int = 0):
        v = np.asarray(vertices_m, dtype=np.float64)
        f = np.asarray(triangles, dtype=np.int64)
        att = np.asarray(attenuation_db_per_m, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or att.shape != (len(f),):
            raise ValueError("RayScene: vertices_m (V, 3), triangles (T, 3), attenuation_db_per_m (T,) expected")
        self.nthreads = int(nthreads)
        self._local = threading.local()         # per-thread scratch arrays, see scratch()
        finite = v[np.all(np.isfinite(v), axis=1)]
        # the bounds of the finite vertices: one NaN vertex must not make every ray NaN (Embree itself skips
        # a triangle with a NaN corner)
        self.center_m = 0.5 * (finite.min(axis=0) + finite.max(axis=0)) if len(finite) else np.zeros(3)
        vc = v - self.center_m
        opaque = ~np.isfinite(att)
        self.n_opaque = int(opaque.sum())
        self.n_penetrable = int((~opaque).sum())
        self._opaque = None
        self._pen = None
        if self.n_opaque:
            self._opaque = o3d.t.geometry.RaycastingScene()
            self._opaque.add_triangles(_tensor(vc, np.float32), _tensor(f[opaque], np.uint32))
        if self.n_penetrable:
            fp = f[~opaque]
            self._pen = o3d.t.geometry.RaycastingScene()
            self._pen.add_triangles(_tensor(vc, np.float32), _tensor(fp, np.uint32))
            a, b, c = vc[fp[:, 0]], vc[fp[:, 1]], vc[fp[:, 2]]
            n = np.cross(b - a, c - a)
            self._pen_normals = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
            self._pen_att = att[~opaque]
        # Embree builds a scene's BVH at its first query: one ray now, so loading pays it, not the first epoch
        probe = o3d.core.Tensor(np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 1.0]], dtype=np.float32))
        for built in (self._opaque, self._pen):
            if built is not None:
                built.test_occlusions(probe, nthreads=self.nthreads)

    @property
    def has_penetrable(self) -> bool:
        return self._pen is not None

    def _rays(self, origins_m, dirs) -> o3d.core.Tensor:
        o = np.asarray(origins_m, dtype=np.float64).reshape(-1, 3) - self.center_m
        d = np.asarray(dirs, dtype=np.float64).reshape(-1, 3)
        o, d = np.broadcast_arrays(o, d)
        r = np.empty((len(d), 6), dtype=np.float32)
        r[:, :3] = o
        r[:, 3:] = d
        return o3d.core.Tensor.from_numpy(r)

    def scratch(self, name: str, shape: tuple, dtype=np.float32) -> np.ndarray:
        """An uninitialised array kept per thread and per ``name`` and reused by the next request of the same
        name in this thread (so: for one query at a time; never hand it out).  Above SCRATCH_MAX_ELEMENTS
        and up to SCRATCH_MIN_ELEMENTS a fresh array each time."""
        size = math.prod(shape)
        if size > SCRATCH_MAX_ELEMENTS or size <= SCRATCH_MIN_ELEMENTS:
            return np.empty(shape, dtype)
        store = getattr(self._local, "arrays", None)
        if store is None:
            store = self._local.arrays = {}
        buf = store.get(name)
        if buf is None or buf.dtype != dtype or buf.size < size:
            buf = store[name] = np.empty(size, dtype)
        return buf[:size].reshape(shape)

    def _origins_f32(self, origins_m) -> np.ndarray:
        return (np.asarray(origins_m, dtype=np.float64).reshape(-1, 3) - self.center_m).astype(np.float32)

    def rays_buffer(self, origins_m, n_per_origin: int, scratch: bool = False) -> np.ndarray:
        """(M, n, 6) float32 buffer whose origins are filled (shifted by the scene centre); fill [..., 3:].

        ``scratch``: the per-thread reused array (see :meth:`scratch`) instead of a new one."""
        o = self._origins_f32(origins_m)
        shape = (len(o), n_per_origin, 6)
        r = self.scratch("rays", shape) if scratch else np.empty(shape, dtype=np.float32)
        for k in range(3):          # one coordinate at a time: numpy's inner loop then runs along n, not along 3
            r[..., k] = o[:, k, None]
        return r

    def rays_buffer_ragged(self, origins_m, counts, scratch: bool = False) -> np.ndarray:
        """(sum(counts), 6) float32 buffer, origin i filled in ``counts[i]`` consecutive rows; fill [:, 3:]."""
        o = self._origins_f32(origins_m)
        counts = np.asarray(counts, dtype=np.intp).reshape(-1)
        shape = (int(counts.sum()), 6)
        r = self.scratch("rays", shape) if scratch else np.empty(shape, dtype=np.float32)
        for k in range(3):
            r[:, k] = o[0, k] if len(o) == 1 else np.repeat(o[:, k], counts)
        return r

    @staticmethod
    def _as_buffer(rays) -> np.ndarray:
        r = np.ascontiguousarray(rays, dtype=np.float32)
        if r.ndim != 2 or r.shape[1] != 6:
            raise ValueError(f"RayScene: rays buffer must be (K, 6) float32, got shape {r.shape}")
        return r

    def occluded_buffer(self, rays: np.ndarray, tnear_m: float = 0.0) -> np.ndarray:
        """Like :meth:`occluded` for a float32 (K, 6) buffer from :meth:`rays_buffer` (no copy)."""
        if self._opaque is None or len(rays) == 0:
            return np.zeros(len(rays), dtype=bool)
        t = o3d.core.Tensor.from_numpy(self._as_buffer(rays))
        return self._opaque.test_occlusions(t, tnear=tnear_m, nthreads=self.nthreads).numpy()

    def touches_penetrable_buffer(self, rays: np.ndarray, tnear_m: float = 0.0) -> np.ndarray:
        """Like :meth:`touches_penetrable` for a float32 (K, 6) buffer (no copy)."""
        if self._pen is None or len(rays) == 0:
            return np.zeros(len(rays), dtype=bool)
        t = o3d.core.Tensor.from_numpy(self._as_buffer(rays))
        return self._pen.test_occlusions(t, tnear=tnear_m, nthreads=self.nthreads).numpy()

    def penetration_buffer(self, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`penetration` for a float32 (K, 6) buffer, sparse: (indices of the rays that touch
        penetrable volumes, their attenuation_db, their path_length_m); every other ray has 0 and 0."""
        if self._pen is None or len(rays) == 0:
            return np.zeros(0, dtype=np.intp), np.zeros(0), np.zeros(0)
        r = self._as_buffer(rays)
        return self._penetration(r, r[:, 3:])

    def _penetration(self, rays: np.ndarray, dirs: np.ndarray):
        """(sel, db, length) for the rays of the float32 buffer ``rays`` that touch foliage.

        ``dirs`` (K, 3): the directions that decide entry / exit (the caller's, before float32)."""
        touched = self._pen.test_occlusions(o3d.core.Tensor.from_numpy(rays), nthreads=self.nthreads).numpy()
        sel = np.flatnonzero(touched)
        if len(sel) == 0:
            return sel, np.zeros(0), np.zeros(0)
        lx = self._pen.list_intersections(o3d.core.Tensor.from_numpy(np.take(rays, sel, axis=0)),
                                          nthreads=self.nthreads)
        ray_ids = lx["ray_ids"].numpy().astype(np.int64)
        prim = lx["primitive_ids"].numpy().astype(np.int64)
        t_hit = lx["t_hit"].numpy().astype(np.float64)
        # exit (+t) when the ray leaves through the face (d . n > 0), entry (-t) otherwise
        d_hit = np.asarray(dirs)[sel[ray_ids]].astype(np.float64, copy=False)
        sign = np.sign(np.einsum("ij,ij->i", d_hit, self._pen_normals[prim]))
        w = sign * t_hit
        length_sel = np.bincount(ray_ids, weights=w, minlength=len(sel))
        db_sel = np.bincount(ray_ids, weights=w * self._pen_att[prim], minlength=len(sel))
        return sel, np.maximum(db_sel, 0.0), np.maximum(length_sel, 0.0)

    def occluded(self, origins_m, dirs, tnear_m: float = 0.0, tfar_m: float = np.inf) -> np.ndarray:
        """(K,) bool: does the ray hit an opaque triangle within [tnear, tfar]?"""
        n = max(len(np.asarray(dirs).reshape(-1, 3)), len(np.asarray(origins_m).reshape(-1, 3)))
        if self._opaque is None or n == 0:
            return np.zeros(n, dtype=bool)
        return self._opaque.test_occlusions(self._rays(origins_m, dirs), tnear=tnear_m, tfar=tfar_m,
                                            nthreads=self.nthreads).numpy()

    def touches_penetrable(self, origins_m, dirs, tnear_m: float = 0.0) -> np.ndarray:
        """(K,) bool: does the ray touch a penetrable (foliage) triangle?"""
        n = max(len(np.asarray(dirs).reshape(-1, 3)), len(np.asarray(origins_m).reshape(-1, 3)))
        if self._pen is None or n == 0:
            return np.zeros(n, dtype=bool)
        return self._pen.test_occlusions(self._rays(origins_m, dirs), tnear=tnear_m, nthreads=self.nthreads).numpy()

    def hit_distance(self, origins_m, dirs, tnear_m: float = 0.0) -> np.ndarray:
        """(K,) distance [m] to the first opaque triangle (inf if none); ``dirs`` must be unit vectors."""
        n = max(len(np.asarray(dirs).reshape(-1, 3)), len(np.asarray(origins_m).reshape(-1, 3)))
        if self._opaque is None or n == 0:
            return np.full(n, np.inf)
        t = self._opaque.cast_rays(self._rays(origins_m, dirs), nthreads=self.nthreads)["t_hit"].numpy()
        t = t.astype(np.float64)
        if tnear_m > 0:
            # Open3D cast_rays has no tnear: rays starting on a surface would hit it at t ~ 0
            close = t < tnear_m
            if np.any(close):
                o = np.broadcast_to(np.asarray(origins_m, np.float64).reshape(-1, 3), (n, 3))[close]
                d = np.broadcast_to(np.asarray(dirs, np.float64).reshape(-1, 3), (n, 3))[close]
                t2 = self._opaque.cast_rays(self._rays(o + d * tnear_m, d), nthreads=self.nthreads)["t_hit"]
                t[close] = t2.numpy() + tnear_m
        return t

    def penetration(self, origins_m, dirs) -> tuple[np.ndarray, np.ndarray]:
        """(attenuation_db (K,), path_length_m (K,)) through penetrable volumes along unit rays."""
        o = np.asarray(origins_m, dtype=np.float64).reshape(-1, 3)
        d = np.asarray(dirs, dtype=np.float64).reshape(-1, 3)
        n = max(len(o), len(d))
        db = np.zeros(n)
        length = np.zeros(n)
        if self._pen is None or n == 0:
            return db, length
        o, d = np.broadcast_arrays(o, d)
        sel, db_sel, length_sel = self._penetration(self._rays(o, d).numpy(), d)
        db[sel] = db_sel
        length[sel] = length_sel
        return db, length
