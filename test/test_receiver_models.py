"""Receiver models: tracking noise (Kaplan), C/N0 link budget, clock (Allan variance), tracking state."""
from __future__ import annotations

import numpy as np
import pytest

from gnss_sim_ros2.core import signals
from gnss_sim_ros2.core.receiver import clock as rclock
from gnss_sim_ros2.core.receiver import cn0 as rcn0
from gnss_sim_ros2.core.receiver import noise
from gnss_sim_ros2.core.receiver.tracking import LLI_HALF_CYCLE, LLI_LOSS_OF_LOCK, Tracker, TrackingConfig
from gnss_sim_ros2.core.time import GnssTime

# ------------------------------------------------------------------------------ noise
# physics-anchors.md (Kaplan, Understanding GPS, eq. 5.23: noncoherent EMLP DLL, B_n = 1 Hz,
# D = 0.5 chip, T = 20 ms, C/A chip 293 m; PLL B_n = 15 Hz, T = 1 ms at L1)
CODE_TABLE = {30: 4.8, 35: 2.6, 40: 1.5, 45: 0.82, 50: 0.46}
PLL_TABLE_MM = {30: 4.5, 40: 1.2, 50: 0.37}


def test_dll_code_noise_reproduces_kaplan_table():
    cn0 = np.array(list(CODE_TABLE))
    sig = noise.dll_sigma_m(cn0, signals.signal("G", "1C").chip_length_m, bn_hz=1.0, spacing_chips=0.5,
                            t_int_s=0.02)
    np.testing.assert_allclose(sig, list(CODE_TABLE.values()), rtol=0.05)
    np.testing.assert_allclose(noise.code_sigma_m("G", "1C", cn0), sig)
    # anchors: "D = 0.1 chip roughly halves these"
    ratio = noise.dll_sigma_m(45, 293.05, spacing_chips=0.1) / noise.dll_sigma_m(45, 293.05, spacing_chips=0.5)
    assert 0.4 < ratio < 0.6
    # a 10x faster code (P(Y), L5) is 10x more precise
    assert noise.code_sigma_m("G", "5Q", 45) == pytest.approx(noise.code_sigma_m("G", "1C", 45) / 10, rel=1e-9)


def test_pll_phase_noise_reproduces_kaplan_table():
    cn0 = np.array(list(PLL_TABLE_MM))
    sig_mm = 1e3 * noise.pll_sigma_m(cn0, signals.wavelength_m("G", "1C"), bn_hz=15.0, t_int_s=0.001)
    np.testing.assert_allclose(sig_mm, list(PLL_TABLE_MM.values()), rtol=0.05)
    np.testing.assert_allclose(1e3 * noise.phase_sigma_m("G", "1C", cn0), sig_mm)
    # GLONASS channels broadcast
    assert noise.phase_sigma_m("R", "1C", 40.0, glo_channel=np.arange(-7, 7)).shape == (14,)


def test_fll_and_doppler_noise():
    # Kaplan eq. 5.12: at strong signal sigma ~ 1/sqrt(C/N0): -10 dB -> x sqrt(10)
    s = noise.fll_sigma_hz(np.array([45.0, 55.0]))
    assert s[0] / s[1] == pytest.approx(np.sqrt(10), rel=0.01)
    # F = 2 near threshold multiplies by sqrt(2)
    assert noise.fll_sigma_hz(30, f_factor=2.0) / noise.fll_sigma_hz(30) == pytest.approx(np.sqrt(2))
    # Doppler from phase differences over 1 s: a fraction of a cycle per second at 40 dB-Hz
    d = noise.doppler_sigma_hz(40.0, method="pll")
    assert 0.001 < d < 0.05
    with pytest.raises(ValueError, match="interval_s"):
        noise.doppler_sigma_hz(40.0, method="pll", interval_s=0.01)
    with pytest.raises(ValueError, match="method"):
        noise.doppler_sigma_hz(40.0, method="xx")
    with pytest.raises(ValueError, match="spacing_chips"):
        noise.dll_sigma_chips(40.0, spacing_chips=1.5)


def test_mean_time_to_slip_orders_of_magnitude():
    # Kaplan's PLL rule of thumb: tracking threshold where 3 sigma = 45 deg (sigma = 15 deg).
    cn0 = np.linspace(20, 35, 1501)
    sig_deg = np.degrees(noise.pll_sigma_rad(cn0))
    cn0_thr = cn0[np.argmin(np.abs(sig_deg - 15.0))]
    t_thr = noise.mean_time_to_slip_s(cn0_thr)
    assert 1.0 < t_thr < 600.0, (cn0_thr, t_thr)
    assert noise.mean_time_to_slip_s(35.0) > 3.2e7  # more than a year well above threshold
    assert np.all(np.diff(noise.mean_time_to_slip_s(cn0)) > 0)


