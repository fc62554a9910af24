"""The documented colcon invocation builds gnss_sim_msgs and gnss_sim from a clone.

On this kind of machine colcon builds against the ROS 2 wheels' prefix (the
venv); on a ROS 2 install against the sourced distribution.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
TRACKED = ["package.xml", "setup.py", "setup.cfg", "resource", "gnss_sim_ros2", "msg_pkg", "launch", "config",
           "worlds"]


@pytest.mark.slow
def test_colcon_builds_both_packages(tmp_path):
    colcon = shutil.which("colcon") or str(Path(sys.executable).parent / "colcon")
    if not Path(colcon).exists():
        pytest.skip("colcon is not installed (it comes with requirements/test.txt)")
    src = tmp_path / "src" / "gnss_sim"
    src.mkdir(parents=True)
    for name in TRACKED:
        p = REPO / name
        if p.is_dir():
            shutil.copytree(p, src / name, ignore=shutil.ignore_patterns("__pycache__"))
        elif p.exists():
            shutil.copy2(p, src / name)
    env = dict(os.environ)
    if not env.get("ROS_DISTRO"):
        prefix = sys.prefix
        env["AMENT_PREFIX_PATH"] = prefix
        env["CMAKE_PREFIX_PATH"] = prefix
        env["PATH"] = f"{Path(sys.executable).parent}:{env['PATH']}"
    res = subprocess.run(
        [colcon, "build", "--base-paths", "src/gnss_sim", "src/gnss_sim/msg_pkg",
         "--cmake-args", f"-DPython3_EXECUTABLE={sys.executable}", "-DBUILD_TESTING=OFF"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600,
    )
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    assert "2 packages finished" in res.stdout
    inst = tmp_path / "install"
    assert (inst / "gnss_sim" / "lib" / "gnss_sim" / "gnss-sim").exists()
    assert (inst / "gnss_sim" / "share" / "ament_index" / "resource_index" / "packages" / "gnss_sim").exists()
    # the receiver profiles ship as package data beside the code that loads them (core/receiver/profile_file.py)
    profiles = {p.name for p in (inst / "gnss_sim").rglob("gnss_sim_ros2/profiles/*.yaml")}
    assert {"geodetic.yaml", "single_frequency.yaml", "ublox_m8t.yaml", "ublox_f9p.yaml"} <= profiles, profiles
    msgs = list((inst / "gnss_sim_msgs").rglob("gnss_sim_msgs/msg/_satellite_states.py"))
    assert msgs, "generated Python messages are missing"
