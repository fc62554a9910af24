"""The threat timeline of a run (core/threats/timeline.py, `gnss-sim threats-plot`): what it reads from fix.csv and
the RINEX file lines up with the scenario's events, and the command refuses a run without labels."""
from __future__ import annotations

import csv
import subprocess
import sys

import numpy as np
import pytest

from gnss_sim_ros2.config_file import load_config
from gnss_sim_ros2.core.simulation import run_simulation, setup_from_config
from gnss_sim_ros2.core.threats.timeline import read_timeline, summary
from gnss_sim_ros2.core.trajectory import Trajectory

STATIC = Trajectory.static([50.0758, 14.4179, 250.0], "geodetic")
SCENARIO = """\
version: 1
events:
  - {type: fault, name: dead, kind: off, start_s: 4, end_s: 7}
  - {type: fault, name: shift, kind: position_offset, offset_enu_m: [30, 40, 0], start_s: 10, end_s: 12}
"""


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("timeline")
    (tmp / "s.yaml").write_text(SCENARIO)
    cfg = load_config(overrides={"/**": {"systems": "GE"},
                                 "receiver": {"noise": False, "scenario": str(tmp / "s.yaml")}})
    run_simulation(setup_from_config(cfg, tmp / "run", STATIC, duration_s=14.0, interval_s=1.0))
    return tmp / "run"


def test_the_timeline_follows_the_labels(run_dir):
    tl = read_timeline(run_dir, STATIC)
    assert len(tl.t_s) == 15 and tl.t_s[1] == 1.0
    assert tl.events == ["dead", "shift"]
    assert tl.event_spans("dead") == [(4.0, 7.0)] and tl.event_spans("shift") == [(10.0, 12.0)]
    off = np.isin(tl.t_s, [4.0, 5.0, 6.0])
    assert not tl.is_fix[off].any() and tl.is_fix[~off].all()
    assert np.isnan(tl.h_err_m[off]).all()
    shifted = np.isin(tl.t_s, [10.0, 11.0])
    np.testing.assert_allclose(tl.h_err_m[shifted], 50.0, atol=1.0)       # 30 m east, 40 m north
    assert np.nanmax(tl.h_err_m[~shifted]) < 5.0
    # off: no observation written at those epochs (RINEX), tracked satellites elsewhere, C/N0 of bands 1 and 5
    on_obs = np.isin(tl.obs_t_s, [4.0, 5.0, 6.0])
    assert not on_obs.any() or (tl.n_tracked[on_obs] == 0).all()
    assert (tl.n_tracked[~on_obs] >= 4).all() and {"1", "5"} <= set(tl.cn0_dbhz)
    assert summary(tl)[0].startswith("dead: active 4-7 s; 3 of 3 epochs without a fix")


def test_the_command_writes_the_figure_and_refuses_a_run_without_labels(run_dir, tmp_path):
    png = tmp_path / "t.png"
    traj = tmp_path / "static.csv"
    traj.write_text("t_s,lat_deg,lon_deg,h_m\n0,50.0758,14.4179,250.0\n")
    out = subprocess.run([sys.executable, "-m", "gnss_sim_ros2.cli", "threats-plot", str(run_dir), "--png", str(png),
                          "--trajectory", str(traj)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and "shift: active 10-12 s" in out.stdout
    plain = tmp_path / "plain"
    plain.mkdir()
    with open(run_dir / "fix.csv", newline="") as f:
        rows = [{k: v for k, v in r.items() if k != "active_events"} for r in csv.DictReader(f)]
    with open(plain / "fix.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    out = subprocess.run([sys.executable, "-m", "gnss_sim_ros2.cli", "threats-plot", str(plain), "--png",
                          str(tmp_path / "u.png")], capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and "no active_events column: the run had no threat scenario" in out.stderr
