"""Fidelity presets: default values of the model switches (speed against accuracy).

Each switch, what it costs and what it buys (figures: README, `gnss-sim bench`):
- ``transmit_time``: "recompute" evaluates the ephemeris again at the transmit
  time of each satellite (light time iterated, ~3 extra ephemeris calls per
  epoch); "expansion" moves the epoch's states back with a second-order
  Taylor series (sub-millimetre over 0.07 s, no extra calls).
- ``light_time_iterations``: 1 leaves ~1 mm of range error, 2 far below.
- ``ionosphere`` / ``troposphere``: "none" saves the models' evaluation and
  removes the delays from both the observations and the receiver's corrections.
- ``fresnel_rays``: rays over the first Fresnel zone per satellite for soft
  edges (0 = one ray: a hard shadow).
- ``noise``: thermal noise, multipath, clock wander, iono residual.
"""
from __future__ import annotations

PRESETS: dict[str, dict] = {
    "fast": {"transmit_time": "expansion", "light_time_iterations": 1, "ionosphere": "klobuchar",
             "troposphere": "saastamoinen", "fresnel_rays": 0},
    "balanced": {"transmit_time": "recompute", "light_time_iterations": 2, "ionosphere": "klobuchar",
                 "troposphere": "saastamoinen", "fresnel_rays": 0},
    "accurate": {"transmit_time": "recompute", "light_time_iterations": 3, "ionosphere": "klobuchar",
                 "troposphere": "saastamoinen", "fresnel_rays": 8},
}


def preset(name: str) -> dict:
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r} (parameter preset: {', '.join(PRESETS)})")
    return dict(PRESETS[name])
