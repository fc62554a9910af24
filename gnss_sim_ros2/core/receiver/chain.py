"""One receiver chain: what every front end runs for one epoch.

``gnss-sim simulate`` (core/simulation.py), ``gnss-sim bench``, ``gnss-sim run``
and the ROS nodes all build the same two objects from the parameter table
(``parameters.py``) and the preset (``core/presets.py``):

- ``core/visibility`` :class:`VisibilityOptions` -- how the scene is cast (mask,
  Fresnel rays, foliage model, visual or collision geometry); the visibility
  node and the offline loop call :meth:`VisibilityOptions.cast` and hand its
  results to the chain;
- :class:`ReceiverChain` -- receiver, tracking, solver (with the elevation
  mask), NMEA and the output writers (RINEX observation file, ``fix.csv``,
  optional NMEA file), with one :meth:`ReceiverChain.step` per epoch::

      (t, antenna ECEF [+ velocity], satellite states, visibility) -> EpochProducts

The antenna velocity, when the caller has none (a TF lookup gives positions
only), is the backward difference of the antenna positions of consecutive
epochs, in both front ends, so that one configuration gives one answer.
"""
from __future__ import annotations

import csv
import io
from collections import deque
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..memo import BoundedCache
from ..presets import preset as preset_switches
from ..signal_plans.plan import default_plans
from ..solver import PvtSolution, SolverConfig, solve_pvt_many
from ..time import GnssTime
from .config import ReceiverConfig
from .engine import Receiver
from .observations import EpochObservations
from .outputs import epoch_arrays, fix_inputs, header, obs_types_for, position_fixes, rinex_lines, rinex_name, spp_rows
from .profiles import load_profile
from .rinex_epochs import prepare_rinex_epochs
from .tracking import TrackingConfig


@dataclass
class ChainSettings:
    """Everything one receiver chain needs, from the receiver node's parameters and the preset."""

    receiver: ReceiverConfig
    solver: SolverConfig
    interval_s: float
    marker_name: str = "GSIM"
    preset: str = "balanced"
    output_dir: Path | None = None
    write_nmea_file: bool = False
    #: preset switches (after overrides) the chain was built with
    switches: dict = field(default_factory=dict)
    #: the SISRE was set explicitly (kept even for precise orbits)
    sisre_given: bool = False
    #: carrier smoothing of the code the position fix uses (Hatch filter) [s]; 0: raw code
    smoothing_s: float = 100.0
    #: RTCM3 output: MSM7 or MSM4, reference station id (DF003)
    rtcm_msm: int = 7
    rtcm_station_id: int = 0

    @classmethod
    def from_params(cls, p: dict, *, switches: dict | None = None, interval_s: float | None = None,
                    receiver_overrides: dict | None = None, have_ephemeris: bool = False) -> ChainSettings:
        """From the receiver node's parameters (``parameters.validate_node("receiver", ...)`` values).

        ``switches``: the preset's switches with overrides (default: the preset's own);
        ``interval_s``: the epoch interval (default ``1 / rate_hz``);
        ``receiver_overrides``: ReceiverConfig fields set last (benchmarks, tests);
        ``have_ephemeris``: the chain may evaluate the ephemeris at transmit time (offline); a node
        has the states at the epoch only and always uses the second-order expansion.
        """
        sw = switches if switches is not None else preset_switches(p["preset"])
        kw = {"systems": p["systems"], "elevation_mask_deg": p["elevation_mask_deg"], "seed": p["seed"],
              "transmit_time": sw["transmit_time"] if have_ephemeris else "expansion",
              "light_time_iterations": sw["light_time_iterations"],
              "ionosphere": p.get("ionosphere") or sw["ionosphere"],
              "troposphere": p.get("troposphere") or sw["troposphere"],
              "noise": bool(p.get("noise", True)) and bool(sw["noise"])}
        if "profile" in p:
            kw["profile"] = p["profile"]
        acq, lose = p.get("cn0_acquire_dbhz", -1.0), p.get("cn0_lose_dbhz", -1.0)
        start = p.get("tracking_start", "")
        if acq >= 0 or lose >= 0 or start:   # negative / empty: the profile's (its other tracking fields kept)
            tracking = load_profile(p.get("profile", "geodetic")).value("tracking", {})
            tracking.update({k: v for k, v in (("acquisition_cn0_dbhz", acq), ("tracking_cn0_dbhz", lose)) if v >= 0})
            if start:
                tracking["start"] = start
            kw["tracking"] = TrackingConfig(**tracking)
        kw["lms_environment"] = p.get("lms_environment", "off")
        kw["spoof_capture_margin_db"] = float(p.get("spoof_capture_margin_db", 3.0))
        kw.update({k: v for k, v in (receiver_overrides or {}).items() if v is not None and v != ""})
        out_dir = p.get("output_dir", "")
        receiver = ReceiverConfig(**kw)
        # the fixes' clock columns: the systems tracked (epochs of robots configured alike solved together)
        return cls(receiver=receiver, solver=SolverConfig(elevation_mask_deg=p["elevation_mask_deg"],
                                                          clock_systems=str(receiver.systems)),
                   interval_s=float(interval_s if interval_s is not None else 1.0 / p["rate_hz"]),
                   marker_name=p.get("marker_name", "GSIM"), preset=p["preset"],
                   output_dir=Path(out_dir) if out_dir else None,
                   write_nmea_file=bool(p.get("write_nmea_file", False)), switches=dict(sw),
                   smoothing_s=float(p.get("smoothing_s", 100.0)),
                   sisre_given="sisre_m" in (receiver_overrides or {}), rtcm_msm=int(p.get("rtcm_msm", 7)),
                   rtcm_station_id=int(p.get("rtcm_station_id", 0)))


