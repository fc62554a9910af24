"""Line-of-sight state of satellites seen from antennas in a scene.

Frames
------
* Antenna positions are in the scene's world frame (the Gazebo world frame,
  metres; ENU at the geodetic origin when ``heading_deg`` = 0).
* Satellite directions / azimuth / elevation are in the *local* ENU frame of
  each antenna (geodetic up at the antenna), as a receiver sees them.  The world
  frame is flat, so away from the origin geodetic up tilts away from world z
  (0.9 deg at 100 km); each direction is rotated
  local ENU -> ECEF -> ENU at the origin -> world (heading) before casting.
  Without a geodetic origin (a bare mesh) world = local ENU everywhere.

States (int8): -1 below the mask (never cast), 0 visible, 1 blocked by an
opaque surface, 2 attenuated by penetrable volumes (foliage), 3 "reflected only"
(set by VisibilityOptions.cast with multipath on, core/multipath/scene_paths.py).

Queries: satellites below ``mask_deg`` are never cast; a scene without
penetrable triangles uses only ``test_occlusions``; the penetrable path is
measured only for rays that are not blocked (a blocked ray reports 0 dB).
Foliage model (``foliage``): "path" (default) measures the path length inside
the penetrable volumes (``list_intersections``, every crossing) and charges
its dB/m; "touch" asks only whether the ray touches foliage at all (one
``test_occlusions``) and charges the fixed ``foliage_touch_db`` (default
constants.FOLIAGE_MEDIAN_LOSS_DB; ``path_in_foliage_m`` is NaN there).

Soft edges (``fresnel_rays`` = K > 0): K extra rays per line of sight, spread
over the first Fresnel zone at the obstacle (a sunflower pattern over the disc
of radius r1 = sqrt(lambda d): angular radius sqrt(lambda / d), satellite at
infinity).  d = the central ray's hit distance when blocked; for a clear ray a
probe ring at ``fresnel_probe_m`` finds the nearest obstacle that reaches into
the Fresnel paraboloid (none: the ray stays fully clear).  The fraction f of
blocked sample rays is read as a straight knife edge cutting the disc (the
circular segment of area fraction f, chord at x r1 from the centre), whence
h = -x r1 and nu = h sqrt(2 / (lambda d)) = -sqrt(2) x, and the loss is
ITU-R P.526-15 eq. (31):  J(nu) = 6.9 + 20 log10(sqrt((nu - 0.1)^2 + 1) + nu - 0.1)
dB for nu > -0.78, else 0.  (f = 0.5 -> 6.0 dB, grazing incidence.)  The
central ray still decides the state; ``diffraction_db`` is reported beside it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import frames
from ..constants import C_MPS, F_L1_HZ, FOLIAGE_MEDIAN_LOSS_DB, WGS84_A_M, WGS84_F
from .raycast import RayScene
from .world_mesh import WorldMesh

STATE_BELOW_MASK = -1
STATE_VISIBLE = 0
STATE_BLOCKED = 1
STATE_ATTENUATED = 2
STATE_REFLECTED_ONLY = 3
STATE_NAMES = {STATE_BELOW_MASK: "below_mask", STATE_VISIBLE: "visible", STATE_BLOCKED: "blocked",
               STATE_ATTENUATED: "attenuated", STATE_REFLECTED_ONLY: "reflected"}

#: GPS L1 wavelength [m] (C_MPS / F_L1_HZ)
L1_WAVELENGTH_M = C_MPS / F_L1_HZ
_RAD_PER_DEG_F32 = np.float32(math.pi / 180.0)
#: up to this many directions (M x N, or the K cast of one antenna) the nine rotation products are one numpy call
#: (fewer calls for the fleet's few rays); above it, three products and two sums per component in place (less
#: memory traffic for the planner's many).  The same float32 numbers either way (test_cast_rows).
FUSED_ROTATION_MAX = 8192


@dataclass
class VisibilityResult:
    """Arrays (M, N) (or (N,) for a single antenna position)."""

    state: np.ndarray             # int8, STATE_*
    attenuation_db: np.ndarray    # penetrable (foliage) loss along the central ray [dB]
    path_in_foliage_m: np.ndarray  # path length inside penetrable volumes [m]
    extra_path_m: np.ndarray      # 0 here; the shortest reflected path's excess after cast_paths (multipath)
    fraction_blocked: np.ndarray  # fraction of the Fresnel disc blocked (0/1 without fresnel_rays)
    diffraction_db: np.ndarray    # knife-edge loss from fraction_blocked (0 without fresnel_rays)
    az_deg: np.ndarray            # local ENU of the antenna
    el_deg: np.ndarray

    def state_names(self) -> np.ndarray:
        return np.vectorize(STATE_NAMES.get, otypes=[object])(self.state)


def knife_edge_loss_db(fraction_blocked):
    """Diffraction loss [dB] from the blocked fraction of the first Fresnel disc (see module docstring)."""
    f = np.clip(np.asarray(fraction_blocked, dtype=np.float64), 0.0, 1.0)
    x = np.linspace(-1.0, 1.0, 4001)
    seg = (np.arccos(x) - x * np.sqrt(1.0 - x * x)) / np.pi    # area fraction beyond the chord, decreasing
    xf = np.interp(f, seg[::-1], x[::-1])
    nu = -math.sqrt(2.0) * xf
    # ITU-R P.526-15 eq. (31)
    j = 6.9 + 20.0 * np.log10(np.sqrt((nu - 0.1) ** 2 + 1.0) + nu - 0.1)
    return np.where(nu > -0.78, j, 0.0)


def _sunflower(k: int):
    """K points spread evenly over the unit disc (Vogel spiral): (rho, phi)."""
    i = np.arange(k)
    rho = np.sqrt((i + 0.5) / k)
    phi = i * math.pi * (3.0 - math.sqrt(5.0))
    return rho, phi


def _perp_basis(d):
    helper = np.where(np.abs(d[:, 2:3]) < 0.9, np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]]))
    u = np.cross(d, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(d, u)
    return u, v


def _enu_rows_at_ecef(ecef):
    """(M, 3, 3): rows east, north, up in ECEF at the WGS 84 geodetic position of ECEF points (M, 3).

    Geodetic latitude by Bowring's formula, one step (B. R. Bowring, Survey Review 23(181), 1976):
    tan(theta) = z a / (p b),  tan(lat) = (z + e'^2 b sin^3 theta) / (p - e^2 a cos^3 theta).  Error below
    1e-9 deg for heights within +-10 km, far below what a direction needs, and vectorised without the
    iteration of a general converter.  The sines and cosines come from the tangent's two terms,
    no angle is formed; on the polar axis (p = 0) longitude 0 is taken.  A few points (<= _FEW_POINTS) on Python
    floats: the same IEEE operations in the same order (no numpy call per operation on a fleet's antennas).
    """
    if len(ecef) <= _FEW_POINTS:
        try:
            terms = []
            for x, y, z in ecef.tolist():
                sl, cl, p = _bowring_terms(x, y, z, math.sqrt)
                terms.append((sl, cl) + ((y / p, x / p) if p > 0 else (0.0, 1.0)))
            return _enu_rows(*zip(*terms)) if terms else np.empty((0, 3, 3))
        except ZeroDivisionError:                   # the Earth's centre: numpy's NaN, as many points get
            pass
    x, y, z = ecef[:, 0], ecef[:, 1], ecef[:, 2]
    sl, cl, p = _bowring_terms(x, y, z, np.sqrt)
    off_axis = p > 0
    so = np.divide(y, p, out=np.zeros_like(p), where=off_axis)
    co = np.divide(x, p, out=np.ones_like(p), where=off_axis)
    return _enu_rows(sl, cl, so, co)


#: up to this many points the ENU rows' arithmetic (_enu_rows_at_ecef, _local_enu_rows) is done on Python floats
_FEW_POINTS = 8


def _bowring_terms(x, y, z, sqrt):
    """(sin lat, cos lat, p) of _enu_rows_at_ecef from ECEF x, y, z (arrays, or floats with math.sqrt)."""
    a = WGS84_A_M
    b = a * (1.0 - WGS84_F)
    e2 = WGS84_F * (2.0 - WGS84_F)
    ep2 = e2 / (1.0 - e2)
    p = sqrt(x * x + y * y)
    za, pb = z * a, p * b
    r = sqrt(za * za + pb * pb)
    s_t, c_t = za / r, pb / r                                   # sin, cos theta
    num = z + ep2 * b * (s_t * s_t * s_t)
    den = p - e2 * a * (c_t * c_t * c_t)
    h = sqrt(num * num + den * den)
    return num / h, den / h, p


def _enu_rows(sl, cl, so, co):
    """(M, 3, 3): rows east, north, up in ECEF from the sines and cosines of latitude and longitude ((M,) arrays,
    or sequences of a few floats: the products on Python floats, the same IEEE operations)."""
    if not isinstance(sl, np.ndarray):
        return np.array([(-so_, co_, 0.0, -sl_ * co_, -sl_ * so_, cl_, cl_ * co_, cl_ * so_, sl_)
                         for sl_, cl_, so_, co_ in zip(sl, cl, so, co)]).reshape(-1, 3, 3)
    rows = np.empty(np.shape(sl) + (3, 3))
    rows[..., 0, 0], rows[..., 0, 1], rows[..., 0, 2] = -so, co, 0.0
    rows[..., 1, 0], rows[..., 1, 1], rows[..., 1, 2] = -sl * co, -sl * so, cl
    rows[..., 2, 0], rows[..., 2, 1], rows[..., 2, 2] = cl * co, cl * so, sl
    return rows


def _local_enu_rows(lat_deg, lon_deg):
    """(M, 3, 3): rows east, north, up in ECEF at each geodetic position."""
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    if sl.ndim == 1 and len(sl) <= _FEW_POINTS:
        sl, cl, so, co = sl.tolist(), cl.tolist(), so.tolist(), co.tolist()
    return _enu_rows(sl, cl, so, co)


def _runs(a):
    """(starts, counts) of the runs of equal consecutive antenna rows (M, 3), or None when no row repeats the one
    before it (the planner's rows repeat each cell's antenna once per time step: the per-antenna work is done once
    per run and repeated; element-wise arithmetic, so each row's numbers are those of its own call)."""
    m = len(a)
    if m < 2:
        return None
    first = np.empty(m, bool)
    first[0] = True
    (a[1:] != a[:-1]).any(axis=1, out=first[1:])
    if first.all():
        return None
    starts = np.flatnonzero(first)
    return starts, np.diff(np.append(starts, m))


def _repeat_runs(x, runs):
    """Per-run rows ``x`` repeated to one per antenna row (as they are when ``runs`` is None)."""
    return x if runs is None else np.repeat(x, runs[1], axis=0)


def _local_enu_rows_at_ecef(rx):
    """(M, 3, 3): rows east, north, up in ECEF at the WGS 84 positions of ECEF points ``rx`` (M, 3)
    (frames.ecef_to_geodetic)."""
    lat, lon, _ = frames.ecef_to_geodetic(rx[:, 0], rx[:, 1], rx[:, 2])
    return _local_enu_rows(np.atleast_1d(lat), np.atleast_1d(lon))


def _check_cast(a, foliage):
    """The checks of a cast's antenna rows (M, 3) and foliage model, before any work."""
    if foliage not in ("path", "touch"):
        raise ValueError(f"visibility: parameter 'foliage' must be 'path' or 'touch', got {foliage!r}")
    if not np.isfinite(a).all():
        raise ValueError("antenna_world_m: non-finite position")


def _world_from_enu_at_ecef(rx, w_t) -> np.ndarray:
    """Scene.world_from_local_enu of antennas at ECEF points ``rx`` (M, 3); ``w_t``: world <- ECEF, transposed."""
    rows = _enu_rows_at_ecef(rx)                                             # enu_A = rows @ ecef
    # R = W @ rows.T with W = world <- ECEF: one (3M, 3) @ (3, 3) product, then a per-antenna transposed view
    return (rows.reshape(-1, 3) @ w_t).reshape(-1, 3, 3).transpose(0, 2, 1)


class _AntennaTerms:
    """Per-antenna terms of a cast, computed when first asked for and kept (read-only): ``rx`` the antennas' ECEF
    (R, 3), ``enu_rows`` their local ENU rows (R, 3, 3) (frames.ecef_to_geodetic), ``world_f32`` world <- local
    ENU as float32 (R, 3, 3) (Scene.world_from_local_enu)."""

    def __init__(self, rx, world_from_ecef_t):
        self.rx, self._w_t = rx, world_from_ecef_t
        rx.setflags(write=False)
        self._enu = self._world = None

    @property
    def enu_rows(self):
        if self._enu is None:
            self._enu = _local_enu_rows_at_ecef(self.rx)
            self._enu.setflags(write=False)
        return self._enu

    @property
    def world_f32(self):
        if self._world is None:
            self._world = _world_from_enu_at_ecef(self.rx, self._w_t).astype(np.float32)
            self._world.setflags(write=False)
        return self._world


def _first_row(res: VisibilityResult) -> VisibilityResult:
    """The result of a single antenna position: each (1, N) array's row (az_deg None stays None)."""
    return VisibilityResult(*(None if x is None else np.asarray(x)[0]
                              for x in (getattr(res, f) for f in res.__dataclass_fields__)))


class Scene:
    """A raycastable scene in the world frame with its geodetic origin and material table."""

    def __init__(self, world: WorldMesh, nthreads: int = 0):
        self.world = world
        self.spherical = world.spherical_coordinates
        att = np.array([np.inf if c.opaque else float(c.attenuation_db_per_m) for c in world.materials.classes])
        per_tri = att[world.material.astype(np.int64)] if len(world.material) else np.zeros(0)
        self.rays = RayScene(world.vertices_m, world.triangles, per_tri, nthreads=nthreads)

    @classmethod
    def load(cls, mesh_path, nthreads: int = 0) -> Scene:
        """From an exported mesh (+ sidecar): see :mod:`.mesh_io`."""
        from .mesh_io import read_scene

        return cls(read_scene(mesh_path), nthreads=nthreads)

    @classmethod
    def from_sdf(cls, sdf_path, materials_yaml=None, use_visuals: bool = False, nthreads: int = 0, *,
                 keep_dynamic: bool = False, strict: bool = False, seed: int = 0) -> Scene:
        """From an SDF world: keyword options as :func:`~.loader.load_sdf_world`."""
        from .loader import load_sdf_world

        return cls(load_sdf_world(Path(sdf_path), materials_yaml=materials_yaml, use_visuals=use_visuals,
                                  keep_dynamic=keep_dynamic, strict=strict, seed=seed), nthreads=nthreads)

    @property
    def has_foliage(self) -> bool:
        return self.rays.has_penetrable

    # ---------------------------------------------------------------- frames
    def world_from_local_enu(self, antenna_world_m) -> np.ndarray:
        """(M, 3, 3) rotations: world vector = R @ (local ENU vector at the antenna)."""
        a = np.asarray(antenna_world_m, dtype=np.float64).reshape(-1, 3)
        if self.spherical is None:
            return np.broadcast_to(np.eye(3), (len(a), 3, 3)).copy()
        return _world_from_enu_at_ecef(self.spherical.world_to_ecef(a), self.spherical.world_from_ecef_t())

    def _local_enu_rows_at(self, antenna_world_m) -> np.ndarray:
        """(M, 3, 3): rows east, north, up in ECEF at the antennas' WGS 84 positions (frames.ecef_to_geodetic)."""
        return _local_enu_rows_at_ecef(self.antenna_ecef(antenna_world_m))

    def antenna_ecef(self, antenna_world_m) -> np.ndarray:
        if self.spherical is None:
            raise ValueError("scene has no geodetic origin (spherical_coordinates): ECEF is undefined")
        return self.spherical.world_to_ecef(antenna_world_m)

    # ---------------------------------------------------------------- visibility
    def visibility(self, antenna_world_m, sat_dirs_enu=None, *, az_deg=None, el_deg=None, mask_deg: float = 0.0,
                   fresnel_rays: int = 0, wavelength_m: float = L1_WAVELENGTH_M, fresnel_probe_m: float = 20.0,
                   tnear_m: float = 1e-3, foliage: str = "path",
                   foliage_touch_db: float = FOLIAGE_MEDIAN_LOSS_DB, azimuth: bool = True) -> VisibilityResult:
        """Line-of-sight state for M antenna positions x N satellites.

        ``antenna_world_m``: (3,) or (M, 3) world frame [m].  Directions as ``sat_dirs_enu`` (N, 3) or
        (M, N, 3) (need not be unit) or ``az_deg``/``el_deg`` (N,) or (M, N), in the local ENU frame of
        each antenna.  Satellites below ``mask_deg`` are not cast (state -1).  ``foliage``: "path" or
        "touch" (module docstring).  ``azimuth`` False: ``az_deg`` of the result is None when the directions are
        given as ``sat_dirs_enu`` (no arctan2 for a caller that reads only the elevations: the planner); the
        states and the rays are the same.
        """
        a = np.asarray(antenna_world_m, dtype=np.float64)
        single = a.ndim == 1
        a = a.reshape(-1, 3)
        _check_cast(a, foliage)
        m = len(a)
        planes = None
        if sat_dirs_enu is not None:
            d = np.asarray(sat_dirs_enu, dtype=np.float64)
            if d.shape[-1] != 3 or d.ndim not in (2, 3):
                raise ValueError(f"sat_dirs_enu: expected (N, 3) or (M, N, 3), got {d.shape}")
            # the three coordinates as contiguous (M, N) planes (what _visibility works on)
            planes = self.rays.scratch("d_enu", (3, m if d.ndim == 2 else len(d), d.shape[-2]), np.float64)
            for k in range(3):
                np.copyto(planes[k], d[..., k])
        res = self._visibility(a, planes, None, az_deg, el_deg, mask_deg, fresnel_rays, wavelength_m,
                               fresnel_probe_m, tnear_m, foliage, foliage_touch_db, azimuth)
        return _first_row(res) if single else res

    def _visibility(self, a, planes, frames_u, az_deg, el_deg, mask_deg, fresnel_rays, wavelength_m,
                    fresnel_probe_m, tnear_m, foliage, foliage_touch_db, azimuth) -> VisibilityResult:
        """visibility() of antenna rows ``a`` (M, 3) and directions either as ``planes`` (3, M, N) float64 (the
        east, north, up coordinates, contiguous) or as ``az_deg``/``el_deg``; ``frames_u``: _frames(a) when the
        caller has them (visibility_ecef), else None."""
        m = len(a)
        scr = self.rays.scratch
        if planes is not None:
            dshape = planes.shape[1:]
            # |d| as np.linalg.norm computes it ((x x + y y) + z z, bit for bit) without its (M, N, 3) temporary
            # (in per-thread scratch arrays: no fresh (M, N) float64 pages on every call)
            sq = np.multiply(planes, planes, out=scr("d_sq", planes.shape, np.float64))
            norm = np.add(sq[0], sq[1], out=scr("d_norm", dshape, np.float64))
            norm += sq[2]
            np.sqrt(norm, out=norm)
            if not norm.all():
                raise ValueError("sat_dirs_enu: zero direction vector")
            # unit directions: all three in float64 (the azimuth, the kept ones of a ragged cast), else up only (the
            # elevation) and east, north straight into float32 (below)
            quick = not azimuth and (m > 1 and self.spherical is not None)
            if quick:
                unit = None
                uz = np.divide(planes[2], norm, out=scr("d_uz", dshape, np.float64))
            else:
                unit = np.divide(planes, norm, out=scr("d_unit", planes.shape, np.float64))
                uz = unit[2]
            if azimuth:
                az = np.arctan2(unit[0], unit[1])
                np.remainder(np.degrees(az, out=az), 360.0, out=az)
            else:
                az = None
            el = np.clip(uz, -1.0, 1.0)
            np.degrees(np.arcsin(el, out=el), out=el)
        else:
            if az_deg is None or el_deg is None:
                raise ValueError("visibility: give sat_dirs_enu or az_deg and el_deg")
            az, el = np.broadcast_arrays(np.asarray(az_deg, np.float64), np.asarray(el_deg, np.float64))
            if az.ndim == 1:
                az, el = np.broadcast_to(az, (m, az.shape[0])), np.broadcast_to(el, (m, el.shape[0]))
        if el.shape[0] != m:
            raise ValueError(f"directions for {el.shape[0]} antenna positions, positions for {m}")
        n = el.shape[1]
        shape = (m, n)
        att_db = np.zeros(shape)
        path = np.zeros(shape)
        diff = np.zeros(shape)
        cast = el >= mask_deg
        all_cast = bool(cast.all())
        # the mask cuts first: directions and rays only for the cast satellites, (M, N) when all are cast,
        # else (K,) in row-major order (flat indices ``flat``, ``per_ant`` of them per antenna); float32
        if all_cast:
            flat = slice(None)
        else:
            flat = cast.reshape(-1).nonzero()[0]
            per_ant = cast.sum(axis=1)
        # float32 work arrays are per-thread scratch (RayScene.scratch): no fresh pages on every call
        dims = shape if all_cast else (len(flat),)
        # many antennas with directions given: rotate all (M, N) directions with (M, 1) coefficients, then keep
        # the cast ones (the same float32 products and sums per ray as rotating only those, without gathering
        # nine coefficients and three directions per ray)
        dense = all_cast or (planes is not None and m > 1 and self.spherical is not None)
        work = shape if dense else dims
        enu_c = scr("enu_c", (3,) + work)               # float32 east, north, up of each (cast) direction
        if planes is not None:
            e_c, n_c, u_c = enu_c
            if quick:                                    # (dense) float32 of the float64 quotient, in one pass
                np.divide(planes[:2], norm, out=enu_c[:2])
                np.copyto(u_c, uz, casting="same_kind")
            else:
                np.copyto(enu_c, unit if dense else unit.reshape(3, -1).take(flat, axis=1), casting="same_kind")
        else:
            az_r, el_r, ce = (scr(name, dims) for name in ("az", "el", "ce"))
            e_c, n_c, u_c = enu_c
            np.copyto(az_r, az if all_cast else az.take(flat), casting="same_kind")
            np.copyto(el_r, el if all_cast else el.take(flat), casting="same_kind")
            # x * float32(pi / 180): the same float32 numbers as np.radians(az, dtype=np.float32), SIMD
            np.multiply(az_r, _RAD_PER_DEG_F32, out=az_r)
            np.multiply(el_r, _RAD_PER_DEG_F32, out=el_r)
            np.cos(el_r, out=ce)
            np.sin(az_r, out=e_c)
            e_c *= ce
            np.cos(az_r, out=n_c)
            n_c *= ce
            np.sin(el_r, out=u_c)
        # rays: origins at the antennas (shifted by the scene centre), directions local ENU -> world (float32)
        if all_cast:
            rays = self.rays.rays_buffer(a, n, scratch=True)
        else:
            rays = self.rays.rays_buffer_ragged(a, per_ant, scratch=True)
        if self.spherical is None:                       # no geodetic origin: world = local ENU everywhere
            rays[..., 3], rays[..., 4], rays[..., 5] = e_c, n_c, u_c
        else:
            runs, terms = frames_u if frames_u is not None else self._frames(a)
            R = _repeat_runs(terms.world_f32, runs)                            # (M, 3, 3) float32
            # R[m, k, j] per ray: (M, 1) broadcast over the satellites, a scalar for one antenna, or repeated
            # per cast satellite (K,)
            if (dense or m == 1) and e_c.size <= FUSED_ROTATION_MAX:
                # few rays: the nine products in one call ((3, 3) x directions), then the two sums per component
                # (the same float32 products and sums, in the same order, as below; fewer calls for a few rays)
                prod = np.multiply(enu_c[None], R.transpose(1, 2, 0)[..., None] if dense else R[0][:, :, None],
                                   out=scr("prod", (3, 3) + work))
                acc3 = np.add(prod[:, 0], prod[:, 1], out=scr("acc3", (3,) + work))
                acc3 += prod[:, 2]
                kept = acc3 if not dense or all_cast else acc3.reshape(3, -1).take(flat, axis=1)
                np.copyto(rays[..., 3:], kept.transpose(tuple(range(1, kept.ndim)) + (0,)))
                coef = None
            elif dense:
                coef = [[R[:, k, j, None] for j in range(3)] for k in range(3)]
            elif m == 1:
                coef = R[0]
            else:
                ant = np.repeat(np.arange(m), per_ant)                        # antenna of each cast ray
                coef = [[np.take(R[:, k, j], ant, mode="clip", out=scr(f"R{k}{j}", dims)) for j in range(3)]
                        for k in range(3)]
            acc, tmp = scr("acc", work), scr("tmp", work)
            for k in range(3 if coef is not None else 0):          # e c0 + n c1 + u c2, in that order, in place
                np.multiply(e_c, coef[k][0], out=acc)
                acc += np.multiply(n_c, coef[k][1], out=tmp)
                acc += np.multiply(u_c, coef[k][2], out=tmp)
                rays[..., 3 + k] = acc if not dense or all_cast else np.take(acc.reshape(-1), flat, mode="clip",
                                                                             out=scr("kept", dims))
        rays = rays.reshape(-1, 6)
        if fresnel_rays > 0:
            o = np.repeat(a, n if all_cast else per_ant, axis=0)
            dw = rays[:, 3:].astype(np.float64)
            t0 = self.rays.hit_distance(o, dw, tnear_m=tnear_m)
            blocked = np.isfinite(t0)
            f = self._fresnel_fraction(o, dw, t0, int(fresnel_rays), float(wavelength_m),
                                       float(fresnel_probe_m), tnear_m)
            frac = np.zeros(shape)
            frac.reshape(-1)[flat] = f
            diff.reshape(-1)[flat] = knife_edge_loss_db(f)
        else:
            blocked = self.rays.occluded_buffer(rays, tnear_m=tnear_m)
            frac = None                                  # from the states, below
        st = blocked.astype(np.int8)                     # STATE_BLOCKED = 1, STATE_VISIBLE = 0
        if self.rays.has_penetrable and len(st):
            # foliage only along the rays that are not blocked: a contiguous float32 copy of those
            clear = np.flatnonzero(~blocked)
            # (mode="clip": the indices are valid, and np.take buffers ``out`` in the default mode)
            r_clear = rays if len(clear) == len(rays) else np.take(rays, clear, axis=0, mode="clip",
                                                                   out=scr("clear", (len(clear), 6)))
            idx = clear if all_cast else flat[clear]
            if foliage == "touch":
                touched = self.rays.touches_penetrable_buffer(r_clear)
                att_db.reshape(-1)[idx[touched]] = float(foliage_touch_db)
                path.reshape(-1)[idx[touched]] = np.nan
                st[clear[touched]] = STATE_ATTENUATED
            else:
                sel, db, ln = self.rays.penetration_buffer(r_clear)            # only the rays touching foliage
                att_db.reshape(-1)[idx[sel]] = db
                path.reshape(-1)[idx[sel]] = ln
                st[clear[sel[ln > 0]]] = STATE_ATTENUATED
        if all_cast:
            state = st.reshape(shape)
        else:
            state = np.full(shape, STATE_BELOW_MASK, dtype=np.int8)
            state.reshape(-1)[flat] = st
        if frac is None:                                 # 1 where the central ray is blocked, else 0 (below the mask)
            frac = np.equal(state, STATE_BLOCKED).astype(np.float64)
        return VisibilityResult(state, att_db, path, np.zeros(shape), frac, diff, az, el)

    def _frames(self, a):
        """(runs of equal antenna rows or None, per-run antenna terms): the per-antenna work, done once per run
        (see _AntennaTerms)."""
        runs = _runs(a)
        return runs, self._antenna_terms(a if runs is None else a[runs[0]])

    def _antenna_terms(self, a_u) -> _AntennaTerms:
        """_AntennaTerms of antenna positions ``a_u`` (R, 3), those of the previous call when its positions and the
        geodetic origin are the same bytes (the planner casts the same cells in every time window, a static
        antenna stands at the same place every epoch)."""
        key = (a_u.tobytes(), a_u.shape, self.spherical.latitude_deg, self.spherical.longitude_deg,
               self.spherical.elevation_m, self.spherical.heading_deg)
        last = self.__dict__.get("_terms")
        if last is None or last[0] != key:
            last = self.__dict__["_terms"] = (key, _AntennaTerms(self.spherical.world_to_ecef(a_u),
                                                                    self.spherical.world_from_ecef_t()))
        return last[1]

    def _fresnel_fraction(self, o, d, t0, k, lam, probe_m, tnear_m):
        rho, phi = _sunflower(k)
        u, v = _perp_basis(d)
        c, s = np.cos(phi)[None, :, None], np.sin(phi)[None, :, None]
        off = rho[None, :, None] * (c * u[:, None, :] + s * v[:, None, :])
        dref = np.where(np.isfinite(t0), np.maximum(t0, tnear_m), np.inf)
        clear = ~np.isfinite(t0)
        if np.any(clear):
            psi = math.sqrt(lam / probe_m)
            dirs = d[clear][:, None, :] + psi * off[clear]
            dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
            oc = np.repeat(o[clear], k, axis=0)
            th = self.rays.hit_distance(oc, dirs.reshape(-1, 3), tnear_m=tnear_m).reshape(-1, k)
            with np.errstate(invalid="ignore"):
                inside = (rho[None, :] * psi * th) <= np.sqrt(lam * th)     # hit inside the Fresnel paraboloid
            dref[clear] = np.where(inside, th, np.inf).min(axis=1)
        frac = np.zeros(len(d))
        has = np.isfinite(dref)
        if np.any(has):
            psi = np.sqrt(lam / dref[has])[:, None, None]
            dirs = d[has][:, None, :] + psi * off[has]
            dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
            occ = self.rays.occluded(np.repeat(o[has], k, axis=0), dirs.reshape(-1, 3), tnear_m=tnear_m)
            frac[has] = occ.reshape(-1, k).mean(axis=1)
        return frac

    def visibility_ecef(self, antenna_world_m, sat_ecef_m, *, mask_deg: float = 0.0, fresnel_rays: int = 0,
                        wavelength_m: float = L1_WAVELENGTH_M, fresnel_probe_m: float = 20.0, tnear_m: float = 1e-3,
                        foliage: str = "path", foliage_touch_db: float = FOLIAGE_MEDIAN_LOSS_DB,
                        azimuth: bool = True) -> VisibilityResult:
        """Visibility from satellite ECEF positions (N, 3) or (M, N, 3); az/el in the antenna's local ENU
        (keywords as :meth:`visibility`)."""
        a = np.asarray(antenna_world_m, dtype=np.float64)
        single = a.ndim == 1
        a2 = a.reshape(-1, 3)
        _check_cast(a2, foliage)
        m = len(a2)
        if self.spherical is None:
            self.antenna_ecef(a2)                        # its error: no geodetic origin
        sat = np.asarray(sat_ecef_m, dtype=np.float64)
        if sat.shape[-1:] != (3,) or not (sat.ndim == 2 or (sat.ndim == 3 and len(sat) == m)):
            raise ValueError(f"sat_ecef_m: expected (N, 3) or (M, N, 3) with M = {m} antenna positions, "
                             f"got {sat.shape}")
        # the per-antenna work once per run of equal rows: the antenna's ECEF and its ENU rows
        runs, terms = frames_u = self._frames(a2)
        rows_u = terms.enu_rows
        rx = _repeat_runs(terms.rx, runs)
        # (3, M, N): the ECEF differences and their ENU coordinates as contiguous planes, in per-thread scratch
        # arrays (_visibility copies what it keeps)
        n = sat.shape[-2]
        scr = self.rays.scratch
        d_ecef = scr("d_ecef", (3, m, n), np.float64)
        np.subtract(sat.T[:, None, :] if sat.ndim == 2 else sat.transpose(2, 0, 1), rx.T[:, :, None], out=d_ecef)
        # rows @ d per antenna, as (3, 3) @ (3, N) products (BLAS; each element the same sum of products as
        # d @ rows.T's); one product per run when the runs are equally long (their rows' columns side by side)
        if runs is not None and (runs[1] == runs[1][0]).all():
            groups, rows_g = len(runs[0]), rows_u
        else:
            groups, rows_g = m, _repeat_runs(rows_u, runs)
        d_enu = scr("d_enu", (3, m, n), np.float64)
        g_shape = (3, groups, (m // groups) * n) if groups else (3, 0, 0)
        np.matmul(rows_g, d_ecef.reshape(g_shape).transpose(1, 0, 2), out=d_enu.reshape(g_shape).transpose(1, 0, 2))
        res = self._visibility(a2, d_enu, frames_u, None, None, mask_deg, fresnel_rays, wavelength_m,
                               fresnel_probe_m, tnear_m, foliage, foliage_touch_db, azimuth)
        return _first_row(res) if single else res

    # ---------------------------------------------------------------- skyline
    def sky_grid(self, antenna_world_m, az_step_deg: float = 2.0, el_step_deg: float = 1.0, tnear_m: float = 1e-3):
        """What the casts find over the whole sky: one ray per cell centre of an azimuth x elevation grid.

        Returns (az_edges_deg (A+1,), el_edges_deg (E+1,), opaque (A, E) bool, foliage (A, E) bool) in the
        antenna's local ENU; ``foliage`` is set where the ray is not blocked but crosses a penetrable
        volume.  Unlike :meth:`horizon_profile` (the highest blocked elevation per azimuth), the grid keeps
        open sky under an overhang (a gap under a beam or a gantry) open."""
        if not (az_step_deg > 0 and el_step_deg > 0):
            raise ValueError(f"sky_grid: az_step_deg and el_step_deg must be > 0, got {az_step_deg}, {el_step_deg}")
        a = np.asarray(antenna_world_m, dtype=np.float64).reshape(3)
        az_e = np.arange(0.0, 360.0 + 1e-9, az_step_deg)
        el_e = np.arange(0.0, 90.0 + 1e-9, el_step_deg)
        if el_e[-1] < 90.0:
            el_e = np.append(el_e, 90.0)
        A, E = np.meshgrid(0.5 * (az_e[:-1] + az_e[1:]), 0.5 * (el_e[:-1] + el_e[1:]), indexing="ij")
        R = self.world_from_local_enu(a)[0]
        dw = (frames.enu_unit_from_az_el(A, E) @ R.T).reshape(-1, 3)
        opaque = self.rays.occluded(a, dw, tnear_m=tnear_m).reshape(A.shape)
        foliage = np.zeros_like(opaque)
        if self.has_foliage:
            foliage = self.rays.touches_penetrable(a, dw, tnear_m=tnear_m).reshape(A.shape) & ~opaque
        return az_e, el_e, opaque, foliage

    def horizon_profile(self, antenna_world_m, az_step_deg: float = 1.0, which: str = "opaque",
                        iterations: int = 14, tnear_m: float = 1e-3):
        """Skyline elevation [deg] at each azimuth (local ENU of the antenna).

        ``which``: "opaque" or "foliage" (penetrable volumes).  The skyline is the highest blocked
        elevation in [0, 90] (0 when nothing is above the horizon), found on a 1-degree sweep then
        refined by bisection (``iterations`` halvings: 1/2^14 deg).  Returns (az_deg, el_deg).
        """
        if which not in ("opaque", "foliage"):
            raise ValueError(f"horizon_profile: which must be 'opaque' or 'foliage', got {which!r}")
        if not az_step_deg > 0:
            raise ValueError(f"horizon_profile: az_step_deg must be > 0, got {az_step_deg}")
        a = np.asarray(antenna_world_m, dtype=np.float64).reshape(3)
        R = self.world_from_local_enu(a)[0]
        az = np.arange(0.0, 360.0, az_step_deg)
        els = np.arange(0.0, 91.0, 1.0)
        test = self.rays.occluded if which == "opaque" else self.rays.touches_penetrable

        def hit(az_, el_):
            dw = frames.enu_unit_from_az_el(az_, el_) @ R.T
            return test(a, dw.reshape(-1, 3), tnear_m=tnear_m).reshape(np.shape(az_))

        A, E = np.meshgrid(az, els, indexing="ij")
        blocked = hit(A, E)
        any_b = blocked.any(axis=1)
        top = np.where(any_b, len(els) - 1 - np.argmax(blocked[:, ::-1], axis=1), -1)
        lo = np.where(top >= 0, els[np.clip(top, 0, None)], 0.0)
        hi = np.minimum(lo + 1.0, 90.0)
        out = np.where(any_b, lo, 0.0)
        ref = any_b & (top < len(els) - 1)
        lo, hi = lo[ref], hi[ref]
        for _ in range(iterations if ref.any() else 0):     # nothing to refine: every azimuth clear or closed
            mid = 0.5 * (lo + hi)
            b = hit(az[ref], mid)
            lo = np.where(b, mid, lo)
            hi = np.where(b, hi, mid)
        out[ref] = 0.5 * (lo + hi)
        return az, out
