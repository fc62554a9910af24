"""`gnss-sim run` under faults: two runs at once, a failed rerun, Ctrl-C / SIGTERM / SIGKILL, orphaned
node processes, a missing TF, a foreign publisher (issue "Faults and bad input")."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("rclpy", reason="rclpy is not installed (run make test, or source ROS 2)")
pytest.importorskip("gnss_sim_msgs", reason="gnss_sim_msgs is not built (run make test)")

CLI = [sys.executable, "-m", "gnss_sim_ros2.cli", "run"]


def _env(**extra):
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", **extra)
    env.pop("ROS_DOMAIN_ID", None)
    return env


def _start(out: Path, *extra, env=None):
    return subprocess.Popen(CLI + ["--out", str(out), "--quiet", *extra], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env or _env(),
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def _wait_for_epochs(folder_glob, parent: Path, size=20_000, timeout=120):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found = [p for p in parent.glob(folder_glob) if p.stat().st_size > size]
        if found:
            return found[0]
        time.sleep(0.3)
    raise AssertionError(f"no RINEX epochs under {parent}")


def _rinex_epochs(path: Path) -> int:
    return sum(1 for ln in path.read_text().splitlines() if ln.startswith("> "))


@pytest.mark.slow
def test_two_runs_at_once_do_not_cross(tmp_path):
    a = _start(tmp_path / "a", "--duration", "30", "--systems", "GE")
    b = _start(tmp_path / "b", "--duration", "30", "--systems", "GE")
    ra, rb = a.communicate(timeout=300), b.communicate(timeout=300)
    assert a.returncode == 0 and b.returncode == 0, (ra[1][-2000:], rb[1][-2000:])
    domains = set()
    for out in (tmp_path / "a", tmp_path / "b"):
        s = json.loads((out / "summary.json").read_text())
        domains.add(s["ros_domain_id"])
        assert s["epochs"] == 31 and s["epochs_without_output"] == 0
        assert s["bag_messages"]["/gnss/fix"] == 31 and s["bag_messages"]["/gnss/satellite_states"] == 31
        assert _rinex_epochs(next(out.glob("*_MO.rnx"))) == 31
        assert s["foreign_publishers"] == {}
    assert len(domains) == 2


@pytest.mark.slow
def test_one_output_folder_is_locked_by_one_run(tmp_path):
    a = _start(tmp_path / "o", "--duration", "3000", "--systems", "G", "--no-record")
    try:
        _wait_for_epochs(".o.partial-*/*_MO.rnx", tmp_path, size=5_000)
        b = subprocess.run(CLI + ["--out", str(tmp_path / "o"), "--duration", "5", "--quiet"], capture_output=True,
                           text=True, env=_env(), timeout=120)
        assert b.returncode == 1
        assert f"output folder {tmp_path / 'o'} is in use by another gnss-sim run (pid {a.pid})" in b.stderr
        assert "Traceback" not in b.stderr
    finally:
        a.send_signal(signal.SIGINT)
        a.communicate(timeout=120)
    assert a.returncode == 130


@pytest.mark.slow
def test_a_failed_rerun_keeps_the_previous_results(tmp_path):
    out = tmp_path / "o"
    ok = subprocess.run(CLI + ["--out", str(out), "--duration", "5", "--systems", "G", "--quiet"],
                        capture_output=True, text=True, env=_env(), timeout=300)
    assert ok.returncode == 0, ok.stderr[-2000:]
    before = {p.name: p.stat().st_size for p in out.rglob("*") if p.is_file()}
    # a world that is there but no SDF fails the run at configure (a missing one is refused before the start)
    broken = tmp_path / "typo.sdf"
    broken.write_text("<sdf version='1.9'><world name='w'><model name='m'>\n")
    bad = subprocess.run(CLI + ["--out", str(out), "--duration", "5", "--world", str(broken),
                                "--quiet"], capture_output=True, text=True, env=_env(), timeout=300)
    assert bad.returncode == 3 and "typo.sdf" in bad.stderr and "Traceback" not in bad.stderr
    assert {p.name: p.stat().st_size for p in out.rglob("*") if p.is_file()} == before
    assert not list(tmp_path.glob(".o.partial-*"))


@pytest.mark.slow
@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_ctrl_c_and_sigterm_end_with_summary_and_closed_files(tmp_path, signum, code):
    from gnss_sim_ros2.recorder import count_messages

    proc = _start(tmp_path / "o", "--duration", "3000", "--systems", "G")
    _wait_for_epochs(".o.partial-*/*_MO.rnx", tmp_path)
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == code, err[-2000:]
    assert "Traceback" not in err
    out = tmp_path / "o"
    s = json.loads((out / "summary.json").read_text())
    assert 3 <= s["epochs"] < 3001
    assert (out / "skyplot.png").stat().st_size > 10_000
    rinex = next(out.glob("*_MO.rnx")).read_text()
    assert "TIME OF LAST OBS" in rinex.split("END OF HEADER")[0]
    assert abs(count_messages(out / "bag")["/gnss/fix"] - s["epochs"]) <= 1


@pytest.mark.slow
def test_the_bag_survives_sigkill(tmp_path):
    from gnss_sim_ros2.recorder import count_messages

    proc = _start(tmp_path / "o", "--duration", "3000", "--systems", "G", "--realtime")
    staged = _wait_for_epochs(".o.partial-*/*_MO.rnx", tmp_path, size=2_000)
    folder = staged.parent

    def epochs_done():     # fix.csv: one row per epoch, line-buffered (RINEX skips epochs with no signal)
        return max(0, len((folder / "fix.csv").read_text().splitlines()) - 1)

    deadline = time.monotonic() + 120
    while epochs_done() < 16 and time.monotonic() < deadline:
        time.sleep(0.2)
    proc.kill()
    proc.communicate(timeout=60)
    n = epochs_done()
    counts = count_messages(folder / "bag")           # rosbags reads the bag as it was left
    print(f"SIGKILL after {n} epochs: {counts.get('/gnss/fix', 0)} fixes in the bag")
    assert n >= 16
    # the split being written is lost: at most 5 s of a real-time run (5 epochs at 1 Hz) plus one in flight
    assert n - 6 <= counts["/gnss/fix"] <= n + 1
    # the next run into the same folder says where the killed run's outputs are and leaves them
    nxt = subprocess.run(CLI + ["--out", str(tmp_path / "o"), "--duration", "2", "--systems", "G", "--no-record"],
                         capture_output=True, text=True, env=_env(), timeout=300)
    assert nxt.returncode == 0 and f"{folder} holds the outputs of a run that was killed" in nxt.stderr
    assert folder.is_dir()


@pytest.mark.slow
def test_node_processes_die_with_a_killed_run(tmp_path):
    import psutil

    proc = _start(tmp_path / "o", "--duration", "3000", "--systems", "G", "--processes", "--no-record")
    _wait_for_epochs(".o.partial-*/*_MO.rnx", tmp_path, size=5_000)
    children = psutil.Process(proc.pid).children(recursive=True)
    assert len(children) >= 4, [c.cmdline() for c in children]
    proc.kill()
    proc.communicate(timeout=60)
    gone, alive = psutil.wait_procs(children, timeout=20)
    assert not alive, [p.cmdline() for p in alive]


@pytest.mark.slow
def test_a_missing_tf_fails_the_run_naming_the_frames(tmp_path):
    t0 = time.monotonic()
    res = subprocess.run(CLI + ["--out", str(tmp_path / "o"), "--duration", "600", "--no-trajectory-player",
                                "--no-record", "--quiet"], capture_output=True, text=True, env=_env(), timeout=300)
    took = time.monotonic() - t0
    print(f"missing TF: the run failed after {took:.1f} s")
    assert res.returncode == 1
    assert "no transform from 'world' to 'gnss_antenna' in TF within tf_timeout_s = 5 s" in res.stderr
    assert "Traceback" not in res.stderr
    assert took < 60          # one timeout, not one per epoch (600 epochs x 5 s)
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_a_foreign_publisher_is_reported(tmp_path):
    import rclpy
    from sensor_msgs.msg import NavSatFix

    domain = 90 + os.getpid() % 10
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain)
    node = rclpy.create_node("intruder", context=ctx)
    pub = node.create_publisher(NavSatFix, "/gnss/fix", 10)
    try:
        res = subprocess.run(CLI + ["--out", str(tmp_path / "o"), "--duration", "3", "--systems", "G", "--quiet",
                                    "--no-record", "--domain-id", str(domain)], capture_output=True, text=True,
                             env=_env(), timeout=300)
    finally:
        node.destroy_publisher(pub)
        node.destroy_node()
        rclpy.shutdown(context=ctx)
    assert res.returncode == 0, res.stderr[-2000:]
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["foreign_publishers"] == {"/gnss/fix": ["/intruder"]}
    assert "/gnss/fix has publishers outside this run's graph: /intruder" in res.stderr
