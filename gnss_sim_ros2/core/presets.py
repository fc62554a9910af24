"""Fidelity presets: default values of the model switches (speed against accuracy).

A preset is a dict of switches; ``SimulationSetup.switches`` overrides single
ones, ``ReceiverConfig`` overrides (``SimulationSetup.receiver_overrides``) win over both.
Costs are per epoch of the demo scenario (courtyard world, demo path, synthetic
GRECJI constellation, ~45 satellites above the horizon, 2-core machine);
effects are measured by ``gnss-sim bench`` (docs/BENCHMARKS.md, the presets' table) and
``bench/bench_skips.py``.

- ``orbit``: "broadcast" keeps the navigation message; "precise" uses the SP3
  orbits and clocks when the setup gives ``sp3_files`` (else broadcast).
  Cost: none per epoch (an SP3 file loads in about the time of a navigation
  file).  Effect: the satellite positions/clocks the observations are built
  from are the truth instead of the broadcast prediction (SISRE ~0.7 m GPS);
  without broadcast group delays (SP3 clocks are ionosphere-free).
- ``transmit_time``: "recompute" evaluates the ephemeris again at a guessed
  transmit time of each satellite and iterates the light time on that state's
  Taylor series (propagation.transmit_time_refined: one extra ephemeris call
  per epoch, ~0.4 ms, a second only when the guess is off by > 0.1 ms; ranges
  equal to re-evaluating at every iteration within 1e-6 m); "expansion" moves
  the epoch's states back with a second-order Taylor series (no extra call;
  range error < 1 mm for the 0.07-0.09 s light time).
- ``light_time_iterations``: iterations of the "expansion" mode: 1 leaves
  ~1 mm of range error, 2 ~1e-6 m, 3 is converged to float precision.  Cost: a
  few vector operations per iteration.  ("recompute" iterates to convergence.)
- ``ionosphere``: the true ionosphere, "auto" (NeQuick-G where the navigation
  header has Galileo's coefficients, else Klobuchar), "nequick", "klobuchar"
  or "none"; ``troposphere``: "saastamoinen" or "none".  "none" removes the
  delays (2-30 m) from the observations *and* the receiver's own corrections:
  the position fix is unchanged but the pseudoranges no longer look like a
  real receiver's.  Cost ~0.1 ms each (Klobuchar, troposphere); NeQuick-G
  ~0.2-0.5 ms per epoch (core/nequick.py).  Effect: with Klobuchar as the
  truth a receiver's Klobuchar correction leaves only a common scale error
  (no horizontal gradient at night); with NeQuick-G it leaves a residual with
  a real receiver's north-south structure (OPEC 2022-001, docs/VALIDATION.md "A
  geodetic receiver in open sky").
- ``noise``: thermal noise, multipath, clock wander, ionosphere residual,
  SISRE.  Cost ~0.1 ms (vectorised per signal).
  On in every preset: the errors are what a receiver simulator is for; the
  benchmark turns it off only to isolate model differences.
- ``fresnel_rays``: rays over the first Fresnel zone per satellite for soft
  edges and a knife-edge diffraction loss (0 = one ray: a hard shadow).
  Cost: K + 1 rays (and a probe ring) per satellite instead of one occlusion
  test; 8 rays ~4x the raycasting time.  Effect: C/N0 drops near edges, so
  tracked sets differ by a few satellites per epoch near buildings.
- ``foliage``: "path" measures the path length through every tree crown hit
  (``list_intersections``) and charges dB/m; "touch" only tests whether a ray
  touches foliage and charges the fixed median single-tree fade
  (constants.FOLIAGE_MEDIAN_LOSS_DB).  Cost: one multi-hit query for the rays
  touching foliage.  Effect: thin or doubled crowns get the median loss.
- ``multipath``: reflections from the scene (core/multipath): "off"; "nlos" finds single-bounce specular
  paths (image method, two casts each) for the satellites whose line of sight is blocked, so a receiver
  may track them on a reflection (state REFLECTED_ONLY, excess delay on code and phase, C/N0 from the
  reflection's Fresnel coefficient and the antenna's LHCP rejection); "full" does it for every satellite
  and passes line of sight + reflections through the DLL/PLL model (code error from the multipath error
  envelope of the profile's correlator spacing and front-end bandwidth); "auto" lets the scene decide, per
  epoch and antenna: "full" where a wall (a non-horizontal opaque facet) lies within ``multipath_range_m``
  of the antenna, "off" elsewhere, where nothing beyond that test is computed
  (core/multipath/wall_proximity.py: a KD-tree of the walls' centroids, ~1 us per antenna in a block,
  20-50 us for one antenna per call; built once per scene, 46 ms for the Hong Kong city's 28,364 wall
  triangles).  The ground alone does not turn it on: open-sky multipath is the receiver's statistical
  code multipath (receiver/code_multipath.py), as in "off".  "auto" resolves to "full" rather than "nlos"
  because on the Hong Kong drive (../shared/data, core/comparison/drive_check.py, scattering on, antenna
  placed with the model's offset) both give the same tracked sets (recall 0.963, precision 0.774), NLOS
  share (0.308 against the real 0.270) and SPP ratio (1.33), but only "full" gives the line-of-sight code
  residuals a tail (RMS 3.4 m, 1.9 % above 10 m; "nlos" 1.3 m and 0 %; the real receiver 9.1 m and 8.1 %),
  for about 1.3x the cost of "nlos" per epoch.  Cost: one distance test per facet and antenna, two rays per
  single-bounce candidate, three per double bounce; on the Hong Kong city (21,314 facets, 31 satellites)
  the cast goes from 0.2 ms to 2.6-2.8 ms per epoch ("nlos", 50-100 m) and 2.8-4.4 ms ("full", 50-200 m),
  bench/bench_multipath.py; nothing when no facet is within ``multipath_range_m`` ("auto" in an open
  field: docs/BENCHMARKS.md, "auto: the scene decides").  Effect: urban single-point errors of tens of
  metres instead of a few, as real receivers show.  ``balanced`` (the default) sets "auto": a city or the
  demo courtyard gets the urban model, an open field pays nothing; ``fast`` keeps "off" (its 10 s epochs
  are for long open-sky runs: reflections would cost it several times its epoch); ``accurate`` keeps
  "full" (also the deterministic ground bounce where there is no wall).
- ``epoch_interval_s``: the epoch interval a run uses when its setup leaves
  it open (``SimulationSetup.interval_s <= 0``, as the benchmark does).  The
  cost of one epoch is nearly independent of the interval, so the real-time
  factor scales with it; the receiver keeps tracking (no interpolation).
"""
from __future__ import annotations

