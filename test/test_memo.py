"""core/memo.py: BoundedCache keeps at most limit + 1 entries, is a dict for lookups, and put returns the value."""
from __future__ import annotations

from gnss_sim_ros2.core.memo import BoundedCache


def test_put_stores_and_returns_the_value():
    c = BoundedCache(2)
    assert c.put("a", 1) == 1 and c.get("a") == 1 and c.get("b") is None
    assert isinstance(c, dict) and c.limit == 2


def test_full_cache_is_emptied_before_the_next_entry():
    c = BoundedCache(2)
    for i in range(3):
        c.put(i, i * 10)
    assert dict(c) == {0: 0, 1: 10, 2: 20}          # limit + 1 entries
    c.put(3, 30)
    assert dict(c) == {3: 30}                         # emptied, then the new entry
    assert max(len(c.put(k, k) and c) for k in range(10, 100)) <= 3


def test_put_of_a_key_held_replaces_it():
    c = BoundedCache(0)
    c.put("k", 1)
    c.put("k", 2)
    assert dict(c) == {"k": 2}
