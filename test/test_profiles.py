"""Receiver profiles as YAML files (issue 26, part B): the shipped ones hold the values their sources state, a user's
file sets the receiver's defaults (arguments still override), bad files are refused naming file, key and line, and
`--profile NAME|FILE` works from the command line and along the parameter path."""
from __future__ import annotations

import re
import textwrap

import pytest
import yaml

from gnss_sim_ros2.cli import main
from gnss_sim_ros2.core.receiver.config import ReceiverConfig
from gnss_sim_ros2.core.receiver.profiles import (
    ProfileError,
    builtin_names,
    filled_in,
    load_profile,
    profile_yaml,
)


def _cli(argv, capsys) -> tuple[int, str, str]:
    try:
        rc = main([str(a) for a in argv])
    except SystemExit as exc:
        rc = exc.code
    out = capsys.readouterr()
    return rc, out.out, out.err


# ------------------------------------------------------------------------------------------------ shipped profiles
def test_the_profiles_ship_as_files():
    assert set(builtin_names()) == {"geodetic", "single_frequency", "ublox_m8t", "ublox_f9p", "polarx5_choke_ring",
                                    "ublox_m8t_hk"}
    for name in builtin_names():
        prof = load_profile(name)
        assert prof.name == name and prof.description and prof.source
        assert prof.path.endswith(f"profiles/{name}.yaml")


def test_the_polarx5_profile_is_what_calibrate_fits_on_esbc(shared_data, tmp_path, capsys):
    """The shipped polarx5_choke_ring is gnss-sim calibrate's output on ESBC 2020-06-25 hours 0-12 (its header says
    how): the same command gives the same profile, so the file can be made again and nobody edited it by hand."""
    d = shared_data / "esbc-2020-177-polarx5"
    rc, _, err = _cli(["calibrate", "--quiet", "--obs", d / "ESBC00DNK_R_20201770000_01D_30S_MO.crx.gz",
                       "--nav", d / "ESBC00DNK_R_20201770000_01D_MN.rnx.gz", "--start", "2020-06-25T00:00:00",
                       "--duration", "43200", "--name", "polarx5_choke_ring", "--out", tmp_path / "cal"], capsys)
    assert rc == 0, err
    fitted = yaml.safe_load((tmp_path / "cal" / "polarx5_choke_ring.yaml").read_text())
    shipped = yaml.safe_load(open(load_profile("polarx5_choke_ring").path).read())
    assert fitted == shipped
    cfg = ReceiverConfig(profile="polarx5_choke_ring")
    assert cfg.antenna == "choke_ring" and cfg.tracking.start == "warm" and not cfg.tracking.half_cycle_flags
    assert cfg.rinex["receiver_type"] == "SEPT POLARX5"


