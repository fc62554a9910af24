"""Nothing already produced is lost, on the commands that write files (core/output_folder.py, core/figures.py).

A run stopped (SIGTERM) or killed (SIGKILL) midway, or one whose writing fails, leaves the earlier results
byte for byte; a figure is never half-written under its name; a default output the user did not name never
replaces a file the command did not write; an output that is a folder is refused before any work; an
interrupted sweep's table keeps the earlier rows of the runs it did not redo.  The folder rules themselves
(a user's file refused, own files replaced) are in test_output_safety.py, `gnss-sim run` under signals in
test_run_faults.py, the RINEX writer under SIGKILL in test_rinex_obs.py."""
from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gnss_sim_ros2.cli import main
from gnss_sim_ros2.core.output_folder import OutputNotOurs, check_unnamed_output, write_manifest

CLI = [sys.executable, "-m", "gnss_sim_ros2.cli"]
SIMULATE = ["simulate", "--position", "50,4,100", "--systems", "G", "--quiet"]


def _contents(folder: Path) -> dict:
    """{relative path: bytes} of every file under ``folder``."""
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _cli(*args, timeout=300):
    return subprocess.run(CLI + [str(a) for a in args], capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> tuple[Path, Path]:
    """(observation, navigation) RINEX of one 60 s simulate run, outside every folder the tests write."""
    out = tmp_path_factory.mktemp("rec") / "o"
    res = _cli(*SIMULATE, "--duration", "60", "--out", out)
    assert res.returncode == 0, res.stderr[-2000:]
    [obs], [nav] = out.glob("*_MO.rnx"), out.glob("*_MN.rnx")
    return obs, nav


# ------------------------------------------------------------------------------------- simulate stopped or killed
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGKILL])
def test_simulate_stopped_or_killed_midway_keeps_the_earlier_results(tmp_path, signum):
    from gnss_sim_ros2.core.rinex.obs_write import truncate_incomplete_epoch

    out = tmp_path / "o"
    assert _cli(*SIMULATE, "--duration", "30", "--out", out).returncode == 0
    before = _contents(out)
    proc = subprocess.Popen(CLI + [*SIMULATE, "--duration", "400000", "--out", str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    staged = []
    while not staged and time.monotonic() < deadline:       # some epochs written under the staging folder
        staged = [p for p in tmp_path.glob(".o.partial-*/*_MO.rnx") if p.stat().st_size > 50_000]
        time.sleep(0.2)
    assert staged, "no epochs staged"
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode in (143, -signal.SIGKILL), err[-2000:]
    assert _contents(out) == before                          # the earlier results, byte for byte
    rinex = staged[0].read_text()
    assert rinex.count("\n> ") >= 10
    assert truncate_incomplete_epoch(staged[0]) == 0          # no torn epoch: readable as it was left
    if signum == signal.SIGTERM:                             # closed, and the user is told where it is
        assert "TIME OF LAST OBS" in rinex.split("END OF HEADER")[0]
        assert f"earlier results in {out} are kept" in err and str(staged[0].parent) in err
        assert "Traceback" not in err
        nxt = _cli(*SIMULATE, "--duration", "30", "--out", out)     # the next run names them and leaves them
        assert nxt.returncode == 0 and f"{staged[0].parent} holds the outputs of a run that was stopped" in nxt.stderr
        assert staged[0].read_text() == rinex


def test_simulate_stopped_into_a_new_folder_keeps_its_epochs_there(tmp_path):
    out = tmp_path / "o"
    proc = subprocess.Popen(CLI + [*SIMULATE, "--duration", "400000", "--out", str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not [p for p in tmp_path.glob(".o.partial-*/*_MO.rnx") if p.stat().st_size > 50_000]:
        assert time.monotonic() < deadline, "no epochs staged"
        time.sleep(0.2)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err[-2000:]
    [obs] = out.glob("*_MO.rnx")
    assert "TIME OF LAST OBS" in obs.read_text().split("END OF HEADER")[0]
    assert not list(tmp_path.glob(".o.partial-*"))


# ------------------------------------------------------------------------- calibrate, compare: failure midway
def _earlier_results(folder: Path, command: str) -> dict:
    """A folder holding an earlier run's results of ``command`` (its manifest lists them)."""
    folder.mkdir()
    (folder / "report.md").write_text("# the earlier report\n")
    (folder / "statistics.json").write_text('{"earlier": true}\n')
    write_manifest(folder, ["report.md", "statistics.json"], command)
    return _contents(folder)


def _fail_in(monkeypatch, module: str, name: str):
    """``module.name`` raises KeyboardInterrupt after writing a part of a file into the folder it is given."""
    import importlib

    def interrupted(*args, **kwargs):
        folder = next(a for a in args if isinstance(a, Path) and a.is_dir())
        (folder / "report.md").write_text("# half a rep")
        raise KeyboardInterrupt

    monkeypatch.setattr(importlib.import_module(module), name, interrupted)


def test_calibrate_interrupted_while_writing_keeps_the_earlier_results(tmp_path, recording, monkeypatch):
    obs, nav = recording
    out = tmp_path / "cal"
    before = _earlier_results(out, "gnss-sim calibrate")
    _fail_in(monkeypatch, "gnss_sim_ros2.core.calibration.report", "write_report")
    assert main(["calibrate", "--obs", str(obs), "--nav", str(nav), "--out", str(out)]) == 130     # interrupted
    assert _contents(out) == before
    assert not list(tmp_path.glob(".cal.partial-*"))


def test_compare_interrupted_while_writing_keeps_the_earlier_results(tmp_path, recording, monkeypatch):
    obs, nav = recording
    out = tmp_path / "cmp"
    before = _earlier_results(out, "gnss-sim compare")
    _fail_in(monkeypatch, "gnss_sim_ros2.core.comparison", "write_report")
    assert main(["compare", "--sim", str(obs), "--real", str(obs), "--nav", str(nav), "--out", str(out)]) == 130
    assert _contents(out) == before
    assert not list(tmp_path.glob(".cmp.partial-*"))


# ------------------------------------------------------------------------------------------------ named files
def test_a_figure_whose_write_fails_leaves_the_previous_one(tmp_path, monkeypatch):
    from matplotlib.figure import Figure

    from gnss_sim_ros2.core.figures import pyplot, save_figure

    plt = pyplot()
    png = tmp_path / "sky.png"
    save_figure(plt.figure(), png)
    before = png.read_bytes()

    def torn(self, fname, **kwargs):              # matplotlib's savefig takes a path or a binary file
        (fname.write if hasattr(fname, "write") else Path(fname).write_bytes)(before[:100])  # a part, then stopped
        raise KeyboardInterrupt

    monkeypatch.setattr(Figure, "savefig", torn)
    with pytest.raises(KeyboardInterrupt):
        save_figure(plt.figure(), png)
    assert png.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["sky.png"]    # no temporary file left


def test_bench_refuses_an_output_folder_before_running(tmp_path, capsys):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.txt").write_text("four years of work\n")
    for option in ("--json", "--plot"):
        assert main(["bench", "--epochs", "3", "--no-real", "--presets", "fast", option, str(mine)]) == 2
        err = capsys.readouterr().err
        assert f"option {option}: {mine} is a folder" in err and "[bench]" not in err    # no preset was run
    assert _contents(mine) == {"thesis.txt": b"four years of work\n"}


def test_skyplot_default_skyline_never_replaces_a_users_file(tmp_path, capsys):
    from gnss_sim_ros2.commands.skyplot import SKYLINE_HEADER
    from gnss_sim_ros2.core.scene.demo_world import demo_world_path

    (tmp_path / "skyline.csv").write_text("my measured skyline\n")
    rc = main(["skyplot", "--world", str(demo_world_path()), "--at", "0,0,1.5", "--time", "2025-06-01T10:00:00",
               "--synthetic", "--csv", str(tmp_path / "sats.csv"), "--png", str(tmp_path / "sky.png")])
    assert rc == 2
    assert "give --skyline-csv FILE" in capsys.readouterr().err
    assert _contents(tmp_path) == {"skyline.csv": b"my measured skyline\n"}    # nothing written
    # skyplot's own skyline (its header) is replaced by the next run; an empty or foreign one is not
    own = tmp_path / "own.csv"
    own.write_text(",".join(SKYLINE_HEADER) + "\n0.0,1.000,0.000\n")
    check_unnamed_output(own, "--skyline-csv", ",".join(SKYLINE_HEADER))
    check_unnamed_output(tmp_path / "absent.csv", "--skyline-csv", ",".join(SKYLINE_HEADER))
    (tmp_path / "empty.csv").write_text("")
    with pytest.raises(OutputNotOurs, match="empty.csv"):
        check_unnamed_output(tmp_path / "empty.csv", "--skyline-csv", ",".join(SKYLINE_HEADER))


def test_export_world_never_replaces_a_users_file_under_the_sidecars_name(tmp_path, capsys):
    from gnss_sim_ros2.core.scene.demo_world import demo_world_path

    (tmp_path / "m.scene.yaml").write_text("my notes\n")
    assert main(["export-world", str(demo_world_path()), "--out", str(tmp_path / "m.ply")]) == 2
    assert "m.scene.yaml exists and gnss-sim did not write it" in capsys.readouterr().err
    assert _contents(tmp_path) == {"m.scene.yaml": b"my notes\n"}


# ------------------------------------------------------------------------------------------------------ sweep
def test_an_interrupted_sweeps_table_keeps_the_earlier_rows(tmp_path):
    from gnss_sim_ros2.core.sweep.table import read_previous_rows, read_rows, rows_so_far, write_rows

    path = tmp_path / "results.parquet"
    earlier = [{"index": i, "run": f"run{i:05d}", "duration_s": 5.0, "status": "ok"} for i in (1, 2)]
    write_rows(earlier, path)
    new = [{"index": 1, "run": "run00001", "duration_s": 3000.0, "status": "ok"}]
    write_rows(rows_so_far(new, read_previous_rows(path)), path)
    assert [(r["run"], r["duration_s"]) for r in read_rows(path)] == [("run00001", 3000.0), ("run00002", 5.0)]
    assert read_previous_rows(tmp_path / "absent.parquet") == []
    (tmp_path / "torn.parquet").write_bytes(b"PAR1 not a table")
    assert read_previous_rows(tmp_path / "torn.parquet") == []
