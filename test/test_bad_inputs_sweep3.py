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
...``); a parameter named ``yes:`` or ``5:`` (YAML reads a bool, a number) ended in a TypeError traceback in
difflib; ``marker_name: ''`` wrote XXXX00XXX_... files (' AB': a file name with a space); a trajectory row with more
values than its header lost the extra without a word; a profile's ``dll_bn_hz: -1`` was refused by the noise model
naming no file or key, ``mp_tau_s: 0`` ran; ``plan --path`` of a binary file said "'utf-8' codec can't decode";
a world's <spherical_coordinates> with longitude 400 or elevation 1e9 m was exported and simulated; ``run --world
absent.sdf`` started every node before the visibility node's configure failed; ``simulate --synthetic --nav F``
and ``--clk F`` without --sp3 ignored the files, a navigation file given as --clk was read as a clock file.
"""
from __future__ import annotations

import os
from pathlib import Path

import pytest
from cli_helpers import assert_refused, case_ids, run_cli

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
    section = "/**:\n  ros__parameters:\n"
    yes_key = _write("yes.yaml", section + "    yes: 5\n")
    int_key = _write("five.yaml", section + "    5: 5\n")
    marker_empty = _write("marker.yaml", section + "    marker_name: ''\n")
    marker_space = _write("marker_space.yaml", section + "    marker_name: ' AB'\n")
    long_row = _write("long_row.csv", "t_s,lat_deg,lon_deg,h_m\n0,48,11,500\n2,48,11,500,7\n")
    profile = "gnss_sim_profile: 1\nname: t\nsignals:\n  G: [1C]\n"
    dll_neg = _write("dll.yaml", profile + "dll_bn_hz: -1\n")
    tau_zero = _write("tau.yaml", profile + "mp_tau_s: 0\n")
    binary = _write("path.csv", bytes(range(128, 256)))
    origin = WORLD.format(pose="0 0 0 0 0 0")
    lon400 = _write("lon400.sdf", origin.replace("<longitude_deg>11<", "<longitude_deg>400<"))
    up1e9 = _write("up1e9.sdf", origin.replace("<elevation>500<", "<elevation>1e9<"))
    empty_materials = _write("materials.yaml", "# nothing yet\n")
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
        ("marker-abbreviated-empty", [*sim, *out, "--mark="], ["option --marker", "empty value ''"]),
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
        ("config-parameter-name-bool", ["config", "--check", yes_key], [str(yes_key), "parameter name True",
                                                                        "quote it"]),
        ("config-parameter-name-number", ["config", "--check", int_key], [str(int_key), "parameter name 5"]),
        ("config-marker-empty", ["config", "--check", marker_empty], [str(marker_empty), "'marker_name' is ''",
                                                                      "4 characters"]),
        ("config-marker-leading-space", ["config", "--check", marker_space], ["'marker_name' is ' AB'"]),
        ("trajectory-row-longer-than-header", ["simulate", "--quiet", *out, "--trajectory", long_row],
         [f"{long_row}:3", "5 values under a header of 4 columns"]),
        ("profile-dll-bandwidth-negative", [*sim, *out, "--profile", dll_neg],
         [f"receiver profile {dll_neg}, line 5", "'dll_bn_hz'", "must be > 0"]),
        ("profile-multipath-time-zero", [*sim, *out, "--profile", tau_zero],
         [f"receiver profile {tau_zero}, line 5", "'mp_tau_s'"]),
        ("plan-path-binary", ["plan", "--world", COURTYARD, "--hours", "0.2", "--quiet", "--out", tmp / "plan",
                              "--path", binary], [f"option --path {binary}", "not a UTF-8 text file"]),
        ("world-origin-longitude-400", ["export-world", lon400, "--quiet", "--out", tmp / "w.ply"],
         [f"{lon400}:1: <spherical_coordinates>", "longitude 400 deg"]),
        ("world-origin-height-1e9", [*sim, *out, "--world", up1e9], [f"{up1e9}:1: <spherical_coordinates>",
                                                                    "height 1e+09 m"]),
        ("run-world-missing", ["run", "--duration", "2", "--quiet", "--out", tmp / "run", "--world",
                               tmp / "absent.sdf"], [f"option --world: parameter 'world_file' {tmp / 'absent.sdf'}",
                                                     "no such file"]),
        ("synthetic-and-nav", ["simulate", "--duration", "2", "--quiet", *out, "--synthetic", "--nav",
                               tmp / "a.rnx"], ["option --synthetic and --nav", "reads no file"]),
        ("clk-without-sp3", [*sim, *out, "--clk", tmp / "a.clk"], ["option --clk", "--sp3"]),
        ("export-materials-empty", ["export-world", COURTYARD, "--quiet", "--out", tmp / "w.ply", "--materials",
                                    empty_materials], [f"materials file {empty_materials} is empty"]),
        ("skyplot-csv-is-default-skyline", [*sky, "--csv", tmp / "skyline.csv", "--png", tmp / "x.png"],
         ["options --csv and --skyline-csv", "same file"]),
    ]


CASE_IDS = case_ids(_cases)


@pytest.mark.parametrize("case", CASE_IDS)
def test_bad_input_is_refused_naming_the_culprit(case, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)          # a blank --out named the current folder: it stays empty
    _, argv, words = next(c for c in _cases(tmp_path) if c[0] == case)     # the case's inputs written first
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
    rc, text = run_cli(["simulate", "--duration", "2", "--position", "48,11,500", "--out", tmp_path / "out",
                        "--dur", "3"], capsys)          # an abbreviation argparse takes for --duration
    assert rc == 0 and "option --duration is given more than once: the last (3.0) is used" in text, text
    rc, text = run_cli(["simulate", "--duration", "2", "--position", "48,11,500", "--out", tmp_path / "out"], capsys)
    assert rc == 0 and "more than once" not in text, text


def test_input_files_as_spreadsheets_and_ros_write_them(tmp_path, capsys):
    """Files other tools write are read as they mean: a trajectory CSV from Excel ("CSV UTF-8": a byte order mark
    first) and with a comment line above its header (both refused: "header must be ... got \\ufefft_s,..."), a
    parameter file with ``rate_hz: 1e1`` (ROS 2's parser reads 10.0; PyYAML read the text '1e1': "must be double")."""
    traj = tmp_path / "excel.csv"
    traj.write_bytes("\ufeff# exported path\nt_s,lat_deg,lon_deg,h_m\n0,48,11,500\n2,48,11,500\n".encode())
    rc, text = run_cli(["simulate", "--duration", "2", "--quiet", "--out", tmp_path / "out", "--trajectory", traj],
                       capsys)
    assert rc == 0 and "epochs 3" in text, text
    cfg = tmp_path / "exp.yaml"
    cfg.write_text("/**:\n  ros__parameters:\n    rate_hz: 1e1\n    elevation_mask_deg: 1.5e1\n")
    rc, text = run_cli(["config", "--check", cfg], capsys)
    assert rc == 0 and "rate_hz: 10.0" in text and "elevation_mask_deg: 15.0" in text, text
    cfg.write_text("/**:\n  ros__parameters:\n    marker_name: '1e1'\n")      # quoted: text, as for ROS
    rc, text = run_cli(["config", "--check", cfg], capsys)
    assert rc == 0 and "marker_name: 1e1" in text, text


@pytest.mark.parametrize("value, expected", [("true", True), ("False", False), (" 1", True), ("off", False)])
def test_launch_switches_take_true_or_false(value, expected):
    """sim.launch.py's switches (record:=, rtk:=, use_sim_time:= ...) go through graph_params.launch_flag."""
    from gnss_sim_ros2.graph_params import launch_flag

    assert launch_flag(value, "record") is expected


@pytest.mark.parametrize("value", ["ture", "maybe", "", "2"])
def test_a_launch_switch_neither_true_nor_false_is_refused(value):
    """``record:=ture`` or ``use_sim_time:=maybe`` was false without a word."""
    from gnss_sim_ros2.graph_params import launch_flag

    with pytest.raises(ValueError, match=f"launch argument record is {value!r}; true or false"):
        launch_flag(value, "record")


def test_a_clock_file_that_is_not_one_is_refused(tmp_path):
    """``--clk`` given a navigation file (RINEX VERSION / TYPE present, file type N) or a clock file without satellite
    clocks added nothing to the run without a word (satpos / simulate ran, rc 0)."""
    from gnss_sim_ros2.core.ephemeris.sp3 import read_rinex_clock

    nav = tmp_path / "nav.rnx"
    nav.write_text(f"{'     3.04           N: GNSS NAV DATA    M: MIXED':<60}RINEX VERSION / TYPE\n"
                   f"{'':<60}END OF HEADER\n")
    with pytest.raises(ValueError, match=r"nav\.rnx, line 1: not a RINEX clock file \(file type 'N'"):
        read_rinex_clock(nav)
    empty = tmp_path / "empty.clk"
    empty.write_text(f"{'     3.04           C                   G':<60}RINEX VERSION / TYPE\n{'':<60}END OF HEADER\n"
                     "AR ABCD 2022 01 01 00 00  0.000000  1    1.0E-09\n")
    with pytest.raises(ValueError, match=r"empty\.clk: no satellite clock record \(AS\)"):
        read_rinex_clock(empty)


def test_sp3_files_of_another_span_say_which_span_they_cover(tmp_path):
    """SP3 files whose epochs all lie outside the span asked said "SP3 data have 0 epochs, fewer than the 11
    interpolation points"; the error names the span asked and the one the files cover."""
    from gnss_sim_ros2.core.ephemeris.sp3 import Sp3Ephemeris
    from gnss_sim_ros2.core.time import GnssTime

    lines = ["#dP2017  2 14  0  0  0.00000000      16 ORBIT IGS14 HLM  IGS", "+    1   G01", "%c G  cc GPS"]
    for k in range(16):
        lines += [f"*  2017  2 14  0 {k:2d}  0.00000000", "PG01  15000.000000  10000.000000  18000.000000      1.0"]
    sp3 = tmp_path / "old.sp3"
    sp3.write_text("\n".join([*lines, "EOF"]) + "\n")
    start = GnssTime.from_iso("2022-01-01T00:00:00")
    with pytest.raises(ValueError, match=r"old\.sp3: no epoch near the span asked \(2022-01-01T00:00:00 \.\. "
                                         r"2022-01-01T01:00:00 GPS\): the files cover 2017-02-14T00:00:00 \.\. "
                                         r"2017-02-14T00:15:00"):
        Sp3Ephemeris.from_files([sp3], start=start, end=start + 3600.0)
    assert len(Sp3Ephemeris.from_files([sp3]).svs()) == 1          # the file itself reads
