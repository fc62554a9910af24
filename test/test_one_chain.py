"""One receiver chain: the ROS graph and the offline tool give one answer for one configuration,
and every front end validates the parameters the same way (issue "One receiver chain")."""
from __future__ import annotations

import csv
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml

from gnss_sim_ros2.config_file import load_config
from gnss_sim_ros2.core.frames import geodetic_to_ecef
from gnss_sim_ros2.core.simulation import SimulationSetup, run_simulation, setup_from_config
from gnss_sim_ros2.core.time import GnssTime
from gnss_sim_ros2.core.trajectory import Trajectory

CLI = [sys.executable, "-m", "gnss_sim_ros2.cli"]
OPEC_ECEF_M = (4027894.0, 307045.6, 4919474.9)   # a static open-sky antenna (Belgium)
WEST_ECEF_M = "-3976219.5082,3382372.5671,3652512.9849"   # negative first coordinate


def _cli(*args, timeout=300, cwd=None):
    env = dict(os.environ, ROS_DOMAIN_ID=str(os.getpid() % 90 + 5))
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    return subprocess.run(CLI + list(args), capture_output=True, text=True, timeout=timeout, env=env, cwd=cwd)


def _code_table(path: Path) -> dict:
    """{(epoch, sv, obs type): value} of every code observation of a RINEX file, read by georinex."""
    import georinex

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = georinex.load(path)
    out = {}
    for var in ds.data_vars:
        if not var.startswith("C"):
            continue
        v = ds[var].values
        for i, j in zip(*np.nonzero(np.isfinite(v))):
            out[(ds.time.values[i], str(ds.sv.values[j]), var)] = float(v[i, j])
    return out


def _fixes(path: Path) -> dict:
    with open(path) as f:
        return {r["time"]: r for r in csv.DictReader(f) if r["status"] == "fix"}


@pytest.mark.slow
def test_run_and_simulate_give_one_answer(tmp_path):
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump({"/**": {"ros__parameters": {"seed": 11, "systems": "GREC"}},
                                   "gnss_sim_ephemeris": {"ros__parameters": {"duration_s": 40.0}}}))
    run = _cli("run", "--config", str(cfg), "--out", str(tmp_path / "run"), "--quiet", "--no-record")
    assert run.returncode == 0, run.stderr[-3000:]
    sim = _cli("simulate", "--config", str(cfg), "--out", str(tmp_path / "sim"), "--quiet")
    assert sim.returncode == 0, sim.stderr[-3000:]
    a = _code_table(next((tmp_path / "run").glob("*_MO.rnx")))
    b = _code_table(next((tmp_path / "sim").glob("*_MO.rnx")))
    assert len(a) > 40 * 20                     # a real run: 41 epochs of tens of signals
    jaccard = len(set(a) & set(b)) / len(set(a) | set(b))
    d = np.array([a[k] - b[k] for k in set(a) & set(b)])
    print(f"run vs simulate: {len(a)} / {len(b)} code observations, Jaccard {jaccard:.5f}, "
          f"code RMS {np.sqrt(np.mean(d ** 2)):.2e} m, max {np.abs(d).max():.2e} m")
    assert jaccard >= 0.999
    assert np.sqrt(np.mean(d ** 2)) <= 1e-3
    fa, fb = _fixes(tmp_path / "run" / "fix.csv"), _fixes(tmp_path / "sim" / "fix.csv")
    assert set(fa) == set(fb) and len(fa) >= 35
    for t in fa:
        pa = geodetic_to_ecef(float(fa[t]["lat_deg"]), float(fa[t]["lon_deg"]), float(fa[t]["h_m"]))
        pb = geodetic_to_ecef(float(fb[t]["lat_deg"]), float(fb[t]["lon_deg"]), float(fb[t]["h_m"]))
        assert np.linalg.norm(np.subtract(pa, pb)) <= 0.01, t


