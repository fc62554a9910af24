"""The planner's quality as occupancy-grid values 0-100 (nav_msgs/OccupancyGrid, a Nav2 costmap layer): low where
the fix will be good.

Mapping (per cell, from quality.FIELDS):
- RTK indicator holds (rtk_rule.py)                                    -> 0 (free: a fixed RTK solution expected);
- no single-point position (fewer used satellites than unknowns: HDOP NaN) -> 100 (lethal for GNSS: no fix);
- otherwise 1 + 98 * min(1, h_acc_m / max_accuracy_m), rounded: the expected single-point horizontal
  accuracy (HDOP x UERE, 1 sigma) scaled from 1 (a perfect single-point fix) to 99 (``max_accuracy_m`` or worse).
nav_msgs/OccupancyGrid: 0 free, 100 occupied, -1 unknown (cells outside the area).
"""
from __future__ import annotations

import numpy as np

COST_RTK = 0
COST_NO_FIX = 100
UNKNOWN = -1


def quality_cost(fields: dict, max_accuracy_m: float) -> np.ndarray:
    """int8 (C,) costs of the cells' ``fields`` ({name: (C,)}: rtk, hdop, h_acc_m); the module doc's mapping."""
    if not (np.isfinite(max_accuracy_m) and max_accuracy_m > 0):
        raise ValueError(f"max_accuracy_m is {max_accuracy_m}: a positive accuracy [m] is needed")
    h = np.asarray(fields["h_acc_m"], float)
    ok = np.isfinite(np.asarray(fields["hdop"], float)) & np.isfinite(h)
    with np.errstate(invalid="ignore"):
        graded = 1.0 + 98.0 * np.minimum(1.0, np.where(ok, h, 0.0) / max_accuracy_m)
    cost = np.where(ok, np.rint(graded), COST_NO_FIX)
    cost = np.where(np.asarray(fields["rtk"], bool), COST_RTK, cost)
    return cost.astype(np.int8)


def grid_cells(area, cost) -> np.ndarray:
    """The row-major (ny * nx,) int8 data of an OccupancyGrid over ``area`` (a grid PlanArea: row 0 at its lower
    y edge, column 0 at its lower x edge, as OccupancyGrid's origin is the lower-left corner of cell (0, 0)),
    UNKNOWN outside the area."""
    return area.to_grid(np.asarray(cost, np.int8), fill=np.int8(UNKNOWN)).astype(np.int8).ravel()