@dataclass
class EpochProducts:
    """What one epoch of the chain produced."""

    t: GnssTime
    antenna_ecef_m: np.ndarray
    obs: EpochObservations
    sol: PvtSolution
    nmea: str = ""
    #: the epoch's RTCM3 messages (empty without RTCM output or without a tracked signal)
    rtcm: bytes = b""


class ReceiverChain:
    """Receiver + solver + writers of one simulated receiver, stepped epoch by epoch.

    ``provider``: the ephemeris (offline) or None (a node, which gets the states in messages);
    ``duration_s``: the span of the run, for the RINEX file name (None: "00U", unknown);
    ``glonass_slots``: GLONASS frequency channels for the RINEX header (None: from the first epoch's states);
    ``nmea``: produce NMEA text every epoch (a node publishes it); the NMEA file follows ``write_nmea_file``;
    ``comment``: who wrote the files (first RINEX header comment);
    ``rtcm``: RTCM3 output: a file path (written epoch by epoch), True (the bytes of each epoch only, in
    ``EpochProducts.rtcm``: a node publishes them) or None; ``rtcm_ephemeris``: with the broadcast
    ephemeris messages of the provider's navigation records (offline).
    """

    def __init__(self, settings: ChainSettings, provider=None, *, duration_s: float | None = None,
                 glonass_slots: dict | None = None, nmea: bool = False, comment: str = "gnss_sim",
                 rtcm: Path | bool | None = None, rtcm_ephemeris: bool = True):
        self.settings = settings
        self.provider = provider
        self.duration_s = duration_s
        self.glonass_slots = glonass_slots
        self.want_nmea = nmea or settings.write_nmea_file
        self.comment = comment
        self.rx: Receiver | None = None
        self.iono: dict | None = getattr(provider, "iono", None)
        self.obs_types = obs_types_for(settings.receiver.profile, settings.receiver.systems)
        self.obs_path: Path | None = None
        self.fix_path: Path | None = None
        self.rtcm_target = rtcm if rtcm not in (None, False) else None
        self.rtcm_ephemeris = rtcm_ephemeris
        self.rtcm_path: Path | None = None
        self._rtcm = None
        self._header = None
        self._writer = None
        self._fix_file = None
        self._fix_csv = None           # writes into _fix_rows: the rows pending, written with the RINEX epochs
        self._fix_rows = io.StringIO()
        #: RINEX epochs formatted and written together: a block's (step_block); an epoch of step is
        #: written at once (a killed node loses no epoch it published: 0.2 ms/epoch at 10 Hz against
        #: writing a second of epochs together, docs/profile-offline-chain.md)
        self._rinex_pending: list = []
        #: (observables, their EpochArrays or None, their RINEX lines or None) made ahead for the next finishes, in
        #: order (prepare)
        self._prepared: deque = deque()
        # the signal plans every Receiver reads (plans.yaml, cached per process) parsed with the chain, so a
        # node pays them when it is configured, not in its first epoch's latency (about 15 ms)
        default_plans()
        self._nmea_file = None
        #: a scenario's events (core/threats/runtime.ThreatRuntime) or None; set before the first epoch
        self.threats = None
        if settings.output_dir is not None:
            settings.output_dir.mkdir(parents=True, exist_ok=True)   # an unwritable folder fails the start
        self.reset()

    # ------------------------------------------------------------------ state of one run
    def reset(self):
        """Forget everything of the previous run (a reconfigured node starts clean); files closed."""
        self.close()
        self.rx = None
        self._header = None
        self._smooth = _SmoothingState()
        self.prior_ecef_m = None
        self._pos_prev = None
        self.epochs = 0
        self.fixes = 0
        self._prepared = deque()

    def set_iono_coefficients(self, iono: dict | None):
        """The navigation header's ionosphere coefficients (a node gets them with the states)."""
        if iono != self.iono:
            self.iono = iono
            if self.rx is not None:
                self.rx.set_iono_coefficients(iono)

    def _receiver(self, states) -> Receiver:
        cfg = self.settings.receiver
        if states.source.startswith("sp3") and not self.settings.sisre_given:
            # observations from precise orbits are the truth: the broadcast message's own error is then real
            # (what a receiver using the navigation file sees), so no synthetic SISRE is drawn on top
            cfg = replace(cfg, sisre_m={s: 0.0 for s in cfg.sisre_m})
        rx = Receiver(cfg, self.provider, self.iono)
        rx.threats = self.threats
        return rx

    def _backward_velocity(self, t, ecef):
        """The antenna velocity [m/s ECEF] as the backward difference to the previous epoch's position (None at
        the first epoch or a repeated time); this epoch's position is kept for the next."""
        v = None
        if self._pos_prev is not None:
            dt = float(t - self._pos_prev[0])
            v = (ecef - self._pos_prev[1]) / dt if dt > 0 else None
        self._pos_prev = (t, ecef)
        return v

    # ------------------------------------------------------------------ one epoch
    def step(self, t: GnssTime, antenna_ecef_m, states, vis_state=None, attenuation_db=None,
             antenna_vel_ecef_mps=None, multipath=None) -> EpochProducts:
        """One epoch; ``multipath``: the reflected paths of the states' rows (VisibilityOptions.cast) or None.
        :meth:`observe` then :meth:`finish`."""
        obs = self.observe(t, antenna_ecef_m, states, vis_state, attenuation_db, antenna_vel_ecef_mps, multipath)
        return self.finish(t, antenna_ecef_m, states, obs)

    def observe(self, t: GnssTime, antenna_ecef_m, states, vis_state=None, attenuation_db=None,
                antenna_vel_ecef_mps=None, multipath=None):
        """The first half of :meth:`step`: the epoch's observables, tracking included (EpochObservations).
        A receiver outputs these raw measurements before its fix (u-blox: RXM-RAWX, then NAV-PVT); the
        receiver node publishes them here, then calls :meth:`finish` with them."""
        ecef, antenna_vel_ecef_mps = self.observe_inputs(t, antenna_ecef_m, states, antenna_vel_ecef_mps)
        obs = self.rx.epoch(t, ecef, states, vis_state, attenuation_db, antenna_vel_ecef_mps=antenna_vel_ecef_mps,
                            multipath=multipath)
        return obs if self.threats is None else self.threats.observations(obs)

    def observe_inputs(self, t: GnssTime, antenna_ecef_m, states, antenna_vel_ecef_mps=None):
        """(antenna ECEF, its velocity or None) of the epoch :meth:`observe` is about to compute (the velocity:
        the given one, else the backward difference; this epoch's position kept for the next), the receiver
        ``rx`` made at the first epoch.  batch_observe.py calls it in observe's place for several receivers."""
        ecef = np.asarray(antenna_ecef_m, dtype=float)
        backward = self._backward_velocity(t, ecef)
        if self.rx is None:
            self.rx = self._receiver(states)
        return ecef, (backward if antenna_vel_ecef_mps is None else antenna_vel_ecef_mps)

    def finish(self, t: GnssTime, antenna_ecef_m, states, obs, sol: PvtSolution | None = None,
               nmea: bool = True) -> EpochProducts:
        """The second half of :meth:`step`: the fix, NMEA, files and RTCM of the observables :meth:`observe`
        gave for this epoch (called once per observe, in order); ``sol``: the fix of :meth:`fix_inputs` of
        ``obs``, solved by the caller (several receivers' in one solver.solve_pvt_many), or None: solved here;
        ``nmea`` False: no NMEA text this epoch unless the NMEA file wants it (a node's topic without
        subscribers)."""
        products = self._products(t, np.asarray(antenna_ecef_m, dtype=float), states, obs, sol,
                                  nmea or self.settings.write_nmea_file)
        self._flush_files()
        return products

    def fix_inputs(self, obs) -> dict:
        """The position fix's inputs from this epoch's observables (one epoch of solver.solve_pvt_many, with
        this receiver's SolverConfig ``settings.solver``): the carrier-smoothed code, started at the last fix.
        The smoothing filter advances: once per epoch, followed by :meth:`finish` with the fix of them."""
        return receivers_fix_inputs([self], [obs])[0]

    def step_block(self, ts, antenna_ecef_m, states, epoch_of_row, vis_state=None, attenuation_db=None,
                   multipath=None) -> list[EpochProducts]:
        """K consecutive epochs at once (offline): :meth:`step` K times, with the observables of the block
        computed together (Receiver.epochs).  ``ts``: K epoch tags; ``antenna_ecef_m``: (K, 3); ``states``:
        the rows of all epochs, epoch by epoch, ``epoch_of_row`` the epoch of each; ``vis_state``,
        ``attenuation_db``: per row or None; ``multipath``: K path sets (rows of their epoch) or None."""
        ecef = np.asarray(antenna_ecef_m, dtype=float).reshape(len(ts), 3)
        vel = [self._backward_velocity(t, p) for t, p in zip(ts, ecef)]
        if self.rx is None:
            self.rx = self._receiver(states)
        obs = self.rx.epochs(ts, ecef, states, epoch_of_row, vis_state, attenuation_db, vel, multipath)
        if self.threats is not None:
            obs = [self.threats.observations(o) for o in obs]
        # the fixes of the block in one solve, each started at the last fix before the block (the same
        # solutions as starting at the previous epoch's, to the solver's convergence of 0.1 mm)
        fix_obs = self._smoothed_many(obs) if self.settings.smoothing_s > 0 else obs
        sols = position_fixes(fix_obs, self.settings.receiver.profile, self.prior_ecef_m, self.settings.solver)
        prepare_rinex_epochs([self] * len(obs), obs)      # the block's RINEX lines formatted in one pass
        try:
            return [self._products(t, p, states, o, sol) for t, p, o, sol in zip(ts, ecef, obs, sols)]
        finally:
            self._flush_files()           # the block's RINEX epochs and fix.csv rows, written together

    def _products(self, t, ecef, states, obs, sol=None, nmea: bool = True) -> EpochProducts:
        """The fix (unless given), NMEA (``nmea`` and the chain's ``want_nmea``), files and RTCM of one epoch's
        observables."""
        if sol is None:
            sol = solve_pvt_many([self.fix_inputs(obs)], self.settings.solver)[0]
        self.epochs += 1
        if sol.is_fix:
            self.prior_ecef_m = sol.pos_ecef_m      # the receiver's own state: before any output fault
        if self.threats is not None:
            sol = self.threats.solution(t, sol)     # output faults act on what the receiver outputs (core/threats)
        if sol.is_fix:
            self.fixes += 1
        text = ""
        if self.want_nmea and nmea:
            from ..nmea import join_sentences, sentences_from_solution

            text = join_sentences(sentences_from_solution(t, sol, cn0_dbhz=obs.cn0_dbhz[
                spp_rows(obs, self.settings.receiver.profile)]))
        prepared = self._prepared.popleft() if self._prepared else None
        if prepared is not None and prepared[0] is obs:
            arrays, lines = prepared[1], prepared[2]
        else:
            self._prepared.clear()
            arrays, lines = self.rinex_outputs([obs])[0]
        if self._header is None:
            self._header = self._make_header(ecef, states)
        if self.settings.output_dir is not None:
            self._write(t, ecef, obs, sol, text, lines)
        rtcm = b""
        if self.rtcm_target is not None and arrays is not None:
            if self._rtcm is None:
                self._rtcm = self._open_rtcm()
            glo = np.char.startswith(np.asarray(states.sv, dtype=str), "R")
            if glo.any():   # a GLONASS satellite the header's slots lack (its record valid later): its channel
                self._rtcm.add_glonass_channels(dict(zip(states.sv[glo], states.glo_channel[glo])))
            rtcm = self._rtcm.write_epoch(t, arrays)
        return EpochProducts(t, ecef, obs, sol, text, rtcm)

    def rinex_outputs(self, obs_list) -> list[tuple]:
        """(EpochArrays for RTCM or None, RINEX satellite lines (rinex/obs_write.FormattedEpoch) or None) of each
        epoch's observables, the lines of all of them formatted in one pass (outputs.rinex_lines); None where the
        chain has no such output or the epoch no tracked signal."""
        has = [len(o.sv) > 0 for o in obs_list]
        lines = iter(rinex_lines([o for o, h in zip(obs_list, has) if h], self.obs_types)
                     if self.settings.output_dir is not None else ())
        return [(self.rtcm_arrays(o), next(lines) if h and self.settings.output_dir is not None else None)
                for o, h in zip(obs_list, has)]

    def rtcm_arrays(self, obs):
        """The EpochArrays of an epoch's observables for RTCM output (None without RTCM or tracked signals)."""
        return epoch_arrays(obs, self.obs_types) if self.rtcm_target is not None and len(obs.sv) else None

    def prepare(self, obs, arrays, lines):
        """What :meth:`finish` of ``obs`` would make itself (:meth:`rinex_outputs`), made ahead with other epochs'
        or receivers' (rinex_epochs.prepare_rinex_epochs); the finishes take them in order, each only if of the
        same ``obs`` object."""
        self._prepared.append((obs, arrays, lines))

    def _smoothed_many(self, obs_list) -> list[EpochObservations]:
        """The observables of consecutive epochs with carrier-smoothed code for the position fix, as receivers
        compute their fix (Hatch filter, RTCA DO-229 2.1.4.1.1: P_s = P / M + (M - 1) / M (P_s' + L - L'), window M
        up to smoothing_s; restarted at a loss of lock).  The raw code stays in the observations and RINEX.
        This chain's epochs of smoothed_code."""
        return smoothed_code([self] * len(obs_list), obs_list)

    # ------------------------------------------------------------------ files
    def _make_header(self, ecef, states):
        """The RINEX header of the run (first epoch's antenna position, GLONASS slots); RTCM uses it too."""
        s = self.settings
        slots = self.glonass_slots
        if slots is None:
            slots = {str(sv): int(ch) for sv, ch in zip(states.sv, states.glo_channel) if sv[0] == "R"}
        cfg = s.receiver
        return header(self.obs_types, s.marker_name, ecef, s.interval_s, slots,
                      comments=[f"{self.comment}, preset {s.preset}",
                                f"seed {cfg.seed}; noise {'on' if cfg.noise else 'off'}"], antenna=cfg.antenna,
                      rinex=cfg.rinex)

    def _open_rtcm(self):
        from ..rtcm.writer import RtcmWriter

        nav = getattr(self.provider, "nav", None) if self.rtcm_ephemeris else None
        navigation = None
        if nav is not None:
            from ..rinex.nav import records_as_dicts

            navigation = records_as_dicts(nav, self.settings.receiver.systems)
        if self.rtcm_target is True:
            sink = _Discard()
        else:
            self.rtcm_path = Path(self.rtcm_target)
            self.rtcm_path.parent.mkdir(parents=True, exist_ok=True)
            sink = self.rtcm_path
        return RtcmWriter(sink, self._header, msm=self.settings.rtcm_msm, station_id=self.settings.rtcm_station_id,
                          navigation=navigation)

    def _open(self, t: GnssTime):
        from ..rinex.obs_write import RinexObsWriter

        s = self.settings
        out = s.output_dir
        out.mkdir(parents=True, exist_ok=True)
        hdr = self._header
        name = rinex_name(s.marker_name, t, self.duration_s, s.interval_s, "MO")
        self.obs_path = out / name
        k = 1
        while self.obs_path.exists():
            # a reconfigured node in the same minute: never overwrite a file; the next file counts up the
            # receiver number of the long name (SSSSMR: RINEX 3.04 section 4.1), so it still ends _MO.rnx
            if k > 9:
                raise ValueError(f"{out}: ten observation files of marker {s.marker_name} start in this minute "
                                 f"already; give another output_dir or marker_name")
            self.obs_path = out / (name[:5] + str(k) + name[6:])
            k += 1
        self._writer = RinexObsWriter(self.obs_path, hdr)
        self.fix_path = out / "fix.csv"
        new = not self.fix_path.exists()
        self._fix_file = open(self.fix_path, "a", newline="", buffering=1)  # noqa: SIM115 - closed in close()
        self._fix_csv = csv.writer(self._fix_rows)
        if new:
            self._fix_csv.writerow(["time", "lat_deg", "lon_deg", "h_m", "n_sats", "status"]
                                   + (["active_events"] if self.threats is not None else [])
                                   + (["spoofed"] if self.threats is not None and self.threats.spoofing else []))
        if s.write_nmea_file:
            self._nmea_file = open(out / "gnss_sim.nmea", "a", buffering=1)  # noqa: SIM115 - closed in close()

    def _write(self, t, ecef, obs, sol, nmea_text, arrays):
        """The epoch's fix.csv row, RINEX epoch (``arrays``: its FormattedEpoch, or None) pending until
        _flush_files, NMEA text."""
        if self._writer is None:
            self._open(t)
        stamp = t.isoformat(digits=3 if self.settings.interval_s < 1 else 0)
        # the scenario's truth labels: the events active at the epoch, ";"-separated (core/threats)
        labels = [";".join(self.threats.labels(t))] if self.threats is not None else []
        if self.threats is not None and self.threats.spoofing:     # the satellites a spoofer has captured
            labels.append(" ".join(sv for sv, v in self.threats.spoofed(t).items() if v["captured"]))
        if sol.is_fix:
            self._fix_csv.writerow([stamp, f"{sol.lat_deg:.9f}", f"{sol.lon_deg:.9f}", f"{sol.h_m:.4f}", sol.n_used,
                                    "fix", *labels])
        else:
            self._fix_csv.writerow([stamp, "", "", "", sol.n_used, "no_fix", *labels])
        if arrays is not None:
            self._rinex_pending.append((t, arrays))
        if self._nmea_file is not None:
            self._nmea_file.write(nmea_text)

    def _flush_files(self):
        """Write the epochs pending: RINEX (one vectorised pass, one system call), then their fix.csv rows (one
        write). :meth:`finish` calls it every epoch, :meth:`step_block` once per block."""
        pending, self._rinex_pending = self._rinex_pending, []
        if pending:
            self._writer.write_epochs([t for t, _ in pending], [a for _, a in pending])
        rows = self._fix_rows.getvalue()
        if rows:
            self._fix_file.write(rows)
            self._fix_rows.seek(0)
            self._fix_rows.truncate()

    def close(self):
        """Close the files (RINEX gets its epochs still pending and its TIME OF LAST OBS); idempotent."""
        if self._writer is not None:
            self._flush_files()
            self._writer.close()
            self._writer = None
        if self._rtcm is not None:
            self._rtcm.close()
            self._rtcm = None
        for f in (self._fix_file, self._nmea_file):
            if f is not None:
                f.close()
        self._fix_file = self._fix_csv = self._nmea_file = None


