"""The receiver chain's fast paths give the results of the straightforward computations they replace.

- propagation.transmit_time_refined (one ephemeris evaluation + Taylor series) against an inertial-frame
  light-time solution of exact circular orbits (brentq, independent of the code under test) and against
  transmit_time_solution (re-evaluation at every iteration);
- the receiver's "recompute" light time against transmit_time_solution on the broadcast ephemeris;
- the vectorised multipath process against its definition (first-order Gauss-Markov per key);
- the tracker's cached key rows: losses of lock and duplicate keys as before;
- the solver's residual test does not exclude a satellite that has no redundancy (alone in its clock group);
- epoch_arrays against a plain loop over the signals (the RINEX layout of the header's observation types).
"""
from __future__ import annotations

import tempfile

import numpy as np
import pymap3d
import pytest
from scipy.optimize import brentq
from test_propagation import CircularOrbits, _rz  # the same independent reference orbits

from gnss_sim_ros2.core import propagation as prop
from gnss_sim_ros2.core.constants import OMEGA_BY_SYSTEM
from gnss_sim_ros2.core.receiver.config import ReceiverConfig
from gnss_sim_ros2.core.receiver.engine import Receiver
from gnss_sim_ros2.core.receiver.outputs import epoch_arrays, obs_types_for
from gnss_sim_ros2.core.receiver.tracking import LLI_LOSS_OF_LOCK, Tracker
from gnss_sim_ros2.core.solver import solve_pvt
from gnss_sim_ros2.core.time import GnssTime

C = 299792458.0
WE = 7.2921151467e-5
GM = 3.986005e14
RX = np.array([3149785.9652, 598260.8822, 5495348.4927])  # OPEC marker


ORB = CircularOrbits(np.full(4, 26560e3), [55, 55, 55, 64.8], [0, 40, 80, 20], [60, 80, 45, 70])


def _inertial_tau(j, t_rx):
    """c tau = |s_I(t_rx - tau) - r_I(t_rx)| in the inertial frame (static receiver)."""
    r_i = _rz(-WE * t_rx) @ RX

    def f(tau):
        return C * tau - np.linalg.norm(ORB.eci(np.full(4, t_rx - tau))[0][j] - r_i)

    return brentq(f, 0.05, 0.2, xtol=1e-18, rtol=1e-15, maxiter=200)


def test_refined_light_time_matches_inertial_solution_and_reevaluation():
    t_rx = 100.0
    calls = []

    def at(t_tx):
        calls.append(1)
        return ORB.ecef(t_tx)            # (pos, vel, acc)

    p_rx, _, _ = ORB.ecef(np.full(4, t_rx))
    guess = np.linalg.norm(p_rx - RX, axis=1) / C     # no Earth rotation, no motion: off by ~1e-7 s
    sol = prop.transmit_time_refined(RX, t_rx, at, guess)
    assert len(calls) == 1
    for j in range(4):
        tau_ref = _inertial_tau(j, t_rx)
        # tolerances as test_propagation: 1e-4 m on 2e7 m ranges, 1e-12 s
        assert sol.range_m[j] == pytest.approx(C * tau_ref, abs=1e-4)
        assert sol.tau_s[j] == pytest.approx(tau_ref, abs=1e-12)
        h = 0.05
        rr_ref = C * (_inertial_tau(j, t_rx + h) - _inertial_tau(j, t_rx - h)) / (2 * h)
        assert sol.range_rate_mps[j] == pytest.approx(rr_ref, abs=1e-5)
    full = prop.transmit_time_solution(RX, t_rx, lambda t: ORB.ecef(t)[:2], iterations=3, n_sats=4)
    # the same fixed point: 1e-6 m (the Taylor step over ~1e-7 s leaves ~1e-14 m)
    np.testing.assert_allclose(sol.range_m, full.range_m, atol=1e-6, rtol=0)
    np.testing.assert_allclose(sol.sat_pos_ecef_m, full.sat_pos_ecef_m, atol=1e-6, rtol=0)
    np.testing.assert_allclose(sol.sat_vel_ecef_mps, full.sat_vel_ecef_mps, atol=1e-9, rtol=0)
    np.testing.assert_allclose(sol.range_rate_mps, full.range_rate_mps, atol=1e-9, rtol=0)
    np.testing.assert_allclose(sol.t_tx, t_rx - sol.tau_s)


def test_refined_light_time_poor_guess_and_no_acceleration():
    t_rx = 100.0
    calls = []

    def at(t_tx):
        calls.append(1)
        return ORB.ecef(t_tx)[:2]        # (pos, vel): first-order series only

    full = prop.transmit_time_solution(RX, t_rx, lambda t: ORB.ecef(t)[:2], iterations=3, n_sats=4)
    # a guess 3 ms off (900 km): more than the Taylor series is trusted for -> evaluated again
    sol = prop.transmit_time_refined(RX, t_rx, at, full.tau_s + 3e-3)
    assert len(calls) == 2
    np.testing.assert_allclose(sol.range_m, full.range_m, atol=1e-6, rtol=0)
    # a GnssTime reception instant gives GnssTime transmit instants
    t0 = GnssTime.from_iso("2022-01-01T00:00:00")
    sol_t = prop.transmit_time_refined(RX, t0 + t_rx, lambda t: ORB.ecef(t - t0), full.tau_s)
    np.testing.assert_allclose(sol_t.range_m, full.range_m, atol=1e-6, rtol=0)
    np.testing.assert_allclose(sol_t.t_tx - t0, t_rx - full.tau_s, atol=1e-12)
    with pytest.raises(ValueError, match="max_evaluations"):
        prop.transmit_time_refined(RX, t_rx, at, full.tau_s, max_evaluations=0)


