"""The receiver's configuration: its profile (signals, antenna, front end, thresholds), error models and
seeds (``ReceiverConfig``; defaults from the receiver profile's YAML file, core/receiver/profiles.py)."""
from __future__ import annotations

import copy
import dataclasses
import re
from dataclasses import dataclass, field, fields

import numpy as np

from .. import signals as sig
from ..multipath.antenna import PATTERNS
from ..vocabulary import IONOSPHERE_MODELS, TRANSMIT_TIME_MODES, TROPOSPHERE_MODELS
from . import cn0 as cn0_model
from . import code_multipath, hardware_bias, outputs, profile_file
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


def _owned(builtin, check=None):
    """A field a receiver profile owns: None (the default) takes the profile's value, else ``builtin``;
    ``check`` (value -> value, ValueError) runs on the profile's and the argument's value alike."""
    return field(default=None, metadata={"builtin": builtin, "check": check})


def _positive(v):
    if not v > 0:
        raise ValueError(f"{v!r} must be > 0")
    return v


def _nonnegative(v):
    if not v >= 0:
        raise ValueError(f"{v!r} must be >= 0")
    return v


def _spacing(v):
    if not 0 < v <= 1:
        raise ValueError(f"{v!r} must be in (0, 1] chips")
    return v


def _antenna(v):
    if v not in PATTERNS:
        raise ValueError(f"{v!r} is not an antenna pattern (one of {', '.join(PATTERNS)})")
    return v


def _regex(v):
    try:
        re.compile(v)
    except re.error as exc:
        raise ValueError(f"{v!r} is not a regular expression: {exc}") from None
    return v


def _signal_regexes(v):
    """{signal key ("C6I"): regular expression on the RINEX id} (excluded_signals)."""
    if not isinstance(v, dict):
        raise ValueError(f"'excluded_signals' = {v!r} is not a mapping of signal keys (C6I) to regular expressions")
    for key, rx in v.items():
        key = str(key)
        if len(key) != 3 or (key[0], key[1:]) not in sig.SIGNALS:
            raise ValueError(f"'excluded_signals': key {key!r} is not a signal (system letter + RINEX code, e.g. C6I)")
        try:
            re.compile(str(rx))
        except re.error as exc:
            raise ValueError(f"'excluded_signals.{key}' = {rx!r} is not a regular expression: {exc}") from None
    return {str(k_): str(rx) for k_, rx in v.items()}


#: dataclass-typed fields a profile gives as a mapping of their fields
_NESTED = {"tracking": TrackingConfig, "link_budget": cn0_model.LinkBudget}


