"""Observables of several receivers in one pass are each receiver's own, bit for bit (issue 31: the fleet receiver
node observes every robot's epoch in one core/receiver/batch_observe.observe_receivers, and a fleet's robot must
give what its own receiver node gives).  Separate chains with the same seeds are the reference; the robots stand
apart, see different satellites (some dropped, epochs without any), blocked and attenuated lines of sight of their
own, skip epochs (their clocks and tracking step over the gap), lag (an epoch late, in the pass of the others' next
epoch), and one robot configured otherwise goes alone."""
from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
from receiver_helpers import synthetic_sky

from gnss_sim_ros2.core.receiver import batch_observe
from gnss_sim_ros2.core.receiver.batch_observe import ReceiverEpoch, observe_receivers

ROBOTS = 5
EPOCHS = 60


def _obs_differ(a, b) -> str | None:
    """The first EpochObservations field whose bits differ, or None."""
    for name, x in a.__dict__.items():
        y = b.__dict__[name]
        if isinstance(x, np.ndarray):
            if x.dtype != y.dtype or x.shape != y.shape or x.tobytes() != y.tobytes():
                return name
        elif hasattr(x, "sec"):              # GnssTime
            if not (np.array_equal(x.sec, y.sec) and np.asarray(x.frac).tobytes() == np.asarray(y.frac).tobytes()):
                return name
        elif np.asarray(x).tobytes() != np.asarray(y).tobytes():
            return name
    return None


def _chains(rcv, out_dir, odd_one_out: bool):
    from gnss_sim_ros2.core.receiver.chain import ChainSettings, ReceiverChain

    chains = []
    for k in range(ROBOTS):
        p = {**rcv, "seed": rcv["seed"] + k, "output_dir": ""}
        if odd_one_out and k == ROBOTS - 1:
            p["elevation_mask_deg"] = rcv["elevation_mask_deg"] + 5.0     # another configuration: its own pass
        chains.append(ReceiverChain(ChainSettings.from_params(p), None))
    return chains


@pytest.fixture(scope="module")
def inputs():
    """The receiver's parameters and per epoch: (t, states, iono) at 10 Hz from the synthetic ephemeris."""
    rcv, start, provider = synthetic_sky(10.0, 60.0)
    return rcv, getattr(provider, "iono", None), [
        (start + i * 0.1, provider.states(start + i * 0.1, systems=rcv["systems"])) for i in range(EPOCHS)]


def _robot_epochs(inputs):
    """Per epoch, per robot: its ReceiverEpoch or None (skipped)."""
    from gnss_sim_ros2.core.frames import geodetic_to_ecef
    from gnss_sim_ros2.core.vocabulary import VisibilityState

    rcv, _, epochs = inputs
    rng = np.random.default_rng(7)
    out = []
    for i in range(len(epochs)):
        row = []
        for k in range(ROBOTS):
            if (k == 1 and i % 7 in (3, 4)) or (k == 4 and i == 0):
                row.append(None)                          # robot 1 skips epochs
                continue
            t, st = epochs[i - 1 if k == 4 else i]        # robot 4 an epoch late: another time in the same pass
            n = len(st)
            keep = np.ones(n, dtype=bool)
            if k >= 2:                                    # satellites differing per robot, changing over time
                keep[rng.choice(n, size=k, replace=False)] = False
            if k == 3 and 20 <= i < 24:
                keep[:] = False                           # no satellite at all
            s = st.select(np.flatnonzero(keep))
            vis = np.full(len(s), int(VisibilityState.VISIBLE), dtype=np.int64)
            att = np.zeros(len(s))
            if len(s):
                blocked = rng.random(len(s)) < 0.15
                attenuated = ~blocked & (rng.random(len(s)) < 0.2)
                vis[blocked] = int(VisibilityState.BLOCKED)
                vis[attenuated] = int(VisibilityState.ATTENUATED)
                att[attenuated] = rng.uniform(2.0, 25.0, attenuated.sum())
            ecef = np.array(geodetic_to_ecef(22.3 + 0.01 * k, 114.2 + 2e-6 * i * (k + 1), 10.0 + k), dtype=float)
            row.append(ReceiverEpoch(t, ecef, s, vis, att))
        out.append(row)
    return out


