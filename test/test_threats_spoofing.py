"""Spoofing through the one receiver chain (core/threats/spoofing.py): capture with a power advantage above the
capture margin, the fix walking to the false path, none captured below it, meaconing, the scenario's errors.

Independent checks: the fix against the scenario's false path (fix.csv), the spoofed pseudoranges against ranges
computed here from the false position, the counterfeit's power from Friis and the antenna table."""
from __future__ import annotations

import csv
import math
import re

import numpy as np
import pytest

from gnss_sim_ros2.config_file import load_config
from gnss_sim_ros2.core.frames import ecef_to_enu, ecef_to_geodetic, enu_to_ecef, geodetic_to_ecef
from gnss_sim_ros2.core.simulation import run_simulation, setup_from_config
from gnss_sim_ros2.core.threats.scenario import ScenarioError, load_scenario
from gnss_sim_ros2.core.trajectory import Trajectory

C = 299792458.0
LAT, LON, H = 50.0758, 14.4179, 250.0
START, END, N = 10.0, 40.0, 50          # the spoofer's window [s after the run start]; runs of N epochs at 1 s
TRUE_ECEF = np.array(geodetic_to_ecef(LAT, LON, H))


def _llh(enu):
    x = enu_to_ecef(np.asarray(enu, dtype=float), LAT, LON, H)
    return [float(v) for v in ecef_to_geodetic(*x)]


#: the spoofer on a mast 80 m east, 15 m up; the false path leaves the true position at the capture northwards, 2 m/s
SPOOFER = _llh([80.0, 0.0, 15.0])
FALSE_PATH = [[START, *_llh([0.0, 0.0, 0.0])], [END, *_llh([0.0, 60.0, 0.0])]]


def _false_enu(t_s):
    return np.array([0.0, 60.0 * np.clip((t_s - START) / (END - START), 0.0, 1.0), 0.0])


def _spoofer_yaml(tmp_path, name, advantage_db, *, mode="simulate", systems="G", extra="", eirp_dbw=-40.0):
    false = "" if mode == "meacon" else f"    false_position: {FALSE_PATH}\n    false_position_type: llh\n"
    p = tmp_path / f"{name}.yaml"
    p.write_text(f"version: 1\nevents:\n  - type: spoofer\n    name: {name}\n    position: {SPOOFER}\n"
                 f"    position_type: llh\n    eirp_dbw: {eirp_dbw}\n    start_s: {START}\n    end_s: {END}\n{false}"
                 f"    systems: {systems}\n    power_advantage_db: {advantage_db}\n    mode: {mode}\n{extra}")
    return str(p)


def _run(tmp_path, name, scenario="", systems="G", extra=None, at=(LAT, LON, H), receiver=None):
    epochs = []

    def observer(t, ecef, obs, sol):
        epochs.append((obs, sol))

    cfg = load_config(overrides={"/**": {"systems": systems, **(extra or {})},
                                 "receiver": {"noise": False, "scenario": scenario, **(receiver or {})}})
    setup = setup_from_config(cfg, tmp_path / name, Trajectory.static(list(at), "geodetic"),
                              duration_s=float(N - 1), interval_s=1.0, observer=observer)
    res = run_simulation(setup)
    with open(res.fix_path, newline="") as f:
        rows = list(csv.DictReader(f))
    return epochs, rows


def _fix_enu(row):
    x = geodetic_to_ecef(float(row["lat_deg"]), float(row["lon_deg"]), float(row["h_m"]))
    return ecef_to_enu(np.array(x), LAT, LON, H)


def _range_offsets(obs, rx_ecef):
    """Per signal: pseudorange minus the geometric range from ``rx_ecef`` and the modelled terms (satellite clock,
    broadcast ionosphere, troposphere): one common value (the clock) when the ranges fit that position."""
    rho = np.linalg.norm(obs.sat_pos_ecef_m - rx_ecef, axis=1)
    return obs.pseudorange_m - rho + C * obs.sat_clock_s - obs.iono_model_m - obs.tropo_model_m


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("base"), "base")


