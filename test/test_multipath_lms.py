"""The land-mobile-satellite layer (core/multipath/lms.py, core/receiver/lms_channel.py): the chain's statistics
against its table, the Loo / echo draws, reproducible streams, off and an open field costing nothing."""
from __future__ import annotations

import numpy as np
import pytest

from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
from gnss_sim_ros2.core.multipath import lms
from gnss_sim_ros2.core.receiver.config import ReceiverConfig
from gnss_sim_ros2.core.receiver.engine import Receiver
from gnss_sim_ros2.core.receiver.lms_channel import LmsChannel, environment_class
from gnss_sim_ros2.core.time import GnssTime
from gnss_sim_ros2.core.vocabulary import VisibilityState

RX = np.array([-2418000.0, 5385000.0, 2405000.0])
T0 = GnssTime.from_iso("2019-04-28T05:00:00")


def test_every_class_is_a_chain_with_its_probabilities_as_stationary_distribution():
    for cls in lms.CLASSES.values():
        for b in range(len(lms.ELEVATION_BANDS_DEG)):
            w = np.array(cls.probability[b])
            p = lms.step_matrix(w, cls.length_m[b], 3.0)
            assert np.allclose(p.sum(axis=1), 1.0)
            assert np.allclose(w @ p, w, atol=1e-9), (cls.name, b)


def test_an_impossible_table_is_refused():
    with pytest.raises(ValueError, match="no 3-state chain"):
        lms.flows((0.98, 0.01, 0.01), (10.0, 100.0, 100.0))   # leaves LOS far more often than it enters it


@pytest.mark.parametrize("name,band", [("urban", 1), ("suburban", 0)])
def test_long_sequences_have_the_tables_probabilities_and_mean_lengths(name, band):
    """2000 chains x 2500 steps of 0.2 m: share of each state within 0.02 of W, mean length of the runs within 6 %
    of D (thousands of runs per state: a sampling error of 2-3 %)."""
    cls = lms.CLASSES[name]
    rng = np.random.default_rng(5)
    n, steps, step_m = 2000, 2500, 0.2
    bands = np.full(n, band)
    s = lms.initial_states(cls, bands, rng.random(n))
    seq = np.empty((steps, n), np.int64)
    for i in range(steps):
        s = lms.next_states(s, cls, bands, step_m, rng.random(n))
        seq[i] = s
    share = np.bincount(seq.ravel(), minlength=3) / seq.size
    assert share == pytest.approx(cls.probability[band], abs=0.02)
    # complete runs (both ends inside the sequence) of each state, in metres
    change = np.diff(seq, axis=0) != 0
    for state in range(3):
        lengths = []
        for c in range(n):
            idx = np.flatnonzero(change[:, c]) + 1
            runs = np.diff(idx)
            starts = seq[idx[:-1], c]
            lengths.append(runs[starts == state])
        lengths = np.concatenate(lengths) * step_m
        assert len(lengths) > 1000
        # a run observed at steps of 0.2 m is the sojourn rounded up to a step: about step / 2 longer
        assert np.mean(lengths) - step_m / 2 == pytest.approx(cls.length_m[band][state], rel=0.06), state


def test_loo_levels_and_echo_powers_and_delays_follow_the_state_parameters():
    """One epoch of 6000 satellites in the urban class (mid band): states drawn from W, the direct signal's level
    N(alpha, psi) dB, the echo's mean power 10^(MP/10) (Rayleigh: E|a|^2), phases uniform, delays exponential of mean
    tau; tolerances a few standard errors."""
    cls = lms.CLASSES["urban"]
    n = 6000
    svs = np.array([f"G{i}" for i in range(1, n + 1)])
    ch = LmsChannel("urban", seed=3)
    rows, level, amp, phase, delay = ch.epoch(RX, 1.0, svs, np.full(n, 45.0), np.ones(n, bool), 0.0)
    state = np.array([ch._state[s] for s in svs[rows]])
    assert np.bincount(state, minlength=3) / n == pytest.approx(cls.probability[1], abs=0.025)
    for s in range(3):
        p = cls.states[s]
        sel = state == s
        m = int(sel.sum())
        assert np.mean(level[sel]) == pytest.approx(p.alpha_db, abs=4 * p.psi_db / np.sqrt(m))
        assert np.std(level[sel]) == pytest.approx(p.psi_db, rel=0.15)
        power = 10 ** (p.mp_db / 10)
        assert np.mean(amp[sel] ** 2) == pytest.approx(power, rel=4 / np.sqrt(m))
        assert np.mean(delay[sel]) == pytest.approx(p.echo_delay_m, rel=4 / np.sqrt(m))
    assert abs(np.mean(np.cos(phase))) < 0.05 and abs(np.mean(np.sin(phase))) < 0.05