@dataclass
class ReceiverConfig:
    #: receiver profile (core/receiver/profiles.py): a built-in name, a .yaml file, a profile mapping or a bare
    #: {system: [codes]} mapping; after construction: the signals tracked, {system: [codes]}
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
    #: land-mobile-satellite layer on the scene's rays (lms_channel.py): off, auto or a class of multipath/lms.py
    lms_environment: str = "off"
    #: a scenario spoofer's counterfeit captures a signal when its power exceeds the authentic one's by this [dB]
    #: (core/threats/spoofing.py)
    spoof_capture_margin_db: float = 3.0
    #: Fields a profile owns (every field but profile_file.RUN_FIELDS) default to None: the profile's value, else
    #: the field's ``builtin`` (a profile that leaves it out, a bare signal mapping); an argument overrides both.
    #: DLL: noise bandwidth [Hz], early-late spacing [chips]
    dll_bn_hz: float | None = _owned(0.5, check=_positive)     # checked here: the noise model named no file
    dll_spacing_chips: float | None = _owned(0.2, check=_spacing)
    #: DLL coherent integration [s] (receiver/noise.py; the PLL's loop: tracking.pll_bn_hz, tracking.pll_t_int_s,
    #: for the carrier-phase noise as for the cycle slips)
    dll_t_int_s: float | None = _owned(0.02, check=_positive)
    #: antenna pattern for reflections (multipath/antenna.py), double-sided front-end bandwidth [Hz],
    #: satellites not tracked (regular expression on the RINEX id)
    antenna: str | None = _owned("patch", check=_antenna)
    frontend_bandwidth_hz: float | None = _owned(4e6, check=_positive)
    excluded_svs: str | None = _owned("", check=_regex)
    #: satellites a signal is not tracked on: per signal ("C6I") a regular expression on the RINEX id (a receiver
    #: configured or built to skip them, e.g. B3I of BeiDou-3; gnss-sim calibrate fits it from a recording)
    excluded_signals: dict | None = _owned({}, check=_signal_regexes)
    #: RINEX header text: {receiver_type, antenna_type} (REC # / TYPE, ANT # / TYPE; outputs.header's defaults
    #: where left out: GNSS_SIM and the antenna pattern's name)
    rinex: dict | None = _owned({}, check=outputs.check_rinex_names)
    #: code multipath/residual model (code_multipath.py): sigma = mp_zenith_m + mp_low_m exp(-el / 15 deg) [m]
    #: (builtin None: the antenna class's open-sky values, code_multipath.OPEN_SKY_MP_M), correlation time [s];
    #: code_multipath_m: per signal ("G1C") {el_deg: [...], sigma_m: [...]} replacing that formula for it
    mp_zenith_m: float | None = _owned(None, check=_nonnegative)
    mp_low_m: float | None = _owned(None, check=_nonnegative)
    mp_tau_s: float | None = _owned(60.0, check=_positive)
    code_multipath_m: dict | None = _owned({}, check=code_multipath.check_table)
    #: true ionosphere = model x (1 + iono_error_frac * g(t)), g smooth, unit variance (world_errors.py), per model.
    #: Klobuchar 0.5: it removes about 50 % of the RMS ionospheric delay (Navipedia, physics-anchors.md).
    #: NeQuick-G 0.3: designed to correct at least 70 % of the delay (Galileo Ionospheric Correction
    #: Algorithm 1.2, 2016, section 1).
    iono_error_frac: dict = field(default_factory=lambda: {"klobuchar": 0.5, "nequick": 0.3})
    #: broadcast orbit + clock error on the line of sight (SISRE) [m] per system (receiver/engine.py module doc)
    sisre_m: dict = field(default_factory=lambda: dict(SISRE_DEFAULT_M))
    #: seed of the world's random errors (ionosphere residual, SISRE): the same for all receivers of one world
    world_seed: int = 0
    #: hardware code biases [m] (core/receiver/hardware_bias.py)
    code_bias_m: dict | None = _owned({}, check=hardware_bias.validate)
    #: C/N0 scatter [dB] (1 sigma, epoch to epoch) at high elevation; it grows towards the horizon as the open-sky
    #: multipath does (code_multipath.CodeMultipath.fading_scale); C/N0 resolution of the receiver's output [dB]
    #: (0: none; a Septentrio SBF record 0.25 dB, u-blox UBX-RXM-RAWX cno 1 dB-Hz)
    cn0_noise_db: float | None = _owned(0.3, check=_nonnegative)
    cn0_resolution_db: float | None = _owned(0.0, check=_nonnegative)
    #: acquisition / loss-of-lock thresholds, ...; None: the profile's mapping of TrackingConfig fields
    tracking: TrackingConfig | None = None
    clock: ClockConfig = field(default_factory=ClockConfig)
    #: None: the profile's mapping of LinkBudget fields
    link_budget: cn0_model.LinkBudget | None = None

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
        prof = profile_file.read(self.profile, type(self))
        for f in fields(self):           # the profile's value, else the builtin, where no argument gave one
            if f.name in profile_file.RUN_FIELDS or not f.init or getattr(self, f.name) is not None:
                continue
            if f.name in _NESTED:
                setattr(self, f.name, _NESTED[f.name](**prof.value(f.name, {})))
            elif "builtin" in f.metadata:
                setattr(self, f.name, prof.value(f.name, copy.deepcopy(f.metadata["builtin"])))
            else:
                setattr(self, f.name, prof.value(f.name))
        for f in fields(self):           # an argument's value checked as a profile's is (profile_file.py)
            check = f.metadata.get("check")
            if check is not None and getattr(self, f.name) is not None:
                try:
                    setattr(self, f.name, check(getattr(self, f.name)))
                except ValueError as exc:
                    said = f"'{f.name}'" in str(exc)
                    raise (exc if said else ValueError(f"receiver: parameter '{f.name}': {exc}")) from None
        self._excluded = re.compile(self.excluded_svs) if self.excluded_svs else None
        self._excluded_signals = {k_: re.compile(rx) for k_, rx in self.excluded_signals.items()}
        if self.link_budget.antenna is None:      # the link budget's gain pattern: the receiver's antenna class
            self.link_budget = dataclasses.replace(self.link_budget, antenna=self.antenna)
        zen, low = code_multipath.OPEN_SKY_MP_M[self.antenna]    # open-sky multipath of the antenna class
        self.mp_zenith_m = zen if self.mp_zenith_m is None else self.mp_zenith_m
        self.mp_low_m = low if self.mp_low_m is None else self.mp_low_m
        self.profile = prof.signal_map()
        if not self.noise:
            self.code_bias_m = {}
            self.clock = ClockConfig(**{**self.clock.__dict__, "noise": False})
            self.tracking = TrackingConfig(**{**self.tracking.__dict__, "random_slips": False})