@pytest.mark.parametrize("odd_one_out", [False, True])
def test_receivers_observed_together_give_each_its_own_bits(inputs, tmp_path, monkeypatch, odd_one_out):
    rcv, iono, _ = inputs
    alone, together = _chains(rcv, tmp_path, odd_one_out), _chains(rcv, tmp_path, odd_one_out)
    for c in alone + together:
        c.set_iono_coefficients(iono)
    passes = []
    block = batch_observe.observe_block
    monkeypatch.setattr(batch_observe, "observe_block", lambda rxs, *a: passes.append(len(rxs)) or block(rxs, *a))
    tracked = compared = 0
    for row in _robot_epochs(inputs):
        idx = [k for k, e in enumerate(row) if e is not None]
        got = observe_receivers([together[k] for k in idx], [row[k] for k in idx])
        for k, obs in zip(idx, got):
            e = row[k]
            want = alone[k].observe(e.t, e.antenna_ecef_m, e.states, e.vis_state, e.attenuation_db)
            assert _obs_differ(want, obs) is None, (k, _obs_differ(want, obs))
            tracked += len(want.sv)
            compared += 1
    assert compared > ROBOTS * EPOCHS - 25 and tracked > 20 * compared       # signals tracked, not empty epochs
    shared = ROBOTS - 1 if odd_one_out else ROBOTS
    assert passes and max(passes) == shared and len(passes) == EPOCHS         # one pass per epoch, the odd robot alone


@pytest.fixture(scope="module")
def canyon_epochs():
    """Per epoch, per robot: its ReceiverEpoch with the demo courtyard's cast (reflections ``full``): robots at
    different places of the demo path, reflected paths of their own (the visibility node's inputs)."""
    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
    from gnss_sim_ros2.core.simulation import AntennaPath, setup_from_config
    from gnss_sim_ros2.core.time import GnssTime
    from gnss_sim_ros2.core.visibility import VisibilityOptions, load_scene
    from gnss_sim_ros2.core.vocabulary import VisibilityState

    cfg = load_config(overrides={"/**": {"rate_hz": 10.0}})
    with tempfile.TemporaryDirectory() as tmp:
        setup = setup_from_config(cfg, Path(tmp))
        opt = VisibilityOptions.from_params({**cfg.node("visibility"), "multipath": "full"})
        scene = load_scene(*setup.scene_files(), opt)
        path = AntennaPath(setup.trajectory, scene)
        rcv = cfg.node("receiver")
        start = GnssTime.from_iso(rcv["start_time"])
        provider, _ = open_ephemeris("synthetic", start, 60.0, rcv["systems"], workdir=tmp)
    out = []
    for i in range(20):
        t = start + 0.1 * i
        st = provider.states(t, systems=rcv["systems"])
        row = []
        for k in range(3):
            ecef, world = path.at(0.1 * i + 7.0 * k)
            state, att, v = opt.cast(scene, world, st.pos_ecef_m)
            above = v.el_deg >= 0.0
            vis = np.where(above, state, int(VisibilityState.BLOCKED)).astype(np.int64)
            row.append(ReceiverEpoch(t, np.asarray(ecef, dtype=float), st, vis, np.where(above, att, 0.0),
                                     getattr(v, "paths", None)))
        out.append(row)
    return rcv, out


def test_reflected_paths_share_the_pass_with_each_robots_bits(canyon_epochs, monkeypatch):
    from gnss_sim_ros2.core.receiver.chain import ChainSettings, ReceiverChain

    rcv, epochs = canyon_epochs
    assert sum(e.multipath is not None and e.multipath.valid.any() for row in epochs for e in row) > 20

    def chains():
        return [ReceiverChain(ChainSettings.from_params({**rcv, "seed": rcv["seed"] + k, "output_dir": ""}), None)
                for k in range(3)]

    alone, together = chains(), chains()
    passes = []
    block = batch_observe.observe_block
    monkeypatch.setattr(batch_observe, "observe_block", lambda rxs, *a: passes.append(len(rxs)) or block(rxs, *a))
    for row in epochs:
        for k, obs in enumerate(observe_receivers(together, row)):
            e = row[k]
            want = alone[k].observe(e.t, e.antenna_ecef_m, e.states, e.vis_state, e.attenuation_db,
                                    multipath=e.multipath)
            assert len(want.sv) and _obs_differ(want, obs) is None, (k, _obs_differ(want, obs))
    assert passes == [3] * len(epochs)


