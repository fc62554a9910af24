"""The simulated receiver, one epoch at a time: satellites + antenna + visibility -> observables.

Observation equations (per satellite s and signal j, all in metres unless noted;
IS-GPS-200N 20.3.3.3.3, RTKLIB manual E.5):

    P  = rho + c (dt_r - dt_s,j) + S_s + I_j + T + B_j + m_j + e_P    pseudorange
    L  = [rho + c (dt_r - dt_s,j) + S_s - I_j + T + e_L] / lambda_j + N_j   carrier phase [cycles]
    D  = -[rho_dot + c (ddt_r - ddt_s)] / lambda_j + e_D         Doppler [Hz]

- rho: geometric range from the satellite at transmit time (light time
  iterated, Earth rotation during travel) to the antenna at the true
  reception time t_true = t_tag - dt_r (the receiver tags epochs by its own
  clock, like a real one);
- dt_s,j: satellite clock (polynomial + periodic relativistic term
  -2 r.v/c^2, IS-GPS-200N 20.3.3.3.3.1) minus the broadcast group delay of the
  signal (GPS/QZSS TGD scaled by (f_L1/f)^2 on L1/L2, IS-GPS-200N 20.3.3.3.3.2;
  Galileo BGD(E1,E5a) on E1/E5a/E5b, OS SIS ICD 5.1.5; BeiDou TGD1 on B1I,
  BDS-SIS-ICD-B1I 5.2.4.10); inter-signal corrections of L5/E6/B1C/B2a are not
  modelled;
- I_j: ionosphere, scaled to f_j.  The *true* ionosphere is NeQuick-G
  (core/nequick.py) where the navigation header has Galileo's coefficients,
  Klobuchar otherwise (``ionosphere``: auto | nequick | klobuchar | none),
  times a slowly varying factor 1 + ``iono_error_frac`` g(t) (the model's own
  error); a receiver correcting with Klobuchar (``iono_model_m``) thus keeps
  a residual with a real one's size and spatial structure;
  T: troposphere (Saastamoinen + Niell);
- S_s: broadcast orbit and clock error of satellite s projected on the line of
  sight (signal-in-space range error, SISRE; same on every signal, code and
  phase), sigma ``sisre_m`` per system;
- g(t) and S_s(t) belong to the simulated *world*, not to one receiver: they
  are smooth functions of GPS time (sums of sinusoids, periods 20 min to
  12 h, random phases from ``world_seed``), so every receiver of one world
  (a base and a rover) sees the same ionosphere and satellite errors at any
  epoch rate, as in reality; what differs between receivers (multipath,
  thermal noise, clock) comes from ``seed``;
- B_j: the receiver's hardware code delay of signal j (inter-system,
  BeiDou-2/-3 and inter-frequency biases, core/receiver/hardware_bias.py);
- m_j: code multipath/residual as a first-order Gauss-Markov process per
  signal, sigma = mp_zenith_m + mp_low_m exp(-el/15 deg) (a stated approximation);
- e: thermal noise from C/N0 (DLL, PLL, FLL jitter, core/receiver/noise.py);
- N_j: an integer ambiguity per continuous track (core/receiver/tracking.py).
"""
from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field

import numpy as np

from .. import constants as k
from .. import propagation as prop
from .. import signals as sig
from ..ephemeris.states import SatelliteStates
from ..frames import az_el_at, ecef_to_geodetic
from ..multipath.antenna import PATTERNS
from ..nequick import NeQuickG
from ..nequick import available as nequick_available
from ..time import GnssTime
from ..vocabulary import IONOSPHERE_MODELS, TRANSMIT_TIME_MODES, TROPOSPHERE_MODELS, VisibilityState
from . import cn0 as cn0_model
from . import hardware_bias
from . import noise as noise_model
from .clock import ClockConfig, ReceiverClock
from .tracking import Tracker, TrackingConfig

#: visibility states (gnss_sim_msgs/SatelliteVisibility)
VISIBLE, BLOCKED, ATTENUATED, REFLECTED_ONLY = (VisibilityState.VISIBLE, VisibilityState.BLOCKED,
                                                VisibilityState.ATTENUATED, VisibilityState.REFLECTED_ONLY)
#: the same as plain ints (an array compared with an IntEnum member costs microseconds more)
_VISIBLE_I, _ATTENUATED_I = int(VISIBLE), int(ATTENUATED)


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
    #: code multipath/residual model (see module doc) [m], correlation time [s]; checked on OPEC 2022-001:
    #: the scatter of each satellite's code residual about its own mean is 0.47-0.69 m RMS per system for the
    #: real NETR9 and 0.65 m for these values with the DLL noise below (test_receiver_acceptance), so kept
    mp_zenith_m: float = 0.15
    mp_low_m: float = 1.2
    mp_tau_s: float = 60.0
    #: true ionosphere = model x (1 + iono_error_frac * g(t)), g smooth, unit variance (module doc), per model.
    #: Klobuchar 0.5: it removes about 50 % of the RMS ionospheric delay (Navipedia, physics-anchors.md).
    #: NeQuick-G 0.3: designed to correct at least 70 % of the delay (Galileo Ionospheric Correction
    #: Algorithm 1.2, 2016, section 1).
    iono_error_frac: dict = field(default_factory=lambda: {"klobuchar": 0.5, "nequick": 0.3})
    #: broadcast orbit + clock error on the line of sight (SISRE) [m] per system (module doc)
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


