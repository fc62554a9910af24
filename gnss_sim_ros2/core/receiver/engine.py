"""The simulated receiver (``Receiver``): satellites + antenna + visibility -> observables, one epoch or a
block of epochs at a time (``Receiver.epochs``, in named stages: antenna, receiver clock, satellites above
the horizon, signals, geometry, satellite clocks, atmosphere, world errors, signal strength, scene
reflections, the land-mobile-satellite layer (lms_channel.py, with ``lms_environment`` on), tracking, receiver
errors, observables, assemble).  Its configuration is config.py
(``ReceiverConfig``), its product observations.py (``EpochObservations``).

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
  Klobuchar otherwise (``ionosphere``: auto | nequick | klobuchar | none; the choice in
  core/receiver/ionosphere.py),
  times a slowly varying factor 1 + ``iono_error_frac`` g(t) (the model's own
  error); a receiver correcting with Klobuchar (``iono_model_m``) thus keeps
  a residual with a real one's size and spatial structure;
  T: troposphere, the receiver's model (Saastamoinen with a standard atmosphere, Niell mapping;
  ``tropo_model_m``) with the true zenith wet delay off the model's by 5 cm x w(t) (world_errors.py);
- S_s: broadcast orbit and clock error of satellite s projected on the line of
  sight (signal-in-space range error, SISRE; same on every signal, code and
  phase), sigma ``sisre_m`` per system;
- g(t), w(t) and S_s(t) belong to the simulated *world* (world_errors.py), not to one receiver: they
  are smooth functions of GPS time (sums of sinusoids, periods 2 h to
  24 h, random phases from ``world_seed``), so every receiver of one world
  (a base and a rover) sees the same ionosphere and satellite errors at any
  epoch rate, as in reality; what differs between receivers (multipath,
  thermal noise, clock) comes from ``seed``;
- B_j: the receiver's hardware code delay of signal j (inter-system,
  BeiDou-2/-3 and inter-frequency biases, core/receiver/hardware_bias.py);
- m_j: code multipath/residual as a first-order Gauss-Markov process per
  signal, sigma from the profile's code_multipath_m table of the signal, else
  mp_zenith_m + mp_low_m exp(-el/15 deg) with the antenna class's open-sky values
  (a stated approximation, core/receiver/code_multipath.py);
- e: thermal noise from C/N0 (DLL, PLL, FLL jitter, core/receiver/noise.py) with the
  profile's loop parameters; C/N0 per signal from the link budget (core/receiver/cn0.py:
  transmit power per signal, antenna class gain per band, or the profile's cn0_table_dbhz);
- N_j: an integer ambiguity per continuous track (core/receiver/tracking.py).
"""
from __future__ import annotations

import copy

import numpy as np

from .. import constants as k
from .. import propagation as prop
from .. import signals as sig
from ..ephemeris.health import signal_usable
from ..ephemeris.states import SatelliteStates
from ..frames import az_el_at, ecef_to_geodetic
from ..memo import BoundedCache, read_only
from ..nequick import NeQuickG
from ..signal_plans import default_plans, gps_day
from ..time import GnssTime
from ..vocabulary import VisibilityState
from . import cn0 as cn0_model
from . import hardware_bias, signal_tables
from . import noise as noise_model
from .clock import ReceiverClock
from .code_multipath import CodeMultipath
from .config import ReceiverConfig
from .ionosphere import klobuchar_coeffs, truth_model
from .lms_channel import LmsChannel, code_and_amplitude
from .observations import EpochObservations, untracked_epoch
from .signal_rows import SignalRows, array_key
from .tracking import Tracker
from .world_errors import ZWD_RESIDUAL_SIGMA_M, WorldErrorTerms, world_process

#: visibility states (gnss_sim_msgs/SatelliteVisibility)
VISIBLE, BLOCKED, ATTENUATED, REFLECTED_ONLY = (VisibilityState.VISIBLE, VisibilityState.BLOCKED,
                                                VisibilityState.ATTENUATED, VisibilityState.REFLECTED_ONLY)
#: the same as plain ints (an array compared with an IntEnum member costs microseconds more)
_VISIBLE_I, _ATTENUATED_I = int(VISIBLE), int(ATTENUATED)


#: the signal rows of receivers configured alike (Receiver._configured_rows), by (_rows_config_key, satellites key)
_SHARED_ROWS = BoundedCache(256)


