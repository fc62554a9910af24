"""The receiver's configuration: its profile (signals, antenna, front end, thresholds), error models and
seeds (``ReceiverConfig``; defaults from signals.PROFILES and signals.RECEIVER_TRAITS)."""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from .. import signals as sig
from ..multipath.antenna import PATTERNS
from ..vocabulary import IONOSPHERE_MODELS, TRANSMIT_TIME_MODES, TROPOSPHERE_MODELS
from . import cn0 as cn0_model
from . import hardware_bias
from .clock import ClockConfig
from .tracking import TrackingConfig

#: default SISRE [m] per system (see ReceiverConfig.sisre_m): broadcast vs precise orbit+clock, global
#: averages of Montenbruck et al., GPS Solutions 19:321 (2015) (physics-anchors.md): GPS 0.7, GLONASS 1.9,
#: BeiDou 1.5, QZSS 0.6 m.  Galileo: their 1.6 m is the early constellation of 2013-14 ("far better
#: today"); on OPEC 2022-001 RTKLIB gives the real receiver 1.28 m horizontal RMS Galileo-only against
#: 1.32 m GPS-only, and the real-minus-model code residuals per satellite are 0.93 m (Galileo) against
#: 1.19 m (GPS) RMS (test_receiver_acceptance), so Galileo gets the GPS value.  NavIC: no published
#: figure at hand, the BeiDou value.
SISRE_DEFAULT_M = {"G": 0.7, "R": 1.9, "E": 0.7, "C": 1.5, "J": 0.6, "I": 1.5}


@dataclass
class ReceiverConfig:
    profile: str | dict = "geodetic"
    systems: str = "GRECJI"
    elevation_mask_deg: float = 10.0
    #: the receiver's errors on: random ones (thermal noise, multipath, clock wander, iono residual, SISRE)
    #: and its hardware code biases; off: an ideal receiver with the deterministic models only
    noise: bool = True
    #: true ionosphere: "auto" (NeQuick-G where Galileo coefficients are given, else Klobuchar), "nequick",
    #: "klobuchar" or "none"; a receiver's own correction is always Klobuchar (unless "none")
    ionosphere: str = "auto"
    troposphere: str = "saastamoinen"  # "saastamoinen" | "none"
    #: transmit-time geometry: "recompute" (ephemeris at t_tx) or "expansion" (2nd order from states at t)
    transmit_time: str = "recompute"
    light_time_iterations: int = 2
    seed: int = 1
    #: DLL: noise bandwidth [Hz], early-late spacing [chips] (None: the profile's, signals.RECEIVER_TRAITS)
    dll_bn_hz: float | None = None
    dll_spacing_chips: float | None = None
    #: antenna pattern for reflections (multipath/antenna.py), double-sided front-end bandwidth [Hz],
    #: satellites not tracked (regular expression on the RINEX id); None: the profile's
    antenna: str | None = None
    frontend_bandwidth_hz: float | None = None
    excluded_svs: str | None = None
    #: code multipath/residual model (code_multipath.py) [m], correlation time [s]; checked on OPEC 2022-001:
    #: the scatter of each satellite's code residual about its own mean is 0.47-0.69 m RMS per system for the
    #: real NETR9 and 0.65 m for these values with the DLL noise below (test_receiver_acceptance), so kept
    mp_zenith_m: float = 0.15
    mp_low_m: float = 1.2
    mp_tau_s: float = 60.0
    #: true ionosphere = model x (1 + iono_error_frac * g(t)), g smooth, unit variance (world_errors.py), per model.
    #: Klobuchar 0.5: it removes about 50 % of the RMS ionospheric delay (Navipedia, physics-anchors.md).
    #: NeQuick-G 0.3: designed to correct at least 70 % of the delay (Galileo Ionospheric Correction
    #: Algorithm 1.2, 2016, section 1).
    iono_error_frac: dict = field(default_factory=lambda: {"klobuchar": 0.5, "nequick": 0.3})
    #: broadcast orbit + clock error on the line of sight (SISRE) [m] per system (receiver/engine.py module doc)
    sisre_m: dict = field(default_factory=lambda: dict(SISRE_DEFAULT_M))
    #: seed of the world's random errors (ionosphere residual, SISRE): the same for all receivers of one world
    world_seed: int = 0
    #: hardware code biases [m] (core/receiver/hardware_bias.py); None: the table of a named profile
    code_bias_m: dict | None = None
    cn0_noise_db: float = 0.3
    #: acquisition / loss-of-lock thresholds; None: the profile's (signals.RECEIVER_TRAITS)
    tracking: TrackingConfig | None = None
    clock: ClockConfig = field(default_factory=ClockConfig)
    link_budget: cn0_model.LinkBudget = field(default_factory=cn0_model.LinkBudget)

    def __post_init__(self):
        if self.ionosphere not in IONOSPHERE_MODELS:
            raise ValueError(f"receiver: parameter 'ionosphere' = {self.ionosphere!r} (one of {IONOSPHERE_MODELS})")
        if isinstance(self.iono_error_frac, (int, float)):
            self.iono_error_frac = {"klobuchar": float(self.iono_error_frac), "nequick": float(self.iono_error_frac)}
        if self.troposphere not in TROPOSPHERE_MODELS:
            raise ValueError(f"receiver: parameter 'troposphere' = {self.troposphere!r} (saastamoinen or none)")
        if self.transmit_time not in TRANSMIT_TIME_MODES:
            raise ValueError(f"receiver: parameter 'transmit_time' = {self.transmit_time!r}")
        bad = {s: v for s, v in dict(self.sisre_m).items() if not (np.isfinite(v) and v >= 0)}
        if bad:
            raise ValueError(f"receiver: parameter 'sisre_m' has values that are not finite and >= 0: {bad}")
        if self.code_bias_m is None:
            named = self.profile if isinstance(self.profile, str) else None
            self.code_bias_m = hardware_bias.PROFILE_CODE_BIAS_M.get(named, {})
        self.code_bias_m = hardware_bias.validate(self.code_bias_m)
        tr = sig.traits(self.profile if isinstance(self.profile, str) else "")
        for name in ("dll_bn_hz", "dll_spacing_chips", "antenna", "frontend_bandwidth_hz", "excluded_svs"):
            if getattr(self, name) is None:
                setattr(self, name, getattr(tr, name))
        if self.tracking is None:
            self.tracking = TrackingConfig(acquisition_cn0_dbhz=tr.acquisition_cn0_dbhz,
                                           tracking_cn0_dbhz=tr.tracking_cn0_dbhz)
        if self.antenna not in PATTERNS:
            raise ValueError(f"receiver: parameter 'antenna' = {self.antenna!r} (one of {PATTERNS})")
        if not (self.frontend_bandwidth_hz > 0 and 0 < self.dll_spacing_chips <= 1):
            raise ValueError("receiver: 'frontend_bandwidth_hz' must be > 0 and 'dll_spacing_chips' in (0, 1]")
        self._excluded = re.compile(self.excluded_svs) if self.excluded_svs else None
        if isinstance(self.profile, str):
            self.profile = sig.profile(self.profile)
        else:
            sig.validate_profile(self.profile)
        if not self.noise:
            self.code_bias_m = {}
            self.clock = ClockConfig(**{**self.clock.__dict__, "noise": False})
            self.tracking = TrackingConfig(**{**self.tracking.__dict__, "random_slips": False})
