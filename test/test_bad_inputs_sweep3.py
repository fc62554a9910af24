"""Bad input, third sweep (every subcommand, the readers behind them, the parameter files): refused naming the option,
file (and line) or parameter; never a traceback, never a silent default, never an input overwritten.

Each case runs the real command line (``gnss_sim_ros2.cli.main``) in this process, as test_bad_inputs.py does.
Before these checks: an empty or blank option value was a silent default (``--out ''`` the current folder,
``--position ''`` the configuration's position, ``--rtcm ''`` the default file, ``--marker ' '`` the default
marker; ``--nav a.rnx ''`` "navigation file : is a folder"; ``export-world ''`` ". cannot read");
``simulate --mesh`` of an empty STL said "the scene has no spherical_coordinates" naming no file, a mesh with a NaN
or a 1e30 m vertex (or a world with a model posed 1e12 m away) ran, a folder or /dev/null as --mesh was "not
found"; a navigation file or mesh that is a symbolic link to itself ended in "RuntimeError: Symlink loop" (a
traceback); ``simulate --rtcm`` naming the --trajectory CSV wrote the RTCM stream over it; ``skyplot --csv x.png
--png x.png`` (and --csv naming the default skyline.csv beside --png) wrote one output over the other;
``satpos --nav /dev/null`` "does not exist"; ``compare --truth-csv`` with a short row ended in "TypeError: float()
argument must be ... 'NoneType'" (a traceback); ``plan --scheduler not-an-address`` said "missing port number"
naming no option; ``bench --speed --peer-python absent`` ran the whole benchmark before saying so in its report;
``config --check`` and ``threats-plot`` errors did not name the command (``error: ...``, ``gnss-sim threats-plot:
...``).
"""
from __future__ import annotations

import os
from pathlib import Path

import pytest
from cli_helpers import assert_refused, run_cli

REPO = Path(__file__).resolve().parents[1]
COURTYARD = str(REPO / "worlds" / "courtyard.sdf")
START = "2025-06-01T10:00:00"
PLY_HEAD = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 1\nproperty list uchar int vertex_indices\nend_header\n")
WORLD = ("<?xml version='1.0'?><sdf version='1.9'><world name='w'><spherical_coordinates><latitude_deg>48"
         "</latitude_deg><longitude_deg>11</longitude_deg><elevation>500</elevation></spherical_coordinates>"
         "<model name='b'><static>true</static><pose>{pose}</pose><link name='l'><collision name='c'><geometry><box>"
         "<size>2 2 2</size></box></geometry></collision></link></model></world></sdf>")