def _rows_config_key(cfg: ReceiverConfig) -> tuple:
    """The configuration fields Receiver._configured_rows reads, as a hashable key."""
    return (tuple(sorted((s, tuple(c)) for s, c in cfg.profile.items())),
            tuple(sorted(cfg.excluded_signals.items())),
            tuple(sorted((g, tuple(sorted(c.items()))) for g, c in (cfg.code_bias_m or {}).items())),
            tuple(sorted((s, float(v)) for s, v in cfg.sisre_m.items())), int(cfg.world_seed))


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
        self.code_multipath = CodeMultipath(config, np.random.default_rng(rng.integers(2**63)))
        self.world_terms = WorldErrorTerms(config.world_seed)
        #: the land-mobile-satellite layer (lms_channel.py): None with lms_environment off
        self.lms = LmsChannel(config.lms_environment, config.seed) if config.lms_environment != "off" else None
        self.set_iono_coefficients(iono_coeffs)
        self._t_prev: GnssTime | None = None
        self._geo_key = None
        self._geo = (0.0, 0.0, 0.0)
        self._signal_cache = BoundedCache(64)
        #: what _configured_rows depends on besides the satellites: the key of the rows receivers share
        self._rows_config_key = _rows_config_key(config)
        #: which signals each satellite transmits on a date (core/signal_plans/plans.yaml)
        self._plans = default_plans()
        self._keep_cache = BoundedCache(64)
        #: the signal rows of a block stacked, by the identity of its epochs' cached rows (a fleet's robots, whose
        #: satellites change seldom, batch_observe.py)
        self._stack_cache = BoundedCache(4)
        self._iono_terms = None
        self._tropo_terms = None
        self._doy_key = None
        self._doy0 = 0.0
        #: a scenario's threats (core/threats/runtime.ThreatRuntime), injected by the chain; None: none
        self.threats = None

    def set_iono_coefficients(self, iono: dict | None) -> None:
        """Take the navigation header's ionosphere coefficients ({"GPSA": [4], "GPSB": [4], "GAL": [3]}, or
        None before any are known) and choose the true ionosphere's model (ReceiverConfig.ionosphere)."""
        self.iono_alpha, self.iono_beta = klobuchar_coeffs(iono)
        #: the true ionosphere's model: "nequick", "klobuchar" or "none"; NeQuick-G only where used
        self.iono_truth = truth_model(self.cfg.ionosphere, iono)
        gal = tuple(iono["GAL"][:3]) if self.iono_truth == "nequick" else None
        if gal is None:
            self._nequick = None
        elif self._nequick is None or self._nequick.coefficients != gal:
            self._nequick = NeQuickG(gal)

    # ------------------------------------------------------------------
    def _rows_of(self, svs: np.ndarray, glo_channel: np.ndarray, day: int, health: np.ndarray) -> SignalRows:
        """The signal rows of satellites ``svs`` on GPS day ``day``: the profile's signals each transmits that
        day (signal_plans: by generation, PRN and date) and whose health allows (ephemeris/health.py: QZSS per
        signal); cached per satellite set, day and health."""
        key = (array_key(svs), array_key(glo_channel), day, array_key(health))
        hit = self._signal_cache.get(key)
        if hit is not None:
            return hit
        shared_key = (self._rows_config_key, key)
        shared = _SHARED_ROWS.get(shared_key)
        if shared is None:      # handed to every receiver configured alike: read-only
            shared = self._configured_rows(svs, glo_channel, day, health)
            for value in vars(shared).values():
                read_only(value)
            _SHARED_ROWS.put(shared_key, shared)
        rows = copy.copy(shared)
        # multipath states: one slot per (sv, code), kept for the receiver's lifetime (this receiver's own)
        rows.mp_idx = self.code_multipath.slots(rows.sv_j, rows.signal_rows[1])
        self._signal_cache.put(key, rows)
        return rows

    def _configured_rows(self, svs, glo_channel, day: int, health) -> SignalRows:
        """_rows_of's rows but the multipath slots: a function of the satellites, the day, their health and the
        configuration's fields in _rows_config_key alone, so receivers configured alike (a fleet's robots, whose
        seeds differ) share them (_SHARED_ROWS): a set of satellites rising costs one of them, not one per robot."""
        sat_i, codes, freq, chip, systems = [], [], [], [], []
        plans = self._plans
        profile = {s: tuple(c) for s, c in self.cfg.profile.items()}
        skip = self.cfg._excluded_signals
        for i, sv in enumerate(svs.tolist()):
            s = sv[0]
            h = int(health[i])
            for code in plans.codes(sv, profile.get(s, ()), day):
                if h and s == "J" and not signal_usable(s, h, code):   # other systems: the provider's choice
                    continue
                if skip and s + code in skip and skip[s + code].fullmatch(sv):   # the profile's excluded_signals
                    continue
                sat_i.append(i)
                codes.append(code)
                systems.append(s)
                freq.append(sig.frequency_hz(s, code, int(glo_channel[i]) if s == "R" else 0))
                chip.append(sig.signal(s, code).chip_length_m)
        rows = SignalRows()
        rows.signal_rows = (np.array(sat_i, dtype=np.int64), np.array(codes, dtype="<U2"), np.array(freq, dtype=float),
                            np.array(chip, dtype=float), np.array(systems, dtype="<U1"))
        sat_i, codes, freq, chip, systems = rows.signal_rows
        rows.lam = k.C_MPS / freq
        rows.gd_factor = sig.group_delay_factor(systems, codes, freq)
        rows.p_min, rows.el_min = cn0_model.power_params(systems, codes) if len(codes) else (np.zeros(0), np.zeros(0))
        rows.sig_key = signal_tables.signal_keys(systems, codes)
        rows.dll_factor = np.array([sig.signal(s, c).dll_noise_factor for s, c in zip(systems, codes)], dtype=float)
        rows.omega = np.array([k.OMEGA_BY_SYSTEM.get(s[0], k.OMEGA_E_GPS_RADPS) for s in svs], dtype=float)
        rows.sv_j = np.asarray(svs)[sat_i]
        rows.code_bias_m = hardware_bias.code_bias_m(self.cfg.code_bias_m, rows.sv_j, codes)
        rows.sisre_sigma = np.array([self.cfg.sisre_m.get(sv[0], 0.0) for sv in svs], dtype=float)
        rows.sisre_terms = self.world_terms.stacked([("sat", str(sv)) for sv in svs]) if len(svs) else None
        return rows

    def _keep_mask(self, sv_all: np.ndarray) -> np.ndarray:
        """Rows of the states whose system is received (configured systems with a profile); cached."""
        key = array_key(sv_all)
        hit = self._keep_cache.get(key)
        if hit is None:
            cfg = self.cfg
            ex = cfg._excluded
            hit = np.array([sv[0] in cfg.systems and sv[0] in cfg.profile and not (ex and ex.fullmatch(sv))
                            for sv in sv_all.tolist()], dtype=bool)
            self._keep_cache.put(key, hit)
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
        :meth:`epoch` called K times does, so the observables are the same.  The stages below fill one
        :class:`_Block` in this order.  batch_observe.py runs them for several receivers' epochs as one block
        (each receiver's memory on its own segment): a stage with memory is stepped per receiver there too.
        """
        b = _Block(ts)
        self._antenna(b, antenna_ecef_m, antenna_vel_ecef_mps)
        self._receiver_clock(b)
        self._satellites_above_horizon(b, states, epoch_of_row, vis_state, attenuation_db)
        self._signals(b)
        if b.m == 0:
            return [self._empty(ts[e], b.bias_ep[e], b.drift_ep[e], *b.sat_rows(e)) for e in range(b.k_n)]
        self._geometry(b)
        self._satellite_clocks(b)
        self._atmosphere(b)
        self._world_errors(b)
        self._signal_strength(b)
        self._scene_reflections(b, multipath)
        if self.lms is not None:
            self._lms_channel(b)
        if self.threats is not None:      # spoofers and jammers on C/N0 before tracking (core/threats)
            self.threats.spoof_signals(b, self.cfg)
            b.cn0 = self.threats.signal_cn0(ts, b.rx_ep, b.e_sig, b.rows.sv_j, b.codes, b.freq, b.cn0,
                                            self.cfg.link_budget, self.cfg.frontend_bandwidth_hz)
        self._tracking(b)
        self._receiver_errors(b)
        self._observables(b)
        if self.threats is not None:      # the captured signals' observables (core/threats/spoofing.py)
            self.threats.spoof_observables(b, self._light_time)
        return self._assemble(b)

    # the stages of epochs(), in order -------------------------------------------------------------
    def _antenna(self, b: _Block, antenna_ecef_m, antenna_vel_ecef_mps) -> None:
        """The antenna's position, velocity and geodetic position per epoch (cached while it stands still)."""
        b.rx_ep = np.asarray(antenna_ecef_m, dtype=float).reshape(b.k_n, 3)
        b.vel_ep = np.zeros((b.k_n, 3))
        if antenna_vel_ecef_mps is not None:
            for e, v in enumerate(antenna_vel_ecef_mps):
                if v is not None:
                    b.vel_ep[e] = v
        b.lat_ep, b.lon_ep, b.h_ep = np.array([self._geodetic(p) for p in b.rx_ep], dtype=float).T

    def _receiver_clock(self, b: _Block) -> None:
        """The receiver clock stepped epoch by epoch (its own random stream); the true reception times."""
        k_n = b.k_n
        b.bias_ep, b.drift_ep, b.dt_ep = np.empty(k_n), np.empty(k_n), np.empty(k_n)
        for e, t in enumerate(b.ts):
            b.bias_ep[e], b.drift_ep[e], b.dt_ep[e] = self._clock_step(t)
        if self.threats is not None and (jump := self.threats.clock_offset_s(b.ts)) is not None:
            b.bias_ep = b.bias_ep + jump      # a receiver clock fault (core/threats/faults.py)
        if k_n == 1:      # one epoch (a node)
            b.t_true = b.ts[0] - b.bias_ep[0]
        else:
            b.t_true = GnssTime(np.array([np.asarray(t.sec) for t in b.ts], dtype=np.int64),
                                np.array([np.asarray(t.frac) for t in b.ts], dtype=float)) - b.bias_ep

    def _clock_step(self, t) -> tuple:
        """The receiver clock stepped to epoch tag ``t`` from the previous epoch (its own stream; not stepped at
        the first epoch): (bias [s], drift [s/s], interval [s])."""
        dt_s = 0.0 if self._t_prev is None else float(t - self._t_prev)
        self._t_prev = t
        if dt_s > 0:
            bias, drift, _ = self.clock.step(dt_s)
            return bias, drift, dt_s
        return self.clock.bias_s, self.clock.steered_drift_sps, dt_s

    def _satellites_above_horizon(self, b: _Block, states, epoch_of_row, vis_state, attenuation_db,
                                  az_el=None) -> None:
        """The rows of ``states`` the receiver looks at (received systems, above the horizon): az/el, visibility.
        ``az_el``: (azimuth, elevation) [deg] of every row computed already (batch_observe.py: the states every
        robot shares, seen from each antenna at once), None: here."""
        e_all = np.asarray(epoch_of_row, dtype=np.int64)
        n_all = len(states)
        vis = np.zeros(n_all, dtype=np.int64) if vis_state is None else np.asarray(vis_state, dtype=np.int64)
        att = np.zeros(n_all) if attenuation_db is None else np.asarray(attenuation_db, dtype=float)
        if az_el is None:
            az, el, _ = az_el_at(b.rx_ep[e_all], b.lat_ep[e_all], b.lon_ep[e_all], states.pos_ecef_m)
        else:
            az, el = az_el
        b.keep = self._keep_mask(np.asarray(states.sv)) & (el > 0.0)
        b.seg_all = np.searchsorted(e_all, np.arange(b.k_n + 1))
        kidx = np.flatnonzero(b.keep)
        b.st = states.select(kidx)
        b.az, b.el, b.vis, b.att, b.e_sat = az[kidx], el[kidx], vis[kidx], att[kidx], e_all[kidx]
        b.svs = np.asarray(b.st.sv)
        b.seg = np.searchsorted(b.e_sat, np.arange(b.k_n + 1))

    def _signals(self, b: _Block, receivers=None) -> None:
        """The signal rows of every epoch (cached per satellite set and day), stacked; epoch e's are
        sig_seg[e]:sig_seg[e+1].  A (satellite, signal) row exists only where the satellite transmits the signal on
        that date (signal_plans) and its broadcast health allows the signal (QZSS: per signal).  ``receivers``:
        the receiver of each epoch (batch_observe.py: one per robot, its own multipath slots), None: this one."""
        k_n, seg, svs, glo = b.k_n, b.seg, b.svs, np.asarray(b.st.glo_channel)
        health = np.asarray(b.st.health)
        rxs = receivers or [self] * k_n
        parts = [rxs[e]._rows_of(svs[seg[e]:seg[e + 1]], glo[seg[e]:seg[e + 1]], gps_day(b.ts[e].sec),
                                 health[seg[e]:seg[e + 1]]) for e in range(k_n)]
        if k_n == 1:
            b.rows = parts[0]
        else:
            key = (tuple(map(id, parts)), seg.tobytes())
            hit = self._stack_cache.get(key)
            if hit is None or any(a is not c for a, c in zip(hit[0], parts)):
                hit = self._stack_cache.put(key, (parts, SignalRows.stack(parts, seg[:-1])))
            b.rows = hit[1]
        b.sat_i, b.codes, b.freq, b.chip, _ = b.rows.signal_rows
        b.m_ep = np.array([len(p.signal_rows[0]) for p in parts], dtype=np.int64)
        b.sig_seg = np.concatenate([[0], np.cumsum(b.m_ep)])
        b.m = len(b.sat_i)
        b.empty = b.sig_seg[1:] == b.sig_seg[:-1]
        if b.m:
            b.e_sig = b.e_sat[b.sat_i]
            b.bias_sat = b.bias_ep[0] if k_n == 1 else b.bias_ep[b.e_sat]
            b.t_true_sat = b.t_true if k_n == 1 else b.t_true[b.e_sat]

    def _geometry(self, b: _Block) -> None:
        """Geometry at the transmit time, seen at the true reception time (light time, Earth rotation)."""
        # rows of (N, 3) arrays by take: the values of fancy indexing at a third of its cost
        b.sol = self._light_time(b.rx_ep.take(b.e_sat, axis=0), b.vel_ep.take(b.e_sat, axis=0), b.t_true_sat,
                                 b.bias_sat, b.st, b.rows.omega)
        b.rho = b.sol.range_m[b.sat_i]
        b.rho_dot = b.sol.range_rate_mps[b.sat_i]
        b.el_j = b.el[b.sat_i]

    def _satellite_clocks(self, b: _Block) -> None:
        """Satellite clock at transmit time (SP3 convention polynomial + relativistic - group delay)."""
        st, sol, sat_i = b.st, b.sol, b.sat_i
        clk_poly = st.clock_bias_s - st.clock_drift_sps * (b.bias_sat + sol.tau_s)
        rel = -2.0 * np.einsum("ij,ij->i", sol.sat_pos_ecef_m, sol.sat_vel_ecef_mps) / k.C_MPS**2
        b.dts = (clk_poly + rel)[sat_i] - b.rows.gd_factor * st.tgd_s[sat_i]
        b.ddts = st.clock_drift_sps[sat_i]

    def _atmosphere(self, b: _Block) -> None:
        """Ionosphere (the broadcast model's and the true model's, scaled to each signal's frequency) and
        troposphere, per satellite."""
        cfg, k_n, seg, sat_i, freq, m = self.cfg, b.k_n, b.seg, b.sat_i, b.freq, b.m
        lat, lon = b.lat_ep[b.e_sat], b.lon_ep[b.e_sat]
        if self.iono_truth != "none":
            l1_delay = prop.klobuchar_l1_delay_s(b.t_true_sat, lat, lon, b.az, b.el, self.iono_alpha, self.iono_beta)
            b.iono_model = prop.iono_code_delay_m(l1_delay[sat_i], freq)
            if self._nequick is not None:
                l1_true = np.empty(len(b.svs))
                for e in range(k_n):
                    s = slice(seg[e], seg[e + 1])
                    t_e = b.t_true if k_n == 1 else b.t_true[e]
                    l1_true[s] = self._nequick.l1_delay_s(t_e.to_datetime("UTC"), b.lat_ep[e], b.lon_ep[e], b.az[s],
                                                          b.el[s])
                b.iono_base = prop.iono_code_delay_m(l1_true[sat_i], freq)
            else:
                b.iono_base = b.iono_model
        else:
            b.iono_model = b.iono_base = np.zeros(m)
        if cfg.troposphere == "saastamoinen":
            doy = np.array([self._day_of_year(t) for t in b.ts])
            # the zenith delays and mapping coefficients per epoch, the mapping per satellite
            tropo, zwd, m_wet = prop.tropo_slant_parts_m(np.maximum(b.el, 1.0), b.lat_ep, b.h_ep, doy,
                                                         epoch_of_row=b.e_sat)
            b.tropo, b.zwd_j, b.m_wet_j = tropo[sat_i], zwd[sat_i], m_wet[sat_i]
        else:
            b.tropo = np.zeros(m)
            b.zwd_j = None

    def _world_errors(self, b: _Block) -> None:
        """The world's errors (world_errors.py): the true ionosphere's own error, the true zenith wet delay's,
        each satellite's SISRE."""
        cfg = self.cfg
        frac = cfg.iono_error_frac.get(self.iono_truth, 0.0)
        if cfg.noise and frac != 0:
            if self._iono_terms is None:
                self._iono_terms = self.world_terms.stacked([("iono",)])
            g_iono = world_process(b.t_true, self._iono_terms)
            b.iono_true = b.iono_base * (1.0 + frac * (g_iono[0] if b.k_n == 1 else g_iono[b.e_sig]))
        else:
            b.iono_true = b.iono_base
        # the true troposphere: the model's (b.tropo, what the receiver corrects with) with the true zenith wet
        # delay, ZWD + ZWD_RESIDUAL_SIGMA_M w(t) (no negative water vapour), on the wet mapping
        b.tropo_true = b.tropo
        if cfg.noise and b.zwd_j is not None:
            if self._tropo_terms is None:
                self._tropo_terms = self.world_terms.stacked([("tropo",)])
            w = world_process(b.t_true, self._tropo_terms)
            d_zwd = ZWD_RESIDUAL_SIGMA_M * (w[0] if b.k_n == 1 else w[b.e_sig])
            b.tropo_true = b.tropo + (np.maximum(b.zwd_j + d_zwd, 0.0) - b.zwd_j) * b.m_wet_j
        rows = b.rows
        b.sisre_m = (rows.sisre_sigma * world_process(b.t_true_sat, rows.sisre_terms))[b.sat_i] if cfg.noise else None

    def _signal_strength(self, b: _Block) -> None:
        """C/N0 of every signal row (link budget, obstruction loss) and whether its line of sight is open."""
        att_j = b.att[b.sat_i]
        b.cn0 = cn0_model.cn0_dbhz_from_params(b.rows.p_min, b.rows.el_min, b.rho, b.el_j, att_j,
                                               budget=self.cfg.link_budget, frequency_hz=b.freq,
                                               signal_keys=b.rows.sig_key)
        b.vis_j = b.vis[b.sat_i]
        b.att_j = att_j
        b.line_ok = (b.vis_j == _VISIBLE_I) | (b.vis_j == _ATTENUATED_I)

    def _scene_reflections(self, b: _Block, multipath) -> None:
        """The scene's reflected paths, epoch by epoch (no memory, no random draw): C/N0 of the composite
        signal, code and phase errors, reflected-only satellites made trackable."""
        m, sat_i, sig_seg = b.m, b.sat_i, b.sig_seg
        b.mp_code, b.mp_phase = np.zeros(m), np.zeros(m)
        ok_all = b.line_ok
        picked = []             # per epoch with reflected paths: (its signal rows with paths, their paths)
        for e in (range(b.k_n) if multipath is not None else ()):
            j0, j1 = sig_seg[e], sig_seg[e + 1]
            paths = multipath[e]
            if j0 == j1 or paths is None or not paths.valid.any():
                continue
            paths = paths.take(b.keep[b.seg_all[e]:b.seg_all[e + 1]])
            loc = sat_i[j0:j1] - b.seg[e]
            rows_mp = np.flatnonzero(paths.valid.any(axis=1)[loc])
            if len(rows_mp):
                picked.append((j0 + rows_mp, paths, loc[rows_mp]))
        if picked:
            rows, err = self._scene_multipath(b, picked)
            # composite amplitude relative to the unobstructed line of sight replaces the obstruction loss
            b.cn0[rows] += b.att_j[rows] + 20.0 * np.log10(np.maximum(err.amplitude, 1e-6))
            b.mp_code[rows] = err.code_m
            b.mp_phase[rows] = err.phase_m
            # no line of sight, a reflected path: tracked if strong enough (thresholds with hysteresis,
            # tracking.py); REFLECTED_ONLY without the paths (a caller with only the state) stays untracked
            nlos_rows = rows[err.nlos]
            ok_all = b.line_ok.copy()
            ok_all[nlos_rows] |= b.vis_j[nlos_rows] == REFLECTED_ONLY
        b.ok_all = ok_all

    def _lms_channel(self, b: _Block) -> None:
        """The land-mobile-satellite layer (lms_channel.py) on the satellites the scene leaves in sight, epoch by epoch
        in order (its chains have memory): C/N0 of the direct signal's state and echo, the echo's code error."""
        cfg = self.cfg
        # the share the scene blocks counts opaque blocking only (foliage in sight); the layer acts on clear lines
        # of sight only: a line through the scene's foliage already carries its shadowing (lms_channel.py)
        in_sight = (b.vis == _VISIBLE_I) | (b.vis == _ATTENUATED_I)
        clear = b.vis == _VISIBLE_I
        sig, cols = [], []                 # per epoch: its signal rows and (level, amplitude, phase, delay) of each
        for e in range(b.k_n):
            s0, s1 = b.seg[e], b.seg[e + 1]
            share = float(np.mean(~in_sight[s0:s1])) if s1 > s0 else 0.0
            out = self.lms.epoch(b.rx_ep[e], b.dt_ep[e], b.svs[s0:s1], b.el[s0:s1], clear[s0:s1], share)
            if out is None:
                continue
            rows, level_db, amp, phase, delay_m = out
            j0, j1 = b.sig_seg[e], b.sig_seg[e + 1]
            at = np.full(s1 - s0, -1)
            at[rows] = np.arange(len(rows))
            pick = at[b.sat_i[j0:j1] - s0]
            sel = np.flatnonzero(pick >= 0)
            r = pick[sel]
            sig.append(j0 + sel)
            cols.append(np.stack([level_db[r], amp[r], phase[r], delay_m[r]]))
        if not sig:
            return
        # the DLL of every epoch's rows in one call, each epoch's rows with the bits of their own call (calls=)
        j = np.concatenate(sig)
        level_db, amp, phase, delay_m = np.concatenate(cols, axis=1)
        epoch = np.repeat(np.arange(len(sig)), [len(x) for x in sig])
        code, mag = code_and_amplitude(level_db, amp, phase, delay_m, b.chip[j], cfg.dll_spacing_chips,
                                       cfg.frontend_bandwidth_hz, calls=epoch)
        b.cn0[j] += 20.0 * np.log10(np.maximum(mag, 1e-6))
        b.mp_code[j] += code

    def _tracking(self, b: _Block) -> None:
        """The tracking loops, epoch by epoch in order (Tracker.update_many)."""
        above = b.el_j >= self.cfg.elevation_mask_deg
        b.tracked, b.lli, b.lock, b.amb = self.tracker.update_many(b.ts, b.rows.sv_j, b.codes, b.cn0,
                                                                   b.ok_all & above, b.sig_seg)

    def _receiver_errors(self, b: _Block, draws=None) -> None:
        """The receiver's random errors: C/N0 noise, code/phase/Doppler thermal noise, code multipath.
        ``draws``: (z_cn0, r, mp_x) of every row drawn already (batch_observe.py: each robot's from its own
        streams), None: :meth:`_noise_draws` of the block."""
        cfg, m = self.cfg, b.m
        draw_cn0 = cfg.noise and cfg.cn0_noise_db > 0
        z_cn0, r, mp_x = draws or self._noise_draws(m, b.sig_seg, b.m_ep, b.e_sig, b.empty, b.dt_ep, b.rows.mp_idx)
        cn0 = b.cn0
        b.cn0_meas = cn0 + cfg.cn0_noise_db * self.code_multipath.fading_scale(b.el_j) * z_cn0 if draw_cn0 else cn0
        if cfg.cn0_resolution_db > 0:           # the receiver's output resolution
            b.cn0_meas = np.round(b.cn0_meas / cfg.cn0_resolution_db) * cfg.cn0_resolution_db
        if cfg.noise:
            # the profile's loops (noise.py); the front end in chip rates b = B_fe T_c per signal
            code_sig = noise_model.dll_sigma_m(cn0, b.chip, cfg.dll_bn_hz, cfg.dll_spacing_chips, cfg.dll_t_int_s,
                                               cfg.frontend_bandwidth_hz * b.chip / k.C_MPS) * b.rows.dll_factor
            ph_sig = noise_model.pll_sigma_m(cn0, b.rows.lam, cfg.tracking.pll_bn_hz, cfg.tracking.pll_t_int_s)
            dop_sig = noise_model.doppler_sigma_hz(cn0)
            b.e_p, b.e_l, b.e_d = code_sig * r[0], ph_sig * r[1], dop_sig * r[2]
            b.mp = self.code_multipath.sigma_m(b.el_j, b.rows.sig_key) * mp_x
        else:
            b.e_p = b.e_l = b.e_d = b.mp = np.zeros(m)

    def _noise_draws(self, m, sig_seg, m_ep, e_sig, empty, dt_ep, mp_idx):
        """(z_cn0 (m,), r (3, m), mp_x (m,)): the noise processes' unit draws of ``m`` signal rows, epoch after
        epoch as K calls of one epoch make them (the same streams: a Generator's draws of n and then m values
        are its n + m values): per epoch C/N0 noise, then code, phase and Doppler noise from rng_noise; the code
        multipath's innovations from its own stream (its states at ``mp_idx`` advanced by ``dt_ep``)."""
        cfg = self.cfg
        draw_cn0 = cfg.noise and cfg.cn0_noise_db > 0
        z_cn0 = np.zeros(m)
        r = np.zeros((3, m))
        mp_x = np.zeros(m)
        if cfg.noise and len(m_ep) == 1:    # one epoch (a node): its draws are blocks of m, rows in order
            lead = 1 if draw_cn0 else 0
            w = self.rng_noise.standard_normal((3 + lead) * m).reshape(3 + lead, m)
            if draw_cn0:
                z_cn0 = w[0]
            r = w[lead:]
            w_mp = self.code_multipath.rng.standard_normal(m)
            if not empty[0]:
                mp_x = self.code_multipath.state(mp_idx, dt_ep[0], w_mp)
        elif cfg.noise:
            lead = 1 if draw_cn0 else 0
            j0_row = sig_seg[e_sig]
            mb_row = m_ep[e_sig]
            base = (3 + lead) * j0_row + (np.arange(m) - j0_row)
            w = self.rng_noise.standard_normal((3 + lead) * m)
            if draw_cn0:
                z_cn0 = w[base]
            for i in range(3):
                r[i] = w[base + (lead + i) * mb_row]
            w_mp = self.code_multipath.rng.standard_normal(m)
            for e in np.flatnonzero(~empty).tolist():
                s = slice(sig_seg[e], sig_seg[e + 1])
                mp_x[s] = self.code_multipath.state(mp_idx[s], dt_ep[e], w_mp[s])
        return z_cn0, r, mp_x

    def _observables(self, b: _Block) -> None:
        """Pseudorange, carrier phase and Doppler (the observation equations of the module doc)."""
        k_n, lam = b.k_n, b.rows.lam
        bias_j = b.bias_ep[0] if k_n == 1 else b.bias_ep[b.e_sig]
        common = b.rho + k.C_MPS * (bias_j - b.dts) + b.tropo_true
        if b.sisre_m is not None:
            common = common + b.sisre_m
        b.pr = common + b.iono_true + b.rows.code_bias_m + b.mp + b.e_p + b.mp_code
        phase_m = common - b.iono_true + b.e_l + b.mp_phase
        b.phase = phase_m / lam + b.amb
        drift_j = b.drift_ep[0] if k_n == 1 else b.drift_ep[b.e_sig]
        b.dop = -(b.rho_dot + k.C_MPS * (drift_j - b.ddts)) / lam + b.e_d

    def _assemble(self, b: _Block) -> list[EpochObservations]:
        """The tracked signals of the block taken at once; epoch e's are the rows cut[e]:cut[e + 1] of those."""
        sel = np.flatnonzero(b.tracked)
        cut = np.searchsorted(sel, b.sig_seg).tolist()
        sat_tr = b.sat_i[sel]
        (t_sv, t_code, t_freq, t_pr, t_phase, t_dop, t_cn0, t_lli, t_lock, t_dts, t_ddts, t_iono, t_tropo, t_el,
         t_rho) = (x[sel] for x in (b.rows.sv_j, b.codes, b.freq, b.pr, b.phase, b.dop, b.cn0_meas, b.lli, b.lock,
                                     b.dts, b.ddts, b.iono_model, b.tropo, b.el_j, b.rho))
        t_pos, t_vel = b.sol.sat_pos_ecef_m.take(sat_tr, axis=0), b.sol.sat_vel_ecef_mps.take(sat_tr, axis=0)
        if b.spoofed is not None:         # captured rows: the satellites at the counterfeit's transmit times
            t_pos, t_vel = b.spoofed.satellites(sel, t_pos, t_vel)
        out = []
        for e in range(b.k_n):
            if b.empty[e]:
                out.append(untracked_epoch(b.ts[e], b.bias_ep[e], b.drift_ep[e], *b.sat_rows(e)))
                continue
            s = slice(b.seg[e], b.seg[e + 1])
            r = slice(cut[e], cut[e + 1])
            out.append(EpochObservations(
                t=b.ts[e], clock_bias_s=b.bias_ep[e], clock_drift_sps=b.drift_ep[e],
                sat_sv=b.svs[s], sat_az_deg=b.az[s], sat_el_deg=b.el[s], sat_vis_state=b.vis[s],
                sat_attenuation_db=b.att[s],
                sv=t_sv[r], code=t_code[r], frequency_hz=t_freq[r], pseudorange_m=t_pr[r], carrier_phase_cyc=t_phase[r],
                doppler_hz=t_dop[r], cn0_dbhz=t_cn0[r], lli=t_lli[r], lock_time_s=t_lock[r], sat_pos_ecef_m=t_pos[r],
                sat_vel_ecef_mps=t_vel[r], sat_clock_s=t_dts[r], sat_clock_drift_sps=t_ddts[r], iono_model_m=t_iono[r],
                tropo_model_m=t_tropo[r], el_deg=t_el[r], true_range_m=t_rho[r],
            ))
        return out

    def _scene_multipath(self, b: _Block, picked):
        """(signal rows of the block with reflected paths, multipath.composite.CompositeErrors of those rows).

        ``picked``: per epoch (its signal rows with paths, its ScenePaths, their satellite rows in it).  Every
        epoch's rows in one composite_errors per front-end bandwidth and path count, each (epoch, bandwidth)
        its own call to the DLL's peak search (``calls``): the bits of one call per epoch and bandwidth."""
        from ..multipath.composite import CompositeErrors, composite_errors  # scipy.special: multipath on only

        cfg = self.cfg
        rows = np.concatenate([p[0] for p in picked])
        out = CompositeErrors(np.empty(len(rows)), np.empty(len(rows)), np.empty(len(rows)),
                              np.empty(len(rows), dtype=bool))
        width = np.array([p[1].excess_m.shape[-1] for p in picked])
        at = np.cumsum([0] + [len(p[0]) for p in picked])
        for w in np.unique(width).tolist():
            ep = np.flatnonzero(width == w)
            pos = np.concatenate([np.arange(at[e], at[e + 1]) for e in ep])
            r = rows[pos]
            fields = [np.concatenate([getattr(picked[e][1], f)[picked[e][2]] for e in ep])
                      for f in ("excess_m", "gamma_co", "gamma_cross", "arrival_el_deg")]
            call = np.repeat(ep, at[ep + 1] - at[ep])
            los = np.where((b.vis_j[r] == BLOCKED) | (b.vis_j[r] == REFLECTED_ONLY), 0.0, 10.0 ** (-b.att_j[r] / 20.0))
            # front-end bandwidth in chip rates per signal (C/A 1.023 Mchip/s, B1I 2.046, ...): grouped by value
            bw_chips = cfg.frontend_bandwidth_hz * b.chip[r] / k.C_MPS
            for bw in np.unique(bw_chips):
                g = np.flatnonzero(bw_chips == bw)
                rg = r[g]
                e = composite_errors(los[g], *(f[g] for f in fields), b.el_j[rg], b.chip[rg], b.rows.lam[rg],
                                     cfg.dll_spacing_chips, float(bw), cfg.antenna, calls=call[g])
                for name, v in e.__dict__.items():
                    getattr(out, name)[pos[g]] = v
        return rows, out

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

    def _empty(self, t, bias, drift, svs, az, el, vis, att):
        # nothing observed this epoch: every track the tracker holds loses lock
        self.tracker.update(t, np.zeros(0, dtype="<U3"), np.zeros(0, dtype="<U2"), np.zeros(0))
        return untracked_epoch(t, bias, drift, svs, az, el, vis, att)


class _Block:
    """The arrays of one block of K epochs as the stages of Receiver.epochs fill them: per epoch (``*_ep``),
    per satellite above the horizon (``az``, ``el``, ``vis``, ``att``, ``e_sat``; epoch e's rows
    seg[e]:seg[e + 1]) and per signal (``sat_i``, ``codes``, ``*_j``, ...; epoch e's rows
    sig_seg[e]:sig_seg[e + 1])."""

    def __init__(self, ts):
        self.ts = ts
        self.k_n = len(ts)
        self.spoofed = None       # a scenario's counterfeit signals (core/threats/spoofing.SpoofedRows)

    def sat_rows(self, e: int):
        """(svs, az, el, vis, att) of the satellites above the horizon at epoch ``e``."""
        s = slice(self.seg[e], self.seg[e + 1])
        return self.svs[s], self.az[s], self.el[s], self.vis[s], self.att[s]


class _NoState(Exception):
    pass