def test_fix_inputs_smoothed_together_are_each_receivers_own(canyon_epochs):
    """chain.receivers_fix_inputs (the fleet's robots' carrier smoothing in one pass) against each robot's own
    ReceiverChain.fix_inputs, epoch after epoch: robots with other smoothing windows and one without smoothing;
    every input bit-equal."""
    from gnss_sim_ros2.core.receiver.chain import ChainSettings, ReceiverChain, receivers_fix_inputs
    from gnss_sim_ros2.core.receiver.outputs import fix_inputs

    rcv, epochs = canyon_epochs

    def chains():
        return [ReceiverChain(ChainSettings.from_params({**rcv, "seed": rcv["seed"] + k, "output_dir": "",
                                                         "smoothing_s": s}), None)
                for k, s in enumerate((100.0, 0.35, 0.0, 100.0))]

    alone, together = chains(), chains()
    for row in epochs:
        row = row + row[:1]
        obs = observe_receivers(together, row)
        got = receivers_fix_inputs(together, obs)
        for k, (chain, o) in enumerate(zip(alone, obs)):
            want = chain.fix_inputs(o)
            assert set(want) == set(got[k])
            for name, v in want.items():
                if isinstance(v, np.ndarray):
                    assert v.dtype == got[k][name].dtype and v.tobytes() == got[k][name].tobytes(), (k, name)
                else:
                    assert v is None and got[k][name] is None, (k, name)
        for a, b in zip(alone, together):
            a.prior_ecef_m = b.prior_ecef_m = row[0].antenna_ecef_m + 5.0
    raw = fix_inputs(obs[0], together[0].settings.receiver.profile, together[0].prior_ecef_m)
    assert not np.array_equal(raw["pseudorange_m"], got[0]["pseudorange_m"])      # the code was smoothed


