"""A simulated receiver against a real one on an urban drive with its 3D model (issue 16 acceptance).

Method (the same for the real and the simulated observation file):

- the antenna: the truth path (lat, lon) placed in the world frame of the city model, ``antenna_height_m``
  above the model's ground under it (a downward cast; the model's vertical datum is not the ellipsoid);
  the simulated receiver moves along it, the model's line-of-sight state is cast from it;
- positions: RTKLIB rnx2rtkp single point on each file with the day's navigation files and the same
  options (mask, Klobuchar, Saastamoinen; code error ratio ``eratio`` so that every epoch solves), the
  horizontal error against the truth of that file (SPAN for the real one, the simulated antenna path for
  the simulated one): RMS and 95th percentile;
- tracked sets: per epoch, the satellites with a pseudorange in the file, above the mask (elevation at
  the truth), among those the ephemeris can serve; recall = |sim & real| / |real|, precision =
  |sim & real| / |sim|, pooled over satellite-epochs;
- NLOS: a tracked satellite-epoch whose line of sight the 3D model blocks (cast from the placed
  antenna); NLOS fraction = NLOS / tracked satellite-epochs;
- excess delay: the pseudorange residual at the truth, r = P + c dt_sat - rho - I_klobuchar - T_saas,
  minus the receiver clock of the epoch (median residual of the line-of-sight satellites of GPS, plus
  the drive's median BeiDou-GPS offset of those medians); the median over the NLOS satellite-epochs.
"""
from __future__ import annotations

import csv
import gzip
import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import constants as k
from .. import propagation as prop
from ..frames import az_el_from_ecef, ecef_to_geodetic, geodetic_to_ecef
from ..metrics import horizontal_stats, rms
from ..rinex.obs_table import GPS_EPOCH_NP, match_epochs
from ..scene.visibility import Scene
from ..signals import frequency_hz, group_delay_factor
from ..simulation import run_simulation, setup_from_config
from ..time import GnssTime
from ..trajectory import Trajectory
from ..visibility import VisibilityOptions
from ..visibility.line_of_sight import line_of_sight
from ..vocabulary import VisibilityState
from .registration import fit_offset, sight_epochs
from .rtklib import rtklib_solutions
from .sources import load_observations

#: RTKLIB 2.4.3 single point options on both files: its code variance is (100 x stats-errphase)^2 +
#: (100 x stats-errphaseel)^2 / sin^2(el) (pntpos.c varerr(), err[0] = 100); the defaults (0.003 m) give
#: 0.3 m, so its chi-square test rejects most urban epochs; x100 ("code sigma x100", physics-anchors.md)
#: gives every epoch a solution
RTKLIB_OPTIONS = {"stats-errphase": "0.3", "stats-errphaseel": "0.3"}
#: iterations of the Earth-rotation correction over the light time
EARTH_ROT_ITER = 2


@dataclass
class Drive:
    t: GnssTime                    # (K,) truth epochs (GPS)
    truth_ecef_m: np.ndarray       # (K, 3)
    antenna_world_m: np.ndarray    # (K, 3) placed in the model
    antenna_ecef_m: np.ndarray     # (K, 3)
    ground_z_m: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def times_np(self) -> np.ndarray:
        ns = np.asarray(self.t.sec, np.int64) * 1_000_000_000 + np.round(np.asarray(self.t.frac) * 1e9).astype(np.int64)
        return GPS_EPOCH_NP + ns.astype("timedelta64[ns]")


def load_drive(truth_csv, scene, antenna_height_m: float = 1.8, offset_m=(0.0, 0.0)) -> Drive:
    """Truth CSV rows ``week, tow_s, lat_deg, lon_deg, h_m`` (no header) placed in ``scene``; ``offset_m``:
    (east, north) [m] added to the placement in the model (its georeference error, :func:`model_offset_m`)."""
    rows = []
    with open(truth_csv, newline="") as f:
        for n, r in enumerate(csv.reader(f), start=1):
            if not r:
                continue
            try:
                rows.append([float(x) for x in r[:5]])
            except ValueError as exc:
                raise ValueError(f"{truth_csv}, line {n}: {exc}") from None
    a = np.array(rows)
    t = GnssTime.from_week_tow(a[:, 0].astype(np.int64), a[:, 1])
    truth = np.array(geodetic_to_ecef(a[:, 2], a[:, 3], a[:, 4])).T.reshape(-1, 3)
    world = scene.spherical.ecef_to_world(truth)
    world[:, :2] += np.asarray(offset_m, dtype=float).reshape(2)
    world, ground = place_on_ground(scene, world[:, :2], antenna_height_m)
    return Drive(t, truth, world, scene.spherical.world_to_ecef(world), ground)