@pytest.mark.slow
@pytest.mark.parametrize("multipath", ["nlos", "full"])
def test_run_and_simulate_give_one_answer_with_reflections(tmp_path, multipath):
    """The reflected paths travel in the Visibility message: a ROS run in a street canyon tracks the same
    signals (REFLECTED_ONLY satellites included) with the same code as the offline chain (full: with the
    walls' diffuse scattering, up to twice multipath_max_paths paths per satellite)."""
    from multipath_scenes import write_canyon_mesh

    mesh = write_canyon_mesh(tmp_path)

    def config(mode):
        cfg = tmp_path / f"cfg_{mode}.yaml"
        # a walk along the canyon at x = 2 m (walls at x = -5, 20 m high, and x = +10, 10 m), antenna 1.5 m up
        cfg.write_text(yaml.safe_dump({
            "/**": {"ros__parameters": {"seed": 5, "systems": "GEC", "start_time": "2019-04-28T05:00:00"}},
            "gnss_sim_ephemeris": {"ros__parameters": {"duration_s": 30.0}},
            "gnss_sim_visibility": {"ros__parameters": {"mesh_file": str(mesh), "multipath": mode,
                                                        "multipath_scattering": mode == "full"}},
            "gnss_sim_receiver": {"ros__parameters": {"profile": "ublox_m8t"}},
            "gnss_sim_trajectory_player": {"ros__parameters": {"waypoints": [0.0, 2.0, -20.0, 1.0,
                                                                             30.0, 2.0, 10.0, 1.0]}}}))
        return str(cfg)

    run = _cli("run", "--config", config(multipath), "--out", str(tmp_path / "run"), "--quiet", "--no-record")
    assert run.returncode == 0, run.stderr[-3000:]
    for mode, out in ((multipath, "sim"), ("off", "off")):
        sim = _cli("simulate", "--config", config(mode), "--out", str(tmp_path / out), "--quiet")
        assert sim.returncode == 0, sim.stderr[-3000:]
    a = _code_table(next((tmp_path / "run").glob("*_MO.rnx")))
    b = _code_table(next((tmp_path / "sim").glob("*_MO.rnx")))
    c = _code_table(next((tmp_path / "off").glob("*_MO.rnx")))
    d = np.array([a[k] - b[k] for k in set(a) & set(b)])
    # the reflections matter here: satellites tracked on reflections only (nlos), codes moved (full)
    nlos_only = {k[1] for k in set(b) - set(c)}
    moved = np.array([abs(b[k] - c[k]) for k in set(b) & set(c)])
    print(f"{multipath}: run {len(a)} / simulate {len(b)} / off {len(c)} code observations; "
          f"{len(nlos_only)} satellites tracked on reflections only; run - simulate RMS "
          f"{np.sqrt(np.mean(d ** 2)):.2e} m, max {np.abs(d).max():.2e} m; full vs off: "
          f"{np.sum(moved > 0.01)} codes moved")
    assert nlos_only
    if multipath == "full":
        assert np.sum(moved > 0.01) > 0.1 * len(moved)
    assert set(a) == set(b)
    assert np.abs(d).max() <= 1e-3


@pytest.mark.slow
def test_run_and_simulate_give_one_answer_with_a_sky_mask(tmp_path):
    """Issue 27: the visibility parameter sky_mask_csv is the scene of the node's static antenna_position (llh) in
    the ROS graph and of `gnss-sim simulate` (which takes that antenna_position): the same satellites blocked,
    the same code; fewer signals than the open sky, so the mask is really used."""
    mask = tmp_path / "mask.csv"
    mask.write_text("azimuth_deg,elevation_deg\n0,50\n90,50\n170,50\n190,5\n350,5\n")   # a wall to the north-east

    def config(with_mask):
        cfg = tmp_path / f"cfg_{int(with_mask)}.yaml"
        vis = {"antenna_position": [22.3, 114.17, 10.0], "antenna_position_type": "llh"}
        if with_mask:
            vis["sky_mask_csv"] = str(mask)
        cfg.write_text(yaml.safe_dump({
            "/**": {"ros__parameters": {"seed": 3, "systems": "GEC", "start_time": "2019-04-28T05:00:00"}},
            "gnss_sim_ephemeris": {"ros__parameters": {"duration_s": 30.0}},
            "gnss_sim_visibility": {"ros__parameters": vis}}))
        return str(cfg)

    run = _cli("run", "--config", config(True), "--out", str(tmp_path / "run"), "--quiet", "--no-record")
    assert run.returncode == 0, run.stderr[-3000:]
    for with_mask, out, extra in ((True, "sim", []), (False, "open", ["--position", "22.3,114.17,10"])):
        sim = _cli("simulate", "--config", config(with_mask), "--out", str(tmp_path / out), "--quiet", *extra)
        assert sim.returncode == 0, sim.stderr[-3000:]
    a = _code_table(next((tmp_path / "run").glob("*_MO.rnx")))
    b = _code_table(next((tmp_path / "sim").glob("*_MO.rnx")))
    c = _code_table(next((tmp_path / "open").glob("*_MO.rnx")))
    masked = {k[1] for k in set(c) - set(b)}
    d = np.array([a[k] - b[k] for k in set(a) & set(b)])
    print(f"sky mask: run {len(a)} / simulate {len(b)} / open sky {len(c)} code observations; satellites under the "
          f"mask {sorted(masked)}; run - simulate max {np.abs(d).max():.2e} m")
    assert masked and set(b) < set(c)
    assert set(a) == set(b)
    assert np.abs(d).max() <= 1e-3


