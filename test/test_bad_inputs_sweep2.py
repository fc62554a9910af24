"""Bad input to the older commands (simulate, compare, skyplot, satpos, export-world, sweep, config, profile,
roundtrip, run), second sweep: refused naming the file (and line), option or parameter; never a traceback, never a
silent default.

Each case runs the real command line (``gnss_sim_ros2.cli.main``) in this process, as test_bad_inputs.py does.
Before these checks: a YAML key given twice kept the last without a word (``duration_s: 10`` then ``20``; a node's
section twice: only the second), a YAML nested 5000 deep ended in a RecursionError traceback, an integer of 401
digits for a double parameter in an OverflowError traceback, a seed of 1e23 passed the table; a binary or UTF-16
parameter file, trajectory, sky mask, materials file or --truth-csv said "'utf-8' codec can't decode byte 0xff"
naming no file; a folder given as --nav / --sp3 / --sim "does not exist"; ``export-world --out /`` said
"PosixPath('/') has an empty name" and ``--out e.txt`` named its temporary path; ``--marker`` with a newline or
a '/' wrote a RINEX file name with it; ``compare --truth 0,0,0`` compared against the Earth's centre; an
observation file cut inside an epoch record was read as if whole; ``skyplot --time`` and ``satpos --start`` in
1970 ran (satpos wrote 0 rows, rc 0); ``sweep --worlds missing.sdf`` and ``--plot x.txt`` were found only by the
runs or after them; ``roundtrip --timeout 0`` waited nothing and reported every message lost; an empty or
'/world' TF frame ran; ``export-world --seed -5`` of a world with a <population> said "expected non-negative
integer"; ``compare --mask-deg 200`` ran, ``--epoch-tol-ms -5`` named no option, ``skyplot --png sky.txt``
ended in matplotlib's "Format 'txt' is not supported".
"""
from __future__ import annotations

from pathlib import Path

import pytest
from cli_helpers import case_ids, refuse_case

REPO = Path(__file__).resolve().parents[1]
COURTYARD = str(REPO / "worlds" / "courtyard.sdf")
START = "2025-06-01T10:00:00"
SECTION = "gnss_sim_ephemeris:\n  ros__parameters:\n"


def _rinex_obs(epochs: str) -> str:
    """A small RINEX 3.04 observation file (GPS C1C L1C) with the epoch records ``epochs``."""
    def h(text, label):
        return f"{text:<60}{label}\n"
    return (h("     3.04           OBSERVATION DATA    M", "RINEX VERSION / TYPE") + h("TEST", "MARKER NAME")
            + h("  4149785.0000   598260.0000  4795348.0000", "APPROX POSITION XYZ")
            + h("G    2 C1C L1C", "SYS / # / OBS TYPES")
            + h("  2022     1     1     0     0    0.0000000     GPS", "TIME OF FIRST OBS") + h("", "END OF HEADER")
            + epochs)


SAT = "{}  20000000.000   105000000.000  \n"


