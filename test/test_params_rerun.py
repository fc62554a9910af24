"""What a run records, reruns (issue 25): the params.yaml that `gnss-sim run` writes (one section per node, the
shared parameters repeated in each, as a ROS parameter file has them) is accepted by `simulate --config`,
`run --config` and `config --check` (load_config: the launch file's config:= reads it the same way), and gives
the RINEX observations of the original configuration."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

CLI = [sys.executable, "-m", "gnss_sim_ros2.cli"]


def _cli(*args, timeout=300):
    env = dict(os.environ, ROS_DOMAIN_ID=str(os.getpid() % 90 + 7))
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    return subprocess.run(CLI + list(args), capture_output=True, text=True, timeout=timeout, env=env)


def _body(folder: Path) -> list[str]:
    """The observation records of the folder's RINEX observation file (after END OF HEADER)."""
    lines = next(folder.glob("*_MO.rnx")).read_text().splitlines()
    end = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln)
    return lines[end + 1:]


@pytest.mark.slow
def test_a_runs_params_file_reruns(tmp_path):
    pytest.importorskip("rclpy", reason="rclpy is not installed (run make test, or source ROS 2)")
    pytest.importorskip("gnss_sim_msgs", reason="gnss_sim_msgs is not built (run make test)")
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump({"/**": {"ros__parameters": {"seed": 7, "systems": "GE",
                                                                "start_time": "2024-03-01T12:00:00"}},
                                   "gnss_sim_ephemeris": {"ros__parameters": {"duration_s": 5.0}},
                                   "gnss_sim_receiver": {"ros__parameters": {"profile": "ublox_m8t"}}}))
    run = _cli("run", "--config", str(cfg), "--out", str(tmp_path / "run"), "--quiet", "--no-record")
    assert run.returncode == 0, run.stderr[-3000:]
    params = tmp_path / "run" / "params.yaml"
    doc = yaml.safe_load(params.read_text())
    # the case of issue 25: a shared-only parameter repeated in every node's section
    assert all(sec["ros__parameters"]["start_time"] == "2024-03-01T12:00:00" for sec in doc.values())
    check = _cli("config", "--check", str(params))
    assert check.returncode == 0, check.stderr
    for name, config in (("again", params), ("original", cfg)):
        sim = _cli("simulate", "--config", str(config), "--out", str(tmp_path / name), "--quiet")
        assert sim.returncode == 0, sim.stderr[-3000:]
    again, original = _body(tmp_path / "again"), _body(tmp_path / "original")
    assert len(original) > 6 * 10                     # 6 epochs of tens of satellites
    assert again == original
    rerun = _cli("run", "--config", str(params), "--out", str(tmp_path / "rerun"), "--quiet", "--no-record")
    assert rerun.returncode == 0, rerun.stderr[-3000:]
    assert _body(tmp_path / "rerun") == _body(tmp_path / "run")


def test_disagreeing_sections_are_refused_naming_both(tmp_path):
    from gnss_sim_ros2.config_file import load_config

    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"gnss_sim_ephemeris": {"ros__parameters": {"start_time": "2024-03-01T12:00:00"}},
                                   "gnss_sim_receiver": {"ros__parameters": {"start_time": "2024-03-02T12:00:00"}}}))
    with pytest.raises(ValueError, match=r"bad.yaml: section 'gnss_sim_ephemeris': parameter 'start_time' is shared "
                                         r"by every node.*gives '2024-03-01T12:00:00' and "
                                         r"section 'gnss_sim_receiver' gives '2024-03-02T12:00:00'"):
        load_config(bad)
    # one node's section alone: the other nodes would keep the default (rcl reads the file so)
    one = tmp_path / "one.yaml"
    one.write_text(yaml.safe_dump({"gnss_sim_ephemeris": {"ros__parameters": {"rate_hz": 2.0}}}))
    with pytest.raises(ValueError, match=r"'rate_hz' is shared by every node.*the default for 'gnss_sim_visibility'"):
        load_config(one)
    res = _cli("simulate", "--config", str(bad), "--out", str(tmp_path / "o"))
    assert res.returncode != 0 and "Traceback" not in res.stderr and "'gnss_sim_receiver'" in res.stderr


def test_derived_sections_hold_what_the_configuration_derives(tmp_path):
    """A run with robots or RTK writes its derived nodes' sections: accepted as written, refused when edited."""
    from gnss_sim_ros2 import graph
    from gnss_sim_ros2.config_file import load_config

    cfg = load_config(None, {"/**": {"output_dir": str(tmp_path / "run"), "seed": 4}})
    for name, extra in (("rtk", graph.rtk_parameter_sections(cfg)), ("robots", graph.robot_parameter_sections(cfg, 3))):
        doc = yaml.safe_load(yaml.safe_dump({**cfg.ros_parameter_file_dict(), **extra}))
        f = tmp_path / f"{name}.yaml"
        f.write_text(yaml.safe_dump(doc))
        assert load_config(f).values == cfg.values, name
    doc["/robot2/gnss_sim_receiver"]["ros__parameters"]["seed"] = 40
    f.write_text(yaml.safe_dump(doc))
    with pytest.raises(ValueError, match=r"section '/robot2/gnss_sim_receiver': parameter 'seed' is 40.*\(6 here\)"):
        load_config(f)
