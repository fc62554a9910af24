"""Acceptance of gnss-sim sweep on an existing cluster: a `dask scheduler` and a `dask worker --nworkers 2`
started as separate processes on a free loopback port; 8 seeds of the 600 s demo give 8 rows."""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gnss_sim_ros2.core.sweep.table import read_rows

REPO = Path(__file__).resolve().parents[1]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(argv, env, log: Path):
    return subprocess.Popen(argv, env=env, stdout=log.open("w"), stderr=subprocess.STDOUT, start_new_session=True)


def _stop(proc):
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGTERM)      # its own session: the worker's nanny children go with it
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)


@pytest.fixture
def dask_cluster(tmp_path):
    """(address, worker log) of a scheduler and one `dask worker --nworkers 2` (1 thread each)."""
    from distributed import Client

    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]).rstrip(":")}
    sched = _start([sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", str(port),
                    "--no-dashboard"], env, tmp_path / "scheduler.log")
    worker = None
    try:
        worker = _start([sys.executable, "-m", "dask", "worker", address, "--nworkers", "2", "--nthreads", "1",
                         "--no-dashboard", "--host", "127.0.0.1"], env, tmp_path / "worker.log")
        deadline = time.monotonic() + 120
        while True:
            try:
                with Client(address, timeout="5s") as c:
                    c.wait_for_workers(2, timeout=max(1.0, deadline - time.monotonic()))
                break
            except (OSError, TimeoutError):
                if time.monotonic() > deadline or sched.poll() is not None or worker.poll() is not None:
                    logs = "\n".join(p.read_text()[-2000:] for p in tmp_path.glob("*.log"))
                    pytest.fail(f"the dask cluster did not come up:\n{logs}")
                time.sleep(1)
        yield address
    finally:
        if worker is not None:
            _stop(worker)
        _stop(sched)


def test_eight_seeds_of_600_s_on_a_hand_started_cluster(dask_cluster, tmp_path):
    out = tmp_path / "sweep"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    r = subprocess.run([sys.executable, "-m", "gnss_sim_ros2.cli", "sweep", "--seeds", "1-8", "--duration", "600",
                        "--scheduler", dask_cluster, "--out", str(out)], env=env, capture_output=True, text=True,
                       timeout=1500)
    assert r.returncode == 0, r.stderr[-3000:]
    rows = read_rows(out / "results.parquet")
    assert len(rows) == 8
    assert [r_["seed"] for r_ in rows] == list(range(1, 9))
    assert all(r_["status"] == "ok" and r_["epochs"] == 601 for r_ in rows), [r_["error"] for r_ in rows]
    assert len({r_["worker"] for r_ in rows}) == 2            # both worker processes ran some
    assert len({round(r_["h_err_p50_m"], 9) for r_ in rows}) == 8   # eight seeds, eight noise draws
    assert "8 runs on 2 worker(s)" in r.stdout
    for i in range(1, 9):
        assert (out / "runs" / f"run{i:05d}" / "fix.csv").is_file()


def test_an_interrupted_sweep_keeps_its_finished_rows(tmp_path):
    """Ctrl-C (SIGINT) in the middle: exit 130, results.parquet holds the runs finished so far."""
    out = tmp_path / "sweep"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.Popen([sys.executable, "-m", "gnss_sim_ros2.cli", "sweep", "--seeds", "1-40", "--duration",
                             "1200", "--workers", "2", "--quiet", "--out", str(out)], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 300
        while not (out / "results.parquet").is_file():      # written as soon as rows arrive
            assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read()[-2000:]
            time.sleep(0.5)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, err[-2000:]
    rows = read_rows(out / "results.parquet")
    assert 1 <= len(rows) < 40
    assert all(r["status"] == "ok" and r["epochs"] == 1201 for r in rows)
    assert not (out / ".cache").exists()