def test_a_3_db_spoofer_takes_every_satellite_and_the_fix_follows_the_false_path(tmp_path, base):
    epochs, rows = _run(tmp_path, "spoof", _spoofer_yaml(tmp_path, "sp", 3.0))
    labels = [r["active_events"] for r in rows]
    assert labels[:int(START)] == [""] * int(START) and set(labels[int(START):int(END)]) == {"sp"}
    for e in range(int(START) + 1, int(END)):
        obs, _ = epochs[e]
        assert len(set(obs.sv.tolist())) >= 5
        false_ecef = enu_to_ecef(_false_enu(float(e)), LAT, LON, H)
        # every GPS signal fits the false position (one common clock term), not the true one
        assert np.ptp(_range_offsets(obs, false_ecef)) < 0.5
        if e >= START + 10:           # 20 m and more away: the ranges no longer fit the true position
            assert np.ptp(_range_offsets(obs, TRUE_ECEF)) > 5.0
        err = np.linalg.norm(_fix_enu(rows[e]) - _false_enu(float(e)))
        assert rows[e]["status"] == "fix" and err < 5.0, (e, err)
    # far from the true path by the end: the fix walked away
    assert np.linalg.norm(_fix_enu(rows[int(END) - 1])[:2]) > 50.0
    # after the spoofer stops, the authentic signals again: the fix back on the true position
    assert np.linalg.norm(_fix_enu(rows[-1])) < 1.0
    # the capture is flagged (loss of lock) on every signal at the spoofer's first epoch
    obs0, _ = epochs[int(START)]
    assert np.all(obs0.lli & 1)


def _cn0_by_signal(obs):
    return dict(zip(zip(obs.sv.tolist(), obs.code.tolist()), obs.cn0_dbhz.tolist()))


def _matched_kappa(chip_rate_hz, fe_hz=16.0e6):
    """int G^2 / (int G)^2 over the front end for BPSK(chip rate) (Betz 2001), computed here with numpy."""
    f = np.linspace(-fe_hz / 2, fe_hz / 2, 400_001)
    g = np.sinc(f / chip_rate_hz) ** 2
    return float(np.trapezoid(g * g, f) / np.trapezoid(g, f) ** 2)


def test_the_counterfeits_c_n0_is_the_authentic_plus_the_advantage_less_their_interference(tmp_path):
    # open sky (authentic = open-sky power), enough EIRP: each counterfeit 3 dB over its authentic signal, lowered by
    # the other counterfeits of its signal as matched-spectrum interference: C / (N0 + kappa_m sum C_other)
    mask = {"elevation_mask_deg": 0.0}       # every counterfeit the spoofer sends is tracked and seen here
    base_epochs, _ = _run(tmp_path, "base0", extra=mask)
    epochs, _ = _run(tmp_path, "spoof_cn0", _spoofer_yaml(tmp_path, "sp", 3.0), extra=mask)
    e = int(START) + 5
    auth, spoofed = _cn0_by_signal(base_epochs[e][0]), _cn0_by_signal(epochs[e][0])
    assert set(spoofed) == set(auth) and len(auth) >= 20
    n0_w = 1.380649e-23 * 290.0                      # k T, the link budget's reference (CODATA 2018)
    chip = {"1C": 1.023e6, "2L": 1.023e6, "2W": 10.23e6, "5Q": 10.23e6}   # IS-GPS-200 / -705: BPSK rates
    for (sv, code), c in spoofed.items():
        others = sum(10 ** ((a + 3.0) / 10) * n0_w for (o, oc), a in auth.items() if oc == code and o != sv)
        want = auth[(sv, code)] + 3.0 - 10 * math.log10(1 + _matched_kappa(chip[code]) * others / n0_w)
        assert c == pytest.approx(want, abs=0.3), (sv, code, c, want)


