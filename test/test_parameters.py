"""One parameter table drives the ROS nodes and the offline tools; errors name file and parameter."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from gnss_sim_ros2.config_file import load_config
from gnss_sim_ros2.parameters import NODE_NAMES, default_config_yaml, defaults

REPO = Path(__file__).resolve().parents[1]


def test_shipped_config_equals_the_table():
    assert (REPO / "config" / "gnss_sim.yaml").read_text() == default_config_yaml(), (
        "config/gnss_sim.yaml is stale: regenerate it with `gnss-sim config > config/gnss_sim.yaml`")
    assert load_config(REPO / "config" / "gnss_sim.yaml").values == defaults().values


def test_shared_then_node_sections(tmp_path):
    f = tmp_path / "p.yaml"
    f.write_text(yaml.safe_dump({
        "/**": {"ros__parameters": {"systems": "GE", "rate_hz": 10}},
        "gnss_sim_receiver": {"ros__parameters": {"systems": "G", "profile": "single_frequency"}},
    }))
    cfg = load_config(f)
    assert cfg.node("ephemeris")["systems"] == "GE"
    assert cfg.node("visibility")["rate_hz"] == 10.0 and isinstance(cfg.node("visibility")["rate_hz"], float)
    assert cfg.node("receiver")["systems"] == "G"
    assert cfg.node("receiver")["profile"] == "single_frequency"
    # the ROS parameter-file view carries the same values
    ros = cfg.ros_parameter_file_dict()
    assert ros[NODE_NAMES["receiver"]]["ros__parameters"]["systems"] == "G"


@pytest.mark.parametrize("doc, message", [
    ({"gnss_sim_receiver": {"ros__parameters": {"profil": "geodetic"}}}, "unknown parameter 'profil'.*'profile'"),
    ({"gnss_sim_receiver": {"ros__parameters": {"profile": "cheap"}}},
     "parameter 'profile': receiver profile 'cheap' is not a built-in one.*geodetic.*or a .yaml file"),
    ({"/**": {"ros__parameters": {"rate_hz": "fast"}}}, "'rate_hz' must be double"),
    ({"/**": {"ros__parameters": {"rate_hz": 0.0}}}, "'rate_hz' is 0.0; minimum"),
    ({"gnss_sim_reciever": {"ros__parameters": {}}}, "unknown node.*gnss_sim_receiver"),
    ({"gnss_sim_receiver": {"profile": "geodetic"}}, "expected 'ros__parameters:'"),
])
def test_bad_files_name_file_section_and_parameter(tmp_path, doc, message):
    f = tmp_path / "bad.yaml"
    f.write_text(yaml.safe_dump(doc))
    with pytest.raises(ValueError, match=message) as info:
        load_config(f)
    assert str(f) in str(info.value)


@pytest.mark.parametrize("section, line, message", [
    ("gnss_sim_visibility", "multipath: off",
     r"'multipath' must be string, got False \(YAML 1.1 reads an unquoted off / no / false as a boolean: "
     r"write 'off' in quotes\)"),
    ("gnss_sim_receiver", "lms_environment: no", r"got False .*write 'off' in quotes"),
    ("gnss_sim_receiver", "tracking_start: yes", r"got True .*write the word in quotes"),   # no 'on' among choices
    ("gnss_sim_rtk", "rtkrcv_path: on", r"got True .*write 'on' in quotes"),
])
def test_a_yaml_boolean_for_a_string_names_the_quotes(tmp_path, section, line, message):
    """YAML 1.1 reads an unquoted off/no/yes/on as a boolean: the error says to quote the word (issue 27)."""
    f = tmp_path / "bool.yaml"
    f.write_text(f"{section}:\n  ros__parameters:\n    {line}\n")
    with pytest.raises(ValueError, match=message) as info:
        load_config(f)
    assert str(f) in str(info.value)


def test_the_quoted_word_is_accepted(tmp_path):
    f = tmp_path / "quoted.yaml"
    f.write_text("gnss_sim_visibility:\n  ros__parameters:\n    multipath: 'off'\n"
                 "gnss_sim_receiver:\n  ros__parameters:\n    lms_environment: 'off'\n")
    cfg = load_config(f)
    assert cfg.node("visibility")["multipath"] == "off" and cfg.node("receiver")["lms_environment"] == "off"


def test_a_number_for_a_string_gets_no_boolean_hint(tmp_path):
    f = tmp_path / "num.yaml"
    f.write_text("gnss_sim_visibility:\n  ros__parameters:\n    multipath: 3\n")
    with pytest.raises(ValueError, match=r"must be string, got 3$"):
        load_config(f)


def test_missing_and_malformed_files(tmp_path):
    with pytest.raises(ValueError, match="does not exist"):
        load_config(tmp_path / "none.yaml")
    f = tmp_path / "broken.yaml"
    f.write_text("a: [1,\n")
    with pytest.raises(ValueError, match="not valid YAML"):
        load_config(f)
