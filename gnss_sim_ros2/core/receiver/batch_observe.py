"""The observables of one epoch of several receivers in one numpy pass (the fleet receiver node's robots).

core/receiver/engine.Receiver.epochs computes a block of K epochs of one receiver: the stages without memory
(geometry, satellite clocks, atmosphere, world errors, C/N0, the observation equations) over all the block's
rows at once, the stages with memory (receiver clock, tracking, noise draws) epoch by epoch.  Here the block's
"epochs" are receivers: robot r's satellites and signals are the block's segment r, the stages without memory
run once over robots x satellites x signals, and each robot's own state acts on its own slice only: its clock
(stepped from its own last epoch), its signal rows (its code multipath's slots), its tracking loops, its noise
streams (rng_noise and the code multipath's, drawn in the order and counts of its epoch alone).  So every robot's
EpochObservations are the bits its ReceiverChain.observe gives alone (test/test_batch_observe.py), as
core/receiver/batch_fix.py does for the fixes.  Where a stage with memory has arithmetic, it runs once over
every robot's rows too, each robot's state gathered from and written back to its own object: the tracking step
(tracking.update_trackers: thresholds, slip probabilities, the steady robots' outputs), the code multipath
states (code_multipath.advance_states), the true reception times; only the draws from each robot's streams and
its clock's step stay a call per robot.  The geodetic position stays per robot too: ecef_to_geodetic of one
point is computed in Python's math (libm), of an array in numpy, whose bits differ.

What cannot share a pass goes through the receiver's own path (ReceiverChain.observe, one robot at a time): a
receiver alone in its group (configurations differ beyond the seed: profile, systems, models...; another
ionosphere model or coefficients; another ephemeris provider), a scenario's threats, the land-mobile-satellite
layer (lms_environment).  Reflected paths (multipath from the visibility cast) share the pass: the composite
signal's errors are computed per receiver's rows as Receiver.epochs does per epoch (``calls``).
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..ephemeris.states import ROW_FIELDS, SatelliteStates
from ..frames import az_el_at
from ..memo import BoundedCache
from ..time import GnssTime
from .code_multipath import advance_states
from .engine import Receiver, _Block
from .observations import EpochObservations
from .tracking import update_trackers

#: whether two ReceiverConfig objects are equal but for the seed, by their identities (held, so never reused)
_SAME_CONFIG = BoundedCache(4096)


@dataclass
class ReceiverEpoch:
    """One receiver's inputs of an epoch, as ReceiverChain.observe takes them (the antenna velocity: the
    backward difference of its positions)."""

    t: GnssTime
    antenna_ecef_m: np.ndarray
    states: SatelliteStates
    vis_state: np.ndarray | None = None
    attenuation_db: np.ndarray | None = None
    multipath: object = None          # multipath.reflections.ScenePaths of the states' rows, or None


def observe_receivers(chains, epochs: list[ReceiverEpoch]) -> list[EpochObservations]:
    """``chains[k].observe(...)`` of ``epochs[k]`` for every k (one epoch per chain, each chain at most once):
    the receivers that can share a pass (module doc) in one numpy pass per group, the others alone; the same
    bits either way."""
    prepared = [chain.observe_inputs(e.t, e.antenna_ecef_m, e.states) for chain, e in zip(chains, epochs)]
    out: list = [None] * len(chains)
    groups: list = []                   # [(representative Receiver, [indices])]
    for i, (chain, e) in enumerate(zip(chains, epochs)):
        rx = chain.rx
        if not _shareable(chain, e):
            groups.append((None, [i]))
            continue
        for rep, idx in groups:
            if rep is not None and _same_pass(rep, rx):
                idx.append(i)
                break
        else:
            groups.append((rx, [i]))
    for _, idx in groups:
        if len(idx) == 1:
            i = idx[0]
            out[i] = _alone(chains[i], epochs[i], *prepared[i])
            continue
        got = observe_block([chains[i].rx for i in idx], [epochs[i] for i in idx], [prepared[i] for i in idx])
        for i, obs in zip(idx, got):
            out[i] = obs
    return out


def _alone(chain, e: ReceiverEpoch, ecef, vel) -> EpochObservations:
    """ReceiverChain.observe after its observe_inputs (made already)."""
    obs = chain.rx.epoch(e.t, ecef, e.states, e.vis_state, e.attenuation_db, antenna_vel_ecef_mps=vel,
                         multipath=e.multipath)
    return obs if chain.threats is None else chain.threats.observations(obs)


def _shareable(chain, e: ReceiverEpoch) -> bool:
    """Whether this receiver's epoch may go into a shared pass: no threats, no LMS layer (their state is the
    receiver's, stepped inside the stages)."""
    rx = chain.rx
    return chain.threats is None and rx.threats is None and rx.lms is None


