"""core/rtk: rtkrcv options, solution parsing, NavSatFix status mapping, and rtkrcv itself fed with our
RTCM3 over its TCP streams (Debian's rtklib 2.4.3 b34; its clock set to the simulated time by faketime)."""
from __future__ import annotations

import os
import time

import numpy as np
import pytest

from gnss_sim_ros2.core.frames import ecef_to_geodetic, enu_to_ecef, geodetic_to_ecef
from gnss_sim_ros2.core.rtcm.frame import epochs_of
from gnss_sim_ros2.core.rtk import solution as rs
from gnss_sim_ros2.core.rtk.config import (
    FORMAT_OPTIONS,
    OWNED_KEYS,
    RtkConfigError,
    default_options,
    merge_options,
    read_conf,
)
from gnss_sim_ros2.core.rtk.process import RtkrcvNotFound, RtkrcvProcess, find_faketime, find_rtkrcv
from gnss_sim_ros2.core.time import GnssTime


def rtklib_llh_line(week, tow, lat, lon, h, q, ns, cov, age, ratio, vel=None, cov_v=None) -> str:
    """A line as RTKLIB 2.4.3 solution.c outpos writes it (C format strings; sqvar cross terms)."""
    def sqvar(c):
        return -np.sqrt(-c) if c < 0 else np.sqrt(c)
    e = cov
    s = (f"{week:4d} {tow:10.3f} {lat:14.9f} {lon:14.9f} {h:10.4f} {q:3d} {ns:3d} {np.sqrt(e[1, 1]):8.4f} "
         f"{np.sqrt(e[0, 0]):8.4f} {np.sqrt(e[2, 2]):8.4f} {sqvar(e[0, 1]):8.4f} {sqvar(e[0, 2]):8.4f} "
         f"{sqvar(e[1, 2]):8.4f} {age:6.2f} {ratio:6.1f}")
    if vel is not None:
        v = cov_v
        s += (f" {vel[1]:10.5f} {vel[0]:10.5f} {vel[2]:10.5f} {np.sqrt(v[1, 1]):9.5f} {np.sqrt(v[0, 0]):8.5f} "
              f"{np.sqrt(v[2, 2]):8.5f} {sqvar(v[0, 1]):8.5f} {sqvar(v[0, 2]):8.5f} {sqvar(v[1, 2]):8.5f}")
    return s + "\r\n"


def test_solution_line_parses_to_enu_covariances():
    cov = np.array([[0.0004, -0.0001, 0.00005], [-0.0001, 0.0009, -0.0002], [0.00005, -0.0002, 0.0025]])
    cov_v = np.array([[0.01, 0.002, 0.0], [0.002, 0.04, -0.001], [0.0, -0.001, 0.09]])
    line = rtklib_llh_line(2190, 518400.0, 59.908867504, 10.75984447, 63.8385, 1, 15, cov, 0.5, 56.2,
                           vel=np.array([0.5, -0.25, 0.01]), cov_v=cov_v)
    sol = rs.parse_llh_line(line)
    assert sol.t == GnssTime.from_week_tow(2190, 518400.0)
    assert (sol.q, sol.ns, sol.quality, sol.status) == (1, 15, "fixed", rs.STATUS_GBAS_FIX)
    assert sol.lat_deg == 59.908867504 and sol.h_m == 63.8385 and sol.ratio == 56.2 and sol.age_s == 0.5
    np.testing.assert_allclose(sol.cov_enu_m2, cov, atol=2e-4 * 0.01 + 1e-8)   # printed with 4 decimals
    np.testing.assert_allclose(sol.vel_enu_mps, [0.5, -0.25, 0.01])
    np.testing.assert_allclose(sol.cov_vel_enu_m2ps2, cov_v, rtol=1e-3, atol=1e-7)
    assert np.allclose(sol.cov_enu_m2, sol.cov_enu_m2.T)
    no_vel = rs.parse_llh_line(rtklib_llh_line(2190, 1.0, 1.0, 2.0, 3.0, 5, 7, cov, 0.0, 0.0))
    assert no_vel.quality == "single" and not no_vel.vel_enu_mps.any()
    assert rs.parse_llh_line("%  GPST   latitude(deg) ...") is None and rs.parse_llh_line("  ") is None
    with pytest.raises(ValueError, match="fields"):
        rs.parse_llh_line("2190 518400.000 59.9 10.7")
    with pytest.raises(ValueError, match="not numeric"):
        rs.parse_llh_line(line.replace("56.2", "x"))