def place_on_ground(scene, xy_world_m, antenna_height_m: float):
    """(world (N, 3), ground_z (N,)): points (N, 2) of the world frame put ``antenna_height_m`` above the scene's
    ground under them (a downward cast from 1000 m: the model's vertical datum is not the ellipsoid)."""
    xy = np.asarray(xy_world_m, float).reshape(-1, 2)
    top = np.column_stack([xy, np.full(len(xy), 1000.0)])
    ground = 1000.0 - scene.rays.hit_distance(top, np.tile([0.0, 0.0, -1.0], (len(top), 1)))
    return np.column_stack([xy, ground + antenna_height_m]), ground


def _gnss_times(times_np) -> GnssTime:
    ns = (np.asarray(times_np, "datetime64[ns]") - GPS_EPOCH_NP).astype(np.int64)
    return GnssTime(ns // 1_000_000_000, (ns % 1_000_000_000) / 1e9)


@dataclass
class FileView:
    """One observation file on the drive's epochs: tracked satellites, model state, residuals."""

    sv: np.ndarray               # (S,)
    tracked: np.ndarray          # (K, S) bool (pseudorange, above the mask, servable)
    blocked: np.ndarray          # (K, S) bool: the model blocks the line of sight
    residual_m: np.ndarray       # (K, S) residual at the truth minus the epoch's clock (NaN: none)
    cn0_dbhz: np.ndarray         # (K, S)


#: the signal of each system whose pseudorange and C/N0 :func:`file_view` reads (the Hong Kong drive's u-blox M8T)
VIEW_CODES = {"G": "1C", "C": "2I", "E": "1C", "R": "1C", "J": "1C"}


def file_view(obs_path, drive: Drive, truth_ecef_m, provider, scene, systems: str = "GC",
              mask_deg: float = 15.0, codes: dict | None = None) -> FileView:
    """Tracked sets, model states and residuals of one RINEX observation file (module docstring); ``codes``:
    system -> band + attribute read (default :data:`VIEW_CODES`)."""
    tab = load_observations(obs_path)
    i_d, i_f = match_epochs(drive.times_np, tab.time, 50_000_000)
    code = {**VIEW_CODES, **(codes or {})}
    svs = np.array([s for s in tab.sv if s[0] in systems])
    kk, ss = len(drive.t), len(svs)
    pr = np.full((kk, ss), np.nan)
    cn0 = np.full((kk, ss), np.nan)
    col = {s: j for j, s in enumerate(tab.sv)}
    for j, s in enumerate(svs):
        p = tab.column("C" + code[s[0]])[:, col[s]]
        c = tab.column("S" + code[s[0]])[:, col[s]]
        pr[i_d, j] = p[i_f]
        cn0[i_d, j] = c[i_f]
    pr[pr <= 0] = np.nan
    t_rx = _gnss_times(tab.time[i_f])
    opts = VisibilityOptions(mask_deg=mask_deg)
    tracked = np.zeros((kk, ss), bool)
    blocked = np.zeros((kk, ss), bool)
    resid = np.full((kk, ss), np.nan)
    iono = getattr(provider, "iono", None) or {}
    alpha, beta = np.asarray(iono.get("GPSA")), np.asarray(iono.get("GPSB"))
    freq = np.array([frequency_hz(s[0], code[s[0]]) for s in svs])
    for n, (d, _) in enumerate(zip(i_d, i_f)):
        ok = np.isfinite(pr[d])
        if not ok.any():
            continue
        sv_e = svs[ok]
        p = pr[d, ok]
        t0 = t_rx[n]
        t_tx = GnssTime(np.full(len(p), t0.sec, np.int64), np.full(len(p), float(t0.frac))) + (-p / k.C_MPS)
        st = provider.states_at(list(sv_e), t_tx)
        have = np.isin(sv_e, st.sv)
        if not have.any():
            continue
        idx = np.flatnonzero(ok)[have]
        p = p[have]
        order = {s: i for i, s in enumerate(st.sv)}
        sel = np.array([order[s] for s in sv_e[have]])
        pos = np.asarray(st.pos_ecef_m)[sel]
        rx = truth_ecef_m[d]
        omega = np.array([k.OMEGA_BY_SYSTEM.get(s[0], k.OMEGA_E_GPS_RADPS) for s in sv_e[have]])
        sat = pos
        for _ in range(EARTH_ROT_ITER):
            rho = np.linalg.norm(sat - rx, axis=1)
            th = omega * rho / k.C_MPS
            c, s_ = np.cos(th), np.sin(th)
            sat = np.column_stack([c * pos[:, 0] + s_ * pos[:, 1], -s_ * pos[:, 0] + c * pos[:, 1], pos[:, 2]])
        rho = np.linalg.norm(sat - rx, axis=1)
        az, el, _ = az_el_from_ecef(rx, sat)
        above = el >= mask_deg
        systems_e = np.array([s[0] for s in sv_e[have]])
        codes_e = np.array([code[s] for s in systems_e])
        dts = (np.asarray(st.clock_bias_s)[sel] + np.asarray(st.relativistic_s)[sel]
               - group_delay_factor(systems_e, codes_e, freq[idx]) * np.asarray(st.tgd_s)[sel])
        lat, lon, h = ecef_to_geodetic(*rx)
        i_m = prop.iono_code_delay_m(prop.klobuchar_l1_delay_s(t0, lat, lon, az, el, alpha, beta), freq[idx])
        t_m = prop.tropo_slant_delay_m(np.maximum(el, 1.0), lat, h, prop.day_of_year(t0))
        r = p + k.C_MPS * dts - rho - i_m - t_m
        state, _, _ = opts.cast(scene, drive.antenna_world_m[d], sat)
        blk = state == int(VisibilityState.BLOCKED)
        tracked[d, idx] = above
        blocked[d, idx] = blk & above
        resid[d, idx] = np.where(above, r, np.nan)
    # receiver clock per epoch: median LOS residual of GPS; BeiDou: + the drive's median C - G offset
    los = tracked & ~blocked
    is_g = np.array([s[0] == "G" for s in svs])
    clk = np.full(kk, np.nan)
    off = {}
    for d in range(kk):
        g = los[d] & is_g
        if g.any():
            clk[d] = np.median(resid[d, g])
    for sys_ in set(s[0] for s in svs) - {"G"}:
        m = np.array([s[0] == sys_ for s in svs])
        diffs = [np.median(resid[d, los[d] & m]) - clk[d] for d in range(kk)
                 if (los[d] & m).any() and np.isfinite(clk[d])]
        off[sys_] = float(np.median(diffs)) if diffs else np.nan
    shift = np.where(is_g[None, :], clk[:, None], clk[:, None] + np.array([off.get(s[0], 0.0) for s in svs])[None, :])
    return FileView(svs, tracked, blocked, resid - shift, cn0)


def set_metrics(sim: FileView, real: FileView) -> dict:
    """Recall, precision of the simulated tracked sets; NLOS fractions and median NLOS excess of both."""
    allsv = sorted(set(sim.sv) | set(real.sv))

    def full(v: FileView, a):
        shape = (a.shape[0], len(allsv))
        out = np.zeros(shape, bool) if a.dtype == bool else np.full(shape, np.nan)
        j = [allsv.index(s) for s in v.sv]
        out[:, j] = a
        return out

    ts, tr = full(sim, sim.tracked), full(real, real.tracked)
    both = int(np.sum(ts & tr))
    out = {"recall": both / max(int(tr.sum()), 1), "precision": both / max(int(ts.sum()), 1),
           "sat_epochs_sim": int(ts.sum()), "sat_epochs_real": int(tr.sum())}
    for name, v in (("sim", sim), ("real", real)):
        nl = v.tracked & v.blocked
        out[f"nlos_fraction_{name}"] = float(nl.sum() / max(int(v.tracked.sum()), 1))
        r = v.residual_m[nl]
        r = r[np.isfinite(r)]
        out[f"nlos_median_excess_m_{name}"] = float(np.median(r)) if len(r) else np.nan
        los = v.residual_m[v.tracked & ~v.blocked]
        los = los[np.isfinite(los)]
        out[f"los_residual_rms_m_{name}"] = float(np.sqrt(np.mean(los**2))) if len(los) else np.nan
        out[f"los_above_10m_{name}"] = float(np.mean(np.abs(los) > 10.0)) if len(los) else np.nan
        c = v.cn0_dbhz
        out[f"cn0_median_nlos_{name}"] = float(np.nanmedian(c[nl])) if nl.any() else np.nan
        out[f"cn0_median_los_{name}"] = float(np.nanmedian(c[v.tracked & ~v.blocked]))
    return out


def model_offset_m(drive: Drive, scene, provider, real: FileView, *, strong_cn0_dbhz: float = 38.0,
                   mask_deg: float = 15.0, span_m: float = 6.0, step_m: float = 2.0, every: int = 1):
    """(east, north) [m] to add to the antenna's placement so that the model agrees best with the real receiver's
    line of sight (its georeference error: core/comparison/registration.py, which also gives the uncertainty),
    on every ``every``-th epoch.  Returns (offset (2,), criterion at 0, criterion at it)."""
    sight = sight_epochs(drive.t, drive.antenna_world_m, provider, real.sv, real.tracked, real.cn0_dbhz,
                         strong_cn0_dbhz=strong_cn0_dbhz, every=every)
    reg = fit_offset(scene, sight, mask_deg=mask_deg, span_m=span_m, step_m=step_m, n_bootstrap=0,
                     strong_cn0_dbhz=strong_cn0_dbhz)
    return np.array(reg.offset_en_m), reg.criterion_zero, reg.criterion_best


def write_trajectory_csv(drive: Drive, path) -> Path:
    """The placed antenna path as a world-frame trajectory CSV (t_s,e_m,n_m,u_m) for ``gnss-sim simulate``."""
    path = Path(path)
    t_s = drive.t - drive.t[0]
    with open(path, "w") as f:
        f.write("t_s,e_m,n_m,u_m\n")
        for ts, p in zip(np.atleast_1d(t_s), drive.antenna_world_m):
            f.write(f"{ts:.3f},{p[0]:.4f},{p[1]:.4f},{p[2]:.4f}\n")
    return path


#: the world of ``hk-tst-city-model``, relative to the model's folder (and to city_scene's ``workdir``)
CITY_WORLD = Path("worlds") / "hong_kong_city_only.world"


def city_scene(model_dir, workdir):
    """The Hong Kong city model (``hk-tst-city-model``: models/, worlds/hong_kong_city_only.world) as a Scene:
    copied into ``workdir`` with the gzipped terrain mesh unpacked (its README), then loaded from the SDF."""
    src, dst = Path(model_dir), Path(workdir)
    world = src / CITY_WORLD
    if not world.is_file():
        raise ValueError(f"{world}: no such world file (hk-tst-city-model)")
    for sub in ("models", "worlds"):
        shutil.copytree(src / sub, dst / sub, dirs_exist_ok=True)
    for gz in (dst / "models").rglob("*.dae.gz"):
        with gzip.open(gz) as fin, open(gz.with_suffix(""), "wb") as fout:
            shutil.copyfileobj(fin, fout)
    os.chmod(dst, 0o755)
    old = os.environ.get("GZ_SIM_RESOURCE_PATH")
    os.environ["GZ_SIM_RESOURCE_PATH"] = str(dst / "models")
    try:
        # the city model's buildings are not marked <static> (the world was made for visuals): keep them
        return Scene.from_sdf(dst / CITY_WORLD, keep_dynamic=True)
    finally:
        if old is None:
            os.environ.pop("GZ_SIM_RESOURCE_PATH", None)
        else:
            os.environ["GZ_SIM_RESOURCE_PATH"] = old


def run_drive(drive: Drive, scene, provider, nav_files, real_obs, workdir, *, config, multipath: str = "nlos",
              diffraction: bool = False, bounces: int = 2, profile: str = "ublox_m8t", mask_deg: float = 15.0,
              systems: str = "GC", real: dict | None = None, range_m: float = 100.0,
              receiver: dict | None = None, scattering: bool = False) -> dict:
    """The whole check (module docstring): simulate along the drive, RTKLIB on both files, the metrics.

    ``config``: the parameter values the run starts from (``config_file.load_config()``), the drive's own
    settings set on top; ``real``: the real file's part from a previous call (``out["real_part"]``), to skip
    recomputing it; ``range_m``: the visibility parameter multipath_range_m; ``receiver``: ReceiverConfig
    overrides."""
    workdir = Path(workdir)
    t_s = np.asarray(drive.t - drive.t[0], dtype=float)
    setup = setup_from_config(
        config, workdir / f"{multipath}_{int(diffraction)}_{bounces}_{range_m:g}_{int(scattering)}",
        Trajectory(t_s, drive.antenna_world_m, "world"), start=drive.t[0], duration_s=float(t_s[-1]), interval_s=1.0,
        scene=scene, ephemeris={"broadcast": (provider, list(nav_files))}, receiver_overrides=dict(receiver or {}),
        switches={"ionosphere": "klobuchar"}).with_params(
        systems=systems, elevation_mask_deg=mask_deg, source="broadcast", nav_files=list(nav_files), profile=profile,
        multipath=multipath, multipath_diffraction=diffraction, multipath_bounces=bounces, multipath_range_m=range_m,
        multipath_scattering=scattering)
    res = run_simulation(setup)
    times = drive.times_np
    sim_sol = rtklib_solutions(res.obs_path, nav_files, systems, times, workdir / "rtk_sim", mask_deg, RTKLIB_OPTIONS)
    if real is None:
        real_sol = rtklib_solutions(real_obs, nav_files, systems, times, workdir / "rtk_real", mask_deg, RTKLIB_OPTIONS)
        real = {"h": horizontal_stats(real_sol.pos_ecef_m, drive.truth_ecef_m),
                "view": file_view(real_obs, drive, drive.truth_ecef_m, provider, scene, systems, mask_deg)}
    sim_view = file_view(res.obs_path, drive, drive.antenna_ecef_m, provider, scene, systems, mask_deg)
    out = set_metrics(sim_view, real["view"])
    out["h_sim"] = horizontal_stats(sim_sol.pos_ecef_m, drive.antenna_ecef_m)
    out["h_real"] = real["h"]
    out["own_fixes"] = (res.fixes, res.epochs)
    err = np.asarray(res.horizontal_error_m, dtype=float)
    out["own_h_rms_m"] = rms(err) if len(err) else np.nan
    out["wall_s"] = res.wall_s
    out["real_part"] = real
    return out


def tracked_counts(view: FileView) -> dict:
    """Per system letter and "all": the (K,) number of satellites ``view`` tracks at each epoch (above the mask,
    servable), to see whether a channel budget caps them (issue 16)."""
    sys_ = np.array([s[0] for s in view.sv])
    out = {s: view.tracked[:, sys_ == s].sum(axis=1) for s in sorted(set(sys_))}
    out["all"] = view.tracked.sum(axis=1)
    return out


def clear_sky_shares(drive: Drive, scene, provider, view: FileView, *, mask_deg: float = 15.0,
                     split_el_deg: float = 35.0, az_bin_deg: float = 45.0, every: int = 1):
    """What ``view`` tracks of the satellites the model leaves in the line of sight (cast from the placed antenna,
    every satellite the ephemeris serves, above the mask): (shares, clear, tracked_clear) where ``shares`` maps
    (elevation band 0: below ``split_el_deg`` / 1: above, azimuth bin start [deg]) -> (tracked share, satellite-
    epochs) and ``clear``, ``tracked_clear`` are (K, S) bool on ``view.sv`` (epochs not visited: False).  A sky
    sector the file leaves untracked where the model is clear points at what the model lacks there."""
    col = {s: j for j, s in enumerate(view.sv)}
    clear = np.zeros(view.tracked.shape, bool)
    acc: dict = {}
    for d in range(0, len(drive.t), max(1, int(every))):
        st = provider.states(drive.t[d], systems="".join(sorted({s[0] for s in view.sv})))
        if len(st) == 0:
            continue
        ok, v = line_of_sight(scene, drive.antenna_world_m[d], st.pos_ecef_m, mask_deg)
        for s, el, az, c in zip(st.sv, v.el_deg, v.az_deg, ok):
            if not c:
                continue
            j = col.get(s)
            t = bool(view.tracked[d, j]) if j is not None else False
            if j is not None:
                clear[d, j] = True
            key = (int(el >= split_el_deg), float(az_bin_deg * np.floor((az % 360.0) / az_bin_deg)))
            n, m = acc.get(key, (0, 0))
            acc[key] = (n + 1, m + int(t))
    shares = {key: (m / n, n) for key, (n, m) in sorted(acc.items())}
    return shares, clear, clear & view.tracked