def test_the_ublox_m8t_hk_profile_is_what_calibrate_fits_on_the_hong_kong_drive(shared_data, tmp_path, capsys,
                                                                               monkeypatch):
    """The shipped ublox_m8t_hk is gnss-sim calibrate's line-of-sight fit on the Hong Kong drive with the city model
    (the three steps of its header: the city mesh, the antenna path placed in it, calibrate --mesh): the same steps
    give the same profile."""
    from gnss_sim_ros2.core.comparison import drive_check

    drive_dir, city = shared_data / "hk-tst-2019-118-urban-drive", shared_data / "hk-tst-city-model"
    if not (drive_dir / "COM3_190428_124409.obs.gz").is_file() or not city.is_dir():
        pytest.skip("needs hk-tst-2019-118-urban-drive and hk-tst-city-model in ../shared/data")
    scene = drive_check.city_scene(city, tmp_path / "city")        # unpacks the terrain mesh (the README's step)
    path = drive_check.write_trajectory_csv(drive_check.load_drive(drive_dir / "groundTruth_TST.csv", scene),
                                            tmp_path / "hk_path_world.csv")
    monkeypatch.setenv("GZ_SIM_RESOURCE_PATH", str(tmp_path / "city" / "models"))
    rc, _, err = _cli(["export-world", tmp_path / "city" / "worlds" / "hong_kong_city_only.world", "--keep-dynamic",
                       "--out", tmp_path / "hk_city.ply"], capsys)
    assert rc == 0, err
    rc, out, err = _cli(["calibrate", "--obs", drive_dir / "COM3_190428_124409.obs.gz", "--nav",
                         drive_dir / "hksc1180.19n", drive_dir / "hksc1180.19b", "--trajectory", path,
                         "--mesh", tmp_path / "hk_city.ply", "--start", "2019-04-28T12:58:21", "--duration", "485",
                         "--base-profile", "ublox_m8t", "--name", "ublox_m8t_hk", "--out", tmp_path / "cal"], capsys)
    assert rc == 0, err
    assert "C/N0 samples kept G1C 1842/2834, C2I 3277/4263" in out       # the counts the header states
    fitted = yaml.safe_load((tmp_path / "cal" / "ublox_m8t_hk.yaml").read_text())
    shipped = yaml.safe_load(open(load_profile("ublox_m8t_hk").path).read())
    assert fitted == shipped
    cfg = ReceiverConfig(profile="ublox_m8t_hk")
    assert cfg.antenna == "patch" and cfg.cn0_resolution_db == 1.0
    # no line-of-sight rise or set on the drive: the base profile's thresholds, and its loops
    assert (cfg.tracking.acquisition_cn0_dbhz, cfg.tracking.tracking_cn0_dbhz, cfg.dll_spacing_chips) == \
        (22.0, 16.0, 0.5)


def test_geodetic_profile_values():
    """A multi-frequency geodetic receiver: GPS L1 C/A, L2 P(Y) (2W), L2C, L5; choke ring; 16 MHz front end
    (P(Y) / L5 at 10.23 Mchip/s need it, NetR9 data sheet); a 0.1 chip narrow correlator, 0.25 Hz DLL (issue 26
    part C: the Septentrio default loop); acquire 20.5, lose 20 dB-Hz (issue 27: where the PolaRx5 of ESBC starts
    and ends its tracks, test_geodetic_thresholds); the code biases measured on OPEC 2022-001 (Galileo -2.9 m,
    BeiDou-2 7.5 m, BeiDou-3 8.9 m)."""
    cfg = ReceiverConfig(profile="geodetic")
    assert cfg.profile == {"G": ["1C", "2W", "2L", "5Q"], "R": ["1C", "2C"], "E": ["1C", "5Q", "7Q", "8Q", "6C"],
                           "C": ["2I", "7I", "6I", "1P", "5P"], "J": ["1C", "2L", "5Q"], "I": ["5A"]}
    assert (cfg.antenna, cfg.dll_spacing_chips, cfg.dll_bn_hz, cfg.frontend_bandwidth_hz) == \
        ("choke_ring", 0.1, 0.25, 16e6)
    assert (cfg.tracking.acquisition_cn0_dbhz, cfg.tracking.tracking_cn0_dbhz) == (20.5, 20.0)
    assert cfg.code_bias_m == {"E": {"*": -2.9}, "C2": {"*": 7.5}, "C3": {"*": 8.9}}
    assert cfg.excluded_svs == "" and cfg._excluded is None
    assert ReceiverConfig().profile == cfg.profile                     # the default profile


def test_single_frequency_profile_values():
    """L1/E1/B1I/G1 and NavIC L5, patch, 4 MHz front end (assumed), the BeiDou-2/-3 split of 1.4 m only."""
    cfg = ReceiverConfig(profile="single_frequency")
    assert cfg.profile == {"G": ["1C"], "R": ["1C"], "E": ["1C"], "C": ["2I"], "J": ["1C"], "I": ["5A"]}
    assert (cfg.antenna, cfg.dll_spacing_chips, cfg.dll_bn_hz, cfg.frontend_bandwidth_hz) == ("patch", 0.2, 0.5, 4e6)
    assert (cfg.tracking.acquisition_cn0_dbhz, cfg.tracking.tracking_cn0_dbhz) == (33.0, 28.0)
    assert cfg.code_bias_m == {"C2": {"*": -1.4}}