def test_the_same_seed_gives_the_same_channel_and_a_satellite_its_own_stream():
    svs = np.array(["G01", "G02", "C10"])
    el = np.array([20.0, 50.0, 70.0])

    def run(seed, svs=svs, el=el):
        ch = LmsChannel("urban", seed)
        return [ch.epoch(RX + [i * 10.0, 0, 0], 1.0, svs, el, np.ones(len(svs), bool), 0.0) for i in range(30)]

    a, b, c = run(7), run(7), run(8)
    for x, y in zip(a, b):
        for u, v in zip(x, y):
            assert np.array_equal(u, v)
    assert any(not np.array_equal(x[2], y[2]) for x, y in zip(a, c))
    # G02's channel does not depend on whether G01 and C10 are in view
    alone = run(7, svs[1:2], el[1:2])
    for x, y in zip(a, alone):
        assert x[1][1] == y[1][0] and x[4][1] == y[4][0]


def test_auto_picks_the_class_from_the_blocked_share():
    assert environment_class("auto", 0.0) is None
    assert environment_class("auto", 0.2).name == "suburban"
    assert environment_class("auto", 0.6).name == "urban"
    assert environment_class("off", 0.9) is None
    assert environment_class("open", 0.0).name == "open"
    with pytest.raises(ValueError, match="lms_environment"):
        LmsChannel("city", 1)


@pytest.fixture(scope="module")
def states(tmp_path_factory):
    prov, _ = open_ephemeris("synthetic", T0, 300.0, "GC", workdir=tmp_path_factory.mktemp("eph"))
    return prov.states(T0, systems="GC")


def _obs(states, vis=None, **kw):
    rx = Receiver(ReceiverConfig(profile="ublox_m8t", systems="GC", seed=4, **kw))
    return rx, rx.epoch(T0, RX, states, vis, None if vis is None else np.zeros(len(states)))


def test_off_and_an_open_field_with_auto_give_the_receiver_of_before_without_a_draw(states):
    _, ref = _obs(states)
    rx_off, off = _obs(states, lms_environment="off")
    rx_auto, auto = _obs(states, lms_environment="auto")
    assert rx_off.lms is None
    assert rx_auto.lms._rng == {}                        # open field: no stream made, nothing drawn
    for o in (off, auto):
        assert np.array_equal(o.sv, ref.sv) and np.array_equal(o.pseudorange_m, ref.pseudorange_m)
        assert np.array_equal(o.cn0_dbhz, ref.cn0_dbhz)


def test_in_a_canyon_only_the_satellites_in_sight_get_the_layer(states):
    """Half the satellites blocked (auto: urban): the blocked ones draw nothing and keep their observables."""
    n = len(states)
    vis = np.where(np.arange(n) % 2 == 0, int(VisibilityState.BLOCKED), int(VisibilityState.VISIBLE))
    _, ref = _obs(states, vis)
    rx, obs = _obs(states, vis, lms_environment="auto")
    in_sight = set(np.asarray(states.sv)[vis == int(VisibilityState.VISIBLE)])
    assert rx.lms._rng and set(rx.lms._rng) <= in_sight
    assert np.array_equal(obs.sv, ref.sv) or len(obs.sv) < len(ref.sv)
    common = np.isin(obs.sv, ref.sv)
    changed = obs.pseudorange_m[common] != ref.pseudorange_m[np.isin(ref.sv, obs.sv)]
    assert changed.any()
    assert set(obs.sv[common][changed]) <= in_sight