@dataclass
class EpochObservations:
    """Everything the receiver produced at one epoch (rows = signals, sat_* rows = satellites)."""

    t: GnssTime                   # epoch tag (receiver time = GPS time + clock bias)
    clock_bias_s: float           # receiver clock offset dt_r
    clock_drift_sps: float
    # satellites above the horizon
    sat_sv: np.ndarray
    sat_az_deg: np.ndarray
    sat_el_deg: np.ndarray
    sat_vis_state: np.ndarray
    sat_attenuation_db: np.ndarray
    # signals (tracked ones only)
    sv: np.ndarray
    code: np.ndarray              # RINEX band+attribute, "1C"
    frequency_hz: np.ndarray
    pseudorange_m: np.ndarray
    carrier_phase_cyc: np.ndarray
    doppler_hz: np.ndarray
    cn0_dbhz: np.ndarray
    lli: np.ndarray
    lock_time_s: np.ndarray
    # what a receiver needs for its own solution, per signal row
    sat_pos_ecef_m: np.ndarray    # at transmit time, in the ECEF frame of reception
    sat_vel_ecef_mps: np.ndarray
    sat_clock_s: np.ndarray       # dt_s,j (incl. relativistic, group delay) as the broadcast gives it
    sat_clock_drift_sps: np.ndarray
    iono_model_m: np.ndarray      # the broadcast model's delay for this signal (what a receiver would remove)
    tropo_model_m: np.ndarray
    el_deg: np.ndarray
    true_range_m: np.ndarray

    @property
    def n_tracked_sats(self) -> int:
        return len(set(np.asarray(self.sv).tolist()))