def test_a_spoofer_too_weak_for_its_advantage_falls_short(tmp_path):
    # -130 dBW total EIRP at 81 m cannot give ~10 signals 3 dB over the authentic (about -78 dBW needed): no capture
    scn = _spoofer_yaml(tmp_path, "weak", 3.0, eirp_dbw=-130.0)
    epochs, rows = _run(tmp_path, "weak", scn)
    for e in range(int(START) + 1, int(END)):
        assert np.ptp(_range_offsets(epochs[e][0], TRUE_ECEF)) < 0.5


def test_minus_3_db_captures_none_the_fix_stays_and_the_signals_are_degraded(tmp_path, base):
    epochs, rows = _run(tmp_path, "weak_adv", _spoofer_yaml(tmp_path, "sp", -3.0))
    b_epochs, b_rows = base
    for e in range(int(START) + 1, int(END)):
        obs, _ = epochs[e]
        assert np.ptp(_range_offsets(obs, TRUE_ECEF)) < 0.5
        assert np.linalg.norm(_fix_enu(rows[e])) < 1.0
        assert not np.any(obs.lli & 1)
    # interference of the counterfeits: every signal's C/N0 lower, none higher
    b_obs, s_obs = b_epochs[int(START) + 5][0], epochs[int(START) + 5][0]
    auth = dict(zip(zip(b_obs.sv.tolist(), b_obs.code.tolist()), b_obs.cn0_dbhz.tolist()))
    drop = np.array([auth[k] - c for k, c in zip(zip(s_obs.sv.tolist(), s_obs.code.tolist()), s_obs.cn0_dbhz)])
    assert np.all(drop >= 0) and drop.max() > 0.05


def test_a_spoofer_of_gps_leaves_galileo_authentic_and_the_residual_test_sees_it(tmp_path):
    epochs, rows = _run(tmp_path, "mixed", _spoofer_yaml(tmp_path, "sp", 3.0, systems="G"), systems="GE")
    obs, sol = epochs[int(END) - 2]
    gal = obs.sv.astype("<U1") == "E"
    false_ecef = enu_to_ecef(_false_enu(END - 2.0), LAT, LON, H)
    assert np.ptp(_range_offsets(obs, false_ecef)[~gal]) < 0.5
    assert np.ptp(_range_offsets(obs, TRUE_ECEF)[gal]) < 0.5
    # two consistent sets 58 m apart cannot both fit: the chi-square test fails or excludes satellites
    assert sol.chi2_ok is False or len(sol.excluded) > 0


def test_meacon_delays_every_range_by_the_same_amount_and_the_clock_takes_it(tmp_path, base):
    delay_s = 2.0e-6
    epochs, rows = _run(tmp_path, "meacon", _spoofer_yaml(tmp_path, "mc", 3.0, mode="meacon",
                                                         extra=f"    delay_s: {delay_s}\n"))
    spoofer = np.array(geodetic_to_ecef(*SPOOFER))
    d_m = float(np.linalg.norm(spoofer - TRUE_ECEF))
    b_epochs, _ = base
    for e in range(int(START) + 1, int(END)):
        obs, sol = epochs[e]
        b_obs, b_sol = b_epochs[e]
        shift = _range_offsets(obs, spoofer) - _range_offsets(b_obs, TRUE_ECEF)[
            [list(zip(b_obs.sv, b_obs.code)).index(k) for k in zip(obs.sv, obs.code)]]
        # every range: the re-broadcast delay and the meaconer -> antenna distance, the same for all
        assert np.allclose(shift, C * delay_s + d_m, atol=0.2), shift
        # the fix: at the meaconer's antenna, where the real signals were received
        assert np.linalg.norm(sol.pos_ecef_m - spoofer) < 1.0
        # ... and the receiver clock the solver estimates takes the delay and the distance
        assert sol.clock_bias_m["G"] - b_sol.clock_bias_m["G"] == pytest.approx(C * delay_s + d_m, abs=0.5)


