"""A scenario through the ROS graph (``gnss-sim run --scenario``) and offline (``gnss-sim simulate
--scenario``): one chain, one answer -- every fault kind (output faults, a clock jump, the satellite faults on G10,
a satellite the demo tracks from the start) and a jammer give the same fix.csv, truth labels included, and the bag
records /gnss/threats/active.  What each kind does is tested offline in test_threats_faults.py."""
from __future__ import annotations

import csv
import json
import os
import subprocess
import sys

import pytest

CLI = [sys.executable, "-m", "gnss_sim_ros2.cli"]

SCENARIO = """\
version: 1
events:
  - {type: fault, name: shift, kind: position_offset, offset_enu_m: [10, 0, 0], start_s: 3, end_s: 6}
  - {type: fault, name: frozen, kind: stuck, start_s: 7, end_s: 10}
  - {type: fault, name: dead, kind: off, start_s: 11, end_s: 13}
  - {type: fault, name: jump, kind: clock_jump_s, jump_s: 1.0e-4, start_s: 14, end_s: 16}
  - type: jammer
    name: ppd
    position: [50.0758, 14.4182, 252.0]
    position_type: llh
    eirp_dbw: -20.0
    center_hz: 1575.42e6
    bandwidth_hz: 10.0e6
    start_s: 17
    end_s: 20
  - {type: fault, name: step, kind: satellite_clock_step_m, satellite: G10, step_m: 25.0, start_s: 21, end_s: 23}
  - {type: fault, name: ramp, kind: satellite_ramp_mps, satellite: G10, ramp_mps: 3.0, start_s: 23, end_s: 25}
  - {type: fault, name: eph, kind: bad_ephemeris, satellite: G10, error_m: 50.0, start_s: 25, end_s: 27}
"""


def _cli(*args, timeout=300):
    env = dict(os.environ, ROS_DOMAIN_ID=str(os.getpid() % 90 + 7))
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    return subprocess.run(CLI + list(args), capture_output=True, text=True, timeout=timeout, env=env)


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _fix_rows_run_and_simulate(tmp_path, scenario, duration_s: int):
    """The fix.csv rows of `gnss-sim run` (the ROS graph) and of `gnss-sim simulate` (offline) of one scenario, in
    tmp_path/run and tmp_path/simulate; each command checked to exit 0."""
    rows = []
    for command in ("run", "simulate"):
        p = _cli(command, "--duration", str(duration_s), "--scenario", str(scenario), "--out", str(tmp_path / command),
                 "--quiet")
        assert p.returncode == 0, f"{command}: {p.stderr[-3000:]}"
        rows.append(_rows(tmp_path / command / "fix.csv"))
    return rows


@pytest.mark.slow
def test_run_and_simulate_apply_one_scenario_alike(tmp_path):
    scn = tmp_path / "scenario.yaml"
    scn.write_text(SCENARIO)
    a, b = _fix_rows_run_and_simulate(tmp_path, scn, 28)
    assert a == b and len(a) == 29
    labels = [r["active_events"] for r in a]
    assert labels[3:6] == ["shift"] * 3 and labels[7:10] == ["frozen"] * 3 and labels[11:13] == ["dead"] * 2
    assert labels[14:16] == ["jump"] * 2 and labels[17:20] == ["ppd"] * 3 and labels[0] == labels[20] == ""
    assert labels[21:23] == ["step"] * 2 and labels[23:25] == ["ramp"] * 2 and labels[25:27] == ["eph"] * 2
    assert labels[27] == ""
    assert all(r["status"] == "no_fix" and r["n_sats"] == "0" for r in a[11:13])           # off
    assert len({(r["lat_deg"], r["lon_deg"]) for r in a[6:10]}) == 1                        # stuck: epoch 6's
    assert max(int(r["n_sats"]) for r in a[17:20]) < min(int(r["n_sats"]) for r in a[:3])  # L1 jammed
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["bag_messages"]["/gnss/threats/active"] == 29


@pytest.mark.slow
def test_world_frame_jammer_is_placed_alike_in_the_graph_and_offline(tmp_path):
    """The demo scenario's car jammer, in world coordinates of the courtyard: the receiver node places it through
    the world's spherical_coordinates (parameter scenario_world, the visibility node's world) and casts it
    through the same scene as `gnss-sim simulate`: the same fix.csv, the fix lost while the car passes."""
    from gnss_sim_ros2.core.scene.demo_world import demo_world_path

    scn = demo_world_path().parents[1] / "config" / "scenarios" / "courtyard_threats.yaml"
    a, b = _fix_rows_run_and_simulate(tmp_path, scn, 50)
    assert a == b and len(a) == 51
    on = [r for r in a if r["active_events"] == "car_jammer"]
    assert len(on) == 31 and all(r["active_events"] == "" for r in a[:20])
    assert any(r["status"] == "no_fix" for r in on) and all(r["status"] == "fix" for r in a[:20])
