"""The words every layer shares: system letters, visibility states, model choices.

One place for each list, so the parameter table, the presets, the receiver,
the nodes and the command line accept and print the same names.
"""
from __future__ import annotations

import enum

#: GNSS systems simulated, RINEX 3.04 satellite system letters (RINEX 3.04 section 3.5)
SYSTEMS = "GRECJI"
SYSTEM_NAMES = {"G": "GPS", "R": "GLONASS", "E": "Galileo", "C": "BeiDou", "J": "QZSS", "I": "NavIC"}


class VisibilityState(enum.IntEnum):
    """Line-of-sight state of one satellite; the numbers of gnss_sim_msgs/SatelliteVisibility.msg."""

    VISIBLE = 0          # free line of sight
    BLOCKED = 1          # hidden by an opaque surface
    ATTENUATED = 2       # through foliage or a soft edge: weakened
    REFLECTED_ONLY = 3   # no direct path, only a reflection reaches the antenna


#: where orbits come from (parameter source)
EPHEMERIS_SOURCES = ("synthetic", "broadcast", "sp3", "download")
#: true ionosphere models (core/receiver/ionosphere.py)
IONOSPHERE_MODELS = ("auto", "nequick", "klobuchar", "none")
TROPOSPHERE_MODELS = ("saastamoinen", "none")
#: how a run's tracking starts (core/receiver/tracking.py TrackingConfig.start)
TRACKING_STARTS = ("warm", "cold")
#: preset switch choices (core/presets.py)
ORBIT_MODES = ("broadcast", "precise")
TRANSMIT_TIME_MODES = ("recompute", "expansion")
FOLIAGE_MODES = ("path", "touch")
PRESET_NAMES = ("fast", "balanced", "accurate")
#: scene multipath: none, reflections of blocked satellites only, every satellite, or every satellite of the
#: antennas with walls in range (core/multipath, core/presets.py)
MULTIPATH_MODES = ("off", "nlos", "full", "auto")


def check_systems(systems: str, where: str) -> str:
    """``systems`` (letters of SYSTEMS, at least one, no repeats kept); ValueError naming ``where``."""
    if not isinstance(systems, str) or not systems or set(systems) - set(SYSTEMS):
        bad = "".join(sorted(set(systems) - set(SYSTEMS))) if isinstance(systems, str) else ""
        extra = f" (unknown: {bad})" if bad else ""
        raise ValueError(f"{where} is {systems!r}{extra}; use one or more letters of {SYSTEMS} "
                         f"({', '.join(f'{k} {v}' for k, v in SYSTEM_NAMES.items())})")
    return "".join(dict.fromkeys(systems))