def test_the_counterfeits_arrive_from_the_spoofer_for_every_satellite(tmp_path, monkeypatch):
    from gnss_sim_ros2.core.frames import az_el_from_ecef
    from gnss_sim_ros2.core.threats import runtime
    from gnss_sim_ros2.core.threats.runtime import ThreatRuntime

    made, truth, tracked = [], [], []
    # the simulation imports the runtime when a scenario asks for it (594b571): the class is caught where it lives
    monkeypatch.setattr(runtime, "ThreatRuntime",
                        lambda *a, **kw: made.append(ThreatRuntime(*a, **kw)) or made[-1])
    def observer(t, ecef, obs, sol):
        truth.append(made[0].spoofed(t))
        tracked.append(set(obs.sv.tolist()))

    cfg = load_config(overrides={"/**": {"systems": "G"},
                                 "receiver": {"noise": False, "scenario": _spoofer_yaml(tmp_path, "sp", 3.0)}})
    setup = setup_from_config(cfg, tmp_path / "truth", Trajectory.static([LAT, LON, H], "geodetic"),
                              duration_s=float(N - 1), interval_s=1.0, observer=observer)
    res = run_simulation(setup)
    az, el, _ = az_el_from_ecef(TRUE_ECEF, np.array(geodetic_to_ecef(*SPOOFER)))
    t_in = truth[int(START) + 3]
    assert truth[0] == {} and len(t_in) >= 5
    assert {round(v["az_deg"]) for v in t_in.values()} == {round(float(az))}
    assert {round(v["el_deg"]) for v in t_in.values()} == {round(float(el))}
    # the spoofer sends every satellite above the horizon; captured: those the receiver tracks (above its mask)
    assert all(v["spoofer"] == "sp" for v in t_in.values())
    captured = {sv for sv, v in t_in.items() if v["captured"]}
    assert captured == tracked[int(START) + 3] and len(captured) >= 5
    # fix.csv: the captured satellites per epoch (column spoofed), none outside the spoofer's window
    with open(res.fix_path, newline="") as f:
        rows = list(csv.DictReader(f))
    assert set(rows[int(START) + 3]["spoofed"].split()) == captured
    assert rows[0]["spoofed"] == "" and rows[-1]["spoofed"] == ""


@pytest.mark.parametrize(("field", "value", "key"), [
    ("mode", "replay", "mode"), ("systems", "GX", "systems"), ("power_advantage_db", "lots", "power_advantage_db"),
    ("delay_s", -1.0, "delay_s"), ("eirp_dbw", 500.0, "eirp_dbw"), ("false_time_offset_s", 2.0, "false_time_offset_s")])
def test_bad_spoofer_fields_name_file_line_and_key(tmp_path, field, value, key):
    p = tmp_path / "bad.yaml"
    eirp = value if field == "eirp_dbw" else -40.0       # a key given twice is an error of its own (yaml_file)
    p.write_text("version: 1\nevents:\n  - type: spoofer\n    position: [50.0, 14.0, 300.0]\n    position_type: llh\n"
                 f"    eirp_dbw: {eirp}\n    start_s: 0\n    end_s: 10\n    false_position: [50.001, 14.0, 300.0]\n"
                 "    false_position_type: llh\n" + (f"    {field}: {value}\n" if field != "eirp_dbw" else ""))
    with pytest.raises(ScenarioError) as exc:
        load_scenario(p)
    msg = str(exc.value)
    assert str(p) in msg and f"events[0].{key}" in msg and re.search(r"line (6|11)\b", msg), msg


def test_a_simulating_spoofer_without_a_false_position_is_refused(tmp_path):
    p = tmp_path / "nofalse.yaml"
    p.write_text("version: 1\nevents:\n  - type: spoofer\n    position: [50.0, 14.0, 300.0]\n    position_type: llh\n"
                 "    eirp_dbw: -40.0\n    start_s: 0\n    end_s: 10\n")
    with pytest.raises(ScenarioError, match=r"nofalse.yaml, line 3.*false_position"):
        load_scenario(p)


