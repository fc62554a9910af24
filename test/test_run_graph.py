"""The running system (`gnss-sim run`): the scenarios of the launch tests, through pytest.

Every node in one process and one process per node; topics flow; RINEX and
bag written and read back by independent readers (georinex, RTKLIB, rosbags);
a bad parameter stops the start with the node's error; a run killed mid-way
leaves valid RINEX and bag files up to the kill.
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("rclpy", reason="rclpy is not installed (run make test, or source ROS 2)")
pytest.importorskip("gnss_sim_msgs", reason="gnss_sim_msgs is not built (run make test)")

CLI = [sys.executable, "-m", "gnss_sim_ros2.cli"]


def _env():
    env = dict(os.environ, ROS_DOMAIN_ID=str(os.getpid() % 100 + 1))
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    return env


def _run(out: Path, *extra, timeout=300):
    return subprocess.run(CLI + ["run", "--out", str(out), "--quiet", *extra], capture_output=True, text=True,
                          env=_env(), timeout=timeout)


def _check_outputs(out: Path, epochs: int):
    import georinex

    summary = json.loads((out / "summary.json").read_text())
    assert summary["epochs"] == epochs
    assert summary["epochs_without_output"] == 0
    obs = next(out.glob("*_MO.rnx"))
    nav = next(out.glob("*_MN.rnx"))
    ds = georinex.load(obs, use="G")
    assert ds.time.size == epochs  # one RINEX epoch per simulated epoch
    counts = summary["bag_messages"]
    for topic in ("/gnss/fix", "/gnss/observations", "/gnss/satellite_states", "/gnss/visibility", "/gnss/status"):
        assert counts.get(topic) == epochs, (topic, counts)  # nothing dropped
    assert (out / "skyplot.png").stat().st_size > 10_000
    if shutil.which("rnx2rtkp"):
        pos = out / "rtk.pos"
        subprocess.run(["rnx2rtkp", "-p", "0", "-sys", "G,E", "-o", str(pos), str(obs), str(nav)],
                       capture_output=True, timeout=120)
        sols = [ln for ln in pos.read_text().splitlines() if ln and not ln.startswith("%")]
        assert len(sols) >= epochs - 2, "RTKLIB computed no solution from the RINEX files of the run"
    return summary


@pytest.mark.slow
def test_composed_run_writes_rinex_bag_skyplot(tmp_path):
    res = _run(tmp_path, "--duration", "15", "--systems", "GE")
    assert res.returncode == 0, res.stderr[-3000:]
    s = _check_outputs(tmp_path, 16)
    assert s["mode"] == "composed" and s["fix_availability"] > 0.9


@pytest.mark.slow
def test_one_process_per_node(tmp_path):
    res = _run(tmp_path, "--duration", "8", "--systems", "GE", "--processes")
    assert res.returncode == 0, res.stderr[-3000:]
    s = _check_outputs(tmp_path, 9)
    assert s["mode"] == "processes"


def test_bad_parameter_stops_the_start(tmp_path):
    # a world file that is there but no SDF (a missing one is refused before the start: test_bad_inputs_sweep3)
    world = tmp_path / "world.sdf"
    world.write_text("not an SDF world\n")
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(f"gnss_sim_visibility:\n  ros__parameters:\n    world_file: {world}\n")
    res = _run(tmp_path / "out", "--config", str(cfg), "--duration", "3", "--no-record")
    assert res.returncode == 3
    assert "gnss_sim_visibility: configure failed" in res.stderr
    assert str(world) in res.stderr


@pytest.mark.slow
def test_killed_run_leaves_valid_rinex_and_bag(tmp_path):
    import georinex

    from gnss_sim_ros2.recorder import count_messages

    out = tmp_path / "o"
    proc = subprocess.Popen(CLI + ["run", "--out", str(out), "--duration", "3000", "--systems", "G"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env())
    deadline = time.monotonic() + 120
    obs = None
    while time.monotonic() < deadline:
        found = list(tmp_path.glob(".o.partial-*/*_MO.rnx"))    # written beside --out, moved there at the end
        if found and found[0].stat().st_size > 20_000:
            obs = found[0]
            break
        time.sleep(0.5)
    assert obs is not None, "the run wrote no RINEX epochs"
    proc.send_signal(signal.SIGTERM)
    proc.wait(timeout=60)
    obs = out / obs.name
    ds = georinex.load(obs, use="G")
    n_rinex = ds.time.size
    assert 3 <= n_rinex < 3001
    counts = count_messages(out / "bag")
    # the bag holds every epoch up to the kill (the last one may be cut between topics)
    assert abs(counts["/gnss/fix"] - n_rinex) <= 1
    assert abs(counts["/gnss/observations"] - n_rinex) <= 1
