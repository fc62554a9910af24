"""The demo scenario, once: what ``gnss-sim simulate`` and ``gnss-sim run`` do with no option.

The hour starting at DEMO_START (GPS), every system of vocabulary.SYSTEMS on the synthetic constellation,
the demo path (trajectory.demo_trajectory) through the demo world (scene.demo_world: worlds/courtyard.sdf).
The parameter table's ``start_time`` default, the benchmarks (presets, speed, scaling) and bench/ scripts take
the start from here.
"""
from __future__ import annotations

#: GPS time of the demo's first epoch, ISO 8601 (the start_time parameter's default)
DEMO_START = "2025-06-01T10:00:00"