def test_receiver_recompute_matches_reevaluated_light_time():
    t0 = GnssTime.from_iso("2022-01-01T00:00:00")
    from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris

    with tempfile.TemporaryDirectory() as tmp:
        prov, _ = open_ephemeris("synthetic", t0, 120.0, "GRECJ", workdir=tmp)
    rcv = Receiver(ReceiverConfig(systems="GRECJ", noise=False, transmit_time="recompute"), prov, prov.iono)
    for i in range(3):
        t = t0 + 10.0 * i
        obs = rcv.epoch(t, RX, prov.states(t, systems="GRECJ"))
    assert len(obs.sv) > 30
    svs, first = np.unique(obs.sv, return_index=True)
    t_true = t - obs.clock_bias_s
    omega = np.array([OMEGA_BY_SYSTEM[s[0]] for s in svs])
    ref = prop.transmit_time_solution(RX, t_true, lambda tt: prov.states_at(list(svs), tt), iterations=3,
                                      omega_e_radps=omega, n_sats=len(svs))
    # 1e-6 m: the broadcast orbit's own round-off (Omega_k ~ 40 rad) is ~2e-7 m
    np.testing.assert_allclose(obs.true_range_m[first], ref.range_m, atol=1e-6, rtol=0)
    np.testing.assert_allclose(obs.sat_pos_ecef_m[first], ref.sat_pos_ecef_m, atol=1e-6, rtol=0)


def test_multipath_is_a_gauss_markov_process_per_key():
    cfg = ReceiverConfig()
    rcv = Receiver(cfg)
    ref_rng = np.random.default_rng(0)
    ref_rng.bit_generator.state = rcv.code_multipath.rng.bit_generator.state      # the same draws
    state = {}
    epochs = [(["G01", "G01", "E05"], ["1C", "2W", "1C"]), (["G01", "E05"], ["1C", "1C"]),
              (["E05", "G01", "R07", "G01"], ["1C", "1C", "1C", "2W"]), (["R07"], ["1C"])]
    for k, (sv, code) in enumerate(epochs):
        el = np.linspace(10.0, 80.0, len(sv))
        dt = 0.0 if k == 0 else 1.0
        got = rcv.code_multipath.values_m(np.array(sv), np.array(code), el, dt)
        # definition (engine module doc): x_k = phi x_{k-1} + sqrt(1 - phi^2) w_k, x_0 = w_0 per (sv, code),
        # phi = exp(-dt / tau), scaled by sigma(el) = mp_zenith + mp_low exp(-el / 15 deg)
        phi = np.exp(-dt / cfg.mp_tau_s) if dt > 0 else 0.0
        w = ref_rng.standard_normal(len(sv))
        sigma = cfg.mp_zenith_m + cfg.mp_low_m * np.exp(-el / 15.0)
        want = []
        for i, key in enumerate(zip(sv, code)):
            x = w[i] if key not in state else phi * state[key] + np.sqrt(1 - phi * phi) * w[i]
            state[key] = x
            want.append(sigma[i] * x)
        np.testing.assert_allclose(got, want, rtol=1e-15, atol=0)


def test_tracker_cached_rows_keep_loss_of_lock_and_duplicate_checks():
    trk = Tracker(rng=1)
    a = (np.array(["G01", "G02", "E05"]), np.array(["1C", "1C", "1C"]))
    b = (np.array(["G01", "E05"]), np.array(["1C", "1C"]))
    cn0 = 45.0
    o1 = trk.update(0.0, *a, cn0)
    o2 = trk.update(1.0, *a, cn0)
    assert o1.tracked.all() and o2.tracked.all() and not (o2.lli & LLI_LOSS_OF_LOCK).any()
    trk.update(2.0, *b, cn0)                # G02 absent: loses lock
    assert not trk.is_tracked("G02", "1C")
    o4 = trk.update(3.0, *a, cn0)           # back: a new track, loss-of-lock flag, new ambiguity
    assert o4.new_track.tolist() == [False, True, False]
    assert o4.lli[1] & LLI_LOSS_OF_LOCK
    assert o4.ambiguity_cyc[1] != o2.ambiguity_cyc[1]
    dup = (np.array(["G01", "G01"]), np.array(["1C", "1C"]))
    for t in (4.0, 5.0):                    # also when the same duplicated set comes again
        with pytest.raises(ValueError, match="duplicate"):
            trk.update(t, *dup, cn0)