def _setup(tmp_path, trajectory, observer, **params) -> SimulationSetup:
    return setup_from_config(load_config(), tmp_path, trajectory, start=GnssTime.from_iso("2025-06-01T10:00:00"),
                             duration_s=120.0, interval_s=1.0, observer=observer).with_params(**params)


def test_the_fix_uses_the_tracked_satellites_above_a_low_mask(tmp_path):
    used, tracked = [], []

    def observer(t, ecef, obs, sol):
        tracked.append(obs.n_tracked_sats)
        used.append(sol.n_used)

    setup = _setup(tmp_path, Trajectory.static(OPEC_ECEF_M, "ecef"), observer, systems="G", elevation_mask_deg=5.0)
    run_simulation(setup)
    ratio = np.sum(used) / np.sum(tracked)
    print(f"mask 5 deg, GPS, open sky: {np.mean(tracked):.1f} satellites tracked, {np.mean(used):.1f} used "
          f"({100 * ratio:.1f} %)")
    assert min(tracked) >= 8
    assert ratio >= 0.95


def test_offline_velocity_of_a_moving_antenna(tmp_path):
    # 3 m/s towards local east, 100 m above the ground, in ECEF (no scene needed)
    lat, lon, h = 50.8, 4.36, 100.0
    p0 = np.array(geodetic_to_ecef(lat, lon, h))
    east = np.array([-np.sin(np.radians(lon)), np.cos(np.radians(lon)), 0.0])
    t_s = np.arange(0.0, 121.0, 10.0)
    path = Trajectory(t_s, p0 + np.outer(3.0 * t_s, east), "ecef")
    vel = []

    def observer(t, ecef, obs, sol):
        if sol.vel_status == "fix":
            vel.append(np.asarray(sol.vel_enu_mps))

    run_simulation(_setup(tmp_path, path, observer, systems="GE"))
    v = np.array(vel[1:])                    # the first epoch has no previous position
    speed_err = np.abs(np.hypot(v[:, 0], v[:, 1]) - 3.0)
    print(f"offline velocity: {len(v)} epochs, mean {v.mean(axis=0).round(3)} m/s ENU, horizontal speed error "
          f"95 % {np.percentile(speed_err, 95):.3f} m/s")
    assert len(v) >= 110
    assert np.linalg.norm(v.mean(axis=0) - [3.0, 0.0, 0.0]) <= 0.02      # no bias (0 m/s before: 3 m/s off)
    assert np.percentile(speed_err, 95) <= 0.05


def test_a_shared_parameter_in_one_node_section_is_refused(tmp_path):
    cfg = tmp_path / "split.yaml"
    cfg.write_text("gnss_sim_receiver:\n  ros__parameters:\n    rate_hz: 2.0\n")
    with pytest.raises(ValueError, match=r"split.yaml.*gnss_sim_receiver.*'rate_hz' is shared by every node.*'/\*\*'"):
        load_config(cfg)
    for cmd in (["config", "--check", str(cfg)], ["simulate", "--config", str(cfg), "--out", str(tmp_path / "o")]):
        res = _cli(*cmd)
        assert res.returncode == 2, (cmd, res.stderr)
        assert "'rate_hz' is shared by every node" in res.stderr and "Traceback" not in res.stderr
    assert not (tmp_path / "o").exists()
    # a node section may still narrow the systems it uses
    ok = tmp_path / "narrow.yaml"
    ok.write_text("gnss_sim_receiver:\n  ros__parameters:\n    systems: G\n")
    assert load_config(ok).node("receiver")["systems"] == "G"