def test_ublox_m8t_profile_values():
    """NEO/LEA-M8T data sheet: GPS L1C/A, GLONASS L1OF, Galileo E1, BeiDou B1I, QZSS L1C/A (no NavIC); 2 MHz,
    0.5 chip, 1 Hz DLL and the thresholds 22/16 dB-Hz are the stated assumptions; no code bias table."""
    cfg = ReceiverConfig(profile="ublox_m8t")
    assert cfg.profile == {"G": ["1C"], "R": ["1C"], "E": ["1C"], "C": ["2I"], "J": ["1C"]}
    assert (cfg.antenna, cfg.dll_spacing_chips, cfg.dll_bn_hz, cfg.frontend_bandwidth_hz) == ("patch", 0.5, 1.0, 2e6)
    assert (cfg.tracking.acquisition_cn0_dbhz, cfg.tracking.tracking_cn0_dbhz) == (22.0, 16.0)
    assert cfg.code_bias_m == {} and cfg.excluded_svs == ""


def test_ublox_f9p_profile_values():
    """ZED-F9P integration manual: L1C/A + L2C (CL pilot 2L), L1OF + L2OF, E1 + E5b pilot (7Q), B1I + B2I, QZSS
    L1C/A + L2C; 4 MHz, 0.2 chip, 1 Hz DLL; no BeiDou GEO (C01-C05, C59-C63, BDS-OS-PS 3.0 table 3-1)."""
    cfg = ReceiverConfig(profile="ublox_f9p")
    assert cfg.profile == {"G": ["1C", "2L"], "R": ["1C", "2C"], "E": ["1C", "7Q"], "C": ["2I", "7I"],
                           "J": ["1C", "2L"]}
    assert (cfg.antenna, cfg.dll_spacing_chips, cfg.dll_bn_hz, cfg.frontend_bandwidth_hz) == ("patch", 0.2, 1.0, 4e6)
    assert (cfg.tracking.acquisition_cn0_dbhz, cfg.tracking.tracking_cn0_dbhz) == (22.0, 16.0)
    geo = [f"C{p:02d}" for p in (1, 2, 3, 4, 5, 59, 60, 61, 62, 63)]
    others = [f"C{p:02d}" for p in (6, 18, 19, 46, 58)]
    assert all(cfg._excluded.fullmatch(sv) for sv in geo)
    assert not any(cfg._excluded.fullmatch(sv) for sv in others)


# ------------------------------------------------------------------------------------------------- a user's file
MY = """\
gnss_sim_profile: 1
description: my receiver
signals:
  G: [1C, 5Q]
  E: [1C]
antenna: choke_ring
dll_bn_hz: 0.25
frontend_bandwidth_hz: 20.0e6
rinex: {receiver_type: MY RX 1, antenna_type: MYANT           NONE}
tracking:
  acquisition_cn0_dbhz: 30.0
  tracking_cn0_dbhz: 24.0
"""
MY_DOC = yaml.safe_load(MY.replace("20.0e6", "20.0e+6"))      # the same profile as a mapping


def test_a_users_file_sets_the_defaults_and_arguments_override(tmp_path):
    f = tmp_path / "my_rx.yaml"
    f.write_text(MY)
    prof = load_profile(f)
    assert prof.name == "my_rx" and prof.path == str(f.resolve())     # name: the file's stem
    cfg = ReceiverConfig(profile=str(f))
    assert cfg.profile == {"G": ["1C", "5Q"], "E": ["1C"]}
    assert (cfg.antenna, cfg.dll_bn_hz, cfg.frontend_bandwidth_hz) == ("choke_ring", 0.25, 20e6)  # 20.0e6: a number
    assert (cfg.tracking.acquisition_cn0_dbhz, cfg.tracking.tracking_cn0_dbhz) == (30.0, 24.0)
    assert cfg.rinex == {"receiver_type": "MY RX 1", "antenna_type": "MYANT           NONE"}
    # what the file leaves out: the receiver's built-in values (those of the single_frequency profile)
    single = ReceiverConfig(profile="single_frequency")
    assert cfg.dll_spacing_chips == single.dll_spacing_chips and cfg.code_bias_m == {}
    # an argument beats the file
    cfg2 = ReceiverConfig(profile=str(f), dll_bn_hz=2.0, antenna="patch")
    assert (cfg2.dll_bn_hz, cfg2.antenna, cfg2.frontend_bandwidth_hz) == (2.0, "patch", 20e6)
    # a bare signal mapping (the old custom profile) still works, with the built-in values
    assert ReceiverConfig(profile={"G": ["1C"]}).antenna == "patch"