def test_the_capture_margin_is_the_receivers_parameter(tmp_path):
    from gnss_sim_ros2.parameters import validate_node

    with pytest.raises(ValueError, match="spoof_capture_margin_db"):
        validate_node("receiver", {"spoof_capture_margin_db": -1.0}, "test.yaml")
    # a receiver needing 4 dB: the 3 dB spoofer captures nothing (the parameter reaches the chain)
    epochs = []
    cfg = load_config(overrides={"/**": {"systems": "G"},
                                 "receiver": {"noise": False, "scenario": _spoofer_yaml(tmp_path, "sp", 3.0),
                                              "spoof_capture_margin_db": 4.0}})
    setup = setup_from_config(cfg, tmp_path / "m4", Trajectory.static([LAT, LON, H], "geodetic"),
                              duration_s=float(N - 1), interval_s=1.0,
                              observer=lambda t, ecef, obs, sol: epochs.append(obs))
    run_simulation(setup)
    for e in range(int(START) + 1, int(END)):
        assert np.ptp(_range_offsets(epochs[e], TRUE_ECEF)) < 0.5


def test_a_false_time_offset_moves_the_receivers_time_not_the_false_position(tmp_path, base):
    # the counterfeits of 5 ms later: the satellites where they are then (~20 m further along their orbits), the fix
    # still on the false path, the receiver's clock 5 ms ahead (less the spoofer -> antenna distance it also takes)
    offset_s = 0.005
    epochs, rows = _run(tmp_path, "late", _spoofer_yaml(tmp_path, "sp", 3.0,
                                                        extra=f"    false_time_offset_s: {offset_s}\n"))
    d_m = float(np.linalg.norm(np.array(geodetic_to_ecef(*SPOOFER)) - TRUE_ECEF))
    for e in range(int(START) + 1, int(END)):
        sol, b_sol = epochs[e][1], base[0][e][1]
        assert np.linalg.norm(_fix_enu(rows[e]) - _false_enu(float(e))) < 5.0
        assert sol.clock_bias_m["G"] - b_sol.clock_bias_m["G"] == pytest.approx(d_m - C * offset_s, abs=1.0)


def test_two_antennas_see_counterfeits_whose_differences_are_the_same_for_every_satellite(tmp_path, base):
    # a second antenna 2 m east (the heading's baseline): authentic range differences vary with each satellite's
    # direction; the counterfeits' differ only by the spoofer -> antenna distances, one value for all
    scn = _spoofer_yaml(tmp_path, "sp", 3.0)
    one, _ = _run(tmp_path, "ant1", scn)
    two, _ = _run(tmp_path, "ant2", scn, at=_llh([2.0, 0.0, 0.0]))
    for e, spoofed in ((5, False), (int(START) + 10, True)):
        a, b = one[e][0], two[e][0]
        pr_b = dict(zip(zip(b.sv.tolist(), b.code.tolist()), b.pseudorange_m.tolist()))
        diff = np.array([pr_b[k] - p for k, p in zip(zip(a.sv.tolist(), a.code.tolist()), a.pseudorange_m)
                         if k in pr_b])
        assert len(diff) >= 10
        assert (np.ptp(diff) < 0.01) if spoofed else (np.ptp(diff) > 0.5), (spoofed, np.ptp(diff))


def test_one_epoch_at_a_time_as_the_node_gives_the_same_spoofed_fixes(tmp_path):
    # the receiver node steps one epoch at a time with the states' expansion (no ephemeris at transmit time)
    scn = _spoofer_yaml(tmp_path, "sp", 3.0, extra="    false_time_offset_s: 0.001\n")
    texts = []
    for batch in (True, False):
        cfg = load_config(overrides={"/**": {"systems": "G"}, "receiver": {"noise": False, "scenario": scn}})
        setup = setup_from_config(cfg, tmp_path / f"b{batch}", Trajectory.static([LAT, LON, H], "geodetic"),
                                  duration_s=float(N - 1), interval_s=1.0)
        setup.batch_observables = batch
        setup.receiver_overrides = {"transmit_time": "expansion"}
        texts.append(run_simulation(setup).fix_path.read_text())
    assert texts[0] == texts[1]
    rows = list(csv.DictReader(texts[1].splitlines()))
    assert np.linalg.norm(_fix_enu(rows[int(END) - 1]) - _false_enu(END - 1.0)) < 5.0