def test_slip_probability_equals_the_full_formula():
    """The rows skipped (probability 0 in double precision whatever I0 is) give exactly what the formula
    gives; the others are the formula itself (weak signals, long gaps, other loop bandwidths)."""
    cn0 = np.linspace(0.0, 60.0, 6001)
    evaluated = 0
    for dt in (0.05, 1.0, 30.0, 3600.0, 1e7):
        for bn, t_int in ((15.0, 0.001), (2.0, 0.02), (100.0, 0.001)):
            full = 1.0 - np.exp(-dt / noise.mean_time_to_slip_s(cn0, bn, t_int))
            got = noise.slip_probability(cn0, dt, bn, t_int)
            np.testing.assert_array_equal(got, full)
            evaluated += int(np.count_nonzero(full))
    assert evaluated > 1000      # the grid reaches the weak signals that can slip
    assert noise.slip_probability(np.array([45.0, 50.0]), 1.0).tolist() == [0.0, 0.0]


# ------------------------------------------------------------------------------- C/N0
def test_noise_density_kt0():
    assert rcn0.DEFAULT_BUDGET.noise_density_dbwhz == pytest.approx(-204.0, abs=0.05)  # kT0, T0 = 290 K


def test_gps_l1_cn0_open_sky():
    r_gps = 26560e3
    el = np.array([90.0, 10.0])
    rho = rcn0.slant_range_m(r_gps, el)
    # geometry: GPS zenith range 20,190 km, at 10 deg ~24,700 km (published)
    assert rho[0] == pytest.approx(20.19e6, rel=2e-3)
    c = rcn0.cn0_dbhz("G", "1C", rho, el)
    # the default budget (patch antenna): ICD -158.5 dBW + 3 dB published margin (Steigenberger et al. 2018)
    # + 0.4 x 1.9 dB path gain at zenith (shaped satellite beam), +4 dBic patch, N0 -204 dBW/Hz, 1.5 dB loss:
    # 51.8 dB-Hz at zenith; receivers report 48-52 (Kaplan's typical values, RTKLIB's simulator table 40-51);
    # 10 deg: -4 dBic, 43.3 dB-Hz (38-44 reported)
    assert 49.0 <= c[0] <= 52.5
    assert 38.0 <= c[1] <= 44.0
    # elevation dependence is monotonic
    els = np.linspace(5, 90, 50)
    cc = rcn0.cn0_dbhz("G", "1C", rcn0.slant_range_m(r_gps, els), els)
    assert np.all(np.diff(cc) > 0)


def test_cn0_edge_of_coverage_and_attenuation():
    # at the ICD's elevation, a 0 dBic antenna receives the ICD minimum plus the published margin, of the
    # tracked component (any orbit radius; test_link_budget)
    for sys_, code, r in (("G", "1C", 26560e3), ("E", "1C", 29600e3), ("C", "2I", 42164e3), ("I", "5A", 42164e3)):
        s = signals.signal(sys_, code)
        rho = rcn0.slant_range_m(r, s.min_power_el_deg)
        want = s.min_power_dbw + s.power_margin_db + s.component_db
        assert rcn0.received_power_dbw(sys_, code, rho, s.min_power_el_deg) == pytest.approx(want, abs=1e-6)
    # the orbit radius is recovered from range and elevation
    assert rcn0.sat_radius_from_range_m(rcn0.slant_range_m(29600e3, 33.0), 33.0) == pytest.approx(29600e3)
    base = rcn0.cn0_dbhz("G", "1C", 21e6, 60.0)
    assert rcn0.cn0_dbhz("G", "1C", 21e6, 60.0, attenuation_db=rcn0.FOLIAGE_MEDIAN_DB) == pytest.approx(base - 12.0)
    # arrays of systems / codes
    c = rcn0.cn0_dbhz(np.array(["G", "E"]), np.array(["1C", "5Q"]), np.array([21e6, 24e6]), np.array([60.0, 40.0]))
    assert c.shape == (2,)
    with pytest.raises(ValueError, match="code"):
        rcn0.cn0_dbhz("G", "7Q", 21e6, 60.0)
    with pytest.raises(ValueError, match="range_m"):
        rcn0.cn0_dbhz("G", "1C", -1.0, 60.0)


