"""Outputs never destroy what the command did not write (issue 25, core/output_folder.py).

A command writes and replaces only its own files (the manifest it leaves in the folder); a folder holding
anything else (a user's file, an input, another command's results; ``--out .`` included) is refused naming the
folder and the file; a failure while writing leaves the previous results as they were."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from gnss_sim_ros2.core.output_folder import MANIFEST_NAME, OutputFolder, OutputNotOurs, check_output_folder

CLI = [sys.executable, "-m", "gnss_sim_ros2.cli"]
SIMULATE = ["simulate", "--position", "50,4,100", "--duration", "10", "--systems", "G", "--quiet"]


def _cli(*args, cwd=None, timeout=300):
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    env.pop("ROS_DOMAIN_ID", None)
    return subprocess.run(CLI + [str(a) for a in args], capture_output=True, text=True, cwd=cwd, env=env,
                          timeout=timeout)


def _contents(folder: Path) -> dict:
    """{relative path: bytes} of every file under ``folder``."""
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _manifest(folder: Path) -> set:
    return set(json.loads((folder / MANIFEST_NAME).read_text())["files"])


def _refused(res, folder: Path, name: str, command: str):
    assert res.returncode == 2, (res.returncode, res.stderr[-2000:])
    assert "Traceback" not in res.stderr
    last = res.stderr.strip().splitlines()[-1]
    assert last.startswith(f"gnss-sim {command}: error: output folder {folder.resolve()} holds {name}"), last


@pytest.fixture(scope="module")
def nav_file(tmp_path_factory) -> Path:
    """A RINEX navigation file written by one simulate run (outside every folder the tests write)."""
    out = tmp_path_factory.mktemp("navsrc") / "o"
    res = _cli(*SIMULATE, "--out", out)
    assert res.returncode == 0, res.stderr[-2000:]
    [nav] = out.glob("*_MN.rnx")
    return nav


# ------------------------------------------------------------------------------------------------- simulate
def test_simulate_refuses_a_folder_holding_a_users_file(tmp_path):
    mine = tmp_path / "mydata"
    mine.mkdir()
    (mine / "thesis.txt").write_text("four years of work\n")
    res = _cli(*SIMULATE, "--out", mine)
    _refused(res, mine, "thesis.txt", "simulate")
    assert _contents(mine) == {"thesis.txt": b"four years of work\n"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mydata"]       # not even a lock file beside it


def test_simulate_keeps_a_stations_rinex_and_its_own_nav_input(tmp_path, nav_file):
    # a station's navigation file in the output folder, passed as --nav: main deleted it (*_MN.rnx)
    station = tmp_path / "station"
    station.mkdir()
    (station / nav_file.name).write_bytes(nav_file.read_bytes())
    before = _contents(station)
    res = _cli(*SIMULATE, "--nav", station / nav_file.name, "--start", "2025-06-01T10:00:00", "--out", station)
    _refused(res, station, nav_file.name, "simulate")
    assert _contents(station) == before
    # the folder's own navigation file (an earlier simulate's) as --nav of a run of another marker: kept
    out = tmp_path / "o"
    assert _cli(*SIMULATE, "--out", out).returncode == 0
    [nav] = out.glob("*_MN.rnx")
    nav_bytes = nav.read_bytes()
    res = _cli(*SIMULATE, "--nav", nav, "--marker", "ABCD", "--start", "2025-06-01T10:00:00", "--out", out)
    assert res.returncode == 0, res.stderr[-2000:]
    assert nav.read_bytes() == nav_bytes
    assert [p.name[:4] for p in out.glob("*_MO.rnx")] == ["ABCD"]       # the earlier observation file went
    assert _manifest(out) == set(_contents(out)) - {MANIFEST_NAME}


@pytest.mark.parametrize("option", ["--config", "--trajectory"])
def test_out_in_the_folder_of_an_input_file_is_refused(tmp_path, option):
    here = tmp_path / "project"
    here.mkdir()
    if option == "--config":
        name, text, args = "my.yaml", "/**:\n  ros__parameters:\n    seed: 3\n", SIMULATE
    else:
        name, text = "path.csv", "t_s,lat_deg,lon_deg,h_m\n0,50,4,100\n10,50,4.0001,100\n"
        args = [a for a in SIMULATE if a not in ("--position", "50,4,100")]
    (here / name).write_text(text)
    res = _cli(*args, option, here / name, "--out", here)
    _refused(res, here, name, "simulate")
    assert _contents(here) == {name: text.encode()}


@pytest.mark.parametrize("command", ["simulate", "run"])
def test_out_dot_with_a_users_file_is_refused(tmp_path, command):
    if command == "run":
        pytest.importorskip("rclpy", reason="rclpy is not installed (run make test, or source ROS 2)")
    here = tmp_path / "work"
    here.mkdir()
    (here / "notes.txt").write_text("mine\n")
    args = SIMULATE if command == "simulate" else ["run", "--duration", "2", "--quiet", "--no-record"]
    res = _cli(*args, "--out", ".", cwd=here)
    _refused(res, here, "notes.txt", command)
    assert _contents(here) == {"notes.txt": b"mine\n"}


def test_a_second_simulate_replaces_exactly_its_own_files(tmp_path):
    out = tmp_path / "o"
    assert _cli(*SIMULATE, "--out", out).returncode == 0
    first = set(_contents(out))
    assert _manifest(out) == first - {MANIFEST_NAME} and len(first) == 4      # MO, MN, fix.csv + manifest
    res = _cli(*SIMULATE, "--start", "2025-06-01T11:00:00", "--out", out)
    assert res.returncode == 0, res.stderr[-2000:]
    second = set(_contents(out))
    assert _manifest(out) == second - {MANIFEST_NAME} and len(second) == 4
    assert second & first == {"fix.csv", MANIFEST_NAME}                       # the earlier RINEX names went
    assert not list(tmp_path.glob(".o.partial-*"))
    (out / "notes.txt").write_text("mine\n")                                  # the user adds a file: refused
    _refused(_cli(*SIMULATE, "--out", out), out, "notes.txt", "simulate")
    assert (out / "notes.txt").read_text() == "mine\n" and set(_contents(out)) == second | {"notes.txt"}


def test_a_failure_while_writing_leaves_the_previous_results(tmp_path):
    import dataclasses

    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.core.simulation import run_simulation, setup_from_config
    from gnss_sim_ros2.core.time import GnssTime
    from gnss_sim_ros2.core.trajectory import Trajectory

    out = tmp_path / "o"
    setup = setup_from_config(load_config(), out, Trajectory.static((50.0, 4.0, 100.0), "geodetic"),
                              start=GnssTime.from_iso("2025-06-01T10:00:00"), duration_s=20.0, interval_s=1.0,
                              batch_epochs=1, batch_observables=False).with_params(systems="G")
    res = run_simulation(setup)
    assert res.obs_path.parent == out.resolve() and res.obs_path.is_file()
    before = _contents(out)
    seen = []

    def fail_at_epoch_5(t, ecef, obs, sol):
        seen.append(t)
        if len(seen) == 5:
            raise RuntimeError("disk gone")

    later = dataclasses.replace(setup, start=GnssTime.from_iso("2025-06-01T11:00:00"), observer=fail_at_epoch_5)
    with pytest.raises(RuntimeError, match="disk gone"):
        run_simulation(later)
    assert len(seen) == 5
    assert _contents(out) == before                       # same names, same bytes: nothing half-written
    assert not list(tmp_path.glob(".o.partial-*"))


# ------------------------------------------------------------------------------------------------------ run
@pytest.mark.slow
def test_run_keeps_a_users_file_and_replaces_only_its_own(tmp_path):
    pytest.importorskip("rclpy", reason="rclpy is not installed (run make test, or source ROS 2)")
    pytest.importorskip("gnss_sim_msgs", reason="gnss_sim_msgs is not built (run make test)")
    mine = tmp_path / "mydata"
    mine.mkdir()
    (mine / "thesis.txt").write_text("four years of work\n")
    _refused(_cli("run", "--out", mine, "--duration", "2", "--systems", "G", "--quiet"), mine, "thesis.txt", "run")
    assert _contents(mine) == {"thesis.txt": b"four years of work\n"}
    out = tmp_path / "r"
    first = _cli("run", "--out", out, "--duration", "3", "--systems", "G", "--quiet")
    assert first.returncode == 0, first.stderr[-2000:]
    assert (out / "bag" / "metadata.yaml").is_file() and _manifest(out) == set(_contents(out)) - {MANIFEST_NAME}
    again = _cli("run", "--out", out, "--duration", "2", "--systems", "G", "--quiet", "--no-record")
    assert again.returncode == 0, again.stderr[-2000:]
    assert not (out / "bag").exists()                    # the first run's bag was the run's own: gone
    assert _manifest(out) == set(_contents(out)) - {MANIFEST_NAME}
    assert json.loads((out / "summary.json").read_text())["epochs"] == 3


# ------------------------------------------------------------------------------------------- the other commands
def test_sweep_and_compare_refuse_a_folder_holding_a_users_file(tmp_path):
    mine = tmp_path / "mydata"
    mine.mkdir()
    (mine / "thesis.txt").write_text("mine\n")
    _refused(_cli("sweep", "--seeds", "1-2", "--duration", "5", "--quiet", "--out", mine), mine, "thesis.txt",
             "sweep")
    _refused(_cli("compare", "--sim", tmp_path / "a.rnx", "--real", tmp_path / "b.rnx", "--out", mine), mine,
             "thesis.txt", "compare")
    assert _contents(mine) == {"thesis.txt": b"mine\n"}


def test_satpos_refuses_its_input_as_output_and_writes_whole_files(tmp_path, nav_file):
    nav = tmp_path / nav_file.name
    nav.write_bytes(nav_file.read_bytes())
    args = ["satpos", "--nav", nav, "--start", "2025-06-01T10:00:00", "--end", "2025-06-01T10:10:00", "--step", "300"]
    res = _cli(*args, "--out", nav)
    assert res.returncode == 2 and "option --out" in res.stderr and "is also an input" in res.stderr, res.stderr
    assert nav.read_bytes() == nav_file.read_bytes()
    res = _cli(*args, "--out", tmp_path / "sat.csv")
    assert res.returncode == 0, res.stderr[-2000:]
    assert (tmp_path / "sat.csv").read_text().startswith("time,sv,")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([nav.name, "sat.csv"])   # no staging left


# ---------------------------------------------------------------------------------------- the rule itself
def test_another_commands_results_and_a_file_in_a_subfolder_are_foreign(tmp_path):
    out = tmp_path / "o"
    (out / "bag").mkdir(parents=True)
    (out / "summary.json").write_text("{}")
    (out / "bag" / "bag_0.mcap").write_text("x")
    (out / MANIFEST_NAME).write_text(json.dumps({"written_by": "gnss-sim run",
                                                 "files": ["summary.json", "bag/bag_0.mcap"]}))
    check_output_folder(out, "gnss-sim run")                       # the run's own folder: accepted
    with pytest.raises(OutputNotOurs, match=r"holds summary\.json, which gnss-sim compare did not write"):
        check_output_folder(out, "gnss-sim compare")               # another command's results
    (out / "bag" / "mine.txt").write_text("mine")
    with pytest.raises(OutputNotOurs, match=r"holds bag/mine\.txt, which gnss-sim run did not write"):
        check_output_folder(out, "gnss-sim run")


def test_a_manifest_never_reaches_outside_its_folder(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    outside = tmp_path / "outside.txt"
    outside.write_text("keep")
    (out / "old.csv").write_text("old")
    (out / MANIFEST_NAME).write_text(json.dumps({"written_by": "gnss-sim run",
                                                 "files": ["old.csv", "../outside.txt", str(outside), "./x"]}))
    folder = OutputFolder(out, command="gnss-sim run")
    staging = folder.acquire()
    (staging / "new.csv").write_text("new")
    folder.commit()
    assert outside.read_text() == "keep"
    assert _contents(out) == {"new.csv": b"new", MANIFEST_NAME: (out / MANIFEST_NAME).read_bytes()}
    assert _manifest(out) == {"new.csv"}


def test_export_world_never_writes_its_sidecar_over_an_input(tmp_path):
    from gnss_sim_ros2.core.scene.demo_world import demo_world_path

    # the sidecar of m.ply is m.scene.yaml: here also the --materials file (main overwrote it)
    materials = tmp_path / "m.scene.yaml"
    materials.write_text("classes: {}\n")
    res = _cli("export-world", demo_world_path(), "--out", tmp_path / "m.ply", "--materials", materials)
    assert res.returncode == 2 and "option --out (sidecar)" in res.stderr and "is also an input" in res.stderr, \
        res.stderr[-2000:]
    assert materials.read_text() == "classes: {}\n" and not (tmp_path / "m.ply").exists()
    res = _cli("export-world", demo_world_path(), "--out", tmp_path / "w.ply")
    assert res.returncode == 0, res.stderr[-2000:]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.scene.yaml", "w.ply", "w.scene.yaml"]


def test_an_rtcm_file_named_inside_the_folder_is_the_runs_own(tmp_path):
    out = tmp_path / "o"
    for _ in range(2):                 # the second run accepts the first's RTCM file and replaces it
        res = _cli(*SIMULATE, "--rtcm", out / "sub" / "x.rtcm3", "--out", out)
        assert res.returncode == 0, res.stderr[-2000:]
    assert "sub/x.rtcm3" in _manifest(out) and (out / "sub" / "x.rtcm3").stat().st_size > 0