@pytest.mark.parametrize("aided", [None, 15.4])
def test_trackers_stepped_together_keep_each_ones_state_and_stream(aided, monkeypatch):
    """tracking.update_trackers (every robot's rows in one call) against each robot's own Tracker.update: robots
    with their own seeds, keys and C/N0 (steady epochs, fades below the thresholds, slips near 25 dB-Hz, keys
    that come and go, skipped and empty epochs); every output row and each tracker's stream state bit-equal."""
    from gnss_sim_ros2.core.receiver.tracking import Tracker, TrackingConfig, update_trackers
    from gnss_sim_ros2.core.time import GnssTime

    cfg = TrackingConfig(acquisition_cn0_dbhz=25.0, tracking_cn0_dbhz=23.0, aided_cn0_dbhz=aided,
                         acquisition_time_s=0.25, start="cold")
    alone = [Tracker(cfg, 100 + r) for r in range(6)]
    together = [Tracker(cfg, 100 + r) for r in range(6)]
    sats = np.array([f"G{p:02d}" for p in range(1, 11)])
    keys_sv, keys_code = np.repeat(sats, 2), np.tile(np.array(["1C", "2W"]), len(sats))
    rng = np.random.default_rng(3)
    base = rng.uniform(36.0, 50.0, (6, len(keys_sv)))
    updates = []                  # the trackers of ``together`` stepped through Tracker._update (update's body)
    original_update, original_step = Tracker.update, Tracker._update
    monkeypatch.setattr(Tracker, "_update", lambda self, *a, **kw: (
        any(self is x for x in together) and updates.append(self)) or original_step(self, *a, **kw))
    t0 = GnssTime.from_iso("2024-01-01T00:00:00")
    calls = slips = acquired = robot_epochs = 0
    for i in range(80):
        t = t0 + 0.1 * i
        rows = []
        for r in range(6):
            if r == 1 and i % 9 == 4:
                continue                                   # robot 1 skips epochs
            keep = np.ones(len(keys_sv), dtype=bool)
            if r >= 3 and i % 11 == r:
                keep[rng.choice(len(keys_sv), size=3, replace=False)] = False    # keys that come and go
            if r == 5 and 30 <= i < 33:
                keep[:] = False                            # no signal at all
            cn0 = base[r].copy()
            if i % 13 == r:
                cn0[rng.choice(len(cn0), size=4, replace=False)] = rng.uniform(20.0, 30.0, 4)   # fades, slips
            if r == 0:
                cn0[0] = 26.0 if i % 4 < 2 else 24.5      # about the acquisition threshold: the wait restarts
            if r == 2 and i >= 40:
                cn0[:3] = 25.5                             # weak, tracked: a slip probability every epoch
            vis = rng.random(len(cn0)) > (0.1 if i % 17 == r else 0.0)
            rows.append((r, t, keys_sv[keep], keys_code[keep], cn0[keep], vis[keep]))
        updates.clear()
        want = [original_update(alone[r], t, sv, code, cn0, visible=vis) for r, t, sv, code, cn0, vis in rows]
        seg = np.concatenate([[0], np.cumsum([len(x[2]) for x in rows])])
        got = update_trackers([together[x[0]] for x in rows], [x[1] for x in rows],
                              np.concatenate([x[2] for x in rows]), np.concatenate([x[3] for x in rows]),
                              np.concatenate([x[4] for x in rows]), np.concatenate([x[5] for x in rows]), seg)
        calls += len(updates)
        robot_epochs += len(rows)
        slips += sum(int(w.slipped.sum()) for w in want)
        acquired += sum(int(w.new_track.sum()) for w in want) if i else 0
        for k, w in enumerate(want):
            s = slice(seg[k], seg[k + 1])
            for name, a, b in zip(("tracked", "lli", "lock", "amb"), (w.tracked, w.lli, w.lock_time_s,
                                                                       w.ambiguity_cyc), got):
                assert a.dtype == b[s].dtype and a.tobytes() == b[s].tobytes(), (i, rows[k][0], name)
    for a, b in zip(alone, together):
        assert a.rng.bit_generator.state == b.rng.bit_generator.state
        assert a._lock_start[: a._n].tobytes() == b._lock_start[: b._n].tobytes()
    assert robot_epochs - calls > 100       # steady robot-epochs filled together, not through Tracker.update
    assert slips > 0 and acquired > 0


def test_trackers_with_only_slip_chances_step_together_unless_one_slips(monkeypatch):
    """A robot whose tracked signals are weak enough to slip (a slip probability every epoch) but whose keys and
    tracks do not change is filled with the steady robots, its slip uniforms drawn from its own stream as
    Tracker.update draws them: only the epochs where one of them slips go through Tracker._update, and every
    output row and stream state is what its own Tracker.update gives."""
    from gnss_sim_ros2.core.receiver.tracking import Tracker, TrackingConfig, update_trackers
    from gnss_sim_ros2.core.time import GnssTime

    cfg = TrackingConfig(acquisition_cn0_dbhz=25.0, tracking_cn0_dbhz=23.0)
    alone = [Tracker(cfg, 7 + r) for r in range(3)]
    together = [Tracker(cfg, 7 + r) for r in range(3)]
    sv, code = np.repeat(np.array(["G01", "G02", "G03", "G04"]), 2), np.tile(np.array(["1C", "2W"]), 4)
    cn0 = np.array([[45.0] * 8, [45.0, 24.0, 45.0, 45.0, 24.5, 45.0, 45.0, 45.0], [23.5] * 8])
    stepped = []
    original_step = Tracker._update
    monkeypatch.setattr(Tracker, "_update", lambda self, *a, **kw: (
        any(self is x for x in together) and stepped.append(self)) or original_step(self, *a, **kw))
    t0 = GnssTime.from_iso("2024-01-01T00:00:00")
    slipped_epochs = 0
    for i in range(300):
        t = t0 + 0.1 * i
        want = [alone[r].update(t, sv, code, cn0[r]) for r in range(3)]
        stepped.clear()
        got = update_trackers(together, [t] * 3, np.tile(sv, 3), np.tile(code, 3), cn0.reshape(-1),
                              np.ones(24, dtype=bool), np.arange(0, 25, 8))
        for r, w in enumerate(want):
            s = slice(8 * r, 8 * r + 8)
            for a, b in zip((w.tracked, w.lli, w.lock_time_s, w.ambiguity_cyc), got):
                assert a.dtype == b[s].dtype and a.tobytes() == b[s].tobytes(), (i, r)
        if i:
            slips = [bool(w.slipped.any()) for w in want]
            slipped_epochs += sum(slips)
            assert [any(x is tr for x in stepped) for tr in together] == slips, i
    for a, b in zip(alone, together):
        assert a.rng.bit_generator.state == b.rng.bit_generator.state
    assert slipped_epochs > 0 and all(alone[r].is_tracked("G01", "1C") for r in range(3))


