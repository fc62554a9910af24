"""Each receiver fault of a scenario (core/threats/faults.py) does what its name says, offline through the one
chain: a run with the fault against the same run without it (noise off: the runs are otherwise identical)."""
from __future__ import annotations

import csv

import numpy as np
import pytest

from gnss_sim_ros2.config_file import load_config
from gnss_sim_ros2.core.frames import enu_rotation
from gnss_sim_ros2.core.simulation import run_simulation, setup_from_config
from gnss_sim_ros2.core.trajectory import Trajectory

C = 299792458.0
START, END = 8.0, 16.0          # the fault's window [s after the run start]; runs of 24 epochs at 1 s


STATIC = Trajectory.static([50.0758, 14.4179, 250.0], "geodetic")
#: north at 3.7 m/s
MOVING = Trajectory(np.array([0.0, 30.0]), np.array([[50.0758, 14.4179, 250.0], [50.0768, 14.4179, 250.0]]),
                    "geodetic")


def _run(tmp_path, name, fault_yaml="", trajectory=STATIC):
    epochs = []

    def observer(t, ecef, obs, sol):
        epochs.append((obs, sol))

    scenario = ""
    if fault_yaml:
        p = tmp_path / f"{name}.yaml"
        p.write_text(f"version: 1\nevents:\n  - type: fault\n    name: {name}\n{fault_yaml}"
                     f"    start_s: {START}\n    end_s: {END}\n")
        scenario = str(p)
    cfg = load_config(overrides={"/**": {"systems": "G"}, "receiver": {"noise": False, "scenario": scenario}})
    setup = setup_from_config(cfg, tmp_path / name, trajectory,
                              duration_s=23.0, interval_s=1.0, observer=observer)
    res = run_simulation(setup)
    with open(res.fix_path, newline="") as f:
        rows = list(csv.DictReader(f))
    return epochs, rows


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("base"), "base")


IN = list(range(int(START), int(END)))
OUT = [e for e in range(24) if e not in IN]


def _pr(obs, sv):
    return obs.pseudorange_m[obs.sv == sv]


def test_off_outputs_nothing(tmp_path, base):
    epochs, rows = _run(tmp_path, "off", "    kind: off\n")
    for e in IN:
        assert len(epochs[e][0].sv) == 0 and not epochs[e][1].is_fix
        assert rows[e]["status"] == "no_fix" and rows[e]["active_events"] == "off"
    for e in OUT:
        assert epochs[e][1].is_fix and rows[e]["active_events"] == ""
        np.testing.assert_allclose(epochs[e][1].pos_ecef_m, base[0][e][1].pos_ecef_m, atol=1e-6)


def test_stuck_repeats_the_last_output(tmp_path):
    _, moving = _run(tmp_path, "moving", trajectory=MOVING)
    epochs, rows = _run(tmp_path, "stuck", "    kind: stuck\n", trajectory=MOVING)
    frozen = moving[IN[0] - 1]
    for e in IN:
        assert (rows[e]["lat_deg"], rows[e]["lon_deg"], rows[e]["h_m"], rows[e]["status"]) == (
            frozen["lat_deg"], frozen["lon_deg"], frozen["h_m"], "fix")
    assert len({moving[e]["lat_deg"] for e in IN}) == len(IN)     # without the fault the fix moves on
    for e in OUT:
        assert rows[e]["lat_deg"] == moving[e]["lat_deg"]


def test_position_offset_moves_the_fix_by_the_enu_offset(tmp_path, base):
    epochs, _ = _run(tmp_path, "offset", "    kind: position_offset\n    offset_enu_m: [10.0, -4.0, 2.0]\n")
    for e in range(24):
        a, b = epochs[e][1], base[0][e][1]
        d_enu = enu_rotation(b.lat_deg, b.lon_deg) @ (a.pos_ecef_m - b.pos_ecef_m)
        np.testing.assert_allclose(d_enu, [10.0, -4.0, 2.0] if e in IN else [0.0, 0.0, 0.0], atol=1e-3)