def _cases(tmp: Path, write: bool = True):
    """(case id, argv, words the message must hold); ``write``: the input files too."""
    def _write(name: str, data: str | bytes) -> Path:
        path = tmp / name
        if write:
            path.write_bytes(data if isinstance(data, bytes) else data.encode())
        return path

    def _loop(name: str) -> Path:
        path = tmp / name
        if write:
            os.symlink(path, path)
        return path

    empty_stl = _write("empty.stl", b"")
    nan_ply = _write("nan.ply", PLY_HEAD + "nan 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    far_ply = _write("far.ply", PLY_HEAD + "1e30 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    bare_ply = _write("bare.ply", PLY_HEAD + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    far_world = _write("far.sdf", WORLD.format(pose="1e12 0 0 0 0 0"))
    loop_mesh, loop_nav = _loop("loop.ply"), _loop("loop.rnx")
    obs = _write("obs.rnx", (
        f"{'     3.04           OBSERVATION DATA    M':<60}RINEX VERSION / TYPE\n"
        f"{'G    2 C1C L1C':<60}SYS / # / OBS TYPES\n{'':<60}END OF HEADER\n"
        "> 2022 01 01 00 00  0.0000000  0  1\nG01  20000000.000   105000000.000  \n"))
    short_truth = _write("truth.csv", "time,x_m,y_m,z_m\n2022-01-01T00:00:00,3149785.9,598260.8\n")
    folder = tmp / "a folder"
    if write:
        folder.mkdir()
    sim = ["simulate", "--duration", "2", "--position", "48,11,500", "--quiet"]
    out = ["--out", tmp / "out"]
    static = ["--start", "2022-01-01T01:00:00", "--position-ecef", "3149785.9652,598260.8822,5495348.4927"]
    sky = ["skyplot", "--world", COURTYARD, "--synthetic", "--at", "0,0,1.5", "--time", START, "--quiet"]
    return [
        ("out-empty", [*sim, "--out", ""], ["option --out", "empty value ''"]),
        ("out-blank", [*sim, "--out", " "], ["option --out", "empty value ' '"]),
        ("position-empty", ["simulate", "--duration", "2", "--quiet", *out, "--position", ""],
         ["option --position", "empty value"]),
        ("rtcm-empty", [*sim, *out, "--rtcm", ""], ["option --rtcm", "empty value"]),
        ("marker-blank", [*sim, *out, "--marker", "  "], ["option --marker", "empty value"]),
        ("nav-empty-element", ["simulate", "--duration", "2", *static, *out, "--nav", tmp / "a.rnx", ""],
         ["option --nav", "empty value"]),
        ("export-world-empty", ["export-world", "", "--out", tmp / "w.ply"], ["argument WORLD.sdf", "empty value"]),
        ("mesh-empty-stl", [*sim, *out, "--mesh", empty_stl], [f"scene mesh {empty_stl}", "no triangles",
                                                               "empty file"]),
        ("mesh-nan-vertex", [*sim, *out, "--mesh", nan_ply], [f"scene mesh {nan_ply}", "vertex 1", "finite"]),
        ("mesh-far-vertex", [*sim, *out, "--mesh", far_ply], [f"scene mesh {far_ply}", "1000 km"]),
        ("mesh-folder", [*sim, *out, "--mesh", folder], [f"scene mesh {folder}", "is a folder"]),
        ("mesh-devnull", [*sim, *out, "--mesh", "/dev/null"], ["scene mesh /dev/null", "not a regular file"]),
        ("mesh-symlink-loop", [*sim, *out, "--mesh", loop_mesh], [f"scene mesh {loop_mesh}", "symbolic link"]),
        ("mesh-no-georeference", [*sim, *out, "--mesh", bare_ply], [f"scene {bare_ply} has no spherical_coordinates",
                                                                    ".scene.yaml"]),
        ("world-model-far", [*sim, *out, "--world", far_world], [f"world {far_world}", "1000 km"]),
        ("nav-symlink-loop", ["simulate", "--duration", "2", *static, "--quiet", *out, "--nav", loop_nav],
         [f"navigation file {loop_nav}", "symbolic link", "nav_files"]),
        ("satpos-nav-devnull", ["satpos", "--nav", "/dev/null", "--start", "2022-01-01T00:00:00", "--end",
                                "2022-01-01T01:00:00", "--step", "600", "--out", tmp / "sat.csv"],
         ["navigation file /dev/null", "not a regular file"]),
        ("skyplot-csv-is-png", [*sky, "--csv", tmp / "x.png", "--png", tmp / "x.png"],
         ["options --csv and --png", "same file"]),
        ("compare-truth-csv-short-row", ["compare", "--sim", obs, "--real", obs, "--quiet", "--out", tmp / "cmp",
                                         "--truth-csv", short_truth],
         [f"{short_truth}, line 2", "4 columns (time,x_m,y_m,z_m) expected, got 3"]),
        ("plan-scheduler-not-an-address", ["plan", "--world", COURTYARD, "--hours", "0.2", "--quiet", "--out",
                                           tmp / "plan", "--scheduler", "not-an-address"],
         ["option --scheduler not-an-address", "cannot reach"]),
        ("bench-peer-python-missing", ["bench", "--speed", "--peer-python", tmp / "no-python"],
         [f"--peer-python {tmp / 'no-python'}", "No such file"]),
        ("config-check-error-names-command", ["config", "--check", tmp / "absent.yaml"],
         ["gnss-sim config: error: configuration file", "does not exist"]),
        ("threats-plot-error-names-command", ["threats-plot", folder, "--png", tmp / "t.png"],
         ["gnss-sim threats-plot: error:", "no fix.csv"]),
        ("skyplot-csv-is-default-skyline", [*sky, "--csv", tmp / "skyline.csv", "--png", tmp / "x.png"],
         ["options --csv and --skyline-csv", "same file"]),
    ]


CASE_IDS = [c[0] for c in _cases(Path("."), write=False)]


@pytest.mark.parametrize("case", CASE_IDS)
def test_bad_input_is_refused_naming_the_culprit(case, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)          # a blank --out named the current folder: it stays empty
    _, argv, words = next(c for c in _cases(tmp_path) if c[0] == case)
    before = _listing(tmp_path)
    rc, text = run_cli(argv, capsys)
    assert_refused(rc, text, words)
    assert _listing(tmp_path) == before, "a refused run wrote a file"


def _listing(folder: Path) -> set:
    """The files and folders a user sees (an output folder's lock file, .out.lock, stays: output_folder.py)."""
    return {p.name for p in folder.iterdir() if not p.name.endswith(".lock")}


def test_rtcm_never_overwrites_an_input(tmp_path, capsys):
    """``simulate --rtcm`` naming the --trajectory CSV is refused and the CSV is left as it was (it was replaced by
    the RTCM stream)."""
    traj = tmp_path / "path.csv"
    traj.write_text("t_s,lat_deg,lon_deg,h_m\n0,48,11,500\n2,48,11,500\n")
    before = traj.read_bytes()
    rc, text = run_cli(["simulate", "--quiet", "--out", tmp_path / "out", "--trajectory", traj, "--rtcm", traj],
                       capsys)
    assert_refused(rc, text, ["option --rtcm", str(traj), "also an input"])
    assert traj.read_bytes() == before


def test_an_option_given_twice_is_said(tmp_path, capsys):
    """argparse keeps the last of an option given twice without a word: the run says which value it used
    (a warning: scripts append an override to a base command line, test_bad_inputs_new_features)."""
    rc, text = run_cli(["simulate", "--duration", "2", "--position", "48,11,500", "--out", tmp_path / "out",
                        "--duration", "3", "--position", "-33.9,151.2,10"], capsys)
    assert rc == 0, text
    assert "warning: option --duration is given more than once: the last (3.0) is used" in text, text
    assert "option --position is given more than once: the last (-33.9,151.2,10) is used" in text, text
    assert "epochs 4" in text, text
    rc, text = run_cli(["simulate", "--duration", "2", "--position", "48,11,500", "--out", tmp_path / "out"], capsys)
    assert rc == 0 and "more than once" not in text, text