def test_status_mapping_follows_nmea_navsat_driver():
    # GGA quality of each RTKLIB Q (solution.c solq_nmea) as nmea_navsat_driver maps it
    assert rs.navsat_status(rs.Q_FIX) == rs.STATUS_GBAS_FIX       # GGA 4 RTK fixed
    assert rs.navsat_status(rs.Q_FLOAT) == rs.STATUS_GBAS_FIX     # GGA 5 RTK float
    assert rs.navsat_status(rs.Q_DGPS) == rs.STATUS_SBAS_FIX      # GGA 2 DGPS
    assert rs.navsat_status(rs.Q_SINGLE) == rs.STATUS_FIX         # GGA 1 autonomous
    assert rs.navsat_status(rs.Q_NONE) == rs.STATUS_NO_FIX
    assert rs.navsat_status(rs.Q_SBAS) == rs.STATUS_SBAS_FIX
    assert rs.navsat_status(rs.Q_PPP) == rs.STATUS_FIX
    with pytest.raises(ValueError, match="quality 9"):
        rs.navsat_status(9)


USER_CONF = """# my rtkrcv setup
inpstr1-type       =serial     # (0:off,1:serial,2:file,3:tcpsvr,4:tcpcli)
inpstr1-path       =ttyACM0:115200:8:n:1:off
inpstr1-format     =ubx
outstr1-format     =xyz
pos1-posmode       =static
pos1-frequency     =l1+2
pos1-navsys        =9
pos2-armode        =fix-and-hold
pos2-arthres       =2.5
stats-prnaccelh    =3.0
ant2-postype       =rtcm
misc-startcmd      =
"""


def test_user_conf_keeps_its_options_and_only_the_streams_change(tmp_path):
    conf = tmp_path / "my.conf"
    conf.write_text(USER_CONF)
    user = read_conf(conf)
    assert user["pos2-arthres"] == "2.5" and user["misc-startcmd"] == "" and user["inpstr1-format"] == "ubx"
    owned = {"inpstr1-type": "tcpcli", "inpstr1-path": "127.0.0.1:1", "inpstr1-format": "rtcm3",
             "outstr1-format": "llh", **FORMAT_OPTIONS}
    merged, replaced = merge_options(user, owned)
    for k, v in user.items():
        if k not in OWNED_KEYS:
            assert merged[k] == v, k
    assert merged["inpstr1-type"] == "tcpcli" and merged["outstr1-format"] == "llh"
    assert sorted(replaced) == ["inpstr1-format", "inpstr1-path", "inpstr1-type", "outstr1-format"]
    assert "pos1-dynamics" not in merged          # no generated defaults over a user's file: rtkrcv's own


def test_bad_conf_is_a_clear_error(tmp_path):
    bad = tmp_path / "bad.conf"
    bad.write_text("pos1-posmode=kinematic\nthis line has no equals sign\n")
    with pytest.raises(RtkConfigError, match=r"bad.conf, line 2"):
        read_conf(bad)
    with pytest.raises(RtkConfigError, match="cannot read"):
        read_conf(tmp_path / "missing.conf")
    with pytest.raises(RtkConfigError, match="rtk_systems"):
        default_options("GX")


def test_rtkrcv_missing_is_a_clear_error(monkeypatch, tmp_path):
    with pytest.raises(RtkrcvNotFound, match="rtkrcv not found '/no/such/rtkrcv'.*rtkrcv_path"):
        RtkrcvProcess(rtkrcv_path="/no/such/rtkrcv")
    monkeypatch.setenv("PATH", str(tmp_path))
    with pytest.raises(RtkrcvNotFound, match="apt-get install rtklib"):
        find_rtkrcv()
    assert issubclass(RtkrcvNotFound, ValueError)