def _same_pass(a: Receiver, b: Receiver) -> bool:
    """Receivers whose stages without memory give the same bits: configurations equal but for the seed, the same
    ephemeris provider, the same true ionosphere (model and coefficients)."""
    if a.provider is not b.provider or a.iono_truth != b.iono_truth:
        return False
    if not (_same_bits(a.iono_alpha, b.iono_alpha) and _same_bits(a.iono_beta, b.iono_beta)):
        return False
    if (a._nequick is None) != (b._nequick is None) or (
            a._nequick is not None and a._nequick.coefficients != b._nequick.coefficients):
        return False
    if a.cfg is b.cfg:
        return True
    key = (id(a.cfg), id(b.cfg))
    hit = _SAME_CONFIG.get(key)
    if hit is None or hit[0] is not a.cfg or hit[1] is not b.cfg:     # the configurations compared once
        hit = _SAME_CONFIG.put(key, (a.cfg, b.cfg, all(f.name == "seed" or getattr(a.cfg, f.name) ==
                                                       getattr(b.cfg, f.name) for f in fields(a.cfg))))
    return hit[2]


def _same_bits(x, y) -> bool:
    """Arrays of the same shape, type and bytes (stricter than equal values: -0.0 is not 0.0; what gives the same
    bits is all a shared pass needs)."""
    if x is y:
        return True
    x, y = np.asarray(x), np.asarray(y)
    return x.shape == y.shape and x.dtype == y.dtype and x.tobytes() == y.tobytes()


def observe_block(rxs: list[Receiver], epochs: list[ReceiverEpoch], prepared) -> list[EpochObservations]:
    """The observables of receivers ``rxs`` (two or more, _same_pass of each other, each _shareable), one epoch
    each: Receiver.epochs' stages over a block whose segment r is receiver r's epoch, the stages with memory on
    each receiver's slice with its own state.  ``prepared``: (antenna ECEF, velocity or None) per receiver."""
    lead, r_n = rxs[0], len(rxs)
    b = _Block([e.t for e in epochs])
    # antenna: each receiver's geodetic position cache
    b.rx_ep = np.array([p[0] for p in prepared], dtype=float).reshape(r_n, 3)
    b.vel_ep = np.zeros((r_n, 3))
    for r, (_, v) in enumerate(prepared):
        if v is not None:
            b.vel_ep[r] = v
    b.lat_ep, b.lon_ep, b.h_ep = np.array([rx._geodetic(p) for rx, p in zip(rxs, b.rx_ep)], dtype=float).T
    # each receiver's clock, stepped from its own last epoch (its own stream); the true reception times at once
    # (GnssTime's scalar and array arithmetic are the same IEEE operations)
    b.bias_ep, b.drift_ep, b.dt_ep = (np.array(c, dtype=float) for c in
                                      zip(*[rx._clock_step(e.t) for rx, e in zip(rxs, epochs)]))
    b.t_true = GnssTime(np.array([e.t.sec for e in epochs], dtype=np.int64),
                        np.array([e.t.frac for e in epochs], dtype=float)) - b.bias_ep
    # the satellites of every receiver, one after another
    n_r = [len(e.states) for e in epochs]
    states = _stacked_states([e.states for e in epochs], n_r)
    e_all = np.repeat(np.arange(r_n), n_r)
    vis = np.concatenate([np.zeros(n, dtype=np.int64) if e.vis_state is None else np.asarray(e.vis_state, np.int64)
                          for e, n in zip(epochs, n_r)])
    att = np.concatenate([np.zeros(n) if e.attenuation_db is None else np.asarray(e.attenuation_db, float)
                          for e, n in zip(epochs, n_r)])
    lead._satellites_above_horizon(b, states, e_all, vis, att,
                                   states.az_el(b) if isinstance(states, _SharedStates) else None)
    lead._signals(b, rxs)
    if b.m == 0:
        return [rx._empty(e.t, b.bias_ep[r], b.drift_ep[r], *b.sat_rows(r)) for r, (rx, e) in
                enumerate(zip(rxs, epochs))]
    lead._geometry(b)
    lead._satellite_clocks(b)
    lead._atmosphere(b)
    lead._world_errors(b)
    lead._signal_strength(b)
    # reflected paths: each receiver's own, every (receiver, bandwidth) its own call of the DLL's peak search
    lead._scene_reflections(b, [e.multipath for e in epochs])
    _tracking(rxs, b)
    lead._receiver_errors(b, draws=_noise_draws(rxs, b))
    lead._observables(b)
    return lead._assemble(b)