def _cases(tmp: Path, write: bool = True):
    """(case id, argv, words the message must hold); ``write``: the input files too."""
    def _write(name: str, data: str | bytes, encoding: str = "utf-8") -> Path:
        path = tmp / name
        if write:
            path.write_bytes(data if isinstance(data, bytes) else data.encode(encoding))
        return path

    folder = tmp / "a folder"
    if write:
        folder.mkdir(exist_ok=True)
    dup = _write("dup.yaml", SECTION + "    duration_s: 10.0\n    duration_s: 20.0\n")
    dup_node = _write("dup_node.yaml", SECTION + "    duration_s: 10.0\n" + SECTION + "    duration_s: 20.0\n")
    deep = _write("deep.yaml", "[" * 5000 + "]" * 5000 + "\n")
    huge = _write("huge.yaml", SECTION + "    duration_s: 1" + "0" * 400 + "\n")
    utf16 = _write("utf16.yaml", SECTION + "    duration_s: 10.0\n", "utf-16")
    slash_frame = _write("frame.yaml", "/**:\n  ros__parameters:\n    world_frame: /world\n")
    profile_dup = _write("profile_dup.yaml", "gnss_sim_profile: 1\ngnss_sim_profile: 1\n")
    binary = _write("binary.yaml", bytes(range(128, 256)) * 4)
    traj16 = _write("trajectory ü.csv", "t_s,lat_deg,lon_deg,h_m\n0,48,11,500\n10,48,11,500\n", "utf-16")
    mask_bin = _write("mask.csv", bytes(range(128, 256)))
    truth16 = _write("truth.csv", "time,x_m,y_m,z_m\n", "utf-16")
    whole = _write("whole.rnx", _rinex_obs("> 2022 01 01 00 00  0.0000000  0  2\n" + SAT.format("G01")
                                           + SAT.format("G02")))
    cut = _write("cut.rnx", _rinex_obs("> 2022 01 01 00 00  0.0000000  0  2\n" + SAT.format("G01") + SAT.format("G02")
                                       + "> 2022 01 01 00 00 30.0000000  0  3\n" + SAT.format("G01")))
    sim = ["simulate", "--duration", "5", "--position", "48,11,500", "--quiet", "--out", tmp / "out"]
    static = ["--start", "2022-01-01T01:00:00", "--position-ecef", "3149785.9652,598260.8822,5495348.4927"]
    export = ["export-world", COURTYARD, "--quiet"]
    cmp_ = ["compare", "--quiet", "--out", tmp / "cmp"]
    sky = ["skyplot", "--world", COURTYARD, "--synthetic", "--at", "0,0,1.5", "--csv", tmp / "sky.csv", "--quiet"]
    satpos = ["satpos", "--nav", tmp / "absent.rnx", "--step", "600", "--out", tmp / "sat.csv"]
    sweep = ["sweep", "--position", "48,11,500", "--duration", "5", "--out", tmp / "sweep", "--print-setup"]
    return [
        ("config-key-twice", ["config", "--check", dup], [str(dup), "'duration_s' twice", "first on line 3"]),
        ("config-section-twice", ["config", "--check", dup_node], [str(dup_node), "'gnss_sim_ephemeris' twice"]),
        ("simulate-config-key-twice", [*sim, "--config", dup], [str(dup), "'duration_s' twice"]),
        ("config-nested-deep", ["config", "--check", deep], [str(deep), "nested too deeply"]),
        ("config-integer-huge", ["config", "--check", huge], [str(huge), "'duration_s'", "too large for a double"]),
        ("config-utf16", ["config", "--check", utf16], [str(utf16), "not a UTF-8 text file"]),
        ("config-frame-slash", ["config", "--check", slash_frame], [str(slash_frame), "'world_frame'", "'/'"]),
        ("seed-beyond-int64", [*sim, "--seed", "99999999999999999999999"], ["option --seed", "64-bit"]),
        ("profile-key-twice", ["profile", "show", profile_dup], [str(profile_dup), "'gnss_sim_profile' twice"]),
        ("export-out-root", [*export, "--out", "/"], ["option --out /", ".ply"]),
        ("export-out-txt", [*export, "--out", tmp / "e.txt"], [f"option --out {tmp / 'e.txt'}", ".ply"]),
        ("export-seed-negative", ["export-world", REPO / "worlds" / "orchard.sdf", "--quiet", "--out", tmp / "o.ply",
                                  "--seed", "-5"], ["option --seed", "minimum is 0"]),
        ("export-materials-binary", [*export, "--out", tmp / "w.ply", "--materials", binary],
         [f"materials file {binary}", "not a UTF-8 text file"]),
        ("marker-newline", [*sim, "--marker", "AB\nCD"], ["option --marker", "'marker_name'", "'\\n'"]),
        ("marker-slash", [*sim, "--marker", "a/b"], ["option --marker", "'marker_name'", "'/'"]),
        ("trajectory-utf16", [*sim[:3], "--quiet", "--out", tmp / "out", "--trajectory", traj16],
         [f"trajectory file {traj16}", "not a UTF-8 text file"]),
        ("sky-mask-binary", [*sim, "--sky-mask", mask_bin], [f"sky mask {mask_bin}", "not a UTF-8 text file"]),
        ("nav-folder", ["simulate", "--duration", "5", *static, "--nav", folder, "--quiet", "--out", tmp / "out"],
         [f"navigation file {folder}", "is a folder"]),
        ("sp3-folder", ["simulate", "--duration", "5", *static, "--sp3", folder, "--quiet", "--out", tmp / "out"],
         [str(folder), "is a folder", "sp3_files"]),
        ("compare-sim-folder", [*cmp_, "--sim", folder, "--real", whole], [str(folder), "is a folder"]),
        ("compare-obs-cut", [*cmp_, "--sim", cut, "--real", whole], [f"{cut}, line 10", "announces 3 satellites",
                                                                     "truncated"]),
        ("compare-truth-centre", [*cmp_, "--sim", whole, "--real", whole, "--truth", "0,0,0"],
         ["option --truth", "Earth's centre"]),
        ("compare-truth-csv-utf16", [*cmp_, "--sim", whole, "--real", whole, "--truth-csv", truth16],
         [f"--truth-csv {truth16}", "not a UTF-8 text file"]),
        ("compare-mask-200", [*cmp_, "--sim", whole, "--real", whole, "--mask-deg", "200"],
         ["option --mask-deg", "maximum is 90"]),
        ("compare-epoch-tolerance", [*cmp_, "--sim", whole, "--real", whole, "--epoch-tol-ms", "-5"],
         ["--epoch-tol-ms -5"]),
        ("skyplot-png-not-png", [*sky, "--time", START, "--png", tmp / "sky.txt"], ["option --png", ".png"]),
        ("skyplot-time-1970", [*sky, "--time", "1970-01-01T00:00:00"], ["option --time", "supported span"]),
        ("skyplot-time-2100", [*sky, "--time", "2100-06-01T00:00:00"], ["option --time", "supported span"]),
        ("satpos-start-1970", [*satpos, "--start", "1970-01-01T00:00:00", "--end", "1970-01-01T01:00:00"],
         ["option --start", "supported span"]),
        ("sweep-world-missing", [*sweep, "--worlds", tmp / "absent.sdf"], ["option --worlds", "no such file"]),
        ("sweep-plot-not-png", [*sweep, "--plot", tmp / "summary.txt"], ["option --plot", ".png"]),
        ("roundtrip-timeout-0", ["roundtrip", "--timeout", "0"], ["option --timeout is 0"]),
        ("roundtrip-timeout-nan", ["roundtrip", "--timeout", "nan"], ["option --timeout is nan"]),
        ("run-antenna-frame-empty", ["run", "--out", tmp / "run", "--antenna-frame", "", "--duration", "2"],
         ["option --antenna-frame", "empty value"]),     # refused by the command line (cli.py) since sweep 3
    ]