def receivers_fix_inputs(chains, obs_list) -> list[dict]:
    """ReceiverChain.fix_inputs of ``obs_list[k]`` for ``chains[k]`` (one epoch of each of several receivers, or a
    receiver's consecutive epochs), the smoothing of all of them in one pass (smoothed_code)."""
    fix_obs = list(obs_list)
    smooth = [k for k, chain in enumerate(chains) if chain.settings.smoothing_s > 0]
    for k, o in zip(smooth, smoothed_code([chains[k] for k in smooth], [obs_list[k] for k in smooth])):
        fix_obs[k] = o
    return [fix_inputs(o, chain.settings.receiver.profile, chain.prior_ecef_m) for chain, o in zip(chains, fix_obs)]


def smoothed_code(chains, obs_list) -> list[EpochObservations]:
    """ReceiverChain._smoothed_many of ``obs_list[k]`` by ``chains[k]``'s filter (a chain given several epochs: its
    consecutive ones, in order).  What needs no state (the carrier in metres, the loss of lock flags) for all
    their signals at once; then the filter in rounds, each round the next epoch of every chain, the arithmetic
    of a round's chains together (each chain's state its own)."""
    from ..constants import C_MPS

    if not obs_list:
        return []
    sizes = [len(o.pseudorange_m) for o in obs_list]
    ends = np.cumsum(sizes).tolist()
    starts = [e - n for e, n in zip(ends, sizes)]

    def cat(name, dtype):
        parts = [np.asarray(getattr(o, name), dtype=dtype) for o in obs_list]
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    lam = C_MPS / cat("frequency_hz", float)
    # the carrier advances where the code is delayed: twice the receiver's own (broadcast) ionosphere
    # model is added to the phase, so the window does not drift with the ionosphere (code-carrier
    # divergence, DO-229 2.1.4.1.1 note); what the model misses still diverges, as in a real receiver
    phase_all = cat("carrier_phase_cyc", float) * lam + 2.0 * cat("iono_model_m", float)
    pr_all = cat("pseudorange_m", float)
    intact_all = ((cat("lli", np.int64) & 1) == 0) & np.isfinite(phase_all)
    rounds: list = []
    seen: dict = {}
    for k, chain in enumerate(chains):
        r = seen[id(chain)] = seen.get(id(chain), -1) + 1
        if r == len(rounds):
            rounds.append([])
        rounds[r].append(k)
    window = {id(chain): _window_epochs(chain) for chain in chains}
    out_list: list = [None] * len(obs_list)
    for ks in rounds:
        if len(ks) == 1:          # one chain's epoch (a block's, epoch by epoch): its slices as they are
            k = ks[0]
            st, rows = chains[k]._smooth, slice(starts[k], ends[k])
            i = st.slots(obs_list[k].sv, obs_list[k].code)
            phase_m = phase_all[rows]
            m, out = _hatch(st.last[i] == st.calls - 1, st.count[i], st.code[i], st.phase[i], intact_all[rows],
                            pr_all[rows], phase_m, window[id(chains[k])])
            st.code[i], st.phase[i], st.count[i], st.last[i] = out, phase_m, m, st.calls
            st.calls += 1
            out_list[k] = _with_code(obs_list[k], out)
            continue
        sts = [chains[k]._smooth for k in ks]
        idx = [st.slots(obs_list[k].sv, obs_list[k].code) for st, k in zip(sts, ks)]
        rows = np.concatenate([np.arange(starts[k], ends[k]) for k in ks])
        phase_m = phase_all[rows]
        m, out = _hatch(np.concatenate([st.last[i] == st.calls - 1 for st, i in zip(sts, idx)]),
                        *(np.concatenate([getattr(st, f)[i] for st, i in zip(sts, idx)])
                          for f in ("count", "code", "phase")),
                        intact_all[rows], pr_all[rows], phase_m,
                        np.repeat([window[id(chains[k])] for k in ks], [sizes[k] for k in ks]))
        j = 0
        for st, i, k in zip(sts, idx, ks):
            n = sizes[k]
            st.code[i], st.phase[i], st.count[i], st.last[i] = out[j:j + n], phase_m[j:j + n], m[j:j + n], st.calls
            st.calls += 1
            out_list[k] = _with_code(obs_list[k], out[j:j + n])
            j += n
    return out_list