class Receiver:
    """A receiver tracking the satellites of one ephemeris provider from a moving antenna."""

    def __init__(self, config: ReceiverConfig, provider=None, iono_coeffs: dict | None = None):
        self.cfg = config
        self.provider = provider
        self._nequick = None
        rng = np.random.default_rng(config.seed)
        self.rng_noise = np.random.default_rng(rng.integers(2**63))
        self.clock = ReceiverClock(config.clock, np.random.default_rng(rng.integers(2**63)))
        self.tracker = Tracker(config.tracking, np.random.default_rng(rng.integers(2**63)))
        self._mp_rng = np.random.default_rng(rng.integers(2**63))
        self.set_iono_coefficients(iono_coeffs)
        self._t_prev: GnssTime | None = None
        #: multipath state per (sv, code): slot in _mp_x (NaN until the key is first seen)
        self._mp_index: dict[tuple[str, str], int] = {}
        self._mp_x = np.full(256, np.nan)
        self._world_terms: dict = {}
        self._geo_key = None
        self._geo = (0.0, 0.0, 0.0)
        self._signal_cache: dict = {}
        self._keep_cache: dict = {}
        self._iono_terms = None
        self._doy_key = None
        self._doy0 = 0.0

    def set_iono_coefficients(self, iono: dict | None) -> None:
        """Take the navigation header's ionosphere coefficients ({"GPSA": [4], "GPSB": [4], "GAL": [3]}, or
        None before any are known) and choose the true ionosphere's model (ReceiverConfig.ionosphere)."""
        self.iono_alpha, self.iono_beta = _klobuchar_coeffs(iono)
        #: the true ionosphere's model: "nequick", "klobuchar" or "none"; NeQuick-G only where used
        self.iono_truth = _truth_model(self.cfg.ionosphere, iono)
        gal = tuple(iono["GAL"][:3]) if self.iono_truth == "nequick" else None
        if gal is None:
            self._nequick = None
        elif self._nequick is None or self._nequick.coefficients != gal:
            self._nequick = NeQuickG(gal)

    # ------------------------------------------------------------------
    def _rows_of(self, svs: np.ndarray, glo_channel: np.ndarray) -> _SignalRows:
        key = (_array_key(svs), _array_key(glo_channel))
        hit = self._signal_cache.get(key)
        if hit is not None:
            return hit
        sat_i, codes, freq, chip, systems = [], [], [], [], []
        for i, sv in enumerate(svs):
            s = sv[0]
            for code in self.cfg.profile.get(s, []):
                sat_i.append(i)
                codes.append(code)
                systems.append(s)
                freq.append(sig.frequency_hz(s, code, int(glo_channel[i]) if s == "R" else 0))
                chip.append(sig.signal(s, code).chip_length_m)
        rows = _SignalRows()
        rows.signal_rows = (np.array(sat_i, dtype=np.int64), np.array(codes, dtype="<U2"), np.array(freq, dtype=float),
                            np.array(chip, dtype=float), np.array(systems, dtype="<U1"))
        sat_i, codes, freq, chip, systems = rows.signal_rows
        rows.lam = k.C_MPS / freq
        rows.gd_factor = sig.group_delay_factor(systems, codes, freq)
        rows.p_min, rows.el_min = cn0_model.power_params(systems, codes) if len(codes) else (np.zeros(0), np.zeros(0))
        rows.omega = np.array([k.OMEGA_BY_SYSTEM.get(s[0], k.OMEGA_E_GPS_RADPS) for s in svs], dtype=float)
        rows.sv_j = np.asarray(svs)[sat_i]
        rows.code_bias_m = hardware_bias.code_bias_m(self.cfg.code_bias_m, rows.sv_j, codes)
        rows.sisre_sigma = np.array([self.cfg.sisre_m.get(sv[0], 0.0) for sv in svs], dtype=float)
        rows.sisre_terms = self._stacked_terms([("sat", str(sv)) for sv in svs]) if len(svs) else None
        # multipath states: one slot per (sv, code), kept for the receiver's lifetime
        mp_idx = np.empty(len(sat_i), dtype=np.int64)
        for j, mp_key in enumerate(zip(rows.sv_j.tolist(), codes.tolist())):
            i = self._mp_index.get(mp_key)
            if i is None:
                i = self._mp_index[mp_key] = len(self._mp_index)
            mp_idx[j] = i
        rows.mp_idx = mp_idx
        if len(self._mp_index) > self._mp_x.size:
            grown = np.full(max(2 * self._mp_x.size, len(self._mp_index)), np.nan)
            grown[: self._mp_x.size] = self._mp_x
            self._mp_x = grown
        if len(self._signal_cache) > 64:
            self._signal_cache.clear()
        self._signal_cache[key] = rows
        return rows

    def _keep_mask(self, sv_all: np.ndarray) -> np.ndarray:
        """Rows of the states whose system is received (configured systems with a profile); cached."""
        key = _array_key(sv_all)
        hit = self._keep_cache.get(key)
        if hit is None:
            cfg = self.cfg
            ex = cfg._excluded
            hit = np.array([sv[0] in cfg.systems and sv[0] in cfg.profile and not (ex and ex.fullmatch(sv))
                            for sv in sv_all.tolist()], dtype=bool)
            if len(self._keep_cache) > 64:
                self._keep_cache.clear()
            self._keep_cache[key] = hit
        return hit

    def _geodetic(self, rx: np.ndarray):
        key = (rx[0], rx[1], rx[2])
        if self._geo_key != key:    # geodetic antenna position: computed again only when it moves
            self._geo_key, self._geo = key, ecef_to_geodetic(*rx)
        return self._geo

    def epoch(self, t: GnssTime, antenna_ecef_m, states: SatelliteStates, vis_state=None, attenuation_db=None,
              antenna_vel_ecef_mps=None, multipath=None) -> EpochObservations:
        """Observables at epoch tag ``t`` (GPS time on the receiver's clock).

        ``states``: satellites at ``t`` (rows); ``vis_state``/``attenuation_db``: per row
        (None: all visible); ``antenna_ecef_m``: (3,) antenna phase centre; ``multipath``: reflected paths
        per row (multipath.reflections.ScenePaths of arrays (N, K)) or None.  One epoch of :meth:`epochs`.
        """
        vel = None if antenna_vel_ecef_mps is None else [antenna_vel_ecef_mps]
        return self.epochs([t], [antenna_ecef_m], states, np.zeros(len(states), dtype=np.int64), vis_state,
                           attenuation_db, vel, [multipath])[0]

    def epochs(self, ts, antenna_ecef_m, states: SatelliteStates, epoch_of_row, vis_state=None,
               attenuation_db=None, antenna_vel_ecef_mps=None, multipath=None) -> list[EpochObservations]:
        """Observables of K consecutive epochs at once (offline, where the inputs of a block are known).

        ``ts``: K epoch tags (scalar GnssTime each, increasing); ``antenna_ecef_m``: (K, 3);
        ``states``: the satellites of all K epochs, rows epoch by epoch, ``epoch_of_row`` (rows,) the
        epoch of each row (non-decreasing); ``vis_state``/``attenuation_db``: per row or None;
        ``antenna_vel_ecef_mps``: (K, 3) or None (zero), a None row is zero; ``multipath``: K reflected
        path sets (each for the rows of its epoch) or None.

        What has no memory -- light time, satellite clocks, atmosphere, world errors, C/N0 -- is computed
        for every row of the block in one go; the receiver clock, the tracking loops and the noise
        processes step epoch by epoch in order, drawing from their random streams exactly as
        :meth:`epoch` called K times does, so the observables are the same.
        """
        cfg = self.cfg
        k_n = len(ts)
        rx_ep = np.asarray(antenna_ecef_m, dtype=float).reshape(k_n, 3)
        vel_ep = np.zeros((k_n, 3))
        if antenna_vel_ecef_mps is not None:
            for b, v in enumerate(antenna_vel_ecef_mps):
                if v is not None:
                    vel_ep[b] = v
        # receiver clock, epoch by epoch (its own random stream)
        bias_ep, drift_ep, dt_ep = np.empty(k_n), np.empty(k_n), np.empty(k_n)
        for b, t in enumerate(ts):
            dt_s = 0.0 if self._t_prev is None else float(t - self._t_prev)
            if dt_s > 0:
                bias_ep[b], drift_ep[b], _ = self.clock.step(dt_s)
            else:
                bias_ep[b], drift_ep[b] = self.clock.bias_s, self.clock.steered_drift_sps
            dt_ep[b] = dt_s
            self._t_prev = t
        if k_n == 1:      # one epoch (a node)
            t_true = ts[0] - bias_ep[0]
        else:
            t_true = GnssTime(np.array([np.asarray(t.sec) for t in ts], dtype=np.int64),
                              np.array([np.asarray(t.frac) for t in ts], dtype=float)) - bias_ep
        # the antenna's geodetic position epoch by epoch (cached while it stands still), then every row's
        # geometry with the same array arithmetic whatever the block size: a block gives the epochs' values
        lat_ep, lon_ep, h_ep = np.array([self._geodetic(p) for p in rx_ep], dtype=float).T

        e_all = np.asarray(epoch_of_row, dtype=np.int64)
        n_all = len(states)
        vis = np.zeros(n_all, dtype=np.int64) if vis_state is None else np.asarray(vis_state, dtype=np.int64)
        att = np.zeros(n_all) if attenuation_db is None else np.asarray(attenuation_db, dtype=float)
        az, el, _ = az_el_at(rx_ep[e_all], lat_ep[e_all], lon_ep[e_all], states.pos_ecef_m)
        keep = self._keep_mask(np.asarray(states.sv)) & (el > 0.0)
        seg_all = np.searchsorted(e_all, np.arange(k_n + 1))
        kidx = np.flatnonzero(keep)
        st = states.select(kidx)
        az, el, vis, att, e_sat = az[kidx], el[kidx], vis[kidx], att[kidx], e_all[kidx]
        svs, glo = np.asarray(st.sv), np.asarray(st.glo_channel)
        seg = np.searchsorted(e_sat, np.arange(k_n + 1))

        # signal rows of every epoch (cached per satellite set), stacked
        parts = [self._rows_of(svs[seg[b]:seg[b + 1]], glo[seg[b]:seg[b + 1]]) for b in range(k_n)]
        rows = parts[0] if k_n == 1 else _SignalRows.stack(parts, seg[:-1])
        sat_i, codes, freq, chip, systems = rows.signal_rows
        m_ep = np.array([len(p.signal_rows[0]) for p in parts], dtype=np.int64)
        sig_seg = np.concatenate([[0], np.cumsum(m_ep)])
        m = len(sat_i)
        out = []
        if m == 0:
            for b in range(k_n):
                s = slice(seg[b], seg[b + 1])
                out.append(self._empty(ts[b], bias_ep[b], drift_ep[b], svs[s], az[s], el[s], vis[s], att[s]))
            return out
        e_sig = e_sat[sat_i]
        bias_sat = bias_ep[0] if k_n == 1 else bias_ep[e_sat]
        t_true_sat = t_true if k_n == 1 else t_true[e_sat]

        # geometry at the transmit time, seen at the true reception time
        sol = self._light_time(rx_ep[e_sat], vel_ep[e_sat], t_true_sat, bias_sat, st, rows.omega)
        lam = rows.lam
        rho = sol.range_m[sat_i]
        rho_dot = sol.range_rate_mps[sat_i]
        el_j = el[sat_i]

        # satellite clock at transmit time (SP3 convention polynomial + relativistic - group delay)
        tau = sol.tau_s
        clk_poly = st.clock_bias_s - st.clock_drift_sps * (bias_sat + tau)
        rel = -2.0 * np.einsum("ij,ij->i", sol.sat_pos_ecef_m, sol.sat_vel_ecef_mps) / k.C_MPS**2
        dts = (clk_poly + rel)[sat_i] - rows.gd_factor * st.tgd_s[sat_i]
        ddts = st.clock_drift_sps[sat_i]

        # atmosphere (per satellite; the ionosphere scaled to each signal's frequency)
        lat, lon = lat_ep[e_sat], lon_ep[e_sat]
        if self.iono_truth != "none":
            l1_delay = prop.klobuchar_l1_delay_s(t_true_sat, lat, lon, az, el, self.iono_alpha, self.iono_beta)
            iono_model = prop.iono_code_delay_m(l1_delay[sat_i], freq)
            if self._nequick is not None:
                l1_true = np.empty(len(svs))
                for b in range(k_n):
                    s = slice(seg[b], seg[b + 1])
                    t_b = t_true if k_n == 1 else t_true[b]
                    l1_true[s] = self._nequick.l1_delay_s(t_b.to_datetime("UTC"), lat_ep[b], lon_ep[b], az[s], el[s])
                iono_base = prop.iono_code_delay_m(l1_true[sat_i], freq)
            else:
                iono_base = iono_model
        else:
            iono_model = iono_base = np.zeros(m)
        if cfg.troposphere == "saastamoinen":
            doy = np.array([self._day_of_year(t) for t in ts])
            # the zenith delays and mapping coefficients per epoch, the mapping per satellite
            tropo = prop.tropo_slant_delay_m(np.maximum(el, 1.0), lat_ep, h_ep, doy, epoch_of_row=e_sat)[sat_i]
        else:
            tropo = np.zeros(m)
        frac = cfg.iono_error_frac.get(self.iono_truth, 0.0)
        if cfg.noise and frac != 0:
            if self._iono_terms is None:
                self._iono_terms = self._stacked_terms([("iono",)])
            g_iono = self._world_process_terms(t_true, self._iono_terms)
            iono_true = iono_base * (1.0 + frac * (g_iono[0] if k_n == 1 else g_iono[e_sig]))
        else:
            iono_true = iono_base

        # signal strength; tracking and the noise processes epoch by epoch, in order
        cn0 = cn0_model.cn0_dbhz_from_params(rows.p_min, rows.el_min, rho, el_j, att[sat_i], budget=cfg.link_budget)
        vis_j = vis[sat_i]
        att_j = att[sat_i]
        line_ok = (vis_j == _VISIBLE_I) | (vis_j == _ATTENUATED_I)
        above = el_j >= cfg.elevation_mask_deg
        sv_j = rows.sv_j
        draw_cn0 = cfg.noise and cfg.cn0_noise_db > 0
        mp_code, mp_phase = np.zeros(m), np.zeros(m)
        ok_all = line_ok
        empty = sig_seg[1:] == sig_seg[:-1]
        # the scene's reflected paths, epoch by epoch (no memory, no random draw)
        for b in (range(k_n) if multipath is not None else ()):
            j0, j1 = sig_seg[b], sig_seg[b + 1]
            paths = multipath[b]
            if j0 == j1 or paths is None or not paths.valid.any():
                continue
            s = slice(j0, j1)
            paths = paths.take(keep[seg_all[b]:seg_all[b + 1]])
            loc = sat_i[s] - seg[b]
            mp_err = self._scene_multipath(paths, loc, vis_j[s], att_j[s], el_j[s], chip[s], lam[s])
            if mp_err is not None:
                rows_mp, err = mp_err
                # composite amplitude relative to the unobstructed line of sight replaces the obstruction loss
                cn0[j0 + rows_mp] += att_j[j0 + rows_mp] + 20.0 * np.log10(np.maximum(err.amplitude, 1e-6))
                mp_code[j0 + rows_mp] = err.code_m
                mp_phase[j0 + rows_mp] = err.phase_m
                # no line of sight, a reflected path: tracked if strong enough (thresholds with hysteresis,
                # tracking.py); REFLECTED_ONLY without the paths (a caller with only the state) stays untracked
                nlos_rows = j0 + rows_mp[err.nlos]
                if ok_all is line_ok:
                    ok_all = line_ok.copy()
                ok_all[nlos_rows] |= vis_j[nlos_rows] == REFLECTED_ONLY
        # the tracking loops, epoch by epoch in order (Tracker.update_many)
        tracked, lli, lock, amb = self.tracker.update_many(ts, sv_j, codes, cn0, ok_all & above, sig_seg)
        # the noise processes' draws, epoch after epoch as K calls of one epoch make them (the same streams:
        # a Generator's draws of n and then m values are its n + m values): per epoch C/N0 noise, then code,
        # phase and Doppler noise from rng_noise; the code multipath's innovations from _mp_rng
        z_cn0 = np.zeros(m)
        r = np.zeros((3, m))
        mp_x = np.zeros(m)
        if cfg.noise:
            lead = 1 if draw_cn0 else 0
            j0_row = sig_seg[e_sig]
            mb_row = m_ep[e_sig]
            base = (3 + lead) * j0_row + (np.arange(m) - j0_row)
            w = self.rng_noise.standard_normal((3 + lead) * m)
            if draw_cn0:
                z_cn0 = w[base]
            for i in range(3):
                r[i] = w[base + (lead + i) * mb_row]
            w_mp = self._mp_rng.standard_normal(m)
            for b in np.flatnonzero(~empty).tolist():
                s = slice(sig_seg[b], sig_seg[b + 1])
                mp_x[s] = self._multipath_state(rows.mp_idx[s], dt_ep[b], w_mp[s])

        # noise
        cn0_meas = cn0 + cfg.cn0_noise_db * z_cn0 if draw_cn0 else cn0
        if cfg.noise:
            code_sig = noise_model.dll_sigma_m(cn0, chip, cfg.dll_bn_hz, cfg.dll_spacing_chips)
            ph_sig = noise_model.pll_sigma_m(cn0, lam)
            dop_sig = noise_model.doppler_sigma_hz(cn0)
            e_p, e_l, e_d = code_sig * r[0], ph_sig * r[1], dop_sig * r[2]
            mp = self._multipath_sigma(el_j) * mp_x
        else:
            e_p = e_l = e_d = mp = np.zeros(m)

        bias_j = bias_ep[0] if k_n == 1 else bias_ep[e_sig]
        common = rho + k.C_MPS * (bias_j - dts) + tropo
        if cfg.noise:
            common = common + (rows.sisre_sigma * self._world_process_terms(t_true_sat, rows.sisre_terms))[sat_i]
        pr = common + iono_true + rows.code_bias_m + mp + e_p + mp_code
        phase_m = common - iono_true + e_l + mp_phase
        phase = phase_m / lam + amb
        drift_j = drift_ep[0] if k_n == 1 else drift_ep[e_sig]
        dop = -(rho_dot + k.C_MPS * (drift_j - ddts)) / lam + e_d

        # the tracked signals of the block taken at once; epoch b's are the rows cut[b]:cut[b + 1] of those
        sel = np.flatnonzero(tracked)
        cut = np.searchsorted(sel, sig_seg).tolist()
        sat_tr = sat_i[sel]
        (t_sv, t_code, t_freq, t_pr, t_phase, t_dop, t_cn0, t_lli, t_lock, t_dts, t_ddts, t_iono, t_tropo, t_el,
         t_rho) = (x[sel] for x in (sv_j, codes, freq, pr, phase, dop, cn0_meas, lli, lock, dts, ddts, iono_model,
                                     tropo, el_j, rho))
        t_pos, t_vel = sol.sat_pos_ecef_m[sat_tr], sol.sat_vel_ecef_mps[sat_tr]
        for b in range(k_n):
            s = slice(seg[b], seg[b + 1])
            if empty[b]:
                out.append(self._observation(ts[b], bias_ep[b], drift_ep[b], svs[s], az[s], el[s], vis[s], att[s]))
                continue
            r = slice(cut[b], cut[b + 1])
            out.append(EpochObservations(
                t=ts[b], clock_bias_s=bias_ep[b], clock_drift_sps=drift_ep[b],
                sat_sv=svs[s], sat_az_deg=az[s], sat_el_deg=el[s], sat_vis_state=vis[s], sat_attenuation_db=att[s],
                sv=t_sv[r], code=t_code[r], frequency_hz=t_freq[r], pseudorange_m=t_pr[r], carrier_phase_cyc=t_phase[r],
                doppler_hz=t_dop[r], cn0_dbhz=t_cn0[r], lli=t_lli[r], lock_time_s=t_lock[r], sat_pos_ecef_m=t_pos[r],
                sat_vel_ecef_mps=t_vel[r], sat_clock_s=t_dts[r], sat_clock_drift_sps=t_ddts[r], iono_model_m=t_iono[r],
                tropo_model_m=t_tropo[r], el_deg=t_el[r], true_range_m=t_rho[r],
            ))
        return out

    def _scene_multipath(self, paths, sat_i, vis_j, att_j, el_j, chip, lam):
        """(signal rows with reflected paths, multipath.composite.CompositeErrors) or None (none this epoch)."""
        from ..multipath.composite import composite_errors  # scipy.special: imported with multipath on only

        cfg = self.cfg
        has = paths.valid.any(axis=1)[sat_i]
        rows_mp = np.flatnonzero(has)
        if len(rows_mp) == 0:
            return None
        si = sat_i[rows_mp]
        los = np.where((vis_j[rows_mp] == BLOCKED) | (vis_j[rows_mp] == REFLECTED_ONLY), 0.0,
                       10.0 ** (-att_j[rows_mp] / 20.0))
        # front-end bandwidth in chip rates per signal (C/A 1.023 Mchip/s, B1I 2.046, ...): grouped by value
        bw_chips = cfg.frontend_bandwidth_hz * chip[rows_mp] / k.C_MPS
        out = None
        for bw in np.unique(bw_chips):
            g = np.flatnonzero(bw_chips == bw)
            e = composite_errors(los[g], paths.excess_m[si[g]], paths.gamma_co[si[g]], paths.gamma_cross[si[g]],
                                 paths.arrival_el_deg[si[g]], el_j[rows_mp[g]], chip[rows_mp[g]], lam[rows_mp[g]],
                                 cfg.dll_spacing_chips, float(bw), cfg.antenna)
            if out is None:
                out = type(e)(*(np.empty(len(rows_mp), dtype=np.asarray(v).dtype) for v in e.__dict__.values()))
            for name, v in e.__dict__.items():
                getattr(out, name)[g] = v
        return rows_mp, out

    def _day_of_year(self, t: GnssTime) -> float:
        """prop.day_of_year(t), from a cached value at the start of t's GPS day (no datetime per epoch)."""
        sec = int(np.asarray(t.sec))
        day0 = sec - sec % 86400
        if self._doy_key != day0:
            self._doy_key, self._doy0 = day0, prop.day_of_year(GnssTime(day0, 0.0))
        return self._doy0 + ((sec - day0) + float(np.asarray(t.frac))) / 86400.0

    # ------------------------------------------------------------------
    def _light_time(self, rx, rx_vel, t_true, bias, st, omega):
        """Light-time solution of the rows of ``st``; ``rx``, ``rx_vel``: (3,) or per row (N, 3); ``t_true``,
        ``bias``: scalar or per row."""
        cfg = self.cfg
        bias = np.asarray(bias, dtype=float)[..., None]
        # the satellites' states at the epoch tag moved back to the true reception time (second order)
        pos = st.pos_ecef_m - st.vel_ecef_mps * bias + 0.5 * st.acc_ecef_mps2 * bias**2
        if cfg.transmit_time == "recompute" and self.provider is not None:
            svs = list(st.sv)

            def at(t_tx):
                s = self.provider.states_at(svs, t_tx)
                if len(s) != len(svs):
                    raise _NoState
                return s.pos_ecef_m, s.vel_ecef_mps, s.acc_ecef_mps2

            # one ephemeris evaluation near the transmit time, light time iterated on its Taylor series
            # (propagation.transmit_time_refined; the same solution as re-evaluating at every iteration)
            tau_guess = np.sqrt(np.einsum("ij,ij->i", pos - rx, pos - rx)) / k.C_MPS
            try:
                return prop.transmit_time_refined(rx, t_true, at, tau_guess, rx_vel, omega)
            except _NoState:
                pass
        vel = st.vel_ecef_mps - st.acc_ecef_mps2 * bias
        return prop.transmit_time_from_states(rx, pos, vel, st.acc_ecef_mps2, t_true, cfg.light_time_iterations,
                                              rx_vel, omega)

    def _stacked_terms(self, keys):
        """(periods (K, 6) int, phases (K, 6)) of the world processes of ``keys`` (see _world_process_terms)."""
        per, pha = [], []
        for key in keys:
            terms = self._world_terms.get(key)
            if terms is None:
                lo, hi = WORLD_PERIODS_S["iono" if key[0] == "iono" else "sat"]
                words = [int(self.cfg.world_seed)] + [int.from_bytes(str(x).encode(), "big") for x in key]
                g = np.random.default_rng(words)
                terms = (np.round(np.exp(g.uniform(np.log(lo), np.log(hi), WORLD_TERMS))).astype(np.int64),
                         g.uniform(0.0, 2.0 * np.pi, WORLD_TERMS))
                self._world_terms[key] = terms
            per.append(terms[0])
            pha.append(terms[1])
        return np.array(per), np.array(pha)

    def _world_process_terms(self, t: GnssTime, terms) -> np.ndarray:
        """Smooth zero-mean unit-variance processes of GPS time, one per row of ``terms`` (_stacked_terms),
        from ``world_seed`` only; ``t`` scalar (every row at t) or (K,) (row k at t[k]; ``terms`` of one row
        serve every t).

        x(t) = sqrt(2/K) sum_k sin(2 pi t / P_k + phi_k), K = 6 terms, integer periods
        P_k log-uniform in the key's band, phases uniform: the same values at any
        epoch rate and for every receiver with the same ``world_seed``.
        """
        sec = np.asarray(t.sec, dtype=np.int64)[..., None]      # t scalar: (1,); t (K,): (K, 1), one per row
        frac = np.asarray(t.frac, dtype=np.float64)[..., None]
        per, pha = terms
        arg = 2.0 * np.pi * ((sec % per) + frac) / per + pha
        return np.sqrt(2.0 / WORLD_TERMS) * np.sin(arg).sum(axis=-1)

    def _multipath(self, sv_j, codes, el_j, dt_s):
        """Code multipath/residual [m] of signals (sv_j, codes) (module doc), first-order Gauss-Markov."""
        idx = np.empty(len(sv_j), dtype=np.int64)
        for j, mp_key in enumerate(zip(np.asarray(sv_j).tolist(), np.asarray(codes).tolist())):
            i = self._mp_index.get(mp_key)
            if i is None:
                i = self._mp_index[mp_key] = len(self._mp_index)
            idx[j] = i
        if len(self._mp_index) > self._mp_x.size:
            grown = np.full(max(2 * self._mp_x.size, len(self._mp_index)), np.nan)
            grown[: self._mp_x.size] = self._mp_x
            self._mp_x = grown
        return self._multipath_rows(idx, el_j, dt_s)

    def _multipath_rows(self, idx, el_j, dt_s):
        return self._multipath_sigma(el_j) * self._multipath_state(idx, dt_s)

    def _multipath_sigma(self, el_j):
        cfg = self.cfg
        return cfg.mp_zenith_m + cfg.mp_low_m * np.exp(-np.maximum(el_j, 0.0) / 15.0)

    def _multipath_state(self, idx, dt_s, w=None):
        """Unit-variance Gauss-Markov states of the slots ``idx`` advanced by ``dt_s`` (one draw each: ``w``, or
        drawn now)."""
        phi = np.exp(-dt_s / self.cfg.mp_tau_s) if dt_s > 0 else 0.0
        if w is None:
            w = self._mp_rng.standard_normal(len(idx))
        prev = self._mp_x[idx]
        x = np.where(np.isnan(prev), w, phi * prev + np.sqrt(1 - phi * phi) * w)
        self._mp_x[idx] = x
        return x

    def _empty(self, t, bias, drift, svs, az, el, vis, att):
        # nothing observed this epoch: every track the tracker holds loses lock
        self.tracker.update(t, np.zeros(0, dtype="<U3"), np.zeros(0, dtype="<U2"), np.zeros(0))
        return self._observation(t, bias, drift, svs, az, el, vis, att)

    @staticmethod
    def _observation(t, bias, drift, svs, az, el, vis, att):
        """An epoch without any signal tracked (satellites above the horizon listed)."""
        z = np.zeros(0)
        return EpochObservations(t, bias, drift, svs, az, el, vis, att, np.zeros(0, "<U3"), np.zeros(0, "<U2"),
                                 z, z, z, z, z, np.zeros(0, np.int8), z, np.zeros((0, 3)), np.zeros((0, 3)), z, z, z,
                                 z, z, z)


