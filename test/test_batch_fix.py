"""Fixes solved together are the fixes solved alone, bit for bit (issue 31: the fleet receiver node solves
every robot's epoch in one solver.solve_pvt_many, and a fleet's robot must give what its own receiver gives)."""
from __future__ import annotations

import dataclasses
import random

import numpy as np
import pytest

from gnss_sim_ros2.core.frames import ecef_to_geodetic, ecef_to_geodetic_pointwise
from gnss_sim_ros2.core.solver import SolverConfig, solve_pvt_many


def _bits_differ(a, b) -> str | None:
    """The first PvtSolution field whose bits differ (NaN equal to NaN), or None."""
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray) and x.dtype.kind == "f":
            if x.shape != y.shape or x.tobytes() != y.tobytes():
                return f.name
        elif isinstance(x, np.ndarray):
            if not np.array_equal(x, y):
                return f.name
        elif isinstance(x, float):
            if np.float64(x).tobytes() != np.float64(y).tobytes():
                return f.name
        elif x != y:
            return f.name
    return None


@pytest.fixture(scope="module")
def epochs(tmp_path_factory):
    """Fix inputs of a demo run's epochs (a moving antenna in the demo city: satellite sets of many sizes),
    varied: a biased satellite or two (residual check exclusions), a system dropped (fewer clock unknowns),
    missing ranges, too few satellites, no starting point."""
    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.core.receiver.outputs import fix_inputs
    from gnss_sim_ros2.core.scene.demo_world import demo_world_path
    from gnss_sim_ros2.core.simulation import run_simulation, setup_from_config
    from gnss_sim_ros2.core.time import GnssTime
    from gnss_sim_ros2.core.trajectory import demo_trajectory

    got = []
    setup = setup_from_config(load_config(), tmp_path_factory.mktemp("demo"), demo_trajectory(),
                              start=GnssTime.from_iso("2025-06-01T10:00:00"), duration_s=60.0, interval_s=1.0,
                              observer=lambda t, ecef, obs, sol: got.append((np.array(ecef, float), obs))
                              ).with_params(world_file=str(demo_world_path()), systems="GREC")
    run_simulation(setup)
    rng = random.Random(3)
    out = []
    for i, (ecef, obs) in enumerate(got):
        systems = sorted({s[0] for s in obs.sv.tolist()})
        first_code = {s: obs.code[obs.sv.astype("<U1") == s][:1].tolist() for s in systems}
        e = fix_inputs(obs, first_code, None if i % 7 == 0 else ecef + 30.0)     # no prior: from the centre
        n = len(e["sv"])
        kind = i % 5
        keep = np.arange(n)
        if kind == 1 and n:
            pr = e["pseudorange_m"].copy()
            pr[rng.randrange(n)] += 80.0
            pr[rng.randrange(n)] += 40.0
            e["pseudorange_m"] = pr
        elif kind == 2 and len(systems) > 1:
            keep = np.flatnonzero(e["sv"].astype("<U1") != rng.choice(systems))
        elif kind == 3 and n:
            pr = e["pseudorange_m"].copy()
            pr[rng.sample(range(n), min(n, 3))] = np.nan
            e["pseudorange_m"] = pr
        elif kind == 4:
            keep = np.arange(min(n, rng.choice([2, 3, 4, 5])))
        if len(keep) != n:
            e = {k: (v[keep] if isinstance(v, np.ndarray) and v.ndim and len(v) == n else v) for k, v in e.items()}
        out.append(e)
    return out


@pytest.mark.parametrize("clock_systems", ["", "GREC"])
def test_epochs_solved_together_give_each_epoch_its_own_bits(epochs, clock_systems):
    """Without clock_systems in sets of the same clock groups; with them (a receiver's systems) all in one set."""
    cfg = SolverConfig(clock_systems=clock_systems)
    alone = [solve_pvt_many([e], cfg)[0] for e in epochs]
    assert len({len(e["sv"]) for e in epochs}) > 5                   # satellite sets of many sizes: padding
    assert sum(a.is_fix for a in alone) > 10 and sum(not a.is_fix for a in alone) >= 3
    assert sum(bool(a.excluded) for a in alone) > 3                   # exclusions by the residual check
    assert sum(a.vel_status == "fix" for a in alone) > 10
    rng = random.Random(11)
    for _ in range(60):
        idx = rng.sample(range(len(epochs)), rng.choice([2, 3, 4, 16, 32]))
        for i, sol in zip(idx, solve_pvt_many([epochs[i] for i in idx], cfg)):
            assert _bits_differ(alone[i], sol) is None, (i, _bits_differ(alone[i], sol))


def test_pointwise_geodetic_is_the_scalar_path_bit_for_bit():
    rng = np.random.default_rng(4)
    v = rng.normal(size=(3000, 3))
    v *= rng.uniform(6.0e6, 4.0e7, (3000, 1)) / np.linalg.norm(v, axis=1)[:, None]
    v[:3] = [[0.0, 0.0, 6.4e6], [1.0, 2.0, 3.0], [6.4e6, 0.0, 0.0]]       # a pole, the Earth centre (pymap3d)
    lat, lon, h = ecef_to_geodetic_pointwise(v[:, 0], v[:, 1], v[:, 2])
    one = np.array([[float(c) for c in ecef_to_geodetic(*p)] for p in v.tolist()])
    for got, want in zip((lat, lon, h), one.T):
        assert got.tobytes() == want.tobytes()


def test_clock_systems_solve_receivers_alike_in_one_pass(epochs, monkeypatch):
    """With the receiver's systems configured, epochs that lack a system (a robot that sees no Galileo) are solved
    in one pass with the others (one _solve_epochs), and a clock group without satellites changes nothing but
    the bits: positions, clocks, DOPs and the residual check as without it."""
    from gnss_sim_ros2.core import solver

    calls = []
    real = solver._solve_epochs
    monkeypatch.setattr(solver, "_solve_epochs", lambda ep, cfg: calls.append(len(ep)) or real(ep, cfg))
    dropped = [i for i, e in enumerate(epochs) if {sv[0] for sv in e["sv"].tolist()}
               != set("GREC") and len(e["sv"]) >= 8]
    full = [i for i, e in enumerate(epochs) if len(e["sv"]) >= 8 and i not in dropped]
    assert dropped and full
    batch = [epochs[i] for i in dropped[:4] + full[:4]]
    plain = solve_pvt_many(batch, SolverConfig())
    assert len(calls) > 1                                  # by clock groups: several passes
    calls.clear()
    padded = solve_pvt_many(batch, SolverConfig(clock_systems="GREC"))
    assert calls == [len(batch)]                           # one pass
    for a, b in zip(plain, padded):
        assert a.is_fix == b.is_fix and a.excluded == b.excluded and a.reason == b.reason
        if a.is_fix:
            np.testing.assert_allclose(b.pos_ecef_m, a.pos_ecef_m, rtol=0, atol=1e-6)
            np.testing.assert_allclose([b.gdop, b.pdop, b.hdop, b.vdop, b.tdop],
                                       [a.gdop, a.pdop, a.hdop, a.vdop, a.tdop], rtol=1e-9)
            assert b.clock_bias_m.keys() == a.clock_bias_m.keys()


def test_clock_systems_checked():
    with pytest.raises(ValueError, match="clock_systems 'GX'"):
        solve_pvt_many([{"sv": ["G01"], "sat_pos_ecef_m": [[2e7, 0, 0]], "pseudorange_m": [2e7]}],
                       SolverConfig(clock_systems="GX"))
