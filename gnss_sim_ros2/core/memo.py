"""Memoisation, once: the bounded caches of values computed again and again for the same inputs.

A cache keyed by hashable arguments of a module function is ``functools.lru_cache(maxsize=...)``
(propagation, solver, nmea, multipath.dll). A cache keyed by something the caller builds (the bytes of a
satellite list, a layout tuple), on an object or in a module, is a ``BoundedCache``: a dict (lookups are
``dict.get``, at C speed on the hot paths) whose ``put`` empties it first when it holds more than ``limit``
entries.  The keys come back in runs (the same satellites epoch after epoch), so emptying a full cache now and
then costs less than least-recently-used bookkeeping on every hit.
"""
from __future__ import annotations


class BoundedCache(dict):
    """A memo of at most ``limit`` + 1 entries: ``put`` empties it when it holds more than ``limit``."""

    __slots__ = ("limit",)

    def __init__(self, limit: int):
        super().__init__()
        self.limit = int(limit)

    def put(self, key, value):
        """Store ``value`` under ``key`` (emptying the cache first when it is over its limit); ``value``."""
        if len(self) > self.limit:
            self.clear()
        self[key] = value
        return value


def read_only(values):
    """``values`` (an array, or a tuple of values) with every numpy array in it made read-only, and returned: a
    kept value handed to every caller must not be written into."""
    for v in values if isinstance(values, tuple) else (values,):
        if hasattr(v, "setflags"):
            v.setflags(write=False)
    return values