def test_signal_rows_shared_by_receivers_configured_alike():
    """Receivers configured alike but for their seeds (a fleet's robots) share the signal rows of a set of
    satellites (engine._SHARED_ROWS), each with its own multipath slots; the shared rows are those a receiver
    computes alone; a receiver configured otherwise (code biases, profile) computes its own."""
    from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
    from gnss_sim_ros2.core.receiver import engine
    from gnss_sim_ros2.core.receiver.config import ReceiverConfig
    from gnss_sim_ros2.core.signal_plans import gps_day
    from gnss_sim_ros2.core.time import GnssTime

    t = GnssTime.from_iso("2025-06-01T10:00:00")
    with tempfile.TemporaryDirectory() as tmp:
        provider, _ = open_ephemeris("synthetic", t, 60.0, "GRECJ", workdir=tmp)
    st = provider.states(t, systems="GRECJ")
    args = (np.asarray(st.sv), np.asarray(st.glo_channel), gps_day(t.sec), np.asarray(st.health))
    # a receiver that has seen other satellites first: its multipath slots differ from a fresh one's
    first = np.asarray(st.sv)[::-1][:5]
    engine._SHARED_ROWS.clear()
    a = engine.Receiver(ReceiverConfig(seed=1))
    b = engine.Receiver(ReceiverConfig(seed=2))
    b._rows_of(first, np.zeros(5, dtype=np.int64), gps_day(t.sec), np.zeros(5, dtype=np.int64))
    rows_a, rows_b = a._rows_of(*args), b._rows_of(*args)
    assert rows_a is not rows_b and rows_a.lam is rows_b.lam             # shared, each its own object
    assert not np.array_equal(rows_a.mp_idx, rows_b.mp_idx)              # each receiver's own slots
    engine._SHARED_ROWS.clear()
    alone = engine.Receiver(ReceiverConfig(seed=2))
    alone._rows_of(first, np.zeros(5, dtype=np.int64), gps_day(t.sec), np.zeros(5, dtype=np.int64))
    rows_alone = alone._rows_of(*args)
    for name in ("lam", "gd_factor", "p_min", "el_min", "omega", "sv_j", "code_bias_m", "sisre_sigma", "mp_idx",
                 "sig_key", "dll_factor"):
        x, y = getattr(rows_b, name), getattr(rows_alone, name)
        assert x.dtype == y.dtype and x.tobytes() == y.tobytes(), name
    for x, y in zip(rows_b.signal_rows, rows_alone.signal_rows):
        assert x.tobytes() == y.tobytes()
    biased = engine.Receiver(ReceiverConfig(seed=2, code_bias_m={"G": {"1C": 1.5}}))
    rows_biased = biased._rows_of(*args)
    assert rows_biased.lam is not rows_b.lam and rows_biased.code_bias_m.max() == 1.5
    other = engine.Receiver(ReceiverConfig(seed=2, profile="ublox_m8t"))
    assert len(other._rows_of(*args).lam) != len(rows_b.lam)