def test_show_prints_a_file_that_loads_back_to_the_same_receiver(tmp_path):
    for name in builtin_names():
        f = tmp_path / f"copy_{name}.yaml"
        f.write_text(profile_yaml(name))
        a, b = ReceiverConfig(profile=str(f)), ReceiverConfig(profile=name)
        assert repr(a) == repr(b), name
        assert filled_in(str(f))["name"] == name


# ------------------------------------------------------------------------------------------------------ bad files
def _line_of(text: str, needle: str) -> int:
    return next(i for i, line in enumerate(text.splitlines(), 1) if needle in line)


BAD = [
    # (what, edit of MY, key path in the message, line holding, words)
    ("unknown key", MY + "dll_bw_hz: 1.0\n", "dll_bw_hz", "dll_bw_hz:", "unknown key (did you mean 'dll_bn_hz'?)"),
    ("unknown nested key", MY.replace("  tracking_cn0_dbhz: 24.0", "  tracking_cn0_dbhz: 24.0\n  strat: warm"),
     "tracking.strat", "strat:", "unknown key"),
    ("wrong type", MY.replace("dll_bn_hz: 0.25", "dll_bn_hz: narrow"), "dll_bn_hz", "dll_bn_hz:",
     "must be a finite number"),
    ("wrong nested type", MY.replace("acquisition_cn0_dbhz: 30.0", "acquisition_cn0_dbhz: [30]"),
     "tracking.acquisition_cn0_dbhz", "acquisition_cn0_dbhz:", "must be a finite number"),
    ("unknown signal", MY.replace("G: [1C, 5Q]", "G: [1C, 4Q]"), r"signals.G\[1\]", "G: [1C, 4Q]",
     "'4Q' is not a known RINEX 3 code"),
    ("unknown system", MY.replace("E: [1C]", "X: [1C]"), "signals.X", "X: [1C]", "not a system letter"),
    ("a run field", MY + "seed: 3\n", "seed", "seed:", "belongs to the run"),
    ("bad value", MY.replace("antenna: choke_ring", "antenna: helix"), "antenna", "antenna:",
     "not an antenna pattern"),
    ("thresholds out of order", MY.replace("tracking_cn0_dbhz: 24.0", "tracking_cn0_dbhz: 34.0"), "tracking",
     "tracking:", "exceeds"),
    ("schema version", MY.replace("gnss_sim_profile: 1", "gnss_sim_profile: 2"), "gnss_sim_profile",
     "gnss_sim_profile:", "schema version 2"),
    ("rinex text too long", MY.replace("MY RX 1", "A RECEIVER TYPE LONGER THAN TWENTY"), "rinex", "rinex:",
     "at most 20 characters"),
]


@pytest.mark.parametrize("what, text, key, line_text, words", BAD, ids=[b[0] for b in BAD])
def test_a_bad_file_is_refused_naming_file_key_and_line(tmp_path, what, text, key, line_text, words):
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    with pytest.raises(ProfileError) as info:
        load_profile(str(f))
    msg = str(info.value)
    assert str(f) in msg, msg
    assert re.search(f"key '{key}'", msg), msg
    assert f"line {_line_of(text, line_text)}" in msg, msg
    assert words in msg, msg
    with pytest.raises(ValueError, match=re.escape(str(f))):      # the receiver refuses it the same way
        ReceiverConfig(profile=str(f))


