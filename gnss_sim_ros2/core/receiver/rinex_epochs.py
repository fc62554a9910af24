"""Several receivers' RINEX epochs formatted in one pass: the fleet's robots at an epoch (batch_fix) or one
chain's block of epochs (ReceiverChain.observe_block). A module of its own below both chain and batch_fix (each
calls it; it calls only the chains' methods and outputs.rinex_lines)."""
from __future__ import annotations

from .outputs import rinex_lines


def prepare_rinex_epochs(chains, obs_list) -> None:
    """The outputs of ``obs_list[k]`` that need no fix (ReceiverChain.rinex_outputs: EpochArrays for RTCM, RINEX
    satellite lines) made for every chain k, the lines of all chains with the same observation types formatted
    in one vectorised pass (outputs.rinex_lines), handed to each chain (ReceiverChain.prepare) for its next finish
    to write.  A group whose epochs do not format (a value that does not fit) is left to the finishes, which raise
    for it as alone.  ``chains`` may hold one chain several times (its consecutive epochs, in order)."""
    groups: dict = {}                    # obs_types key -> [k]
    for k, chain in enumerate(chains):
        groups.setdefault(tuple((s, tuple(c)) for s, c in chain.obs_types.items()), []).append(k)
    for idx in groups.values():
        first = chains[idx[0]]
        with_lines = [k for k in idx if chains[k].settings.output_dir is not None and len(obs_list[k].sv)]
        try:
            lines = dict(zip(with_lines, rinex_lines([obs_list[k] for k in with_lines], first.obs_types)))
        except ValueError:
            continue
        for k in idx:
            chains[k].prepare(obs_list[k], chains[k].rtcm_arrays(obs_list[k]), lines.get(k))
