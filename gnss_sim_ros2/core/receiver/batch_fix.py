"""The position fixes of several receivers' epochs in one solve (the fleet receiver node's robots).

Each receiver (core/receiver/chain.ReceiverChain) keeps its own state: its smoothing filter and last fix
(ReceiverChain.fix_inputs), its SolverConfig, its RAIM exclusions (solver.solve_pvt_many excludes per epoch).
solve_pvt_many gives every epoch the bits it gets alone, whatever the epochs solved with it, so a robot's fix
here is the one its own receiver node computes (test_fleet_layout.py compares the two layouts byte for byte).
The receivers' RINEX epochs are formatted together too (prepare_rinex_epochs), each written by its own finish.
"""
from __future__ import annotations

from ..memo import BoundedCache
from ..rinex.obs_write import EpochFormatter
from ..solver import PvtSolution, solve_pvt_many
from .outputs import epoch_arrays


def solve_receivers_fixes(chains, obs_list) -> list[PvtSolution]:
    """The fix of ``obs_list[k]`` (this epoch's observables of receiver ``chains[k]``, from its
    ReceiverChain.observe) for every k: one solve_pvt_many per distinct SolverConfig (one for robots
    configured alike), in the order given.  Advances each chain's smoothing filter (fix_inputs): call once per
    epoch of a chain, then chains[k].finish(..., sol=) with its solution (its RINEX lines formatted here with the
    other chains': prepare_rinex_epochs)."""
    inputs = [chain.fix_inputs(obs) for chain, obs in zip(chains, obs_list)]
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


#: EpochFormatter per obs_types (its layouts cached across epochs)
_FORMATTERS = BoundedCache(16)


def prepare_rinex_epochs(chains, obs_list) -> None:
    """The EpochArrays and RINEX satellite lines of ``obs_list[k]`` for every chain k that writes a RINEX file, the
    lines of all chains with the same observation types formatted in one vectorised pass (rinex/obs_write
    EpochFormatter: the bytes each chain's writer would format), handed to each chain (ReceiverChain.prepare) for
    its next finish to write.  Epochs that do not format (a value that does not fit) are left to their finish,
    which raises for them as it does alone."""
    groups: dict = {}                    # obs_types key -> [(chain, obs, arrays)]
    for chain, obs in zip(chains, obs_list):
        if not (len(obs.sv) and chain.wants_arrays()):
            continue
        arrays = epoch_arrays(obs, chain.obs_types)
        if chain.settings.output_dir is None:          # RTCM only: no RINEX lines
            chain.prepare(obs, arrays)
            continue
        key = tuple((s, tuple(c)) for s, c in chain.obs_types.items())
        groups.setdefault(key, []).append((chain, obs, arrays))
    for key, members in groups.items():
        fmt = _FORMATTERS.get(key)
        if fmt is None:
            fmt = EpochFormatter({s: list(c) for s, c in key})
            _FORMATTERS.put(key, fmt)
        try:
            lines = fmt.format_arrays([arrays for _, _, arrays in members])
        except ValueError:
            lines = [None] * len(members)
        for (chain, obs, arrays), ep_lines in zip(members, lines):
            chain.prepare(obs, arrays, ep_lines)