from .vocabulary import (
    FOLIAGE_MODES,
    IONOSPHERE_MODELS,
    MULTIPATH_MODES,
    ORBIT_MODES,
    TRANSMIT_TIME_MODES,
    TROPOSPHERE_MODELS,
)

#: the switches every preset sets (see the module docstring)
SWITCHES = ("orbit", "transmit_time", "light_time_iterations", "ionosphere", "troposphere", "noise",
            "fresnel_rays", "foliage", "multipath", "epoch_interval_s")

PRESETS: dict[str, dict] = {
    "fast": {"orbit": "broadcast", "transmit_time": "expansion", "light_time_iterations": 1,
             "ionosphere": "klobuchar", "troposphere": "saastamoinen", "noise": True, "fresnel_rays": 0,
             "foliage": "touch", "multipath": "off", "epoch_interval_s": 10.0},
    "balanced": {"orbit": "broadcast", "transmit_time": "expansion", "light_time_iterations": 2,
                 "ionosphere": "auto", "troposphere": "saastamoinen", "noise": True, "fresnel_rays": 0,
                 "foliage": "path", "multipath": "auto", "epoch_interval_s": 1.0},
    "accurate": {"orbit": "precise", "transmit_time": "recompute", "light_time_iterations": 3,
                 "ionosphere": "auto", "troposphere": "saastamoinen", "noise": True, "fresnel_rays": 8,
                 "foliage": "path", "multipath": "full", "epoch_interval_s": 1.0},
}

_CHOICES = {"orbit": ORBIT_MODES, "transmit_time": TRANSMIT_TIME_MODES, "ionosphere": IONOSPHERE_MODELS,
            "troposphere": TROPOSPHERE_MODELS, "foliage": FOLIAGE_MODES, "multipath": MULTIPATH_MODES}


def preset(name: str, overrides: dict | None = None) -> dict:
    """The switches of preset ``name`` with ``overrides`` applied (checked)."""
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r} (parameter preset: {', '.join(PRESETS)})")
    out = dict(PRESETS[name])
    for key, value in (overrides or {}).items():
        if key not in SWITCHES:
            raise ValueError(f"unknown preset switch {key!r} (switches: {', '.join(SWITCHES)})")
        if key in _CHOICES and value not in _CHOICES[key]:
            raise ValueError(f"preset switch {key!r} = {value!r}: use one of {', '.join(_CHOICES[key])}")
        if key in ("light_time_iterations", "fresnel_rays") and (int(value) != value or value < (
                1 if key == "light_time_iterations" else 0)):
            raise ValueError(f"preset switch {key!r} = {value!r}: a non-negative integer (>= 1 for iterations)")
        if key == "epoch_interval_s" and not value > 0:
            raise ValueError(f"preset switch 'epoch_interval_s' = {value!r}: must be > 0")
        out[key] = value
    return out