def test_foliage_the_scene_models_is_not_shadowed_twice(states):
    """Satellites seen through the scene's foliage (attenuated) count as in sight for the class (opaque blocking
    only) and draw nothing: the scene already shadows them (lms_channel.py)."""
    n = len(states)
    kind = np.arange(n) % 3
    vis = np.choose(kind, [int(VisibilityState.BLOCKED), int(VisibilityState.VISIBLE),
                           int(VisibilityState.ATTENUATED)])
    rx, _ = _obs(states, vis, lms_environment="auto")
    sv = np.asarray(states.sv)
    assert rx.lms._rng and set(rx.lms._rng) <= set(sv[kind == 1])
    # no wall, two thirds of the sky through foliage: an open field for the layer, nothing drawn
    rx, _ = _obs(states, np.where(kind == 1, int(VisibilityState.VISIBLE), int(VisibilityState.ATTENUATED)),
                 lms_environment="auto")
    assert rx.lms._rng == {}


def test_street_canyon_with_the_layer_batch_equals_epoch_by_epoch(tmp_path, tmp_path_factory):
    """The layer has memory (its chains): the offline blocks and a node's epoch-by-epoch chain draw alike (the
    two-wall canyon of test_simulation_batch, auto: its walls make it urban, blocks of 25)."""
    import dataclasses

    from multipath_scenes import canyon_scene
    from test_simulation_batch import _assert_same, _record

    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.core.scene.georeference import SphericalCoordinates
    from gnss_sim_ros2.core.scene.visibility import Scene
    from gnss_sim_ros2.core.simulation import setup_from_config
    from gnss_sim_ros2.core.trajectory import Trajectory

    eph = {"synthetic": open_ephemeris("synthetic", T0, 120.0, "GC", workdir=tmp_path_factory.mktemp("eph2"))}
    w = canyon_scene().world
    scene = Scene(dataclasses.replace(w, spherical_coordinates=SphericalCoordinates(22.2982, 114.1788, 0.0)))
    setup = setup_from_config(load_config(), tmp_path / "c", Trajectory.static(np.array([0.0, 0.0, 2.0]), "world"),
                              start=T0, duration_s=60.0, interval_s=1.0, scene=scene, ephemeris=eph,
                              switches={"ionosphere": "klobuchar"}, batch_epochs=25).with_params(
        systems="GC", source="synthetic", multipath="nlos", profile="ublox_m8t", lms_environment="auto")
    _, a = _record(dataclasses.replace(setup, out_dir=tmp_path / "epoch"), batch=False)
    _, b = _record(dataclasses.replace(setup, out_dir=tmp_path / "batch"), batch=True)
    _assert_same(a, b, 61)
    off_setup = dataclasses.replace(setup.with_params(lms_environment="off"), out_dir=tmp_path / "off")
    _, off = _record(off_setup, batch=True)
    assert any(not np.array_equal(x[0].pseudorange_m, y[0].pseudorange_m) for x, y in zip(a, off))   # it acted



def test_repeated_rows_go_through_the_dll_once_with_the_bits_of_every_row():
    """code_and_amplitude computes rows equal in every input and call label once: its result equals the DLL of
    every row (the private _code_and_amplitude, nothing merged) bit for bit, with repeated rows anywhere in the
    order and rows equal but for their call label (whose call may search a wider grid) kept apart."""
    from gnss_sim_ros2.core.receiver import lms_channel

    rng = np.random.default_rng(5)
    n = 60
    rows = np.column_stack([rng.normal(-3.0, 4.0, n), rng.rayleigh(0.2, n), rng.uniform(-np.pi, np.pi, n),
                            rng.exponential(25.0, n), rng.choice([293.05, 29.305, 146.53], n),
                            rng.integers(0, 5, n)])
    rows[0, 3] = 400.0                                        # call rows[0, 5]'s grid is wider than the others'
    relabelled = rows[:20].copy()
    relabelled[:, 5] = (relabelled[:, 5] + 1) % 5               # the same inputs in another call
    every = np.vstack([rows, rows[rng.integers(0, n, 90)], relabelled])[rng.permutation(n + 110)]
    assert len(np.unique(every, axis=0)) < len(every)           # repeated rows there are
    for lab in (every[:, 5].astype(int), None):
        want = lms_channel._code_and_amplitude(*every[:, :5].T, 0.1, 4e6, lab)
        got = lms_channel.code_and_amplitude(*every[:, :5].T, 0.1, 4e6, calls=lab)
        for w, g in zip(want, got):
            assert np.array_equal(w.view(np.int64), g.view(np.int64))
    empty = lms_channel.code_and_amplitude(*(np.empty(0) for _ in range(5)), 0.1, 4e6, calls=np.empty(0, int))
    assert empty[0].shape == (0,) and empty[1].shape == (0,)
