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

The run holds the nodes' parameters (``SimulationSetup.receiver_params``,
``visibility_params``, ``ephemeris_params``: every parameter of the table, as
``config_file.load_config`` gives them to the nodes), and the chain and the
visibility options are built from them as the nodes build them
(``ChainSettings.from_params``, ``VisibilityOptions.from_params``;
test_parameter_path.py).  Model switches come from the preset (core/presets.py)
with ``SimulationSetup.switches`` overriding single ones.
"""
from __future__ import annotations

import dataclasses
import logging
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .ephemeris.coverage import check_coverage
from .ephemeris.precise_broadcast import PreciseWithBroadcastGroupDelay
from .ephemeris.provider import open_ephemeris
from .ephemeris.states import SatelliteStates
from .frames import az_el_from_ecef, check_receiver_position, geodetic_to_ecef
from .metrics import horizontal_errors_m
from .presets import preset as preset_switches
from .receiver.chain import ChainSettings, ReceiverChain
from .receiver.engine import ATTENUATED, BLOCKED, VISIBLE
from .receiver.outputs import rinex_name, write_navigation
from .scene.world_mesh import world_bounds_xy
from .time import GnssTime
from .trajectory import Trajectory
from .visibility import VisibilityOptions, load_scene
from .visibility.moving_obstacles import boxes_along_paths, paths_far_from_world
from .visibility.world_offset import is_zero, offset_note, shifted_scene


@dataclass
class SimulationSetup:
    """One offline run: the nodes' parameters (what a node would get from the same configuration) and what is
    specific to running it here (span, output folder, path, block size, observer, caches)."""

    start: GnssTime
    duration_s: float
    #: epoch interval [s]; <= 0: the preset's epoch_interval_s
    interval_s: float
    out_dir: Path
    trajectory: Trajectory
    #: the receiver node's parameters, every one (shared ones included: ``config_file.load_config(...).node
    #: ("receiver")``): ChainSettings.from_params builds the chain from them as the node does, with output_dir
    #: the run's folder and the epoch interval above
    receiver_params: dict
    #: the visibility node's parameters, every one: the scene files and VisibilityOptions.from_params
    visibility_params: dict
    #: the ephemeris node's parameters, every one: source, nav_files, sp3_files, clk_files
    ephemeris_params: dict
    #: RTCM3 file written next to the RINEX (None: none; "": the RINEX observation name with .rtcm3)
    rtcm_path: str | None = None
    #: with broadcast ephemeris messages (1019-1046) from the navigation records
    rtcm_ephemeris: bool = True
    #: ReceiverConfig overrides (benchmarks, tests), set after the parameters
    receiver_overrides: dict = field(default_factory=dict)
    progress: bool = False
    #: preset switch overrides (core/presets.SWITCHES), e.g. {"foliage": "touch"}
    switches: dict = field(default_factory=dict)
    #: epochs whose states, elevations and raycasts are computed in one block (1: epoch by epoch)
    batch_epochs: int = 300
    #: the observables of a block computed together (ReceiverChain.step_block); False: epoch by epoch
    #: (ReceiverChain.step, what a node does); the same results (test_simulation_batch.py)
    batch_observables: bool = True
    #: drop scene triangles that cannot block a ray above the mask from the trajectory (crop_world_mesh)
    crop_scene: bool = False
    #: called after every epoch as observer(t, true_ecef_m, obs, sol) (benchmarks, tests)
    observer: object = None
    #: already loaded scene (core.scene.visibility.Scene) to use instead of world_file/mesh_file
    scene: object = None
    #: already opened ephemerides by source name: {"broadcast": (provider, nav_paths), "sp3": ...};
    #: used instead of opening the files again (benchmarks running one scenario many times)
    ephemeris: dict = field(default_factory=dict)
    #: paths (Trajectory, world frame, base of the box) of moving boxes of the visibility parameter
    #: obstacle_model_size_m that block satellites (core/visibility/moving_obstacles.py; simulate --obstacle-path)
    obstacle_paths: list = field(default_factory=list)

    def node_params(self) -> dict[str, dict]:
        """{"ephemeris": ..., "visibility": ..., "receiver": ...}: the parameters of the nodes this run stands for."""
        return {"ephemeris": self.ephemeris_params, "visibility": self.visibility_params,
                "receiver": self.receiver_params}

    def with_params(self, **values) -> SimulationSetup:
        """A copy with parameters set by name in every node holding them (``systems``, ``preset``: all three;
        ``profile``: the receiver's; ``multipath``: the visibility node's), values as the parameter table takes
        them; a name no node has is a ValueError."""
        nodes = {key: dict(p) for key, p in self.node_params().items()}
        for name, value in values.items():
            holders = [p for p in nodes.values() if name in p]
            if not holders:
                raise ValueError(f"parameter {name!r}: no node of an offline run has it")
            for p in holders:
                p[name] = value
        return dataclasses.replace(self, ephemeris_params=nodes["ephemeris"], visibility_params=nodes["visibility"],
                                   receiver_params=nodes["receiver"])

    # the parameters the loop itself reads (one value per configuration: shared ones from the receiver's)
    @property
    def systems(self) -> str:
        return self.receiver_params["systems"]

    @property
    def preset(self) -> str:
        return self.receiver_params["preset"]

    @property
    def marker_name(self) -> str:
        return self.receiver_params["marker_name"]

    @property
    def elevation_mask_deg(self) -> float:
        return self.receiver_params["elevation_mask_deg"]

    def scene_files(self) -> tuple[str, str, str]:
        """(world_file, mesh_file, materials_file) of the visibility node."""
        v = self.visibility_params
        return v["world_file"], v["mesh_file"], v["materials_file"]

    def orbit_files(self) -> tuple[list, list, list]:
        """(nav_files, sp3_files, clk_files) of the ephemeris node."""
        e = self.ephemeris_params
        return list(e["nav_files"]), list(e["sp3_files"]), list(e["clk_files"])


def setup_from_config(cfg, out_dir: Path, trajectory: Trajectory | None = None, **extra) -> SimulationSetup:
    """The offline run of one configuration (``config_file.load_config``): the nodes' parameters as they get them.

    ``trajectory``: the antenna's path (static position, CSV); None: the trajectory player's path
    (``trajectory_file``, ``waypoints`` or the demo path) with its ``antenna_offset_m``, in the world
    given (the demo courtyard when none is).  ``extra``: other SimulationSetup fields (``start``,
    ``duration_s``, ``interval_s`` replace start_time, duration_s and 1 / rate_hz).
    """
    from .scene.demo_world import demo_world_path
    from .trajectory import antenna_path, robot_path

    eph, vis, rcv, trj = cfg.node("ephemeris"), cfg.node("visibility"), cfg.node("receiver"), cfg.node("trajectory")
    if vis.get("sky_mask_csv") and "scene" not in extra:       # a measured mask as the scene, as the visibility node
        from .visibility.sky_mask import check_mask_options, mask_scene, static_antenna_ecef

        trajectory, ecef = static_antenna_ecef(vis["antenna_position"], vis["antenna_position_type"], trajectory)
        check_mask_options(VisibilityOptions.from_params(vis), "parameter 'sky_mask_csv'")
        extra["scene"] = mask_scene(vis["sky_mask_csv"], ecef)
    if trajectory is None:
        trajectory = antenna_path(robot_path(trj), trj["antenna_offset_m"])
        if not vis["world_file"] and not vis["mesh_file"]:
            vis["world_file"] = str(demo_world_path())
    if extra.get("obstacle_paths") and not (vis["world_file"] or vis["mesh_file"] or "scene" in extra):
        raise ValueError("option --obstacle-path: an obstacle moves in the world frame of a scene, and the run has "
                         "none (open sky): give --world, --mesh or --sky-mask")      # was ignored without a word
    run = {"start": GnssTime.from_iso(rcv["start_time"]), "duration_s": eph["duration_s"],
           "interval_s": 1.0 / rcv["rate_hz"], **extra}
    return SimulationSetup(out_dir=Path(out_dir), trajectory=trajectory, receiver_params=rcv, visibility_params=vis,
                           ephemeris_params=eph, **run)


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
    rtcm_path: Path | None = None

    @property
    def realtime_factor(self) -> float:
        return self.sim_s / self.wall_s if self.wall_s > 0 else float("inf")


#: sampling step of glonass_slots [s]: a GLONASS broadcast record serves +-15 min of its tb (select.WINDOW_S)
GLONASS_SLOT_STEP_S = 900.0


def glonass_slots(provider, start, duration_s: float, systems: str) -> dict[str, int]:
    """{"R01": frequency channel k} of every GLONASS satellite ``provider`` serves at some instant of the run
    [start, start + duration_s] (RINEX 3.04 section 5.2, header GLONASS SLOT / FRQ #), not only of those at
    the first epoch: a satellite rising later in the run keeps its phase and Doppler in a reader that takes
    the wavelength from this header.  Its states are sampled every GLONASS_SLOT_STEP_S and at the end."""
    if "R" not in systems:
        return {}
    span_s = max(float(duration_s), 0.0)
    n = int(np.ceil(span_s / GLONASS_SLOT_STEP_S))
    slots: dict[str, int] = {}
    for k in range(n + 1):
        st = provider.states(start + min(k * GLONASS_SLOT_STEP_S, span_s), systems="R")
        for sv, ch in zip(np.asarray(st.sv).tolist(), np.asarray(st.glo_channel).tolist()):
            slots.setdefault(str(sv), int(ch))
    return dict(sorted(slots.items()))


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
            source = getattr(getattr(scene, "world", None), "source", "")       # the file: it named none
            raise ValueError(f"the scene {source} has no spherical_coordinates (a world's <spherical_coordinates>, a "
                             f"mesh's .scene.yaml sidecar): cannot place a geodetic/ECEF path in it")
        if trajectory.frame == "world":     # the points as the scene places them: receivers the simulator models
            lines = trajectory.source_lines
            check_receiver_position(scene.antenna_ecef(trajectory.pos), "ecef",
                                    trajectory.source or "antenna path (world frame)",
                                    labels=lambda i: lines[i] if lines else f" point {i + 1}")

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
    source = setup.ephemeris_params["source"]
    nav_files, sp3_files, _ = setup.orbit_files()
    if sw["orbit"] == "precise" and sp3_files and source in ("broadcast", "sp3"):
        return "sp3"
    if sw["orbit"] == "broadcast" and source == "sp3" and nav_files:
        return "broadcast"
    return source


def chain_settings(setup: SimulationSetup, interval_s: float | None = None) -> ChainSettings:
    """The receiver node's ChainSettings.from_params on the setup's receiver parameters, writing into the run's
    folder at its epoch interval, the ephemeris at hand (transmit time evaluated, not expanded)."""
    sw = switches(setup)
    interval_s = interval_s if interval_s is not None else _interval_s(setup, sw)
    return ChainSettings.from_params({**setup.receiver_params, "output_dir": str(setup.out_dir)}, switches=sw,
                                     interval_s=interval_s, receiver_overrides=setup.receiver_overrides,
                                     have_ephemeris=True)


def visibility_options(setup: SimulationSetup) -> VisibilityOptions:
    """The visibility node's VisibilityOptions.from_params on the setup's visibility parameters."""
    return VisibilityOptions.from_params(setup.visibility_params, switches(setup))


def _interval_s(setup: SimulationSetup, sw: dict) -> float:
    interval_s = float(setup.interval_s) if setup.interval_s > 0 else float(sw["epoch_interval_s"])
    if not np.isfinite(interval_s):
        raise ValueError(f"interval_s = {setup.interval_s!r}: must be a finite number of seconds")
    return interval_s


def run_simulation(setup: SimulationSetup) -> SimulationResult:
    """Simulate ``setup`` into ``setup.out_dir`` (core/output_folder.py): a folder holding files this command did
    not write is refused; the run writes into a staging folder beside it whose files replace the previous run's
    at the end; a run that fails leaves the previous results as they were (one stopped by Ctrl-C / SIGTERM
    after its first epoch keeps what it wrote, closed, as ``gnss-sim run`` does: in the folder when it held no
    earlier results, else in the staging folder)."""
    from .output_folder import OutputFolder

    inputs = [*(f for files in setup.orbit_files() for f in files), *setup.scene_files()]
    folder = OutputFolder(setup.out_dir, command="gnss-sim simulate", inputs=inputs)
    staging = folder.acquire()
    for old in folder.stale:        # as `gnss-sim run` says it: a stopped or killed run's outputs, never removed
        print(f"note: {old} holds the outputs of a run that was stopped or killed; left as it is", file=sys.stderr)
    rtcm_path = setup.rtcm_path     # an RTCM file named inside the folder is one of the run's files too
    if rtcm_path and folder.final in Path(rtcm_path).resolve().parents:
        rtcm_path = str(staging / Path(rtcm_path).resolve().relative_to(folder.final))
    try:
        res = _simulate_into(dataclasses.replace(setup, out_dir=staging, rtcm_path=rtcm_path))
    except BaseException as exc:
        # a failure (an Exception) leaves nothing; a stop (KeyboardInterrupt, SIGTERM) keeps closed epochs
        if isinstance(exc, Exception) or not any(staging.glob("*_MO*.rnx")):
            folder.abandon()
        elif not folder.keep_stopped():     # never over earlier results: the stopped run's stay staged
            print(f"stopped: the earlier results in {folder.final} are kept; this run's closed outputs are in "
                  f"{staging}", file=sys.stderr)
        raise
    folder.commit()
    res.obs_path, res.nav_path = folder.final_path(res.obs_path), folder.final_path(res.nav_path)
    res.fix_path, res.rtcm_path = folder.final_path(res.fix_path), folder.final_path(res.rtcm_path)
    return res


def _simulate_into(setup: SimulationSetup) -> SimulationResult:
    """The simulation of :func:`run_simulation`, written into ``setup.out_dir`` (its staging folder)."""
    t_setup0 = time.perf_counter()
    sw = switches(setup)
    interval_s = _interval_s(setup, sw)
    if int(setup.batch_epochs) < 1:
        raise ValueError(f"batch_epochs = {setup.batch_epochs!r}: must be >= 1")
    n_epochs = int(np.floor(setup.duration_s / interval_s + 1e-9)) + 1
    vis_opt = visibility_options(setup)
    scene = setup.scene if setup.scene is not None else load_scene(*setup.scene_files(), vis_opt)
    if not is_zero(setup.visibility_params.get("world_offset_enu_m", [])):     # applied on purpose, said aloud
        scene = shifted_scene(scene, setup.visibility_params["world_offset_enu_m"])
        print(offset_note(setup.visibility_params["world_offset_enu_m"]), file=sys.stderr)
    path = AntennaPath(setup.trajectory, scene)
    if setup.obstacle_paths and scene is not None:     # a path in another frame or unit: said, not silent
        for msg in paths_far_from_world(setup.obstacle_paths, world_bounds_xy(scene)):
            logging.getLogger(__name__).warning(msg)
    if scene is not None and setup.crop_scene:
        scene = _cropped_scene(scene, path, n_epochs, interval_s, setup.elevation_mask_deg, vis_opt.fresnel_rays)
        path = AntennaPath(setup.trajectory, scene)
    settings = chain_settings(setup, interval_s)
    out = Path(setup.out_dir)

    source = orbit_source(setup, sw)
    nav_files, sp3_files, clk_files = setup.orbit_files()
    if source in setup.ephemeris:
        provider, nav_paths = setup.ephemeris[source]
    else:
        provider, nav_paths = open_ephemeris(source, setup.start, setup.duration_s, setup.systems, nav_files,
                                             sp3_files, clk_files, workdir=out / ".ephemeris")
    if (source == "sp3" and not isinstance(provider, PreciseWithBroadcastGroupDelay)
            and (nav_files or "broadcast" in setup.ephemeris)):
        brdc, brdc_paths = setup.ephemeris.get("broadcast") or open_ephemeris(
            "broadcast", setup.start, setup.duration_s, setup.systems, nav_files)
        provider, nav_paths = PreciseWithBroadcastGroupDelay(provider, brdc, setup.start, setup.duration_s), brdc_paths
        # the pair serves the satellites both files have: no usable one is an error before anything is written
        check_coverage(provider, setup.start, setup.duration_s, setup.systems, sp3_files + nav_files, warn=False)

    out.mkdir(parents=True, exist_ok=True)   # the staging folder: exactly one observation, navigation, fix.csv
    nav_path = out / rinex_name(setup.marker_name, setup.start, setup.duration_s, interval_s, "MN")
    nav_written = write_navigation(nav_path, provider, setup.systems)
    if nav_written is None and nav_paths:
        shutil.copyfile(nav_paths[0], nav_path)
        nav_written = nav_path
    glo_slots = glonass_slots(provider, setup.start, setup.duration_s, setup.systems)
    rtcm = None
    if setup.rtcm_path is not None:
        rtcm = Path(setup.rtcm_path) if setup.rtcm_path else out / rinex_name(
            setup.marker_name, setup.start, setup.duration_s, interval_s, "MO").replace("_MO.rnx", "_MO.rtcm3")
    chain = ReceiverChain(settings, provider, duration_s=setup.duration_s, glonass_slots=glo_slots,
                          comment=f"gnss_sim simulate, source {source}", rtcm=rtcm,
                          rtcm_ephemeris=setup.rtcm_ephemeris)
    if setup.receiver_params.get("scenario"):      # the scenario's events (core/threats), the node's way
        # imported here: a run without a scenario does without them (10 ms of the start-up)
        from .threats.runtime import ThreatRuntime
        from .threats.scenario import load_scenario

        chain.threats = ThreatRuntime(load_scenario(setup.receiver_params["scenario"]), scene, start=setup.start)
    res = SimulationResult(None, nav_written, out / "fix.csv", 0, 0, [], [], [], [], [], 0.0, 0.0,
                           interval_s=interval_s, orbit_source=source)
    svs_all = np.asarray(provider.svs(setup.systems), dtype="<U3")
    if chain.threats is not None:          # a fault on a satellite the ephemerides lack (G99): said, not silent
        for msg in chain.threats.scenario.absent_satellites(setup.systems, svs_all.tolist()):
            logging.getLogger(__name__).warning(msg)
    fix_est, fix_true = [], []
    wall0 = time.perf_counter()
    cpu0 = time.process_time()
    res.setup_s = wall0 - t_setup0
    mask = setup.elevation_mask_deg
    visible, blocked, attenuated = int(VISIBLE), int(BLOCKED), int(ATTENUATED)
    try:
        for i0 in range(0, n_epochs, int(setup.batch_epochs)):
            t_rel = np.arange(i0, min(i0 + int(setup.batch_epochs), n_epochs)) * interval_s
            block = _EpochBlock(setup, provider, svs_all, path, scene, t_rel, interval_s, vis_opt)
            if setup.batch_observables:
                products = chain.step_block(*block.stacked())
            else:
                products = (chain.step(*block.epoch(b), multipath=block.paths_of(b)) for b in range(len(t_rel)))
            products = list(products)
            for b, ep in enumerate(products):
                i = i0 + b
                t, ecef = ep.t, ep.antenna_ecef_m
                obs, sol = ep.obs, ep.sol
                if sol.is_fix:
                    fix_est.append(sol.pos_ecef_m)
                    fix_true.append(ecef)
                if setup.observer is not None:
                    setup.observer(t, ecef, obs, sol)
                res.tracked_per_epoch.append(obs.n_tracked_sats)
                if setup.progress and (i % max(1, n_epochs // 20) == 0 or i == n_epochs - 1):
                    el = time.perf_counter() - wall0
                    print(f"\r[simulate] epoch {i + 1}/{n_epochs}  {obs.n_tracked_sats} sats tracked  "
                          f"{(t_rel[b] + interval_s) / max(el, 1e-9):.0f}x real time", end="", file=sys.stderr,
                          flush=True)
            # satellites above the mask per visibility state, epoch by epoch (the block's counts at once)
            n_sat = [len(ep.obs.sat_el_deg) for ep in products]
            if products and sum(n_sat):
                e = np.repeat(np.arange(len(products)), n_sat)
                el = np.concatenate([ep.obs.sat_el_deg for ep in products])
                state = np.concatenate([ep.obs.sat_vis_state for ep in products])
                e, state = e[el >= mask], state[el >= mask]
                for code, counts in ((visible, res.visible_per_epoch), (blocked, res.blocked_per_epoch),
                                     (attenuated, res.attenuated_per_epoch)):
                    counts.extend(np.bincount(e[state == code], minlength=len(products)).tolist())
            else:
                for counts in (res.visible_per_epoch, res.blocked_per_epoch, res.attenuated_per_epoch):
                    counts.extend([0] * len(products))
    finally:
        chain.close()
    if setup.progress:
        print(file=sys.stderr)
    res.obs_path, res.epochs, res.fixes = chain.obs_path, chain.epochs, chain.fixes
    res.rtcm_path = chain.rtcm_path
    if fix_est:
        res.horizontal_error_m = horizontal_errors_m(np.array(fix_est), np.array(fix_true)).tolist()
    res.wall_s = time.perf_counter() - wall0
    res.cpu_s = time.process_time() - cpu0
    res.sim_s = n_epochs * interval_s
    shutil.rmtree(out / ".ephemeris", ignore_errors=True)
    return res


class _EpochBlock:
    """Satellite states, elevations and visibility of a block of epochs, computed at once."""

    def __init__(self, setup, provider, svs_all, path, scene, t_rel, interval_s, vis_opt: VisibilityOptions):
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
        self.vis = self.att = self.paths = None
        if scene is not None:
            boxes = (boxes_along_paths(setup.obstacle_paths, t_rel, setup.visibility_params["obstacle_model_size_m"])
                     if setup.obstacle_paths else None)
            self.vis, self.att, v = vis_opt.cast(scene, world, sat, obstacles=boxes)
            self.paths = getattr(v, "paths", None)          # reflections (VisibilityOptions.multipath)

    def stacked(self):
        """(epoch tags, antenna ECEF (K, 3), states of every epoch one after another, epoch of each row,
        visibility state per row or None, attenuation per row or None, K path sets or None): the block
        as ReceiverChain.step_block takes it (the rows of :meth:`epoch` for each epoch, in order)."""
        ts = [GnssTime(sec, frac) for sec, frac in zip(np.atleast_1d(self.t.sec).tolist(),
                                                       np.atleast_1d(self.t.frac).tolist())]
        if self.states is None:
            return ts, self.ecef, SatelliteStates.empty(self.t[0], "none"), np.zeros(0, np.int64), None, None, None
        kk, jj = np.nonzero(self.use)
        st = self.states.select(self.row[kk, jj])
        paths = None if self.paths is None else [self.paths_of(b) for b in range(self.k)]
        if self.vis is None:
            return ts, self.ecef, st, kk, None, None, paths
        return ts, self.ecef, st, kk, self.vis[kk, jj], self.att[kk, jj], paths

    def paths_of(self, b: int):
        """The reflected paths of epoch b's satellites (rows as in :meth:`epoch`), or None."""
        if self.paths is None or self.states is None:
            return None
        cols = np.flatnonzero(self.use[b])
        return self.paths.take((b, cols))

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
