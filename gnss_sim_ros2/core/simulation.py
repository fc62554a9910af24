"""The offline simulation loop: what `gnss-sim simulate`, the benchmarks and the tests share.

Per epoch (GPS time tag t on the grid start + k * interval):
antenna position (static, or along a path) -> satellite states at t ->
visibility from the scene (if any) -> receiver observables -> position fix ->
RINEX epoch (written and handed to the OS at once) and a fix.csv row.

Offline the whole trajectory is known in advance, so the first three steps run
for ``SimulationSetup.batch_epochs`` epochs at once: one ephemeris evaluation
(``states_at``) for every satellite and epoch of the block, one
azimuth/elevation computation and one Open3D query for all rays of the block.
Satellites more than 1 degree below the horizon never reach the receiver (it
drops everything below 0 degrees itself); only the systems simulated are
evaluated; the ephemeris is loaded for the simulated span only (provider.py).
The results equal the epoch-by-epoch chain (test_simulation_batch.py).

Model switches come from the preset (core/presets.py) with
``SimulationSetup.switches`` overriding single ones.
"""
from __future__ import annotations

import csv
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .ephemeris.precise_broadcast import PreciseWithBroadcastGroupDelay
from .ephemeris.provider import open_ephemeris
from .ephemeris.states import SatelliteStates
from .frames import az_el_from_ecef, geodetic_to_ecef
from .presets import preset as preset_switches
from .receiver.engine import ATTENUATED, BLOCKED, VISIBLE, Receiver, ReceiverConfig
from .receiver.outputs import epoch_arrays, header, obs_types_for, position_fix, rinex_name, write_navigation
from .rinex.obs_write import RinexObsWriter
from .time import GnssTime
from .trajectory import Trajectory


@dataclass
class SimulationSetup:
    start: GnssTime
    duration_s: float
    interval_s: float
    out_dir: Path
    trajectory: Trajectory
    systems: str = "GRECJI"
    elevation_mask_deg: float = 10.0
    source: str = "synthetic"
    nav_files: list = field(default_factory=list)
    sp3_files: list = field(default_factory=list)
    clk_files: list = field(default_factory=list)
    world_file: str = ""
    mesh_file: str = ""
    materials_file: str = ""
    preset: str = "balanced"
    fresnel_rays: int = -1
    receiver: dict = field(default_factory=dict)   # ReceiverConfig overrides
    marker_name: str = "GSIM"
    seed: int = 1
    progress: bool = False
    #: preset switch overrides (core/presets.SWITCHES), e.g. {"foliage": "touch"}
    switches: dict = field(default_factory=dict)
    #: epochs whose states, elevations and raycasts are computed in one block (1: epoch by epoch)
    batch_epochs: int = 300
    #: drop scene triangles that cannot block a ray above the mask from the trajectory (crop_world_mesh)
    crop_scene: bool = False
    #: called after every epoch as observer(t, true_ecef_m, obs, sol) (benchmarks, tests)
    observer: object = None
    #: already loaded scene (core.scene.visibility.Scene) to use instead of world_file/mesh_file
    scene: object = None
    #: already opened ephemerides by source name: {"broadcast": (provider, nav_paths), "sp3": ...};
    #: used instead of opening the files again (benchmarks running one scenario many times)
    ephemeris: dict = field(default_factory=dict)


@dataclass
class SimulationResult:
    obs_path: Path
    nav_path: Path | None
    fix_path: Path
    epochs: int
    fixes: int
    tracked_per_epoch: list
    visible_per_epoch: list
    blocked_per_epoch: list
    attenuated_per_epoch: list
    horizontal_error_m: list
    wall_s: float
    sim_s: float
    setup_s: float = 0.0          # scene, ephemeris and files before the first epoch [s]
    cpu_s: float = 0.0            # CPU time of this process (all its threads) during the epoch loop [s]
    interval_s: float = 0.0
    orbit_source: str = ""

    @property
    def realtime_factor(self) -> float:
        return self.sim_s / self.wall_s if self.wall_s > 0 else float("inf")