# ------------------------------------------------------------------------------ clock
def _overlapping_adev(x, dt, m):
    """Overlapping Allan deviation from phase samples x (IEEE 1139 / NIST SP 1065 eq. 11)."""
    d = x[2 * m:] - 2 * x[m:-m] + x[: -2 * m]
    return np.sqrt(np.mean(d * d) / (2.0 * (m * dt) ** 2))


def test_clock_allan_deviation_matches_h_coefficients():
    h0, hm2 = 2e-19, 2e-20  # TCXO, Brown & Hwang
    clk = rclock.ReceiverClock(rclock.ClockConfig(h0=h0, h_m2=hm2, steering="none"), rng=12345)
    bias, _, _ = clk.simulate(400_000, 1.0)
    for tau in (1, 10, 100):
        expected = np.sqrt(h0 / (2 * tau) + 2 * np.pi**2 / 3 * hm2 * tau)  # NIST SP 1065 table 2
        got = _overlapping_adev(bias, 1.0, tau)
        print(f"tau {tau:4d} s: ADEV {got:.3e} expected {expected:.3e}")
        # statistical tolerance: > 1000 degrees of freedom at tau = 100 s -> ~3 % one sigma
        assert got == pytest.approx(expected, rel=0.10)


def test_clock_millisecond_jumps_deterministic():
    cfg = rclock.ClockConfig(initial_bias_s=2.3e-4, initial_drift_sps=4.7e-7, noise=False)
    clk = rclock.ReceiverClock(cfg)
    bias, drift, jumped = clk.simulate(10_000, 1.0)
    idx = np.nonzero(jumped)[0]
    assert len(idx) == 4
    np.testing.assert_array_equal(jumped[idx], -1e-3)
    assert np.all(np.abs(bias) <= 1e-3 + 1e-12)
    # without the jumps the bias is the straight line b0 + d t (constant drift)
    raw = bias - np.cumsum(jumped)
    t = np.arange(1, 10_001) * 1.0
    np.testing.assert_allclose(raw, 2.3e-4 + 4.7e-7 * t, atol=1e-15)
    np.testing.assert_array_equal(drift, 4.7e-7)
    # the first jump happens when 2.3e-4 + 4.7e-7 t exceeds 1 ms: t > 1638.3 s -> index 1638 (t = 1639 s)
    assert idx[0] == 1638
    assert set(np.diff(idx)) <= {2127, 2128}  # then every 1 ms / 4.7e-7 = 2127.7 s
    # the epoch-by-epoch interface does the same
    clk2 = rclock.ReceiverClock(cfg)
    steps = np.array([clk2.step(1.0) for _ in range(10_000)])
    np.testing.assert_allclose(steps[:, 0], bias, atol=1e-15)
    np.testing.assert_array_equal(np.nonzero(steps[:, 2])[0], idx)


def test_clock_jumps_with_noise_and_negative_drift():
    cfg = rclock.ClockConfig(initial_drift_sps=-8e-7)
    bias, _, jumped = rclock.ReceiverClock(cfg, rng=7).simulate(20_000, 1.0)
    assert np.all(jumped[jumped != 0] == 1e-3)
    assert np.count_nonzero(jumped) >= 15
    assert np.all(np.abs(bias) < 1e-3 + 1e-6)


def test_clock_continuous_steering_and_validation():
    b, d, j = rclock.ReceiverClock(rclock.ClockConfig(steering="continuous", initial_bias_s=1e-4),
                                   rng=1).simulate(3600, 1.0)
    assert not np.any(j)
    assert np.all(np.abs(b[600:]) < 1e-7)   # free running would have drifted 1.8 ms
    with pytest.raises(ValueError, match="steering"):
        rclock.ClockConfig(steering="magic")
    with pytest.raises(ValueError, match="dt_s"):
        rclock.ReceiverClock().step(0.0)


