"""`ros2 launch gnss_sim ...` as a user types it, and every executable under SIGINT/SIGTERM.

Needs the real launch tools (../shared/ros2-tools): `make test` runs this file in .venv-launch
with gnss_sim registered in its ament index; the main suite skips it.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("launch_ros", reason="launch_ros is not installed here: make test runs this file in "
                    ".venv-launch (../shared/ros2-tools)")
from ament_index_python.packages import get_package_prefix, get_package_share_directory  # noqa: E402
from launch_helpers import NODES, Probe  # noqa: E402

from gnss_sim_ros2.recorder import count_messages  # noqa: E402

LIB = Path(get_package_prefix("gnss_sim")) / "lib" / "gnss_sim"


def _start(cmd, log: Path):
    """A child that SIGINT reaches (a background job of a non-interactive shell would ignore it)."""
    f = open(log, "w")
    return subprocess.Popen(cmd, stdout=f, stderr=subprocess.STDOUT, env=os.environ.copy(),
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL)), f


def _stop(proc, f, sig=signal.SIGINT, timeout_s=60.0) -> int:
    proc.send_signal(sig)
    try:
        return proc.wait(timeout=timeout_s)
    finally:
        f.close()


@pytest.fixture
def probe():
    p = Probe(speed=4.0)
    yield p
    p.close()


def test_package_is_in_the_ament_index():
    share = Path(get_package_share_directory("gnss_sim"))
    assert (share / "launch" / "sim.launch.py").is_file() and not (share / "launch").is_symlink()
    assert (share / "package.xml").is_file() and (share / "config" / "gnss_sim.yaml").is_file()
    assert (share / "worlds" / "courtyard.sdf").is_file()
    assert (LIB / "container").is_file() and (LIB / "recorder").is_file()
    out = subprocess.run(["ros2", "component", "types"], capture_output=True, text=True, check=True).stdout
    assert "gnss_sim\n  gnss_sim::TrajectoryPlayer\n  gnss_sim::EphemerisNode\n" in out


def test_ros2_launch_records_and_ends_cleanly_on_sigint(tmp_path, probe):
    """record:=true without `ros2 bag` here: gnss_sim's recorder node writes the bag; SIGINT: rc 0."""
    out = tmp_path / "out"
    proc, f = _start(["ros2", "launch", "gnss_sim", "sim.launch.py", f"output_dir:={out}", "record:=true"],
                     tmp_path / "launch.log")
    try:
        assert probe.wait_for(lambda: all(probe.state_or_none(n) == "active" for n in NODES), 120.0), \
            (tmp_path / "launch.log").read_text()[-3000:]
        probe.start_clock()
        assert probe.wait_for(lambda: len(probe.fixes_copy()) >= 8, 60.0)
    finally:
        rc = _stop(proc, f)
    log = (tmp_path / "launch.log").read_text()
    assert rc == 0, log[-3000:]
    assert "Traceback" not in log
    assert "recording into" in log and "process has died" not in log
    counts = count_messages(out / "bag")
    assert counts.get("/gnss/fix", 0) >= 8, counts
    assert list(out.glob("GSIM*_MO.rnx"))


def test_record_into_an_existing_bag_fails_the_launch(tmp_path):
    out = tmp_path / "out"
    (out / "bag").mkdir(parents=True)
    res = subprocess.run(["ros2", "launch", "gnss_sim", "sim.launch.py", f"output_dir:={out}", "record:=true"],
                         capture_output=True, text=True, timeout=60)
    assert res.returncode != 0
    assert f"the bag folder {out / 'bag'} exists already" in res.stdout + res.stderr
    assert "process started" not in res.stdout + res.stderr  # no node ran without its bag


def test_record_with_no_recorder_at_all_is_an_error(monkeypatch):
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "sim_launch", Path(get_package_share_directory("gnss_sim")) / "launch" / "sim.launch.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    real = importlib.util.find_spec
    monkeypatch.setattr(mod.importlib.util, "find_spec",
                        lambda name, *a: None if name in ("ros2bag", "rosbags") else real(name, *a))
    with pytest.raises(RuntimeError, match="nothing can record here"):
        mod._recorder("/tmp/gnss_sim_no_such_output_dir")


def _launch_module():
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "sim_launch", Path(get_package_share_directory("gnss_sim")) / "launch" / "sim.launch.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_composed_argument_layouts_and_refusal():
    mod = _launch_module()
    assert [mod.layout_of(v) for v in ("true", "False", "robot", "1", "off")] == \
        ["composed", "node", "robot", "composed", "node"]
    with pytest.raises(ValueError, match="launch argument composed is 'container'.*robot"):
        mod.layout_of("container")


def test_every_launch_argument_has_a_description():
    """nav2 bring-up's convention: `ros2 launch ... --show-args` tells a user what each argument does."""
    res = subprocess.run(["ros2", "launch", "gnss_sim", "sim.launch.py", "--show-args"], capture_output=True,
                         text=True, timeout=60)
    assert res.returncode == 0, res.stdout + res.stderr
    mod = _launch_module()
    for name in mod.ARGS:
        assert f"'{name}':" in res.stdout, (name, res.stdout)
    assert "no description given" not in res.stdout, res.stdout


def test_strict_world_argument_is_checked_by_the_parameter_table(tmp_path):
    """strict_world:= reaches the visibility parameters through load_config: a value that is no bool is refused
    naming the argument before any node starts."""
    res = subprocess.run(["ros2", "launch", "gnss_sim", "sim.launch.py", f"output_dir:={tmp_path / 'out'}",
                          "strict_world:=maybe"], capture_output=True, text=True, timeout=60)
    text = res.stdout + res.stderr
    assert res.returncode != 0, text
    assert "strict_world" in text and "process started" not in text, text


@pytest.mark.parametrize("exe, args, sig", [
    ("container", [], signal.SIGTERM),
    ("container", [], signal.SIGINT),
    ("receiver_node", [], signal.SIGTERM),
    ("lifecycle_manager", ["-p", "node_names:=[gnss_sim_absent]"], signal.SIGTERM),
    ("lifecycle_manager", ["-p", "node_names:=[gnss_sim_absent]"], signal.SIGINT),
    ("recorder", ["-p", "bag_dir:={tmp}/bag"], signal.SIGTERM),
])
def test_executables_exit_0_on_signals(tmp_path, probe, exe, args, sig):
    cmd = [str(LIB / exe), "--ros-args", *[a.format(tmp=tmp_path) for a in args]]
    proc, f = _start(cmd, tmp_path / "exe.log")
    name = {"container": "gnss_sim_container", "receiver_node": "gnss_sim_receiver",
            "lifecycle_manager": "gnss_sim_lifecycle_manager", "recorder": "gnss_sim_recorder"}[exe]
    try:
        assert probe.wait_for(lambda: name in probe.node.get_node_names(), 60.0), (tmp_path / "exe.log").read_text()
        time.sleep(0.5)
    finally:
        rc = _stop(proc, f, sig, timeout_s=30.0)
    log = (tmp_path / "exe.log").read_text()
    assert rc == 0, log
    assert "Traceback" not in log
    if exe == "recorder":
        assert (tmp_path / "bag" / "metadata.yaml").is_file()  # the bag was closed



if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-q"]))