def test_missing_signals_version_file_and_name(tmp_path):
    f = tmp_path / "nosig.yaml"
    f.write_text("gnss_sim_profile: 1\nantenna: patch\n")
    with pytest.raises(ProfileError, match=f"{re.escape(str(f))}.*'signals'.*missing"):
        load_profile(f)
    f.write_text("signals: {G: [1C]}\n")
    with pytest.raises(ProfileError, match="gnss_sim_profile: 1.*missing"):
        load_profile(f)
    f.write_text("signals: {G: [1C\n")
    with pytest.raises(ProfileError, match="not valid YAML"):
        load_profile(f)
    with pytest.raises(ProfileError, match="does not exist"):
        load_profile(tmp_path / "none.yaml")
    with pytest.raises(ProfileError, match="'ublox_f8p' is not a built-in one \\(did you mean 'ublox_f9p'\\?\\)"):
        load_profile("ublox_f8p")


def test_new_fields_of_the_dataclasses_are_profile_keys():
    """The keys come from the dataclasses: every init field of ReceiverConfig but the run's, and every field of
    TrackingConfig / LinkBudget under tracking / link_budget."""
    import dataclasses

    from gnss_sim_ros2.core.receiver.profile_file import RUN_FIELDS
    doc = filled_in("geodetic")
    owned = {f.name for f in dataclasses.fields(ReceiverConfig) if f.init} - RUN_FIELDS
    assert owned <= set(doc) and not (RUN_FIELDS & set(doc))
    from gnss_sim_ros2.core.receiver.tracking import TrackingConfig
    assert set(doc["tracking"]) == {f.name for f in dataclasses.fields(TrackingConfig) if f.init}


