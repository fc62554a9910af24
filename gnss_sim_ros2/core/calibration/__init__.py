"""Receiver calibration from a real recording (``gnss-sim calibrate``), ROS-free.

Modules: reading.py (observations over a span, navigation data, antenna position or path -> elevations),
signal_stats.py (per-signal statistics: C/N0 and code noise against elevation, arcs, LLI flags, tracked pairs;
also what ``gnss-sim compare`` reports sim against real), fit.py (statistics -> a receiver profile, the YAML
schema of core/receiver profiles), report.py (report.md + figures).
"""