def test_residual_test_does_not_exclude_a_satellite_without_redundancy():
    lat, lon, h = 59.9, 10.75, 60.0
    rx = np.array(pymap3d.geodetic2ecef(lat, lon, h))
    az = np.array([10.0, 75.0, 140.0, 200.0, 260.0, 320.0, 35.0, 110.0, 180.0, 250.0])
    el = np.array([75.0, 40.0, 25.0, 55.0, 15.0, 35.0, 20.0, 65.0, 30.0, 45.0])
    sv = ["G02", "G05", "G07", "G13", "G20", "G29", "G30", "G31", "G32", "I02"]   # NavIC alone in its clock
    e, n, u = (22e6 * np.cos(np.radians(el)) * np.sin(np.radians(az)),
               22e6 * np.cos(np.radians(el)) * np.cos(np.radians(az)), 22e6 * np.sin(np.radians(el)))
    sats = np.column_stack(pymap3d.enu2ecef(e, n, u, lat, lon, h))
    pr = np.linalg.norm(sats - rx, axis=1) + 1000.0
    pr[4] += 60.0     # G20: a 60 m blunder, far beyond the 0.3-1.2 m sigmas
    sol = solve_pvt(sv, sats, pr)
    assert sol.status == "fix", sol.reason
    # I02's residual is zero whatever its error (its own clock absorbs it): it cannot be tested, so the
    # one exclusion goes to the blunder
    assert sol.excluded == ["G20"]
    assert sol.used[9] and sol.n_used == 9
    np.testing.assert_allclose(sol.pos_ecef_m, rx, atol=1e-3)


def test_epoch_arrays_layout_matches_plain_loop():
    t0 = GnssTime.from_iso("2022-01-01T00:00:00")
    from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris

    with tempfile.TemporaryDirectory() as tmp:
        prov, _ = open_ephemeris("synthetic", t0, 60.0, "GRECJI", workdir=tmp)
    rcv = Receiver(ReceiverConfig(), prov, prov.iono)
    obs = rcv.epoch(t0, RX, prov.states(t0))
    obs_types = obs_types_for(rcv.cfg.profile, "GRECJI")
    obs_types["G"] = obs_types["G"][:-2]     # a header without S of the last GPS code: those stay blank
    ea = epoch_arrays(obs, obs_types)
    rows = {sv: i for i, sv in enumerate(ea.sv)}
    assert list(rows) == list(dict.fromkeys(obs.sv.tolist()))
    n_set = 0
    for j in range(len(obs.sv)):
        sv, code = str(obs.sv[j]), str(obs.code[j])
        i = rows[sv]
        for kind, v in (("C", obs.pseudorange_m[j]), ("L", obs.carrier_phase_cyc[j]), ("D", obs.doppler_hz[j]),
                        ("S", obs.cn0_dbhz[j])):
            if kind + code not in obs_types[sv[0]]:
                continue
            c = obs_types[sv[0]].index(kind + code)
            assert ea.codes[sv[0]][c] == kind + code
            assert ea.value[i, c] == v
            n_set += 1
            if kind in "CL":       # RINEX 3.04 5.7: SSI = min(max(int(cn0 / 6), 1), 9)
                assert ea.ssi[i, c] == min(max(int(obs.cn0_dbhz[j] / 6), 1), 9)
            if kind == "L":
                assert ea.lli[i, c] == int(obs.lli[j])
    assert np.count_nonzero(np.isfinite(ea.value)) == n_set


def test_rinex_lines_are_the_lines_of_the_epoch_arrays():
    """outputs.rinex_lines (the observables placed straight into the writer's flat layout, several epochs in one
    pass) gives each epoch the satellite lines its epoch_arrays get from the RINEX formatter; a satellite of a
    system without observation types is refused."""
    from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
    from gnss_sim_ros2.core.receiver.outputs import formatter_for, rinex_lines

    t0 = GnssTime.from_iso("2022-01-01T00:00:00")
    with tempfile.TemporaryDirectory() as tmp:
        prov, _ = open_ephemeris("synthetic", t0, 3600.0, "GRECJI", workdir=tmp)
    rcv = Receiver(ReceiverConfig(), prov, prov.iono)
    obs_list = [rcv.epoch(t0 + k, RX, prov.states(t0 + k)) for k in (0.0, 1.0, 1800.0)]   # other satellites later
    assert obs_list[0].sv.tolist() != obs_list[2].sv.tolist()
    obs_types = obs_types_for(rcv.cfg.profile, "GRECJI")
    obs_types["G"] = obs_types["G"][:-2]     # a header without S of the last GPS code: those stay blank
    got = rinex_lines(obs_list, obs_types)
    want = formatter_for(obs_types).format_arrays([epoch_arrays(o, obs_types) for o in obs_list])
    assert [(g.n_sv, g.lines) for g in got] == [(w.n_sv, w.lines) for w in want]
    assert all(g.lines for g in got)
    del obs_types["E"]
    with pytest.raises(ValueError, match="'E"):
        rinex_lines(obs_list[:1], obs_types)
