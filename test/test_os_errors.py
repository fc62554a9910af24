"""Operating-system errors (an output under a regular file, a read-only file system) are one line naming the
path and the reason, rc 1, for every command that writes; never a traceback."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-m", "gnss_sim_ros2.cli"]


@pytest.mark.parametrize("make_args", [
    lambda bad: ["simulate", "--position", "50,4,100", "--duration", "2", "--systems", "G", "--out", bad, "--quiet"],
    lambda bad: ["run", "--out", bad, "--duration", "2", "--quiet", "--no-record"],
    lambda bad: ["export-world", str(REPO / "worlds" / "courtyard.sdf"), "--out", f"{bad}/w.ply"],
], ids=["simulate", "run", "export-world"])
@pytest.mark.parametrize("where", ["under_a_file", "read_only_fs"])
def test_os_errors_are_one_line(tmp_path, make_args, where):
    if where == "under_a_file":
        (tmp_path / "plain").write_text("not a folder")
        bad = str(tmp_path / "plain" / "out")
    else:
        bad = "/proc/gnss_sim_no_such_dir/out"      # /proc refuses new entries even for root
    res = subprocess.run(CLI + make_args(bad), capture_output=True, text=True, timeout=300)
    assert res.returncode == 1, (res.returncode, res.stderr[-2000:])
    assert "Traceback" not in res.stderr
    last = res.stderr.strip().splitlines()[-1]
    assert last.startswith("gnss-sim ") and ": error: " in last and ("plain" in last or "/proc/" in last), last


@pytest.mark.parametrize("signum, code", [(2, 130), (15, 143)])
def test_simulate_stopped_by_a_signal_closes_its_rinex(tmp_path, signum, code):
    import signal
    import time

    proc = subprocess.Popen(CLI + ["simulate", "--position", "50,4,100", "--duration", "86400", "--systems", "G",
                                   "--out", str(tmp_path / "o"), "--quiet"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        found = list(tmp_path.glob(".o.partial-*/*_MO.rnx"))     # written beside --out, moved there at the end
        if found and found[0].stat().st_size > 50_000:
            break
        time.sleep(0.2)
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == code and "Traceback" not in err, err[-2000:]
    found = list((tmp_path / "o").glob("*_MO.rnx"))                # a stopped run keeps its closed epochs
    assert len(found) == 1 and not list(tmp_path.glob(".o.partial-*"))
    header = found[0].read_text().split("END OF HEADER")[0]
    assert "TIME OF LAST OBS" in header