def test_a_released_signal_is_acquired_again_through_the_acquisition_threshold(tmp_path):
    # the spoofer stops at END: the loops lose their counterfeits; the authentic signals are not handed over below
    # the acquisition threshold.  Default thresholds: none tracked at the release epoch, every one back at the next
    # with a new track (LLI bit 0) and the fix on the true position; a receiver that acquires only above 60 dB-Hz
    # (above every authentic signal here) gets none of them back
    scn = _spoofer_yaml(tmp_path, "sp", 3.0)
    epochs, rows = _run(tmp_path, "rel", scn)
    end = int(END)
    assert len(epochs[end - 1][0].sv) >= 10 and len(epochs[end][0].sv) == 0 and rows[end]["status"] == "no_fix"
    back = epochs[end + 1][0]
    assert len(back.sv) == len(epochs[end - 1][0].sv) and np.all(back.lli & 1)
    assert np.linalg.norm(_fix_enu(rows[end + 1])) < 1.0
    high, _ = _run(tmp_path, "rel60", scn, receiver={"cn0_acquire_dbhz": 60.0})
    assert len(high[end - 1][0].sv) >= 10            # warm start, then captured: tracked above the 25 dB-Hz loss level
    assert all(len(high[e][0].sv) == 0 for e in range(end, N))


def test_the_captured_satellites_are_tracked_ones(tmp_path):
    # fix.csv's spoofed column counts satellites whose counterfeit the receiver tracks: none below the elevation
    # mask, where the spoofer also sends (it knows no mask), so captured <= tracked at every epoch
    epochs, rows = _run(tmp_path, "mask", _spoofer_yaml(tmp_path, "sp", 3.0), extra={"elevation_mask_deg": 25.0})
    wide, _ = _run(tmp_path, "nomask", "", extra={"elevation_mask_deg": 0.0})
    for e in range(int(START), int(END)):
        captured = set(rows[e]["spoofed"].split())
        assert captured and captured <= set(epochs[e][0].sv.tolist()), e
        assert len(set(wide[e][0].sv.tolist())) > len(captured)      # the sky has more above the horizon


def test_a_captured_loop_stays_on_its_counterfeit_when_the_advantage_falls(tmp_path):
    # a spoofer with EIRP enough for 3 dB at 80 m, driven to 300 m away: its counterfeits fall ~10 dB short,
    # below the authentic signals but far above the tracking threshold; a fresh capture would not happen, the loops
    # already on the counterfeits stay there (the drag-off moved them off the authentic code phase)
    far = _llh([300.0, 0.0, 15.0])
    path = f"[[{START}, {', '.join(map(str, SPOOFER))}], [{START + 5}, {', '.join(map(str, SPOOFER))}], " \
           f"[{START + 10}, {', '.join(map(str, far))}]]"
    p = tmp_path / "moving.yaml"
    with open(_spoofer_yaml(tmp_path, "sp", 3.0, eirp_dbw=-55.0)) as f:
        p.write_text(f.read().replace(f"    position: {SPOOFER}\n", f"    path: {path}\n"))
    epochs, rows = _run(tmp_path, "moving", str(p))
    cn0_near = np.median(epochs[int(START) + 2][0].cn0_dbhz)
    for e in range(int(START) + 12, int(END)):
        assert np.median(epochs[e][0].cn0_dbhz) < cn0_near - 8.0         # the counterfeits 8+ dB weaker than at 80 m
        assert len(rows[e]["spoofed"].split()) == len(set(epochs[e][0].sv.tolist())), e
        assert np.linalg.norm(_fix_enu(rows[e]) - _false_enu(float(e))) < 5.0, e
