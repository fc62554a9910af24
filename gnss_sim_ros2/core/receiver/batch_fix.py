"""The position fixes of several receivers' epochs in one solve (the fleet receiver node's robots).

Each receiver (core/receiver/chain.ReceiverChain) keeps its own state: its smoothing filter and last fix
(ReceiverChain.fix_inputs), its SolverConfig, its RAIM exclusions (solver.solve_pvt_many excludes per epoch).
solve_pvt_many gives every epoch the bits it gets alone, whatever the epochs solved with it, so a robot's fix
here is the one its own receiver node computes (test_fleet_layout.py compares the two layouts byte for byte).
The receivers' RINEX epochs are formatted together too (rinex_epochs.prepare_rinex_epochs), each written by its own
finish.
"""
from __future__ import annotations

from ..solver import PvtSolution, solve_pvt_many
from .chain import receivers_fix_inputs
from .rinex_epochs import prepare_rinex_epochs


def solve_receivers_fixes(chains, obs_list) -> list[PvtSolution]:
    """The fix of ``obs_list[k]`` (this epoch's observables of receiver ``chains[k]``, from its
    ReceiverChain.observe) for every k: one solve_pvt_many per distinct SolverConfig (one for robots
    configured alike), in the order given.  Advances each chain's smoothing filter (fix_inputs): call once per
    epoch of a chain, then chains[k].finish(..., sol=) with its solution (its RINEX lines formatted here with the
    other chains': prepare_rinex_epochs)."""
    inputs = receivers_fix_inputs(chains, obs_list)
    prepare_rinex_epochs(chains, obs_list)
    by_config: list = []                 # [(SolverConfig, [indices])]; SolverConfig compares by value
    for i, chain in enumerate(chains):
        cfg = chain.settings.solver
        for known, idx in by_config:
            if known is cfg or known == cfg:
                idx.append(i)
                break
        else:
            by_config.append((cfg, [i]))
    sols: list = [None] * len(inputs)
    for cfg, idx in by_config:
        for i, sol in zip(idx, solve_pvt_many([inputs[i] for i in idx], cfg)):
            sols[i] = sol
    return sols
