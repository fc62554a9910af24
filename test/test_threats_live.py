"""Events started and stopped during a run (core/threats/live.py, the receiver node's ~/threats/start and
~/threats/stop): the scenario file's checks and error texts, and the same effect and labels as the same event
written in a file."""
from __future__ import annotations

import math

import numpy as np
import pytest

from gnss_sim_ros2.core.frames import ecef_to_geodetic, enu_to_ecef, geodetic_to_ecef
from gnss_sim_ros2.core.receiver.cn0 import LinkBudget
from gnss_sim_ros2.core.threats.live import event_from_text, start_event, stop_event
from gnss_sim_ros2.core.threats.runtime import ThreatRuntime
from gnss_sim_ros2.core.threats.scenario import Scenario, ScenarioError, load_scenario
from gnss_sim_ros2.core.time import GnssTime

T0 = GnssTime.from_iso("2024-05-01T10:00:00", scale="GPS")
ANT_LLH = (50.0758, 14.4179, 250.0)
ANT = np.array(geodetic_to_ecef(*ANT_LLH))
#: a 2 MHz jammer 200 m east of the antenna, 1.5 m up
JAM_LLH = ecef_to_geodetic(*enu_to_ecef(np.array([200.0, 0.0, 1.5]), *ANT_LLH))
JAMMER = (f"{{type: jammer, name: ppd, position: [{JAM_LLH[0]:.9f}, {JAM_LLH[1]:.9f}, {JAM_LLH[2]:.3f}], "
          f"position_type: llh, eirp_dbw: -30, center_hz: 1575.42e6, bandwidth_hz: 2.0e6")


def _cn0(runtime, t_rel_s):
    """C/N0 of a GPS L1 C/A and an L5 row (45 dB-Hz each) at run time ``t_rel_s`` through the runtime."""
    t = T0 + float(t_rel_s)
    return runtime.signal_cn0([t], ANT[None, :], np.zeros(2, int), np.array(["G05", "G05"]), np.array(["1C", "5Q"]),
                              np.array([1575.42e6, 1176.45e6]), np.array([45.0, 45.0]), LinkBudget(antenna="patch"),
                              20.0e6)


def _empty():
    return ThreatRuntime(Scenario((), "test"), start=T0)


def test_a_started_event_acts_and_labels_as_the_same_event_of_a_file(tmp_path):
    live = _empty()
    assert start_event(live, JAMMER + ", start_s: 5, end_s: 9}", now_s=3.0) == "ppd"
    (tmp_path / "s.yaml").write_text(f"version: 1\nevents: [{JAMMER}, start_s: 5, end_s: 9}}]\n")
    filed = ThreatRuntime(load_scenario(tmp_path / "s.yaml"), start=T0)
    for t in (4.0, 5.0, 8.0, 9.0):
        np.testing.assert_array_equal(_cn0(live, t), _cn0(filed, t))
        assert live.labels(T0 + t) == filed.labels(T0 + t)
        assert live.status(T0 + t) == filed.status(T0 + t)
    jammed = _cn0(live, 6.0)
    assert jammed[0] < 45.0 - 3.0 and jammed[1] == 45.0        # L1 C/A hit, L5 outside the jammer's band
    assert live.labels(T0 + 6.0) == ["ppd"] and live.labels(T0 + 9.0) == []


def test_start_defaults_to_now_and_stop_ends_it_then():
    rt = _empty()
    name = start_event(rt, JAMMER + "}", now_s=10.0)
    assert [rt.labels(T0 + t) for t in (9.0, 10.0, 50.0)] == [[], [name], [name]]
    assert _cn0(rt, 10.0)[0] < 42.0
    stop_event(rt, name, now_s=20.0)
    assert rt.labels(T0 + 19.0) == [name] and rt.labels(T0 + 20.0) == []
    assert _cn0(rt, 20.0)[0] == 45.0
    with pytest.raises(ValueError, match="over already"):
        stop_event(rt, name, now_s=30.0)
    with pytest.raises(ValueError, match=r"no threat event 'car' in this run \(events: ppd\)"):
        stop_event(rt, "car", now_s=30.0)


def test_faults_started_live_act_on_the_outputs():
    rt = _empty()
    name = start_event(rt, "type: fault\nkind: position_offset\noffset_enu_m: [10, 0, 0]\n", now_s=0.0)
    assert name == "fault0" and [f.name for f in rt.output_faults.faults] == ["fault0"]
    stop_event(rt, name, now_s=4.0)
    assert rt.output_faults.faults[0].end_s == 4.0
    assert start_event(rt, "{type: fault, kind: clock_jump_s, jump_s: 1.0e-3}", now_s=5.0) == "fault1"
    assert rt.clock_offset_s([T0 + 6.0])[0] == pytest.approx(1.0e-3)


def test_the_file_error_texts_name_the_line_and_key():
    with pytest.raises(ScenarioError) as exc:
        event_from_text("type: jammer\nposition: [1, 2, 3]\npower_w: 3\n", [], 0.0)
    assert "line 3: key 'events[0].power_w': unknown key 'power_w'; allowed here: type, name" in str(exc.value)
    with pytest.raises(ScenarioError, match="line 2: key 'events\\[0\\].kind': is 'bogus'; one of off, stuck"):
        event_from_text("type: fault\nkind: bogus\n", [], 0.0)
    with pytest.raises(ScenarioError, match="expected one event"):
        event_from_text("- type: fault\n", [], 0.0)
    with pytest.raises(ScenarioError, match="not valid YAML"):
        event_from_text("{type: fault", [], 0.0)
    with pytest.raises(ScenarioError, match="event name 'ppd' is already used"):
        event_from_text(JAMMER + "}", ["ppd"], 0.0)
    assert event_from_text("{type: fault, kind: off}", ["fault0"], 2.5).name == "fault1"
    ev = event_from_text("{type: fault, kind: off}", [], 2.5)
    assert (ev.start_s, ev.end_s) == (2.5, math.inf)


def test_the_runtime_rules_hold_for_a_started_event():
    rt = _empty()                                            # no scene: a world position cannot be placed
    with pytest.raises(ValueError, match="needs a georeferenced scene"):
        start_event(rt, "{type: jammer, position: [1, 2, 3], eirp_dbw: -30, center_hz: 1575.42e6, "
                        "bandwidth_hz: 0}", now_s=0.0)
    assert rt.scenario.events == () and rt.jammers == []      # nothing half-added