# ---------------------------------------------------------------------------- tracking
def test_track_appears_blocked_returns():
    # a receiver switched on at the first epoch (start cold): its tracks are acquired then, flagged
    tr = Tracker(TrackingConfig(random_slips=False, half_cycle_time_s=6.0, start="cold"), rng=3)
    t0 = GnssTime.from_iso("2022-01-01T00:00:00")
    outs = []
    for i in range(30):
        visible = not (10 <= i < 15)
        outs.append(tr.update(t0 + float(i), ["G05", "E11"], ["1C", "1C"], [45.0, 45.0], visible=visible))
    o0, o1, o6, o10, o15 = outs[0], outs[1], outs[6], outs[10], outs[15]
    # epoch 0: new track; GPS L1 C/A (data channel) flags loss of lock + half cycle, Galileo E1C (pilot) only LLI 1
    assert o0.tracked.all() and o0.new_track.all()
    assert o0.lli[0] == LLI_LOSS_OF_LOCK | LLI_HALF_CYCLE and o0.lli[1] == LLI_LOSS_OF_LOCK
    assert o1.lli[0] == LLI_HALF_CYCLE and o1.lli[1] == 0
    assert o6.lli[0] == 0 and o6.lock_time_s[0] == pytest.approx(6.0)
    assert not o10.tracked.any() and np.all(o10.lli == 0) and np.all(o10.lock_time_s == 0)
    assert o15.new_track.all() and o15.lli[0] == 3 and o15.lli[1] == 1 and o15.lock_time_s[0] == 0.0
    # a new continuous track draws new ambiguities; within a track they stay constant
    assert np.all(o15.ambiguity_cyc != o0.ambiguity_cyc)
    assert np.all(outs[9].ambiguity_cyc == o0.ambiguity_cyc)
    assert np.all(outs[29].ambiguity_cyc == o15.ambiguity_cyc)
    assert outs[29].lock_time_s[0] == pytest.approx(14.0)


def test_hysteresis_absence_and_forced_slip():
    tr = Tracker(TrackingConfig(random_slips=False, start="cold"), rng=4)   # acquired, not found locked
    seq = [30.0, 34.0, 30.0, 29.0, 27.0, 30.0, 32.9, 33.0]
    tracked = [bool(tr.update(float(i), ["C20"], ["2I"], [c]).tracked[0]) for i, c in enumerate(seq)]
    #          below acq, acquire, hold (>=28), hold, lost (<28), not re-acquired (<33), no, re-acquired
    assert tracked == [False, True, True, True, False, False, False, True]
    # a key absent from an epoch loses lock
    tr.update(8.0, ["C20", "G01"], ["2I", "1C"], [40.0, 40.0])
    out = tr.update(9.0, ["G01"], ["1C"], [40.0])
    assert not tr.is_tracked("C20", "2I") and out.tracked[0]
    out = tr.update(10.0, ["C20", "G01"], ["2I", "1C"], [40.0, 40.0])
    assert out.new_track[0] and not out.new_track[1]
    # forced slip: LLI bit 0, ambiguity +-1, lock time restarts
    before = out.ambiguity_cyc[1]
    out = tr.update(11.0, ["C20", "G01"], ["2I", "1C"], [40.0, 40.0], force_slip=[False, True])
    assert out.slipped[1] and out.lli[1] & LLI_LOSS_OF_LOCK and out.lock_time_s[1] == 0.0
    assert abs(int(out.ambiguity_cyc[1]) - int(before)) == 1
    with pytest.raises(ValueError, match="not after"):
        tr.update(11.0, ["G01"], ["1C"], [40.0])
    with pytest.raises(ValueError, match="duplicate"):
        tr.update(12.0, ["G01", "G01"], ["1C", "1C"], [40.0, 40.0])
    with pytest.raises(ValueError, match="tracking_cn0_dbhz"):
        TrackingConfig(acquisition_cn0_dbhz=30.0, tracking_cn0_dbhz=35.0)


def test_acquisition_time_and_random_slips_rare_at_strong_signal():
    tr = Tracker(TrackingConfig(acquisition_time_s=2.0, start="cold"), rng=5)
    tracked = [bool(tr.update(float(i), ["G07"], ["1C"], [45.0]).tracked[0]) for i in range(5)]
    assert tracked == [False, False, True, True, True]
    # at 45 dB-Hz the mean time to slip is astronomically long: no slip in an hour of 1 s epochs
    slips = sum(int(tr.update(float(i), ["G07"], ["1C"], [45.0]).slipped[0]) for i in range(5, 3605))
    assert slips == 0


