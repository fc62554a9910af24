"""The scenario file (core/threats/scenario.py): what it reads, and errors naming the file, line and key."""
from __future__ import annotations

import math

import pytest

from gnss_sim_ros2.core.threats.scenario import (
    FaultEvent,
    JammerEvent,
    ScenarioError,
    SpooferEvent,
    load_scenario,
)
from gnss_sim_ros2.parameters import validate_node

GOOD = """\
version: 1
events:
  - type: jammer
    name: car
    path: [[0, -50, 0, 1], [100, 50, 0, 1]]
    eirp_dbw: -40
    center_hz: 1575.42e6
    bandwidth_hz: 0
    start_s: 10
    end_s: .inf
  - type: spoofer
    position: [50.0, 14.0, 300.0]
    position_type: llh
    eirp_dbw: -70
    start_s: 0
    end_s: 5
    false_position: [[0, 0, 0, 0], [10, 100, 0, 0]]
    systems: GE
    mode: simulate
  - type: fault
    kind: satellite_ramp_mps
    satellite: G05
    ramp_mps: 0.5
    start_s: 1
    end_s: 2
"""


def _write(tmp_path, text):
    p = tmp_path / "scn.yaml"
    p.write_text(text)
    return p


def test_a_scenario_is_read_with_every_event_kind(tmp_path):
    s = load_scenario(_write(tmp_path, GOOD))
    jam, spo, flt = s.events
    assert isinstance(jam, JammerEvent) and jam.name == "car" and jam.bandwidth_hz == 0.0
    assert math.isinf(jam.end_s) and bool(jam.active(1e6)) and not bool(jam.active(9.99))
    assert jam.track.at(50.0).tolist() == [0.0, 0.0, 1.0]          # halfway along the path
    assert isinstance(spo, SpooferEvent) and spo.systems == "GE" and spo.track.frame == "llh"
    assert spo.false_track.at(5.0)[0] == pytest.approx(50.0)
    assert isinstance(flt, FaultEvent) and flt.kind == "satellite_ramp_mps" and flt.satellite == "G05"
    assert s.needs_scene_frame()                                    # the jammer's path is in world coordinates


@pytest.mark.parametrize("old, new, line, key, words", [
    ("    bandwidth_hz: 0\n", "    bandwidth_hz: 0\n    power_w: 3\n", 9, "events[0].power_w", "unknown key"),
    ("    eirp_dbw: -40\n", "    eirp_dbw: loud\n", 6, "events[0].eirp_dbw", "must be a number"),
    ("    kind: satellite_ramp_mps\n", "    kind: melt\n", 21, "events[2].kind", "one of off"),
    ("    satellite: G05\n", "    satellite: GPS5\n", 22, "events[2].satellite", "satellite id"),
    ("    end_s: 5\n", "    end_s: 0\n", 16, "events[1].end_s", "must be after start_s"),
    ("    mode: simulate\n", "    mode: replay\n", 19, "events[1].mode", "simulate, meacon"),
    ("version: 1\n", "version: 2\n", 1, "version", "schema version 2"),
])
def test_errors_name_file_line_and_key(tmp_path, old, new, line, key, words):
    assert old in GOOD
    p = _write(tmp_path, GOOD.replace(old, new, 1))
    with pytest.raises(ScenarioError) as exc:
        load_scenario(p)
    msg = str(exc.value)
    assert str(p) in msg and f"line {line}" in msg and f"key '{key}'" in msg and words in msg, msg


def test_a_missing_key_names_the_event(tmp_path):
    p = _write(tmp_path, GOOD.replace("    ramp_mps: 0.5\n", ""))
    with pytest.raises(ScenarioError, match=r"line 20: key 'events\[2\]': fault 'satellite_ramp_mps' needs key "
                                            r"'ramp_mps'"):
        load_scenario(p)


def test_the_parameter_validates_the_file_once_and_keeps_its_absolute_path(tmp_path, monkeypatch):
    p = _write(tmp_path, GOOD)
    monkeypatch.chdir(tmp_path)
    assert validate_node("receiver", {"scenario": "scn.yaml"}, "test")["scenario"] == str(p.resolve())
    _write(tmp_path, GOOD.replace("eirp_dbw: -40", "eirp_dbw: []"))
    with pytest.raises(ValueError, match=r"parameter 'scenario'.*line 6: key 'events\[0\].eirp_dbw'"):
        validate_node("receiver", {"scenario": "scn.yaml"}, "test")


def test_a_spoofer_is_run_and_its_world_positions_need_a_georeferenced_scene(tmp_path):
    from gnss_sim_ros2.core.threats.runtime import ThreatRuntime

    s = load_scenario(_write(tmp_path, GOOD))
    with pytest.raises(ValueError, match=r"world coordinates needs a georeferenced scene"):
        ThreatRuntime(s)                 # the jammer's path and the spoofer's false path are world positions
    llh = GOOD.replace("false_position: [[0, 0, 0, 0], [10, 100, 0, 0]]",
                       "false_position: [[0, 50.0, 14.0, 300], [10, 50.001, 14.0, 300]]\n    false_position_type: llh")
    llh = llh.replace("path: [[0, -50, 0, 1], [100, 50, 0, 1]]",
                      "position: [50.0, 14.001, 300.0]\n    position_type: llh")
    rt = ThreatRuntime(load_scenario(_write(tmp_path, llh)))
    assert rt.spoofing is not None and [e.name for e in rt.spoofing.spoofers] == ["spoofer1"]