def test_clock_jump_shifts_every_range_and_the_clock_not_the_fix(tmp_path, base):
    jump = 1e-4
    epochs, _ = _run(tmp_path, "jump", f"    kind: clock_jump_s\n    jump_s: {jump}\n")
    for e in IN:
        obs, sol = epochs[e]
        b_obs, b_sol = base[0][e]
        assert obs.clock_bias_s - b_obs.clock_bias_s == pytest.approx(jump, abs=1e-12)
        # every pseudorange c * jump longer, less the range change over those 100 us (|range rate| < 1 km/s)
        np.testing.assert_allclose(obs.pseudorange_m - b_obs.pseudorange_m, C * jump, atol=0.1)
        np.testing.assert_allclose(sol.pos_ecef_m, b_sol.pos_ecef_m, atol=0.5)
    for e in OUT:
        assert epochs[e][0].clock_bias_s == base[0][e][0].clock_bias_s


@pytest.mark.parametrize("kind, value, expect", [
    ("satellite_clock_step_m", "step_m: 25.0", lambda t: 25.0),
    ("satellite_ramp_mps", "ramp_mps: 3.0", lambda t: 3.0 * (t - START)),
])
def test_a_satellite_clock_fault_is_on_that_satellites_ranges_only(tmp_path, base, kind, value, expect):
    sv = str(base[0][0][0].sv[0])
    epochs, _ = _run(tmp_path, kind, f"    kind: {kind}\n    satellite: {sv}\n    {value}\n")
    for e in range(24):
        obs, b_obs = epochs[e][0], base[0][e][0]
        d = obs.pseudorange_m - b_obs.pseudorange_m
        mine = obs.sv == sv
        np.testing.assert_allclose(d[mine], expect(float(e)) if e in IN else 0.0, atol=1e-6)
        np.testing.assert_allclose(d[~mine], 0.0, atol=1e-6)
        lam = C / obs.frequency_hz[mine]
        d_phase = (obs.carrier_phase_cyc - b_obs.carrier_phase_cyc)[mine] * lam
        np.testing.assert_allclose(d_phase, expect(float(e)) if e in IN else 0.0, atol=1e-6)
    # the fix follows the wrong range, or the solver's residual check throws the satellite out
    sol = epochs[IN[-1]][1]
    moved = np.linalg.norm(sol.pos_ecef_m - base[0][IN[-1]][1].pos_ecef_m)
    assert moved > 0.5 or sv in sol.excluded
    assert sv not in base[0][IN[-1]][1].excluded


def test_bad_ephemeris_moves_the_orbit_the_receiver_solves_with_not_the_ranges(tmp_path, base):
    sv = str(base[0][0][0].sv[0])
    epochs, _ = _run(tmp_path, "eph", f"    kind: bad_ephemeris\n    satellite: {sv}\n    error_m: 50.0\n")
    for e in IN:
        obs, b_obs = epochs[e][0], base[0][e][0]
        np.testing.assert_array_equal(obs.pseudorange_m, b_obs.pseudorange_m)
        mine = obs.sv == sv
        d = obs.sat_pos_ecef_m[mine] - b_obs.sat_pos_ecef_m[mine]
        radial = b_obs.sat_pos_ecef_m[mine] / np.linalg.norm(b_obs.sat_pos_ecef_m[mine], axis=1, keepdims=True)
        np.testing.assert_allclose(d, 50.0 * radial, atol=1e-6)
        assert np.all(obs.sat_pos_ecef_m[~mine] == b_obs.sat_pos_ecef_m[~mine])
    sol = epochs[IN[-1]][1]
    moved = np.linalg.norm(sol.pos_ecef_m - base[0][IN[-1]][1].pos_ecef_m)
    assert moved > 0.5 or sv in sol.excluded
