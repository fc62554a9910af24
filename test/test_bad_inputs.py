"""Every option checked once, from the parameter table (issue 25): bad input is refused up front.

Each case runs the real command line (``gnss_sim_ros2.cli.main``) in this process and asserts a clear
refusal: exit code != 0, no traceback, and the message names the option (or the file and line).  Before
issue 25 these ran with rc 0 (latitude 91 wrapped over the pole, an antenna at the Earth's centre tracked
46 satellites, a height of 1e8 m left a 0-byte RINEX), climbed in memory without a word (--duration 1e9,
sweep --seeds 1-100000000, satpos --step 0.0001: 23.6 GB and the OOM killer) or ended in a MemoryError
traceback (skyplot --fresnel-rays 1e8); simulate refused the profiles ublox_f9p / ublox_m8t that
``gnss-sim config`` documents.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from cli_helpers import assert_refused, run_cli

from gnss_sim_ros2.core.frames import (
    HEIGHT_SPAN_M,
    LATITUDE_SPAN_DEG,
    LONGITUDE_SPAN_DEG,
    check_receiver_position,
    geodetic_to_ecef,
)
from gnss_sim_ros2.parameters import MAX_EPOCHS, param

REPO = Path(__file__).resolve().parents[1]
COURTYARD = str(REPO / "worlds" / "courtyard.sdf")
START = "2025-06-01T10:00:00"


def _cases(tmp: Path, write: bool = True):
    """(case id, argv, words the message must hold) for every bad input of the issue; ``write``: the input
    files too (not when only the ids are collected)."""
    def _write(path: Path, text: str) -> Path:
        if write:
            path.write_text(text)
        return path

    lat91 = _write(tmp / "lat91.csv", "t_s,lat_deg,lon_deg,h_m\n0,48,11,500\n10,91,11,500\n")
    centre = _write(tmp / "centre.csv", "t_s,x_m,y_m,z_m\n0,0,0,0\n")
    high = _write(tmp / "high_world.csv", "t_s,e_m,n_m,u_m\n0,0,0,0\n10,0,0,1e8\n")
    nan = _write(tmp / "nan.csv", "t_s,lat_deg,lon_deg,h_m\n0,48,nan,500\n")
    long_cfg = _write(tmp / "long.yaml", "gnss_sim_ephemeris:\n  ros__parameters:\n    duration_s: 1.0e+9\n")
    sim = ["simulate", "--out", tmp / "out", "--quiet"]
    here = ["--position", "48,11,500"]
    sky = ["skyplot", "--world", COURTYARD, "--time", START, "--synthetic", "--csv", tmp / "sky.csv"]
    sweep = ["sweep", *here, "--duration", "10", "--out", tmp / "sweep", "--print-setup"]
    return [
        ("latitude-91", [*sim, "--position", "91,0,0"], ["option --position", "latitude 91 deg"]),
        ("longitude-400", [*sim, "--position", "0,400,0"], ["option --position", "longitude 400 deg"]),
        ("height-1e8", [*sim, "--position", "0,0,1e8"], ["option --position", "height 1e+08 m"]),
        ("height-below", [*sim, "--position", "0,0,-2000"], ["option --position", "height -2000 m"]),
        ("earth-centre", [*sim, "--position-ecef", "0,0,0"], ["option --position-ecef", "Earth's centre"]),
        ("ecef-in-space", [*sim, "--position-ecef", "26560000,0,0"], ["option --position-ecef", "geodetic height"]),
        ("csv-latitude", [*sim, "--trajectory", lat91], [f"{lat91}:3", "latitude 91 deg"]),
        ("csv-ecef-centre", [*sim, "--trajectory", centre], [f"{centre}:2", "Earth's centre"]),
        ("csv-not-finite", [*sim, "--trajectory", nan], [f"{nan}:2", "finite"]),
        ("csv-world-height", [*sim, "--trajectory", high, "--world", COURTYARD], [f"{high}:3", "geodetic height"]),
        ("duration-1e9", [*sim, *here, "--duration", "1e9"], ["option --duration", "maximum"]),
        ("epochs", [*sim, *here, "--duration", "86400", "--rate", "100"],
         ["option --duration", "option --rate", "epochs", f"{MAX_EPOCHS:.0e}"]),
        ("epochs-interval", [*sim, *here, "--duration", "86400", "--interval", "0.01"],
         ["option --interval", "epochs"]),
        ("config-duration", ["config", "--check", long_cfg], [str(long_cfg), "'duration_s'", "maximum"]),
        ("satpos-step", ["satpos", "--nav", tmp / "absent.rnx", "--start", "2025-06-01T00:00:00", "--end",
                         "2025-06-02T00:00:00", "--step", "0.0001", "--out", tmp / "sat.csv"],
         ["option --step", "8.64e+08 epochs", "GB"]),
        ("satpos-systems", ["satpos", "--nav", tmp / "absent.rnx", "--start", START, "--end", START, "--step", "30",
                            "--systems", "GX", "--out", tmp / "sat.csv"], ["option --systems", "X"]),
        ("sweep-seeds", [*sweep, "--seeds", "1-100000000"], ["option --seeds", "100000000 runs"]),
        ("sweep-product", [*sweep, "--seeds", "1-5000", "--dates", "2025-01-01..2025-01-03"],
         ["--dates 3", "--seeds 5000", "15000 runs"]),
        ("sweep-preset", [*sweep, "--presets", "fast,turbo"], ["option --presets", "'turbo'"]),
        ("fresnel-rays", [*sky, "--at", "0,0,1.5", "--fresnel-rays", "100000000"],
         ["option --fresnel-rays", "maximum"]),
        ("fresnel-negative", [*sky, "--at", "0,0,1.5", "--fresnel-rays", "-1"], ["option --fresnel-rays"]),
        ("skyplot-mask", [*sky, "--at", "0,0,1.5", "--mask-deg", "95"], ["option --mask-deg", "maximum"]),
        ("skyplot-at-height", [*sky, "--at", "0,0,1e8"], ["option --at", "geodetic height"]),
        # run's errors name the option too (its option table was keyed the wrong way round: "command line")
        ("run-rate", ["run", "--out", tmp / "run", "--rate", "-5"], ["option --rate", "'rate_hz'"]),
        ("run-duration", ["run", "--out", tmp / "run", "--duration", "1e9"], ["option --duration", "maximum"]),
    ]


CASE_IDS = [c[0] for c in _cases(Path("."), write=False)]


@pytest.mark.parametrize("case", CASE_IDS)
def test_bad_input_is_refused_naming_the_option(case, tmp_path, capsys):
    _, argv, words = next(c for c in _cases(tmp_path) if c[0] == case)
    rc, text = run_cli(argv, capsys)
    assert_refused(rc, text, words)
    assert not list((tmp_path / "out").glob("*.rnx")), "nothing may be written for a refused run"


@pytest.mark.parametrize("profile", ["ublox_f9p", "ublox_m8t"])
def test_simulate_takes_every_profile_of_the_table(profile, tmp_path, capsys):
    """The built-in profiles (gnss_sim_ros2/profiles/*.yaml) run through `simulate --profile` (10 s) as through
    --config."""
    from gnss_sim_ros2.core.receiver.profiles import builtin_names

    assert profile in builtin_names()
    rc, text = run_cli(["simulate", "--profile", profile, "--duration", "10", "--position", "48,11,500",
                     "--out", tmp_path / "out", "--quiet"], capsys)
    assert rc == 0, text
    obs = list((tmp_path / "out").glob("*_MO.rnx"))
    assert len(obs) == 1 and obs[0].stat().st_size > 0
    assert "epochs 11" in text


def test_cli_choices_are_the_tables(capsys):
    """--preset offers exactly the table's choices (one list, parameters.py); --profile takes a name or a file
    (checked by the table's check, test_profiles.py) and its help names every built-in profile."""
    from gnss_sim_ros2.cli import build_parser
    from gnss_sim_ros2.core.receiver.profiles import builtin_names

    sub = next(a for a in build_parser()._actions if a.dest == "command").choices["simulate"]
    opts = {a.dest: a for a in sub._actions}
    assert opts["profile"].choices is None and opts["profile"].metavar == "NAME|FILE"
    assert all(name in opts["profile"].help for name in builtin_names())
    assert tuple(opts["preset"].choices) == tuple(param("/**", "preset").choices)


# ------------------------------------------------------------------------------------ the one position checker
LAT_LO, LAT_HI = LATITUDE_SPAN_DEG
LON_LO, LON_HI = LONGITUDE_SPAN_DEG
H_LO, H_HI = HEIGHT_SPAN_M
EDGES = [(LAT_HI, 0.0, 0.0), (LAT_LO, 0.0, 0.0), (0.0, 180.0, 0.0), (0.0, LON_LO, 0.0), (0.0, LON_HI, 0.0),
         (45.0, 10.0, H_LO), (-45.0, -170.0, H_HI), (LAT_HI, 180.0, H_HI), (LAT_LO, LON_LO, H_LO)]


@pytest.mark.parametrize("llh", EDGES)
def test_position_bounds_are_inclusive_scalar(llh):
    """Exactly on a bound is a position (poles, the antimeridian, the height span's ends), as geodetic and as ECEF."""
    assert np.array_equal(check_receiver_position(llh, "geodetic", "p"), np.array(llh))
    assert check_receiver_position(llh, "llh", "p").shape == (3,)
    ecef = np.array(geodetic_to_ecef(*llh))
    assert np.array_equal(check_receiver_position(ecef, "ecef", "p"), ecef)


def test_position_bounds_are_inclusive_array():
    """One call checks many rows (pymap3d-style broadcasting over rows); the shape is kept."""
    llh = np.array(EDGES)
    assert check_receiver_position(llh, "geodetic", "p").shape == llh.shape
    ecef = np.stack(geodetic_to_ecef(llh[:, 0], llh[:, 1], llh[:, 2]), axis=-1)
    assert check_receiver_position(ecef, "ecef", "p").shape == ecef.shape


def _just_outside():
    up, down = np.inf, -np.inf
    return [((np.nextafter(LAT_HI, up), 0.0, 0.0), "latitude"), ((np.nextafter(LAT_LO, down), 0.0, 0.0), "latitude"),
            ((0.0, np.nextafter(LON_HI, up), 0.0), "longitude"), ((0.0, np.nextafter(LON_LO, down), 0.0), "longitude"),
            ((0.0, 0.0, H_HI + 0.01), "height"), ((0.0, 0.0, H_LO - 0.01), "height"),
            ((0.0, 0.0, np.nan), "finite"), ((np.inf, 0.0, 0.0), "finite")]


@pytest.mark.parametrize("llh, word", _just_outside())
def test_position_just_outside_is_refused(llh, word):
    with pytest.raises(ValueError, match=word):
        check_receiver_position(llh, "geodetic", "option --position")
    if word == "height":         # the same point in ECEF: refused through its geodetic height
        with pytest.raises(ValueError, match="geodetic height"):
            check_receiver_position(np.array(geodetic_to_ecef(*llh)), "ecef", "p")


def test_position_error_names_the_first_bad_row():
    rows = np.array([[48.0, 11.0, 500.0], [48.0, 11.0, 600.0], [95.0, 11.0, 0.0], [-95.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match=r"^traj.csv:4: latitude 95 deg"):
        check_receiver_position(rows, "geodetic", "traj.csv", labels=[":2", ":3", ":4", ":5"])
    with pytest.raises(ValueError, match=r"^p \(row 3\): latitude 95 deg"):
        check_receiver_position(rows, "geodetic", "p")
    with pytest.raises(ValueError, match=r"needs 3 numbers"):
        check_receiver_position([1.0, 2.0], "geodetic", "p")
    with pytest.raises(ValueError, match=r"unknown position frame"):
        check_receiver_position([0.0, 0.0, 0.0], "enu", "p")


def test_parameter_table_uses_the_same_checker():
    """The nodes' static positions (antenna_position, base_position) go through the same rule and name the
    parameter: a base station at 9500 m is a position (was refused above 9000 m), 10001 m is not."""
    from gnss_sim_ros2.config_file import load_config

    ok = load_config(None, {"rtk": {"base_position": [48.0, 11.0, 9500.0], "base_position_type": "llh"}})
    assert ok.node("rtk")["base_position"] == [48.0, 11.0, 9500.0]
    with pytest.raises(ValueError, match=r"parameter 'base_position'.*height 10001 m is outside -500\.\.10000 m"):
        load_config(None, {"rtk": {"base_position": [48.0, 11.0, 10001.0], "base_position_type": "llh"}})
    with pytest.raises(ValueError, match=r"parameter 'antenna_position'.*Earth's centre"):
        load_config(None, {"visibility": {"antenna_position": [0.0, 0.0, 0.0], "antenna_position_type": "ecef"}})


@pytest.mark.parametrize("position, kind, words", [
    ([0.0, 0.0, 1e8], "world", "geodetic height"),
    ([91.0, 0.0, 0.0], "llh", "latitude 91 deg"),
    ([0.0, 0.0, 0.0], "ecef", "Earth's centre"),
])
def test_visibility_node_refuses_an_impossible_static_antenna(position, kind, words):
    """The node's antenna_position goes through the same checker (world: as its scene places it); the configure
    transition fails naming the parameter."""
    pytest.importorskip("rclpy", reason="rclpy is not installed (run make test)")
    from rclpy.parameter import Parameter
    from ros_helpers import RosFixture

    from gnss_sim_ros2.nodes.visibility_node import VisibilityNode

    ros = RosFixture()
    try:
        overrides = [Parameter("use_sim_time", value=True), Parameter("antenna_position", value=position),
                     Parameter("antenna_position_type", value=kind)]
        node = ros.add(VisibilityNode(node_name="gnss_sim_bad_visibility", parameter_overrides=overrides,
                                      context=ros.context))
        node.trigger_configure()
        assert node._state_machine.current_state[1] == "unconfigured"
        assert "parameter 'antenna_position'" in node.last_error and words in node.last_error, node.last_error
    finally:
        ros.close()
