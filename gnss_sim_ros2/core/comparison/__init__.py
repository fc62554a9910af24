"""Simulated against real observations (``gnss-sim compare``).

Modules: sources.py (RINEX or bag -> ObsTable), pairing.py (signals matched), statistics.py (differences,
common offsets, statistics), truth.py (CSV ground truth), compare.py (the method), report.py (Markdown +
figures).  The single point solver is core/comparison/spp.py, the RTKLIB wrappers core/comparison/rtklib.py.
"""
from .compare import Comparison, compare
from .report import write_figures, write_report
from .sources import load_observations

__all__ = ["Comparison", "compare", "load_observations", "write_figures", "write_report"]
