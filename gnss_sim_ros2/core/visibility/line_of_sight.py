"""Which satellites a scene leaves in the line of sight of an antenna: the one classification of line of sight
against blocked that the Hong Kong drive check (core/comparison/drive_check.py) and ``gnss-sim calibrate --world
| --mesh`` (core/calibration) share.  A satellite is in the line of sight when it is at or above the mask and the
scene's cast (:meth:`VisibilityOptions.cast`, no reflections) does not mark it BLOCKED (foliage attenuates, it
does not block)."""
from __future__ import annotations

import numpy as np

from ..vocabulary import VisibilityState
from .options import VisibilityOptions


def line_of_sight(scene, antenna_world_m, sat_ecef_m, mask_deg: float):
    """(los, v): ``los`` (N,) bool, satellites ``sat_ecef_m`` (N, 3) at or above ``mask_deg`` and not blocked
    as seen from ``antenna_world_m`` (3,) in ``scene``; ``v`` the VisibilityResult (az_deg, el_deg, ...)."""
    state, _, v = VisibilityOptions(mask_deg=mask_deg).cast(scene, antenna_world_m, sat_ecef_m)
    return (state != int(VisibilityState.BLOCKED)) & (np.asarray(v.el_deg) >= mask_deg), v


def line_of_sight_epochs(scene, antenna_world_m, sat_ecef_m, mask_deg: float) -> np.ndarray:
    """(E, S) bool: :func:`line_of_sight` of each epoch's antenna ``antenna_world_m`` (E, 3) to the satellites
    ``sat_ecef_m`` (E, S, 3); False where a satellite position or the antenna is not finite (NaN)."""
    a = np.asarray(antenna_world_m, float).reshape(-1, 3)
    sat = np.asarray(sat_ecef_m, float)
    out = np.zeros(sat.shape[:2], bool)
    for e in range(len(a)):
        ok = np.all(np.isfinite(sat[e]), axis=1)
        if ok.any() and np.all(np.isfinite(a[e])):
            out[e, ok] = line_of_sight(scene, a[e], sat[e, ok], mask_deg)[0]
    return out