CASE_IDS = case_ids(_cases)


@pytest.mark.parametrize("case", CASE_IDS)
def test_bad_input_is_refused_naming_the_culprit(case, tmp_path, capsys):
    refuse_case(_cases, case, tmp_path, capsys)
    for out in ("out", "cmp", "sweep", "run"):
        assert not list((tmp_path / out).glob("*")) if (tmp_path / out).is_dir() else True, out
    assert not (tmp_path / "sat.csv").exists() and not list(tmp_path.glob("*.ply"))


def test_a_whole_observation_file_still_reads(tmp_path):
    """The epoch-record count check leaves a whole file (the cut one's first epoch) as it was: 2 satellites."""
    from gnss_sim_ros2.core.rinex.obs_read import load_rinex

    path = tmp_path / "whole.rnx"
    path.write_text(_rinex_obs("> 2022 01 01 00 00  0.0000000  0  2\n" + SAT.format("G01") + SAT.format("G02")))
    table = load_rinex(path)
    assert len(table.time) == 1 and list(table.sv) == ["G01", "G02"]
    assert table.values["C1C"].tolist() == [[20000000.0, 20000000.0]]


def test_yaml_merge_keys_may_still_be_overridden():
    """A key given twice is refused, a ``<<`` merge overridden by the mapping's own key is not (YAML merge type)."""
    import yaml

    from gnss_sim_ros2.core.yaml_file import unique_keys

    doc = yaml.load("base: &b {a: 1, c: 2}\nuse:\n  <<: *b\n  a: 3\n", Loader=unique_keys(yaml.SafeLoader))
    assert doc["use"] == {"a": 3, "c": 2}
    with pytest.raises(yaml.YAMLError, match=r"'a' twice \(first on line 1\)"):
        yaml.load("a: 1\nb: 2\na: 3\n", Loader=unique_keys(yaml.SafeLoader))
