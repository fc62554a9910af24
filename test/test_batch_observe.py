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
    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
    from gnss_sim_ros2.core.time import GnssTime

    rcv = load_config(overrides={"/**": {"rate_hz": 10.0}}).node("receiver")
    start = GnssTime.from_iso(rcv["start_time"])
    with tempfile.TemporaryDirectory() as tmp:
        provider, _ = open_ephemeris("synthetic", start, 60.0, rcv["systems"], workdir=tmp)
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
