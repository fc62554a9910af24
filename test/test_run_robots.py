"""`gnss-sim run --robots N`: several robots in one graph, each its namespace, one ephemeris and one scene.

Real runs of the node graph: every robot's topics in the bag, its RINEX in out/robot<k>, its own positions,
the same satellites served to all; per-robot figures and the worst robot in summary.json; bad counts and
--rtk with several robots refused, naming the options.
"""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy", reason="rclpy is not installed (run make test, or source ROS 2)")
pytest.importorskip("gnss_sim_msgs", reason="gnss_sim_msgs is not built (run make test)")

import subprocess  # noqa: E402

CLI = [sys.executable, "-m", "gnss_sim_ros2.cli"]


def _run(out: Path, *extra, timeout=300):
    env = dict(os.environ, ROS_DOMAIN_ID=str((os.getpid() + 7) % 100 + 1))
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    return subprocess.run(CLI + ["run", "--out", str(out), "--quiet", *extra], capture_output=True, text=True,
                          env=env, timeout=timeout)


def _bag_messages(bag: Path, topics) -> dict:
    from rosbags.highlevel import AnyReader

    from gnss_sim_ros2.recorder import typestore

    out = {t: [] for t in topics}
    with AnyReader([bag], default_typestore=typestore()) as reader:
        conns = [c for c in reader.connections if c.topic in out]
        for conn, _, raw in reader.messages(connections=conns):
            out[conn.topic].append(reader.deserialize(raw, conn.msgtype))
    return out


def _each_robot_its_outputs(out: Path, s: dict, epochs: int):
    """Two robots' topics in the bag at every epoch, one observation file each in out/robot<k>, one
    navigation file, one /gnss/satellite_states per epoch (one ephemeris node for both)."""
    import georinex

    counts = s["bag_messages"]
    assert counts["/gnss/satellite_states"] == epochs
    for k in (0, 1):
        for t in ("fix", "observations", "status", "vel", "nmea", "visibility"):
            assert counts.get(f"/robot{k}/gnss/{t}") == epochs, (k, t, counts)
        obs = list((out / f"robot{k}").glob("*_MO.rnx"))
        assert len(obs) == 1, list(out.rglob("*.rnx"))
        assert georinex.load(obs[0], use="G").time.size == epochs
        assert s["per_robot"][f"robot{k}"]["fix_availability"] > 0.9
        assert s["per_robot"][f"robot{k}"]["epochs_without_output"] == 0
    assert "/gnss/fix" not in counts
    assert len(list(out.glob("*_MN.rnx"))) == 1 and not list(out.glob("*_MO.rnx"))


def _stamp(m) -> float:
    return m.header.stamp.sec + m.header.stamp.nanosec * 1e-9


@pytest.mark.slow
def test_two_robots_each_its_namespace_one_ephemeris(tmp_path):
    out = tmp_path / "o"
    res = _run(out, "--robots", "2", "--duration", "10", "--systems", "GE")
    assert res.returncode == 0, res.stderr[-3000:]
    s = json.loads((out / "summary.json").read_text())
    epochs = 11
    assert s["epochs"] == epochs and s["epochs_without_output"] == 0 and s["robots"] == 2
    _each_robot_its_outputs(out, s, epochs)
    assert s["scene_loads"]["loaded"] == 1 and s["scene_loads"]["shared"] >= 1    # one world for both
    per = s["per_robot"]
    worst = s["worst_robot"]
    assert worst["fix_availability"]["value"] == min(f["fix_availability"] for f in per.values())
    assert worst["latency_ms_p99"]["value"] == max(f["latency_ms_p99"] for f in per.values())
    for f in per.values():
        assert f["latency_ms_median"] <= f["latency_ms_p95"] <= f["latency_ms_p99"]
        # each robot's fix is published after its observations (ReceiverChain.observe, publish, finish)
        assert f["fix_latency_ms_median"] > f["latency_ms_median"] > 0
    # composed (one executor): every robot's observations go out before any robot's fix (ReceiverNode queues
    # the fix half behind what waits in the executor), so no robot's observations wait for another one's fix
    assert max(f["latency_ms_median"] for f in per.values()) < min(f["fix_latency_ms_median"] for f in per.values())

    msgs = _bag_messages(out / "bag", ["/robot0/gnss/visibility", "/robot1/gnss/visibility", "/tf_static"])
    v0 = {_stamp(m): m for m in msgs["/robot0/gnss/visibility"]}
    v1 = {_stamp(m): m for m in msgs["/robot1/gnss/visibility"]}
    assert set(v0) == set(v1) and len(v0) == epochs
    for t in v0:
        a = np.array([v0[t].antenna_world_m.x, v0[t].antenna_world_m.y])
        b = np.array([v1[t].antenna_world_m.x, v1[t].antenna_world_m.y])
        assert np.linalg.norm(a - b) > 1.0, f"both robots at {a} at t = {t}"        # the convoy: apart
        # the same satellites served to both (one /gnss/satellite_states): the same ones above the horizon
        assert {x.sv for x in v0[t].satellites} == {x.sv for x in v1[t].satellites}
    frames = {tf.child_frame_id for m in msgs["/tf_static"] for tf in m.transforms}
    assert {"robot0/gnss_antenna", "robot1/gnss_antenna"} <= frames