def _stacked_states(parts: list[SatelliteStates], n_r: list[int]):
    """SatelliteStates.concatenate of ``parts`` (``n_r`` rows each) as Receiver._satellites_above_horizon reads it:
    the instants of states at one instant each repeated per row at once (the values concatenate's per-part rows
    hold); one part shared by every receiver (the fleet node's robots: one decoded message's states) as
    _SharedStates."""
    if (not sum(n_r) or len({p.source for p in parts}) > 1
            or not all(np.ndim(p.t.sec) == 0 and np.ndim(p.t.frac) == 0 for p in parts)):
        return SatelliteStates.concatenate(parts)
    if all(p is parts[0] for p in parts):
        return _SharedStates(parts[0], len(parts))
    t = GnssTime(np.repeat(np.array([p.t.sec for p in parts], dtype=np.int64), n_r),
                 np.repeat(np.array([p.t.frac for p in parts], dtype=float), n_r))
    kw = {name: np.concatenate([np.asarray(getattr(p, name)) for p in parts]) for name in ROW_FIELDS}
    return SatelliteStates(t=t, source=parts[0].source, **kw)


class _SharedStates:
    """``copies`` copies of the rows of ``states`` (at one instant) one after another, as
    Receiver._satellites_above_horizon reads them (len, sv, select, and az_el given): ``select`` gathers the rows
    it keeps from ``states`` itself (the values of the stacked states' select, instants per row), no field stacked
    but the satellites' names."""

    def __init__(self, states: SatelliteStates, copies: int):
        self.states = states
        self.sv = np.concatenate([np.asarray(states.sv)] * copies)

    def __len__(self) -> int:
        return len(self.sv)

    def az_el(self, b: _Block) -> tuple:
        """(azimuth, elevation) [deg] of every stacked row: copy r seen from antenna r of ``b`` (rx_ep, lat_ep,
        lon_ep), the antennas against the satellites broadcast in one frames.az_el_at (element by element the
        operations of the stacked rows' call, the antennas' trigonometry once each)."""
        az, el, _ = az_el_at(b.rx_ep[:, None, :], b.lat_ep[:, None], b.lon_ep[:, None],
                             np.asarray(self.states.pos_ecef_m))
        return az.reshape(-1), el.reshape(-1)

    def select(self, idx: np.ndarray) -> SatelliteStates:
        """Stacked rows ``idx`` (an index array)."""
        out = self.states.select(idx % len(self.states))
        t = self.states.t
        out.t = GnssTime(np.full(len(idx), t.sec, dtype=np.int64), np.full(len(idx), t.frac, dtype=float))
        return out


def _tracking(rxs, b: _Block) -> None:
    """Each receiver's tracking loops on its signal rows (Receiver._tracking), every receiver's rows in one
    tracking.update_trackers (each tracker's state and stream its own)."""
    ok = b.ok_all & (b.el_j >= rxs[0].cfg.elevation_mask_deg)
    b.tracked, b.lli, b.lock, b.amb = update_trackers([rx.tracker for rx in rxs], b.ts, b.rows.sv_j, b.codes,
                                                      b.cn0, ok, b.sig_seg)


def _noise_draws(rxs, b: _Block):
    """(z_cn0, r, mp_x) of every signal row, each receiver's from its own streams (Receiver._noise_draws of its
    epoch alone: C/N0, code, phase and Doppler noise as blocks of its m rows from rng_noise, the code multipath's
    innovations from its own stream), the code multipath states of every receiver advanced at once."""
    cfg, m = rxs[0].cfg, b.m
    if not cfg.noise:
        return np.zeros(m), np.zeros((3, m)), np.zeros(m)
    lead = 1 if cfg.cn0_noise_db > 0 else 0
    w, w_mp, models, slots, dt = [], [], [], [], []
    bounds = b.sig_seg.tolist()
    for r, rx in enumerate(rxs):
        j0, j1 = bounds[r], bounds[r + 1]
        if j0 == j1:                     # alone: no signal row, no draw (Receiver.epochs returns before)
            continue
        w.append(rx.rng_noise.standard_normal((3 + lead) * (j1 - j0)).reshape(3 + lead, j1 - j0))
        w_mp.append(rx.code_multipath.rng.standard_normal(j1 - j0))
        models.append(rx.code_multipath)
        slots.append(b.rows.mp_idx[j0:j1])
        dt.append(b.dt_ep[r])
    w = np.concatenate(w, axis=1)
    mp_x = advance_states(models, slots, dt, np.concatenate(w_mp))
    return (w[0] if lead else np.zeros(m)), w[lead:], mp_x