@pytest.mark.parametrize("option, value, message", [
    ("--rate", "1000", "option --rate: parameter 'rate_hz' is 1000.0; maximum is 100.0"),
    ("--rate", "0", "option --rate: parameter 'rate_hz' is 0.0; minimum"),
    ("--interval", "0", "option --interval is 0.0"),
    ("--mask-deg", "95", "option --mask-deg: parameter 'elevation_mask_deg' is 95.0; maximum is 90.0"),
    ("--mask-deg", "nan", "'elevation_mask_deg' is nan; a finite number"),
    ("--start", "1975-01-01T00:00:00", "option --start: parameter 'start_time' is '1975-01-01T00:00:00': outside"),
    ("--duration", "0", "option --duration: parameter 'duration_s' is 0.0; minimum"),
    ("--systems", "GX", "option --systems: parameter 'systems' is 'GX' (unknown: X)"),
])
def test_impossible_values_are_errors_naming_the_option(tmp_path, option, value, message):
    res = _cli("simulate", "--position-ecef", WEST_ECEF_M, option, value, "--out", str(tmp_path / "o"), "--quiet")
    assert res.returncode == 2, res.stdout
    assert message in res.stderr and "Traceback" not in res.stderr, res.stderr
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("doc, message", [
    ({"/**": {"ros__parameters": {"rate_hz": 1000.0}}}, "'rate_hz' is 1000.0; maximum is 100.0"),
    ({"/**": {"ros__parameters": {"elevation_mask_deg": 95.0}}}, "'elevation_mask_deg' is 95.0; maximum is 90.0"),
    ({"/**": {"ros__parameters": {"start_time": "1975-01-01T00:00:00"}}}, "outside the supported span"),
    ({"/**": {"ros__parameters": {"systems": "GZ"}}}, "'systems' is 'GZ' (unknown: Z)"),
    ({"gnss_sim_receiver": {"ros__parameters": {"cn0_lose_dbhz": 40.0}}}, "'cn0_lose_dbhz' (40.0) exceeds"),
])
def test_config_check_simulate_and_run_agree(tmp_path, doc, message):
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(yaml.safe_dump(doc))
    with pytest.raises(ValueError, match="bad.yaml"):
        load_config(cfg)
    for cmd in (["config", "--check", str(cfg)],
                ["simulate", "--config", str(cfg), "--out", str(tmp_path / "s"), "--quiet"],
                ["run", "--config", str(cfg), "--out", str(tmp_path / "r"), "--quiet", "--no-record"]):
        res = _cli(*cmd, timeout=120)
        assert res.returncode == 2, (cmd, res.stderr[-2000:])
        assert message in res.stderr and "Traceback" not in res.stderr, (cmd, res.stderr[-2000:])


def test_negative_numbers_after_a_space(tmp_path):
    res = _cli("simulate", "--position-ecef", WEST_ECEF_M, "--duration", "3", "--systems", "G", "--mask-deg", "-5",
               "--out", str(tmp_path / "w"), "--quiet")
    assert res.returncode == 0, res.stderr
    header = next((tmp_path / "w").glob("*_MO.rnx")).read_text().splitlines()
    pos = next(ln for ln in header if "APPROX POSITION XYZ" in ln)
    assert np.allclose([float(v) for v in pos.split()[:3]], [float(v) for v in WEST_ECEF_M.split(",")], atol=1e-3)
    south = _cli("simulate", "--position", "-33.8688,-151.2093,40", "--duration", "2", "--systems", "G",
                 "--out", str(tmp_path / "s"), "--quiet")
    assert south.returncode == 0, south.stderr
    lat = [float(r["lat_deg"]) for r in _fixes(tmp_path / "s" / "fix.csv").values()]
    assert lat and all(abs(v + 33.8688) < 1e-3 for v in lat)


def test_a_reset_chain_repeats_its_run(tmp_path):
    """Per-run state (receiver, tracking, clock, prior fix) is forgotten on reset: a reconfigured node starts
    clean and gives the first run's answer again."""
    from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
    from gnss_sim_ros2.core.receiver.chain import ChainSettings, ReceiverChain

    p = load_config().node("receiver")
    chain = ReceiverChain(ChainSettings.from_params({**p, "systems": "GE", "output_dir": ""}))
    t0 = GnssTime.from_iso(p["start_time"])
    eph, _ = open_ephemeris("synthetic", t0, 30.0, "GE", workdir=tmp_path)
    ecef = np.array(OPEC_ECEF_M)

    def one_run():
        rows = []
        for k in range(10):
            ep = chain.step(t0 + float(k), ecef, eph.states(t0 + float(k), systems="GE"))
            rows.append(np.asarray(ep.obs.pseudorange_m).copy())
        return rows

    first = one_run()
    assert chain.epochs == 10 and chain.fixes == 10 and chain.prior_ecef_m is not None
    chain.reset()
    assert chain.epochs == 0 and chain.prior_ecef_m is None and chain.rx is None
    again = one_run()
    assert len(first[0]) > 10
    assert all(np.array_equal(a, b) for a, b in zip(first, again))