def rtkrcv_and_faketime() -> bool:
    try:
        find_rtkrcv()
        find_faketime()
    except RtkrcvNotFound:
        return False
    return True


needs_rtkrcv = pytest.mark.skipif(not rtkrcv_and_faketime(), reason="RTKLIB rtkrcv and libfaketime are not "
                                  "installed (apt-get install rtklib faketime)")


@pytest.fixture(scope="module")
def base_rover(tmp_path_factory):
    """RTCM3 of a base and a rover 360 m apart, 1 Hz for 90 s, epoch by epoch."""
    from test_rtcm_rtklib import BASE_ECEF_M, START, simulate_to_rtcm

    out = tmp_path_factory.mktemp("rtk")
    lat, lon, h = ecef_to_geodetic(*BASE_ECEF_M)
    rover_ecef = np.asarray(enu_to_ecef(np.array([300.0, 200.0, 0.0]), lat, lon, h))
    kw = dict(systems="GE", duration_s=90.0, interval_s=1.0)
    base = simulate_to_rtcm(out / "base", BASE_ECEF_M, seed=11, marker="BASE", **kw)
    rover = simulate_to_rtcm(out / "rover", rover_ecef, seed=22, marker="ROVR", **kw)
    start_utc = GnssTime.from_iso(START).to_datetime("UTC")
    return {"base": epochs_of(base["rtcm"].read_bytes()), "rover": epochs_of(rover["rtcm"].read_bytes()),
            "rover_ecef": rover_ecef, "start_utc": start_utc, "out": out}


def run_rtkrcv(proc: RtkrcvProcess, base_rover, pace_s: float = 0.03) -> None:
    assert proc.wait_connected(15.0), proc.log_text()
    for b, r in zip(base_rover["base"], base_rover["rover"]):
        proc.feed_base(b)
        proc.feed_rover(r)
        time.sleep(pace_s)
    t_end = time.monotonic() + 5.0
    while proc.solutions < len(base_rover["rover"]) and time.monotonic() < t_end:
        time.sleep(0.1)


@needs_rtkrcv
def test_rtkrcv_fixes_our_streams(base_rover):
    sols, nmea = [], []
    proc = RtkrcvProcess(on_solution=sols.append, on_nmea=nmea.append, clock_start_utc=base_rover["start_utc"])
    with proc:
        run_rtkrcv(proc, base_rover)
        workdir = proc.workdir
    assert not proc.running and not workdir.exists()       # its own work folder is removed
    n = len(base_rover["rover"])
    fixed = [s for s in sols if s.q == rs.Q_FIX]
    err = np.array([np.linalg.norm(np.array(geodetic_to_ecef(s.lat_deg, s.lon_deg, s.h_m)) - base_rover["rover_ecef"])
                    for s in fixed])
    rms = float(np.sqrt(np.mean(err ** 2))) if len(err) else float("inf")
    print(f"\nrtkrcv on our RTCM3 over TCP: {len(sols)} solutions for {n} epochs, {len(fixed)} fixed, "
          f"3D error RMS {rms * 100:.2f} cm; {len(nmea)} NMEA sentences")
    assert len(sols) >= 0.95 * n
    assert len(fixed) >= 0.9 * n and rms < 0.02
    assert all(s.cov_enu_m2[0, 0] > 0 and s.cov_enu_m2[2, 2] > 0 for s in fixed)
    assert any(line.startswith("$GPGGA") or line.startswith("$GNGGA") for line in nmea)