def load_scene(world_file: str = "", mesh_file: str = "", materials_file: str = ""):
    """The raycasting scene from an exported mesh or an SDF world (None when neither is given)."""
    if not world_file and not mesh_file:
        return None
    from .scene.visibility import Scene

    if mesh_file:
        return Scene.load(mesh_file)
    return Scene.from_sdf(world_file, materials_yaml=materials_file or None)


def crop_world_mesh(world, antenna_world_m, mask_deg: float, margin_deg: float = 0.0):
    """The triangles of ``world`` (a WorldMesh) that may block a ray at or above the mask.

    A ray from an antenna p at elevation >= m rises tan(m) per metre of
    horizontal distance, so a triangle whose highest vertex z_t and nearest
    horizontal distance d to the bounding box of the antenna positions satisfy
    z_t - z_min < tan(m) d can never block it (conservative: the whole box
    against the triangle's bounding box).  ``m`` = ``mask_deg - margin_deg``
    (margin for the tilt of geodetic up across the world and for Fresnel rays).
    Returns (cropped WorldMesh, number of triangles dropped).
    """
    import dataclasses

    a = np.asarray(antenna_world_m, dtype=np.float64).reshape(-1, 3)
    m_deg = max(float(mask_deg) - float(margin_deg), 0.0)
    tri = world.vertices_m[world.triangles]                       # (T, 3, 3)
    lo, hi = tri.min(axis=1), tri.max(axis=1)
    bmin, bmax = a.min(axis=0), a.max(axis=0)
    dx = np.maximum(0.0, np.maximum(lo[:, 0] - bmax[0], bmin[0] - hi[:, 0]))
    dy = np.maximum(0.0, np.maximum(lo[:, 1] - bmax[1], bmin[1] - hi[:, 1]))
    keep = hi[:, 2] - bmin[2] >= np.tan(np.radians(m_deg)) * np.hypot(dx, dy)
    parts = []
    out = dataclasses.replace(world, triangles=world.triangles[keep], material=world.material[keep], parts=parts)
    return out, int((~keep).sum())


class AntennaPath:
    """Antenna positions along a trajectory in ECEF and (with a scene) in the world frame."""

    def __init__(self, trajectory: Trajectory, scene=None):
        self.tr = trajectory
        self.scene = scene
        if trajectory.frame == "world" and (scene is None or scene.spherical is None):
            raise ValueError("a path in world coordinates (t_s,e_m,n_m,u_m) needs a georeferenced scene "
                             "(--world with spherical_coordinates, or --mesh)")
        if trajectory.frame != "world" and scene is not None and scene.spherical is None:
            raise ValueError("the scene has no spherical_coordinates: cannot place a geodetic/ECEF path in it")

    def at(self, t_s: float):
        """(ecef (3,), world (3,) or None)."""
        p = self.tr.position(t_s)
        if self.tr.frame == "world":
            return self.scene.antenna_ecef(p), p
        if self.tr.frame == "geodetic":
            ecef = np.array(geodetic_to_ecef(*p))
        else:
            ecef = p
        world = self.scene.spherical.ecef_to_world(ecef) if self.scene is not None else None
        return ecef, world

    def at_many(self, t_s):
        """(ecef (K, 3), world (K, 3) or None) at the times ``t_s`` (K,)."""
        p = np.asarray(self.tr.position(np.asarray(t_s, dtype=float)), dtype=float).reshape(-1, 3)
        if self.tr.frame == "world":
            return self.scene.antenna_ecef(p), p
        if self.tr.frame == "geodetic":
            ecef = np.stack(geodetic_to_ecef(p[:, 0], p[:, 1], p[:, 2]), axis=-1)
        else:
            ecef = p
        world = self.scene.spherical.ecef_to_world(ecef) if self.scene is not None else None
        return ecef, world


def switches(setup: SimulationSetup) -> dict:
    """The preset's switches with the setup's overrides."""
    return preset_switches(setup.preset, setup.switches)


def orbit_source(setup: SimulationSetup, sw: dict | None = None) -> str:
    """The ephemeris source after the ``orbit`` switch: "precise" takes SP3 when sp3_files are given,
    "broadcast" takes the navigation files when they are given."""
    sw = sw or switches(setup)
    if sw["orbit"] == "precise" and setup.sp3_files and setup.source in ("broadcast", "sp3"):
        return "sp3"
    if sw["orbit"] == "broadcast" and setup.source == "sp3" and setup.nav_files:
        return "broadcast"
    return setup.source