def test_half_cycle_flag_lasts_until_the_frame_sync_word():
    """LLI bit 1 from acquisition to the end of the first frame sync word of the navigation data: uniform over
    the frame period plus the word (GPS LNAV 6 s + 0.6 s, GLONASS 2 s + 0.3 s, BeiDou GEO D2 0.6 s + 0.06 s);
    never on a pilot (Galileo E1C)."""
    from gnss_sim_ros2.core.receiver.tracking import half_cycle_sync

    assert half_cycle_sync("G05", "1C") == (6.0, 0.6) and half_cycle_sync("R07", "1C") == (2.0, 0.3)
    assert half_cycle_sync("C03", "2I") == (0.6, 0.06) and half_cycle_sync("C23", "2I") == (6.0, 0.6)
    tr = Tracker(TrackingConfig(random_slips=False, start="cold"), rng=11)   # every track acquired
    svs, codes = ["G05", "R07", "C03", "E11"], ["1C", "1C", "2I", "1C"]
    ends = {sv: [] for sv in svs}
    dt = 0.1
    for cycle in range(200):                  # 200 tracks of 8 s each, 1 s blocked between them
        t0 = cycle * 9.0
        flagged = np.zeros(4)
        for i in range(80):
            o = tr.update(t0 + i * dt, svs, codes, [45.0] * 4)
            flagged += (o.lli & LLI_HALF_CYCLE) > 0
        tr.update(t0 + 8.5, svs, codes, [45.0] * 4, visible=False)
        for j, sv in enumerate(svs):
            ends[sv].append(flagged[j] * dt)
    g, r, c = (np.array(ends[s]) for s in ("G05", "R07", "C03"))
    assert g.min() >= 0.6 - 1e-9 and g.max() <= 6.6 + dt and abs(g.mean() - 3.6) < 0.3
    assert r.min() >= 0.3 - 1e-9 and r.max() <= 2.3 + dt and abs(r.mean() - 1.3) < 0.15
    assert c.max() <= 0.66 + dt
    assert max(ends["E11"]) == 0.0
def test_update_many_equals_update_epoch_by_epoch():
    """A block of epochs through Tracker.update_many gives what update gives epoch by epoch, with the
    same random draws afterwards: keys coming and going, weak signals that slip, blocked epochs, an epoch
    without keys, strong steady runs (the block's fast path)."""
    rng = np.random.default_rng(3)
    keys = [("G01", "1C"), ("G01", "2W"), ("G07", "1C"), ("E11", "1C"), ("E11", "5Q"), ("G30", "1C")]
    epochs = []
    for b in range(400):
        present = [k for i, k in enumerate(keys) if not (i == 5 and 100 < b < 180) and not (150 <= b < 152)]
        if b == 300:
            present = []
        cn0 = np.where(rng.random(len(present)) < 0.05, 27.0, 45.0) if b < 250 else np.full(len(present), 45.0)
        cn0[[i for i, k in enumerate(present) if k[0] == "G07"]] = 26.5 if 200 < b < 230 else 45.0
        vis = np.ones(len(present), bool)
        if 50 < b < 55:
            vis[:1] = False
        if b != 300:    # a key below the mask (not visible), then between the two thresholds (never acquired)
            present = present + [("C20", "2I")]
            cn0 = np.append(cn0, 30.0 if b < 330 else 40.0)
            vis = np.append(vis, b >= 200)
        epochs.append((GnssTime(1_300_000_000 + b), present, cn0, vis))
    one = Tracker(TrackingConfig(), rng=7)
    many = Tracker(TrackingConfig(), rng=7)
    calls = []
    many_update = many.update
    many.update = lambda *a, **kw: calls.append(1) or many_update(*a, **kw)
    want = []
    for t, present, cn0, vis in epochs:
        out = one.update(t, [k[0] for k in present], [k[1] for k in present], cn0, visible=vis)
        want.append((out.tracked, out.lli, out.lock_time_s, out.ambiguity_cyc))
    got = []
    for b0 in range(0, len(epochs), 70):
        blk = epochs[b0:b0 + 70]
        seg = np.concatenate([[0], np.cumsum([len(e[1]) for e in blk])])
        flat = [k for e in blk for k in e[1]]
        res = many.update_many([e[0] for e in blk], [k[0] for k in flat], [k[1] for k in flat],
                               np.concatenate([e[2] for e in blk]), np.concatenate([e[3] for e in blk]), seg)
        got += [tuple(a[seg[i]:seg[i + 1]] for a in res) for i in range(len(blk))]
    slips = 0
    for (wt, wl, wk, wa), (gt, gl, gk, ga) in zip(want, got):
        np.testing.assert_array_equal(gt, wt)
        np.testing.assert_array_equal(gl, wl)
        np.testing.assert_array_equal(gk, wk)
        np.testing.assert_array_equal(ga, wa)
        slips += int(np.sum((wl & LLI_LOSS_OF_LOCK) > 0))
    assert slips > 10 and one.rng.random() == many.rng.random()
    assert len(calls) < len(epochs) / 2     # the steady runs were filled together