@needs_rtkrcv
def test_rtkrcv_runs_a_user_conf(base_rover, tmp_path):
    conf = tmp_path / "user.conf"
    conf.write_text(USER_CONF.replace("pos1-posmode       =static", "pos1-posmode       =kinematic"))
    sols = []
    proc = RtkrcvProcess(user_conf=conf, on_solution=sols.append, clock_start_utc=base_rover["start_utc"],
                         workdir=tmp_path / "work")
    with proc:
        run_rtkrcv(proc, base_rover)
    written = read_conf(tmp_path / "work" / "gnss_sim_rtkrcv.conf")
    assert written["pos2-arthres"] == "2.5" and written["pos2-armode"] == "fix-and-hold"
    assert written["inpstr1-format"] == "rtcm3" and "inpstr1-format" in proc.replaced_options
    assert sum(s.q == rs.Q_FIX for s in sols) >= 0.9 * len(base_rover["rover"])


@needs_rtkrcv
def test_stop_leaves_no_process(base_rover):
    proc = RtkrcvProcess(clock_start_utc=base_rover["start_utc"])
    proc.start()
    assert proc.wait_connected(15.0)
    pid = proc.proc.pid
    proc.stop()
    with pytest.raises(ProcessLookupError):
        os.killpg(pid, 0)
    proc.stop()                  # twice: no error


@needs_rtkrcv
def test_rtkrcv_dies_with_a_killed_parent(tmp_path):
    """A node process killed with SIGKILL (no cleanup at all) takes rtkrcv with it (PR_SET_PDEATHSIG)."""
    import signal
    import subprocess
    import sys

    code = ("import datetime, sys, time\n"
            "from gnss_sim_ros2.core.rtk.process import RtkrcvProcess\n"
            "p = RtkrcvProcess(clock_start_utc=datetime.datetime(2022, 1, 1))\n"
            "p.start()\n"
            "print(p.proc.pid, flush=True)\n"
            "time.sleep(60)\n")
    parent = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    pid = int(parent.stdout.readline())
    os.kill(pid, 0)                                   # rtkrcv runs
    parent.send_signal(signal.SIGKILL)
    parent.wait(10)
    t_end = time.monotonic() + 10.0
    while time.monotonic() < t_end:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            break
        time.sleep(0.1)
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)


def test_baseline_line_parses_to_heading():
    # 1.2 m at 30 deg from north: e = 0.6, n = 1.0392; RTKLIB outenu layout
    line = ("2190 518400.000 0.6000 1.0392 0.0100   1  14   0.0020   0.0030   0.0060   0.0000   0.0000"
            "   0.0000   0.00  45.2\r\n")
    b = rs.parse_enu_line(line)
    assert abs(b.heading_deg - 30.0) < 0.01 and abs(b.length_m - 1.2) < 1e-3 and b.quality == "fixed"
    np.testing.assert_allclose(np.diag(b.cov_enu_m2), [0.002 ** 2, 0.003 ** 2, 0.006 ** 2])
    # sd: (n sde)^2 + (e sdn)^2 over length^4, in degrees
    sd = np.degrees(np.hypot(1.0392 * 0.002, 0.6 * 0.003) / 1.2 ** 2)
    assert abs(b.heading_sd_deg - sd) < 1e-3
    assert rs.parse_enu_line("% header") is None
    with pytest.raises(ValueError, match="15 expected"):
        rs.parse_enu_line("2190 518400.000 0.6 1.0")


@pytest.fixture(scope="module")
def two_antennas(base_rover):
    """RTCM3 of two antennas of one robot, 1.2 m apart at heading 30 deg (the second from the first)."""
    from test_rtcm_rtklib import simulate_to_rtcm

    lat, lon, h = ecef_to_geodetic(*base_rover["rover_ecef"])
    a1 = base_rover["rover_ecef"]
    a2 = np.asarray(enu_to_ecef(np.array([0.6, 1.2 * np.cos(np.radians(30.0)), 0.0]), lat, lon, h))
    kw = dict(systems="GE", duration_s=90.0, interval_s=1.0)
    first = simulate_to_rtcm(base_rover["out"] / "a1", a1, seed=31, marker="ANT1", **kw)
    second = simulate_to_rtcm(base_rover["out"] / "a2", a2, seed=32, marker="ANT2", **kw)
    return {"base": epochs_of(first["rtcm"].read_bytes()), "rover": epochs_of(second["rtcm"].read_bytes()),
            "start_utc": base_rover["start_utc"]}


