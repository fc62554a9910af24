"""Messages for people (issue 25): a warning is one line through logging ("gnss-sim <command>: warning: <file>:
<reason>"), not Python's warning with its source line; --quiet (every subcommand has it) silences warnings; no
interpreter noise at exit; in the nodes a warning goes through the node's logger."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from gnss_sim_ros2.cli import COMMANDS, build_parser

CLI = [sys.executable, "-m", "gnss_sim_ros2.cli"]
NOISE = ("Traceback", "warnings.warn(", "ResourceWarning", "Exception ignored", "check_coverage(")


def _cli(*args, timeout=300):
    env = dict(os.environ, ROS_DOMAIN_ID=str(os.getpid() % 90 + 9), PYTHONWARNINGS="default")
    return subprocess.run(CLI + list(args), capture_output=True, text=True, timeout=timeout, env=env)


def _stderr_lines(res) -> list[str]:
    """stderr without the progress lines (\\r-separated '[simulate] epoch ...')."""
    return [ln for ln in res.stderr.replace("\r", "\n").splitlines() if ln.strip() and not ln.startswith("[")]


def test_a_warning_is_one_line_and_quiet_silences_it(opec_dir, tmp_path):
    nav = opec_dir / "OPEC00NOR_S_20220010000_01D_GN.rnx"
    # 23:50 + 20 min runs past the file's last records: satellites without ephemeris (EphemerisCoverageWarning)
    args = ["simulate", "--nav", str(nav), "--start", "2022-01-01T23:50:00", "--duration", "30"]
    res = _cli(*args, "--out", str(tmp_path / "a"))
    assert res.returncode == 0, res.stderr[-2000:]
    lines = _stderr_lines(res)
    print("\n".join(lines))
    assert lines, "no warning: the case does not warn any more"
    for ln in lines:
        assert ln.startswith(f"gnss-sim simulate: warning: {nav}: "), ln
    assert not any(n in res.stderr for n in NOISE), res.stderr[-2000:]
    quiet = _cli(*args, "--quiet", "--out", str(tmp_path / "b"))
    assert quiet.returncode == 0 and quiet.stderr == "", quiet.stderr[-2000:]


def test_every_subcommand_takes_quiet():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    missing = [name for name in COMMANDS if "--quiet" not in sub.choices[name]._option_string_actions]
    assert not missing


def test_no_noise_at_exit(tmp_path):
    """A simulate run and a sky plot end without tracebacks, ResourceWarnings or 'Exception ignored'."""
    res = _cli("simulate", "--duration", "10", "--out", str(tmp_path / "sim"))
    assert res.returncode == 0, res.stderr[-2000:]
    assert not any(n in res.stderr for n in NOISE), res.stderr[-2000:]
    from gnss_sim_ros2.core.scene.demo_world import demo_world_path

    sky = _cli("skyplot", "--world", str(demo_world_path()), "--at", "0,0,1.5", "--time", "2025-06-01T10:00:00",
               "--synthetic", "--csv", str(tmp_path / "sky.csv"), "--png", str(tmp_path / "sky.png"))
    assert sky.returncode == 0, sky.stderr[-2000:]
    assert not any(n in sky.stderr for n in NOISE), sky.stderr[-2000:]
    assert all(ln.startswith("gnss-sim skyplot: warning: ") for ln in _stderr_lines(sky)), sky.stderr


def test_a_nodes_warning_goes_through_its_logger(opec_dir, capfd):
    """The ephemeris node configured over a span its navigation file does not cover: the warning is one line of
    the node's logger ([WARN] [...] [gnss_sim_ephemeris]: <file>: ...), no Python warning."""
    pytest.importorskip("rclpy", reason="rclpy is not installed (run make test, or source ROS 2)")
    pytest.importorskip("gnss_sim_msgs", reason="gnss_sim_msgs is not built (run make test)")
    import warnings

    from rclpy.parameter import Parameter
    from ros_helpers import RosFixture

    from gnss_sim_ros2.nodes.ephemeris_node import EphemerisNode

    nav = opec_dir / "OPEC00NOR_S_20220010000_01D_GN.rnx"
    ros = RosFixture()
    showwarning = warnings.showwarning
    try:
        node = ros.add(EphemerisNode(parameter_overrides=[
            Parameter("source", value="broadcast"), Parameter("nav_files", value=[str(nav)]),
            Parameter("start_time", value="2022-01-01T23:50:00"), Parameter("duration_s", value=30.0),
            Parameter("output_dir", value="")], context=ros.context))
        node.trigger_configure()
        assert node._state_machine.current_state[1] == "inactive", node.last_error
        node.trigger_cleanup()
    finally:
        warnings.showwarning = showwarning
        ros.close()
    err = capfd.readouterr().err
    lines = [ln for ln in err.splitlines() if str(nav) in ln]
    print("\n".join(lines))
    assert lines and all("[WARN]" in ln and "[gnss_sim_ephemeris]" in ln for ln in lines), err[-2000:]
    assert "warnings.warn(" not in err and "EphemerisCoverageWarning" not in err