#: Klobuchar coefficients used when a navigation file carries none: the GPS broadcast of
#: 2022-01-01 (OPEC00NOR_S_20220010000_01D_GN.rnx header, IONOSPHERIC CORR GPSA/GPSB)
KLOBUCHAR_FALLBACK_ALPHA = np.array([1.2107e-08, -7.4506e-09, -5.9605e-08, 1.1921e-07])
KLOBUCHAR_FALLBACK_BETA = np.array([1.1674e05, -2.4576e05, -6.5536e04, 1.1141e06])


#: period bands [s] of the world's smooth error processes: ionosphere residual 20 min to 4 h
#: (travelling disturbances to diurnal shape errors), satellite orbit/clock error 2 h to 12 h
#: (clock wander to the once-per-revolution orbit error of MEO satellites)
WORLD_PERIODS_S = {"iono": (1200.0, 14400.0), "sat": (7200.0, 43200.0)}
WORLD_TERMS = 6


class _NoState(Exception):
    pass


class _SignalRows:
    """What the receiver derives once per set of satellites (Receiver._rows_of)."""

    signal_rows: tuple          # (sat_i, codes, freq, chip, systems)
    lam: np.ndarray
    gd_factor: np.ndarray
    p_min: np.ndarray
    el_min: np.ndarray
    omega: np.ndarray
    sv_j: np.ndarray
    code_bias_m: np.ndarray
    sisre_sigma: np.ndarray
    sisre_terms: tuple | None
    mp_idx: np.ndarray

    @staticmethod
    def stack(parts: list, sat_offset) -> _SignalRows:
        """The rows of several epochs one after another; ``sat_offset``: the first satellite row of each
        epoch in the stacked states (signal_rows[0] then indexes those)."""
        out = _SignalRows()
        cols = list(zip(*(p.signal_rows for p in parts)))
        out.signal_rows = (np.concatenate([c + o for c, o in zip(cols[0], sat_offset)]),
                           *(np.concatenate(c) for c in cols[1:]))
        for name in ("lam", "gd_factor", "p_min", "el_min", "omega", "sv_j", "code_bias_m", "sisre_sigma",
                     "mp_idx"):
            setattr(out, name, np.concatenate([getattr(p, name) for p in parts]))
        terms = [p.sisre_terms for p in parts if p.sisre_terms is not None]
        out.sisre_terms = (np.concatenate([x[0] for x in terms]), np.concatenate([x[1] for x in terms])) \
            if terms else None
        return out