@needs_rtkrcv
def test_moving_baseline_heading(two_antennas):
    """rtkrcv movingbase (base position from its own single point solution each epoch) gives the baseline
    of two antennas and its heading."""
    sols = []
    proc = RtkrcvProcess(options=default_options("GE", mode="movingbase"), on_solution=sols.append,
                         clock_start_utc=two_antennas["start_utc"], solution_format="enu")
    with proc:
        run_rtkrcv(proc, two_antennas)
    fixed = [b for b in sols if b.q == rs.Q_FIX]
    heading = np.array([b.heading_deg for b in fixed])
    length = np.array([b.length_m for b in fixed])
    print(f"\nmoving baseline 1.2 m at 30 deg: {len(fixed)} of {len(sols)} fixed, heading {heading.mean():.3f} "
          f"+- {heading.std():.3f} deg (reported sd {np.mean([b.heading_sd_deg for b in fixed]):.3f}), "
          f"length {length.mean():.4f} m")
    assert len(fixed) >= 0.9 * len(two_antennas["rover"])
    assert np.all(np.abs(heading - 30.0) < 0.5) and np.all(np.abs(length - 1.2) < 0.01)
    assert 0 < np.mean([b.heading_sd_deg for b in fixed]) < 1.0


@needs_rtkrcv
def test_rtkrcv_moving_rover_position_and_velocity(base_rover):
    """A rover driving east at 1 m/s from 360 m off the base: fixed positions on the path, ENU velocity of
    rtkrcv's dynamics model close to (1, 0, 0) m/s."""
    from test_rtcm_rtklib import BASE_ECEF_M, simulate_to_rtcm

    from gnss_sim_ros2.core.trajectory import Trajectory

    lat, lon, h = ecef_to_geodetic(*BASE_ECEF_M)
    ends = np.array([enu_to_ecef(np.array([300.0 + d, 200.0, 0.0]), lat, lon, h) for d in (0.0, 90.0)])
    path = Trajectory(np.array([0.0, 90.0]), ends, "ecef")
    rover = simulate_to_rtcm(base_rover["out"] / "moving", path, "GE", 90.0, 1.0, 23, "MOVR")
    sols = []
    proc = RtkrcvProcess(on_solution=sols.append, clock_start_utc=base_rover["start_utc"])
    with proc:
        run_rtkrcv(proc, {"base": base_rover["base"], "rover": epochs_of(rover["rtcm"].read_bytes())})
    t0 = GnssTime.from_iso("2022-01-01T01:00:00")
    fixed = [s for s in sols if s.q == rs.Q_FIX]
    err = np.array([np.linalg.norm(np.array(geodetic_to_ecef(s.lat_deg, s.lon_deg, s.h_m)) - path.position(s.t - t0))
                    for s in fixed])
    vel = np.array([s.vel_enu_mps for s in fixed[10:]])           # after the filter has converged
    v_err = vel - np.array([1.0, 0.0, 0.0])
    v_rms = np.sqrt(np.mean(v_err ** 2, axis=0)) * 100
    v_sd = np.sqrt(np.mean([np.diag(s.cov_vel_enu_m2ps2) for s in fixed[10:]], axis=0)) * 100
    print(f"\nmoving rover 1 m/s: {len(fixed)} of {len(sols)} fixed, 3D error RMS "
          f"{np.sqrt(np.mean(err ** 2)) * 100:.2f} cm, velocity error RMS E/N/U {v_rms.round(2)} cm/s, "
          f"reported sd {v_sd.round(2)} cm/s")
    assert len(fixed) >= 0.9 * 91
    assert np.sqrt(np.mean(err ** 2)) < 0.02
    assert np.all(np.sqrt(np.mean(v_err ** 2, axis=0)) < 0.05)