def _hatch(tracked_before, count, code, phase, intact, pr, phase_m, n_max):
    """One Hatch filter step of signals: (window length M, smoothed code) from the state (tracked at the previous
    call, its M, smoothed code and phase [m]), this epoch's loss-of-lock check, code and phase [m], and the
    longest window n_max (DO-229 2.1.4.1.1, see ReceiverChain._smoothed_many)."""
    # the window goes on for a signal also tracked at the previous call, without a loss of lock;
    # a signal not tracked at the previous epoch starts again
    go_on = tracked_before & intact
    m = np.where(go_on, np.minimum(count + 1, n_max), 1)
    return m, np.where(go_on, pr / m + (m - 1) / m * (code + phase_m - phase), pr)


def _with_code(obs: EpochObservations, pseudorange_m) -> EpochObservations:
    """A shallow copy of the observables with another code (copy.copy without __reduce_ex__)."""
    out = object.__new__(EpochObservations)
    out.__dict__.update(obs.__dict__)
    out.pseudorange_m = pseudorange_m
    return out


def _window_epochs(chain) -> int:
    """The Hatch filter's longest window of a chain [epochs]: smoothing_s over the epoch interval."""
    return max(1, int(round(chain.settings.smoothing_s / chain.settings.interval_s)))


class _SmoothingState:
    """Hatch filter state per signal (sv, code): smoothed code [m], phase [m], epochs in the window, and
    the call that last saw it (ReceiverChain._smoothed_many)."""

    def __init__(self):
        self.index: dict = {}
        self._cache = BoundedCache(64)
        self.calls = 0
        self._grow(64)

    def _grow(self, cap):
        def more(old, fill, dtype):
            new = np.full(cap, fill, dtype=dtype)
            if old is not None:
                new[: len(old)] = old
            return new

        g = self.__dict__.get
        self.code, self.phase = more(g("code"), np.nan, float), more(g("phase"), np.nan, float)
        self.count, self.last = more(g("count"), 0, np.int64), more(g("last"), -2, np.int64)

    def slots(self, sv, code) -> np.ndarray:
        sv, code = np.asarray(sv), np.asarray(code)
        key = (sv.dtype.str, code.dtype.str, sv.tobytes(), code.tobytes())
        hit = self._cache.get(key)
        if hit is None:
            hit = np.array([self.index.setdefault(k, len(self.index)) for k in zip(sv.tolist(), code.tolist())],
                           dtype=np.int64)
            if len(self.index) > len(self.code):
                self._grow(2 * len(self.index))
            self._cache.put(key, hit)
        return hit


class _Discard:
    """An RTCM sink that keeps nothing: the bytes of each epoch are returned to the caller."""

    def write(self, data: bytes) -> int:
        return len(data)