def _array_key(a) -> tuple:
    """Hashable key of an array's contents (dtype, shape, bytes)."""
    a = np.ascontiguousarray(a)
    return (a.dtype.str, a.shape, a.tobytes())


def _truth_model(setting: str, iono: dict | None) -> str:
    """The true ionosphere's model for ``setting`` (ReceiverConfig.ionosphere) and the header's coefficients.

    "auto": NeQuick-G where the Galileo coefficients are given and the library is installed, Klobuchar
    otherwise (a warning names the missing library).  "nequick" without coefficients: Klobuchar while none
    are known (``iono`` None: a node before its first message), an error when a header lacks them.
    """
    has_gal = bool(iono) and iono.get("GAL") is not None and len(iono["GAL"]) >= 3 and any(iono["GAL"][:3])
    if setting == "auto":
        if has_gal and not nequick_available():
            warnings.warn("receiver: the 'nequick' package is not installed; the true ionosphere falls back to "
                          "Klobuchar (pip install --no-deps nequick, see requirements/no-deps.txt)", stacklevel=3)
            return "klobuchar"
        return "nequick" if has_gal else "klobuchar"
    if setting == "nequick" and not has_gal:
        if iono is None:
            return "klobuchar"
        raise ValueError("receiver: parameter 'ionosphere' = 'nequick' needs the Galileo coefficients (GAL "
                         "IONOSPHERIC CORR) in the navigation header; none were given")
    return setting


def _klobuchar_coeffs(iono: dict | None):
    """GPS alpha/beta from a navigation header dict ({"GPSA": [...], "GPSB": [...]}); typical values otherwise."""
    if iono:
        a = iono.get("GPSA") or iono.get("alpha")
        b = iono.get("GPSB") or iono.get("beta")
        if a is not None and b is not None and len(a) == 4 and len(b) == 4:
            return np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return KLOBUCHAR_FALLBACK_ALPHA, KLOBUCHAR_FALLBACK_BETA
