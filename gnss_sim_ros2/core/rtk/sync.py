"""Rover and base RTCM3 put in epoch order for rtkrcv.

rtkrcv keeps only the newest base epoch it has decoded in a server cycle
(RTKLIB 2.4.3 rtksvr.c ``decoderaw``: ``obs[1][0]`` is overwritten) and pairs
every rover epoch of the cycle with it.  Fed as the messages come, a rover
epoch that arrives before the base epoch of the same time is solved against
the previous base epoch (age one interval), and a fast run (many epochs per
cycle) pairs rover epochs with later base epochs.  :class:`EpochSync` holds
each rover epoch back until the base epoch of the same (or a later) time has
gone out, so rtkrcv sees base t, then rover t.  Epochs are keyed by their MSM
GPS time of week (frame.epoch_gps_ms).  A rover epoch waits for at most
``max_wait_epochs`` later rover epochs: without base data the rover still
reaches rtkrcv (its single solution), never a growing queue.
"""
from __future__ import annotations

from ..rtcm.frame import epoch_gps_ms

_HALF_WEEK_MS = 302_400_000
_WEEK_MS = 604_800_000


def _ms_diff(a: int, b: int) -> int:
    """a - b [ms] across a week rollover."""
    return (a - b + _HALF_WEEK_MS) % _WEEK_MS - _HALF_WEEK_MS


class EpochSync:
    """``push(which, data)`` -> the (which, bytes) to send now, in order; ``which`` "rover" or "base"."""

    def __init__(self, max_wait_epochs: int = 5):
        self.max_wait_epochs = int(max_wait_epochs)
        self.base_ms: int | None = None
        self.held: list[tuple[int, bytes]] = []     # rover epochs waiting for their base epoch
        self.released_unpaired = 0                  # rover epochs sent without their base epoch

    def push(self, which: str, data: bytes) -> list[tuple[str, bytes]]:
        ms = epoch_gps_ms(data)
        if which == "base":
            out = [("base", data)]
            if ms is not None:
                self.base_ms = ms if self.base_ms is None or _ms_diff(ms, self.base_ms) > 0 else self.base_ms
                out += self._release(lambda t: _ms_diff(t, self.base_ms) <= 0)
            return out
        if ms is None:                               # no observations (station, ephemerides): nothing to pair
            return [("rover", data)]
        if self.base_ms is not None and _ms_diff(ms, self.base_ms) <= 0 and not self.held:
            return [("rover", data)]
        self.held.append((ms, data))
        if len(self.held) > self.max_wait_epochs:   # the base is late or gone: let the oldest go
            self.released_unpaired += 1
            return [("rover", self.held.pop(0)[1])]
        return []

    def _release(self, ready) -> list[tuple[str, bytes]]:
        out = []
        while self.held and ready(self.held[0][0]):
            out.append(("rover", self.held.pop(0)[1]))
        return out

    def flush(self) -> list[tuple[str, bytes]]:
        """Everything still held (the node stops)."""
        out = [("rover", d) for _, d in self.held]
        self.released_unpaired += len(self.held)
        self.held = []
        return out