def receiver_config(setup: SimulationSetup) -> ReceiverConfig:
    sw = switches(setup)
    kw = {"systems": setup.systems, "elevation_mask_deg": setup.elevation_mask_deg, "seed": setup.seed,
          "transmit_time": sw["transmit_time"], "light_time_iterations": sw["light_time_iterations"],
          "ionosphere": sw["ionosphere"], "troposphere": sw["troposphere"], "noise": sw["noise"]}
    kw.update({k: v for k, v in setup.receiver.items() if v is not None and v != ""})
    return ReceiverConfig(**kw)


def run_simulation(setup: SimulationSetup) -> SimulationResult:
    t_setup0 = time.perf_counter()
    sw = switches(setup)
    interval_s = float(setup.interval_s) if setup.interval_s > 0 else float(sw["epoch_interval_s"])
    if not np.isfinite(interval_s):
        raise ValueError(f"interval_s = {setup.interval_s!r}: must be a finite number of seconds")
    if int(setup.batch_epochs) < 1:
        raise ValueError(f"batch_epochs = {setup.batch_epochs!r}: must be >= 1")
    out = Path(setup.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    for old in list(out.glob("*_MO.rnx")) + list(out.glob("*_MN.rnx")):
        old.unlink()  # exactly one observation and one navigation file per run
    n_epochs = int(np.floor(setup.duration_s / interval_s + 1e-9)) + 1
    scene = setup.scene if setup.scene is not None else load_scene(setup.world_file, setup.mesh_file,
                                                                   setup.materials_file)
    path = AntennaPath(setup.trajectory, scene)
    fresnel = setup.fresnel_rays if setup.fresnel_rays >= 0 else sw["fresnel_rays"]
    if scene is not None and setup.crop_scene:
        scene = _cropped_scene(scene, path, n_epochs, interval_s, setup.elevation_mask_deg, fresnel)
        path = AntennaPath(setup.trajectory, scene)

    source = orbit_source(setup, sw)
    if source in setup.ephemeris:
        provider, nav_paths = setup.ephemeris[source]
    else:
        provider, nav_paths = open_ephemeris(source, setup.start, setup.duration_s, setup.systems, setup.nav_files,
                                             setup.sp3_files, setup.clk_files, workdir=out / ".ephemeris")
    if (source == "sp3" and not isinstance(provider, PreciseWithBroadcastGroupDelay)
            and (setup.nav_files or "broadcast" in setup.ephemeris)):
        brdc, brdc_paths = setup.ephemeris.get("broadcast") or open_ephemeris(
            "broadcast", setup.start, setup.duration_s, setup.systems, setup.nav_files)
        provider, nav_paths = PreciseWithBroadcastGroupDelay(provider, brdc, setup.start, setup.duration_s), brdc_paths
    cfg = receiver_config(setup)
    if source == "sp3" and "sisre_m" not in setup.receiver:
        # observations from precise orbits are the truth: the broadcast message's own error is then real
        # (what a receiver using the navigation file sees), so no synthetic SISRE is drawn on top
        cfg.sisre_m = {s: 0.0 for s in cfg.sisre_m}
    rx = Receiver(cfg, provider, getattr(provider, "iono", None))

    ecef0, _ = path.at(0.0)
    obs_types = obs_types_for(cfg.profile, setup.systems)
    obs_path = out / rinex_name(setup.marker_name, setup.start, setup.duration_s, interval_s, "MO")
    nav_path = out / rinex_name(setup.marker_name, setup.start, setup.duration_s, interval_s, "MN")
    nav_written = write_navigation(nav_path, provider, setup.systems)
    if nav_written is None and nav_paths:
        shutil.copyfile(nav_paths[0], nav_path)
        nav_written = nav_path
    glo_slots = {}
    st0 = provider.states(setup.start, systems=setup.systems)
    for sv, ch in zip(st0.sv, st0.glo_channel):
        if sv[0] == "R":
            glo_slots[str(sv)] = int(ch)
    hdr = header(obs_types, setup.marker_name, ecef0, interval_s, glo_slots,
                 comments=[f"gnss_sim simulate, preset {setup.preset}, source {source}",
                           f"seed {setup.seed}; noise {'on' if cfg.noise else 'off'}"])
    fix_path = out / "fix.csv"
    res = SimulationResult(obs_path, nav_written, fix_path, 0, 0, [], [], [], [], [], 0.0, 0.0,
                           interval_s=interval_s, orbit_source=source)
    svs_all = np.asarray(provider.svs(setup.systems), dtype="<U3")
    digits = 3 if interval_s < 1 else 0
    fix_est, fix_true = [], []
    wall0 = time.perf_counter()
    cpu0 = time.process_time()
    res.setup_s = wall0 - t_setup0
    prior = None
    with RinexObsWriter(obs_path, hdr) as writer, open(fix_path, "w", newline="") as fcsv:
        w = csv.writer(fcsv)
        w.writerow(["time", "lat_deg", "lon_deg", "h_m", "n_sats", "status"])
        for i0 in range(0, n_epochs, int(setup.batch_epochs)):
            t_rel = np.arange(i0, min(i0 + int(setup.batch_epochs), n_epochs)) * interval_s
            block = _EpochBlock(setup, provider, svs_all, path, scene, t_rel, interval_s, fresnel, sw["foliage"])
            for b in range(len(t_rel)):
                i = i0 + b
                t, ecef, states, vis_state, att = block.epoch(b)
                obs = rx.epoch(t, ecef, states, vis_state, att)
                sol = position_fix(obs, cfg.profile, prior)
                stamp = t.isoformat(digits=digits)
                if sol.is_fix:
                    prior = sol.pos_ecef_m
                    res.fixes += 1
                    fix_est.append(sol.pos_ecef_m)
                    fix_true.append(ecef)
                    w.writerow([stamp, f"{sol.lat_deg:.9f}", f"{sol.lon_deg:.9f}", f"{sol.h_m:.4f}", sol.n_used,
                                "fix"])
                else:
                    w.writerow([stamp, "", "", "", sol.n_used, "no_fix"])
                if len(obs.sv):
                    writer.write_epoch(t, epoch_arrays(obs, obs_types))
                if setup.observer is not None:
                    setup.observer(t, ecef, obs, sol)
                res.epochs += 1
                above = obs.sat_el_deg >= setup.elevation_mask_deg
                res.tracked_per_epoch.append(obs.n_tracked_sats)
                res.visible_per_epoch.append(int(np.sum(above & (obs.sat_vis_state == VISIBLE))))
                res.blocked_per_epoch.append(int(np.sum(above & (obs.sat_vis_state == BLOCKED))))
                res.attenuated_per_epoch.append(int(np.sum(above & (obs.sat_vis_state == ATTENUATED))))
                if setup.progress and (i % max(1, n_epochs // 20) == 0 or i == n_epochs - 1):
                    el = time.perf_counter() - wall0
                    print(f"\r[simulate] epoch {i + 1}/{n_epochs}  {obs.n_tracked_sats} sats tracked  "
                          f"{(t_rel[b] + interval_s) / max(el, 1e-9):.0f}x real time", end="", file=sys.stderr,
                          flush=True)
    if setup.progress:
        print(file=sys.stderr)
    if fix_est:
        res.horizontal_error_m = horizontal_errors_m(np.array(fix_est), np.array(fix_true)).tolist()
    res.wall_s = time.perf_counter() - wall0
    res.cpu_s = time.process_time() - cpu0
    res.sim_s = n_epochs * interval_s
    shutil.rmtree(out / ".ephemeris", ignore_errors=True)
    return res


class _EpochBlock:
    """Satellite states, elevations and visibility of a block of epochs, computed at once."""

    def __init__(self, setup, provider, svs_all, path, scene, t_rel, interval_s, fresnel, foliage):
        k, n = len(t_rel), len(svs_all)
        self.t = setup.start + t_rel                                   # GnssTime (K,)
        self.ecef, world = path.at_many(t_rel)
        self.k = k
        if n == 0:
            self.states = None
            return
        t_rows = GnssTime(np.repeat(np.atleast_1d(self.t.sec), n), np.repeat(np.atleast_1d(self.t.frac), n))
        st = provider.states_at(np.tile(svs_all, k), t_rows)
        # rows keep the input order (epoch-major) and drop satellites without a valid record: locate them
        kk = np.rint((st.t - self.t[0]) / interval_s).astype(np.int64) if len(st) else np.zeros(0, np.int64)
        order = np.argsort(svs_all)
        jj = order[np.searchsorted(svs_all[order], np.asarray(st.sv))] if len(st) else np.zeros(0, np.int64)
        row = np.full((k, n), -1, dtype=np.int64)
        row[kk, jj] = np.arange(len(st))
        sat = np.zeros((k, n, 3))                                      # missing: Earth centre (el = -90)
        sat[kk, jj] = st.pos_ecef_m
        _, el, _ = az_el_from_ecef(self.ecef[:, None, :], sat)
        # the receiver drops satellites below 0 deg itself (exact cut); 1 deg margin here
        self.use = (row >= 0) & (el > -1.0)
        self.row, self.states = row, st
        self.vis = self.att = None
        if scene is not None:
            v = scene.visibility_ecef(world, sat, mask_deg=setup.elevation_mask_deg, fresnel_rays=fresnel,
                                      foliage=foliage)
            self.vis = np.where(v.state < 0, VISIBLE, v.state)
            self.att = v.attenuation_db + v.diffraction_db

    def epoch(self, b: int):
        """(t, antenna ECEF, SatelliteStates, visibility state or None, attenuation or None) of epoch b."""
        t = self.t[b]
        if self.states is None:
            return t, self.ecef[b], SatelliteStates.empty(t, "none"), None, None
        cols = np.flatnonzero(self.use[b])
        st = self.states.select(self.row[b, cols])
        st.t = t
        if self.vis is None:
            return t, self.ecef[b], st, None, None
        return t, self.ecef[b], st, self.vis[b, cols], self.att[b, cols]


def _cropped_scene(scene, path, n_epochs, interval_s, mask_deg, fresnel):
    from .scene.visibility import Scene

    t_rel = np.arange(n_epochs) * interval_s
    if len(t_rel) > 100_000:       # the bounding box only needs the path's vertices and ends
        t_rel = np.unique(np.concatenate([t_rel[:: max(1, len(t_rel) // 100_000)], t_rel[-1:]]))
    _, world = path.at_many(t_rel)
    tr = path.tr
    if tr.frame == "world":        # every vertex of the path inside the run's time span
        inside = (tr.t_s >= 0) & (tr.t_s <= t_rel[-1])
        world = np.vstack([world, tr.pos[inside]]) if not tr.loop else np.vstack([world, tr.pos])
    # margin: tilt of geodetic up across the path (1 deg per 111 km) + Fresnel sample rays (6 deg)
    span_m = float(np.max(np.linalg.norm(world[:, :2], axis=1))) if len(world) else 0.0
    margin = np.degrees(span_m / 6.371e6) + 0.1 + (6.0 if fresnel > 0 else 0.0)
    cropped, _ = crop_world_mesh(scene.world, world, mask_deg, margin)
    return Scene(cropped, nthreads=scene.rays.nthreads)


def horizontal_errors_m(est_ecef_m, true_ecef_m) -> np.ndarray:
    """Horizontal distance [m] of estimates (K, 3) from true positions (K, 3), in the local ENU of the truth."""
    from .frames import ecef_to_geodetic

    est = np.asarray(est_ecef_m, dtype=np.float64).reshape(-1, 3)
    true = np.asarray(true_ecef_m, dtype=np.float64).reshape(-1, 3)
    lat, lon, _ = ecef_to_geodetic(true[:, 0], true[:, 1], true[:, 2])
    la, lo = np.radians(lat), np.radians(lon)
    d = est - true
    e = -np.sin(lo) * d[:, 0] + np.cos(lo) * d[:, 1]
    n = -np.sin(la) * np.cos(lo) * d[:, 0] - np.sin(la) * np.sin(lo) * d[:, 1] + np.cos(la) * d[:, 2]
    return np.hypot(e, n)


def _horizontal_error(est_ecef, true_ecef) -> float:
    from .frames import ecef_to_enu, ecef_to_geodetic

    lat, lon, h = ecef_to_geodetic(*true_ecef)
    d = ecef_to_enu(est_ecef, lat, lon, h)
    return float(np.hypot(d[0], d[1]))