# ------------------------------------------------------------------------------------------------- command line
def test_simulate_with_a_profile_file(tmp_path, capsys, monkeypatch):
    """`simulate --profile my.yaml` (relative to the working directory): the file's signals and RINEX names."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "my.yaml").write_text(MY)
    rc, out, err = _cli(["simulate", "--profile", "my.yaml", "--duration", "5", "--systems", "GE",
                         "--out", tmp_path / "out", "--quiet"], capsys)
    assert rc == 0, err
    (obs,) = (tmp_path / "out").glob("*_MO.rnx")
    header = obs.read_text().split("END OF HEADER")[0].splitlines()
    rec = next(h for h in header if h[60:].strip() == "REC # / TYPE / VERS")
    ant = next(h for h in header if h[60:].strip() == "ANT # / TYPE")
    assert rec[20:40].strip() == "MY RX 1" and ant[20:40] == "MYANT           NONE"
    types = {h[0]: h[7:60].split() for h in header if h[60:].strip() == "SYS / # / OBS TYPES"}
    assert types == {"G": ["C1C", "L1C", "D1C", "S1C", "C5Q", "L5Q", "D5Q", "S5Q"],
                     "E": ["C1C", "L1C", "D1C", "S1C"]}


@pytest.mark.parametrize("arg, words", [
    ("nosuch", ["option --profile", "'nosuch' is not a built-in one", "geodetic"]),
    ("bad.yaml", ["option --profile", "bad.yaml, line 3: key 'dll_bn_hz'", "must be a finite number"]),
    ("missing.yaml", ["option --profile", "missing.yaml does not exist"]),
])
def test_simulate_refuses_a_bad_profile_in_one_line(tmp_path, capsys, monkeypatch, arg, words):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.yaml").write_text("gnss_sim_profile: 1\nsignals: {G: [1C]}\ndll_bn_hz: wide\n")
    rc, out, err = _cli(["simulate", "--profile", arg, "--duration", "5", "--out", tmp_path / "out"], capsys)
    assert rc == 2, out + err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, (w, err)
    assert not (tmp_path / "out").exists() or not list((tmp_path / "out").glob("*.rnx"))


def test_profile_list_and_show(tmp_path, capsys):
    rc, out, _ = _cli(["profile", "list"], capsys)
    assert rc == 0 and [line.split()[0] for line in out.splitlines()] == list(builtin_names())
    rc, out, _ = _cli(["profile", "show", "ublox_m8t"], capsys)
    assert rc == 0
    doc = yaml.safe_load(out)
    assert doc["signals"]["G"] == ["1C"] and doc["tracking"]["acquisition_cn0_dbhz"] == 22.0
    rc, out, err = _cli(["profile", "show", "nosuch"], capsys)
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "'nosuch'" in err


def test_parameter_table_checks_the_profile(tmp_path, monkeypatch):
    """The parameter 'profile' (one check, parameters.py): a name stays, a file becomes its absolute path, a bad
    one names the parameter, the file, the key and the line."""
    from gnss_sim_ros2.config_file import load_config

    monkeypatch.chdir(tmp_path)
    (tmp_path / "my.yaml").write_text(MY)
    cfg = load_config(None, {"receiver": {"profile": "my.yaml"}})
    assert cfg.node("receiver")["profile"] == str(tmp_path / "my.yaml")
    assert load_config(None, {"receiver": {"profile": "ublox_m8t"}}).node("receiver")["profile"] == "ublox_m8t"
    # a run's params.yaml (gnss-sim run writes cfg.ros_parameter_file_dict()) reruns from another folder
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "params.yaml").write_text(yaml.safe_dump(cfg.ros_parameter_file_dict()))
    monkeypatch.chdir(tmp_path / "run")
    again = load_config(tmp_path / "run" / "params.yaml")
    assert again.node("receiver")["profile"] == str(tmp_path / "my.yaml")
    assert repr(ReceiverConfig(profile=again.node("receiver")["profile"])) == repr(ReceiverConfig(profile=MY_DOC))
    monkeypatch.chdir(tmp_path)
    conf = tmp_path / "params.yaml"
    conf.write_text(textwrap.dedent("""\
        gnss_sim_receiver:
          ros__parameters:
            profile: bad.yaml
    """))
    (tmp_path / "bad.yaml").write_text(MY + "clock: {}\n")
    with pytest.raises(ValueError) as info:
        load_config(conf)
    msg = str(info.value)
    assert "parameter 'profile'" in msg and str(tmp_path / "bad.yaml") in msg and "key 'clock'" in msg
    assert f"line {_line_of(MY + 'clock: {}', 'clock:')}" in msg


def test_threshold_parameters_keep_the_profiles_other_tracking_fields(tmp_path):
    """cn0_acquire_dbhz / cn0_lose_dbhz override only the thresholds of the profile's tracking."""
    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.core.receiver.chain import ChainSettings

    f = tmp_path / "slow.yaml"
    f.write_text(MY.replace("  tracking_cn0_dbhz: 24.0", "  tracking_cn0_dbhz: 24.0\n  acquisition_time_s: 4.0"))
    cfg = load_config(None, {"receiver": {"profile": str(f), "cn0_acquire_dbhz": 35.0}})
    tr = ChainSettings.from_params(cfg.node("receiver")).receiver.tracking
    assert (tr.acquisition_cn0_dbhz, tr.tracking_cn0_dbhz, tr.acquisition_time_s) == (35.0, 24.0, 4.0)
    with pytest.raises(ValueError, match="cn0_lose_dbhz.*exceeds"):      # 31 > the file's acquisition 30
        load_config(None, {"receiver": {"profile": str(f), "cn0_lose_dbhz": 31.0}})


def test_run_takes_the_profile_option_as_simulate_does(tmp_path, monkeypatch):
    """`gnss-sim run --profile NAME|FILE` sets the receiver node's parameter through the same table check; an error
    names the option (the ROS graph itself is not started here)."""
    import argparse

    from gnss_sim_ros2.commands.run.command import PARAM_OPTIONS, _overrides, add_arguments
    from gnss_sim_ros2.config_file import load_config

    monkeypatch.chdir(tmp_path)
    (tmp_path / "my.yaml").write_text(MY)
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = parser.parse_args(["--profile", "my.yaml", "--rtk"])
    cfg = load_config(None, _overrides(args), PARAM_OPTIONS)
    assert cfg.node("receiver")["profile"] == str(tmp_path / "my.yaml") and cfg.node("receiver")["rtcm"] is True
    with pytest.raises(ValueError, match="option --profile: parameter 'profile': receiver profile 'f9p'"):
        load_config(None, _overrides(parser.parse_args(["--profile", "f9p"])), PARAM_OPTIONS)