@pytest.mark.slow
def test_two_robots_one_process_per_node(tmp_path):
    """The robots' sections of the parameter file (/robot<k>/<node>) reach the nodes of their own processes."""
    out = tmp_path / "p"
    res = _run(out, "--robots", "2", "--duration", "4", "--systems", "G", "--processes")
    assert res.returncode == 0, res.stderr[-3000:]
    s = json.loads((out / "summary.json").read_text())
    assert s["epochs_without_output"] == 0 and s["mode"] == "processes"
    for k in (0, 1):
        assert s["bag_messages"].get(f"/robot{k}/gnss/fix") == 5
        assert list((out / f"robot{k}").glob("*_MO.rnx"))


@pytest.mark.slow
def test_two_robots_one_process_per_robot(tmp_path):
    """--layout robot: each robot's player, visibility and receiver in a process of its own, the one ephemeris
    node in the run's: every robot's outputs, one publisher of the satellite states, no scene in the run's
    process, each robot process busy with its epochs."""
    out = tmp_path / "r"
    epochs = 7
    res = _run(out, "--robots", "2", "--duration", "6", "--systems", "GE", "--layout", "robot")
    assert res.returncode == 0, res.stderr[-3000:]
    s = json.loads((out / "summary.json").read_text())
    assert s["mode"] == "robot_processes" and s["epochs"] == epochs and s["epochs_without_output"] == 0
    _each_robot_its_outputs(out, s, epochs)
    assert s["scene_loads"]["loaded"] == 0            # the visibility nodes are not in the run's process
    assert set(s["processes"]) == {"gnss_sim_run", "robot0", "robot1"}
    for k in (0, 1):
        assert s["processes"][f"robot{k}"]["cpu_ms_per_epoch"] > 0, s["processes"]
        assert s["processes"][f"robot{k}"]["peak_rss_mb"] > 0
    assert s["satellite_states_publishers"] == ["/gnss_sim_ephemeris"]


def test_layout_and_processes_refused_together(tmp_path):
    res = _run(tmp_path / "o", "--layout", "robot", "--processes", "--duration", "2", "--no-record")
    assert res.returncode == 2, res.stderr
    assert "--processes" in res.stderr and "--layout robot" in res.stderr
    assert not (tmp_path / "o").exists()
    bad = _run(tmp_path / "o", "--layout", "container", "--duration", "2", "--no-record")
    assert bad.returncode == 2 and "--layout" in bad.stderr and "robot" in bad.stderr


@pytest.mark.parametrize("count", ["0", "-2", "17"])
def test_bad_robot_count_refused_naming_the_option(tmp_path, count):
    res = _run(tmp_path / "o", "--robots", count, "--duration", "2", "--no-record")
    assert res.returncode == 2, res.stderr
    assert "option --robots" in res.stderr and "1..16" in res.stderr
    assert not (tmp_path / "o").exists()


def test_rtk_with_several_robots_refused_naming_both(tmp_path):
    res = _run(tmp_path / "o", "--robots", "2", "--rtk", "--duration", "2", "--no-record")
    assert res.returncode == 2, res.stderr
    assert "--rtk" in res.stderr and "--robots 2" in res.stderr


def test_path_files_one_per_robot(tmp_path):
    (tmp_path / "a.csv").write_text("t_s,e_m,n_m,u_m\n0,0,0,1.5\n10,5,0,1.5\n")   # there: the count is what is wrong
    cfg = tmp_path / "c.yaml"
    cfg.write_text(f"gnss_sim_trajectory_player:\n  ros__parameters:\n    robot_trajectory_files: "
                   f"['{tmp_path / 'a.csv'}']\n")
    res = _run(tmp_path / "o", "--robots", "3", "--config", str(cfg), "--duration", "2", "--no-record")
    assert res.returncode == 2, res.stderr
    assert "robot_trajectory_files" in res.stderr and "--robots" in res.stderr


@pytest.mark.slow
def test_missing_tf_of_the_robots_names_their_frames(tmp_path):
    """Without the players (Gazebo's TF expected), the run stops naming a robot's own antenna frame."""
    cfg = tmp_path / "c.yaml"
    cfg.write_text("gnss_sim_visibility:\n  ros__parameters:\n    tf_timeout_s: 0.5\n")
    res = _run(tmp_path / "o", "--robots", "2", "--no-trajectory-player", "--config", str(cfg), "--duration", "5",
               "--no-record")
    assert res.returncode == 1, res.stderr[-2000:]
    assert "no transform from 'world' to 'robot0/gnss_antenna'" in res.stderr
    assert "Traceback" not in res.stderr
