"""The one object the receiver chain calls for a scenario's events (offline and in the nodes alike):
:class:`ThreatRuntime`.  ``ReceiverChain.threats`` holds it (None: no scenario, nothing changes); the chain hands
it to its ``Receiver``.  Calls per block of epochs, in the chain's order:

1. ``clock_offset_s(ts)`` -- receiver clock faults (Receiver._receiver_clock);
2. ``signal_cn0(...)`` -- jamming on every signal row's C/N0, before tracking (Receiver.epochs);
3. ``observations(obs)`` -- satellite faults on the ranges, then the output faults on the observations
   (off, stuck), before the fix;
4. ``solution(t, sol)`` -- output faults on the fix; ``labels(t)`` the active events (fix.csv, topic).

Spoofing (spoofing.py): ``spoof_signals(b, cfg)`` right before ``signal_cn0`` (the same stage: capture or
interference on each signal's C/N0, so loss of lock and capture follow the thresholds; jammers add on top) and
``spoof_observables(b, light_time)`` after the observables (the captured rows' code, phase and Doppler, the
satellites the receiver solves them with, loss-of-lock flags); ``spoofed(t)`` the per-satellite ground truth
(spoofer, arrival direction, captured signals).  Both are no-ops without a spoofer.

Times are relative to the run start: the first epoch seen, unless ``start`` is given.
"""
from __future__ import annotations

import numpy as np

from ..frames import az_el_from_ecef, geodetic_to_ecef
from ..time import GnssTime
from . import faults as fault_model
from . import jamming, spectra
from .scenario import Scenario, SpooferEvent
from .spoofing import Spoofing


class ThreatRuntime:
    """A scenario's events applied to one receiver (module doc).  ``scene``: the loaded scene (core/scene
    Scene) for world positions and the jammer -> antenna casts, or None (open sky; llh positions only)."""

    def __init__(self, scenario: Scenario, scene=None, start: GnssTime | None = None):
        self.scenario = scenario
        self.scene = scene
        self.start = start
        self.jammers = scenario.jammers
        self.faults = scenario.faults
        self.output_faults = fault_model.OutputFaults(self.faults)
        #: the last epoch's per-band status {band: {"jamming_indicator": 0-255, "agc_db": dB}}
        self.band_status: dict = {}
        self._status_by_t: dict = {}
        #: the spoofers' model (spoofing.py), None without a spoofer
        self.spoofing = Spoofing(self, _tkey) if scenario.spoofers else None
        spherical = getattr(scene, "spherical", None)
        if spherical is None and scenario.needs_scene_frame():
            raise ValueError(f"scenario {scenario.source}: an event placed in world coordinates needs a "
                             f"georeferenced scene (a world with spherical_coordinates); use position_type: llh")

    # ------------------------------------------------------------------ time and labels
    def t_rel(self, ts) -> np.ndarray:
        """Seconds after the run start of epoch tags ``ts`` (a list of GnssTime or one)."""
        ts = list(ts) if isinstance(ts, (list, tuple)) else [ts]
        if self.start is None:
            self.start = ts[0]
        return np.array([float(t - self.start) for t in ts])

    def labels(self, t) -> list[str]:
        """Names of the events active at epoch ``t`` (file order)."""
        tr = float(self.t_rel(t)[0])
        return [e.name for e in self.scenario.events if bool(e.active(tr))]

    def active_spoofers(self, t_rel_s: float) -> list[SpooferEvent]:
        """The spoofing hook: the spoofers active at run time ``t_rel_s`` (a spoofing model acts on them)."""
        return [s for s in self.scenario.spoofers if bool(s.active(t_rel_s))]

    def spoofed(self, t) -> dict:
        """Ground truth of the spoofers at epoch ``t``: {sv: {"spoofer", "az_deg", "el_deg", "captured": [codes]}}
        (spoofing.Spoofing.truth; empty without an active spoofer)."""
        return {} if self.spoofing is None else self.spoofing.truth(t)

    # ------------------------------------------------------------------ stages
    def spoof_signals(self, b, cfg) -> None:
        """The spoofers' counterfeits on block ``b``'s C/N0 (capture or interference), kept as ``b.spoofed``."""
        b.spoofed = None if self.spoofing is None else self.spoofing.signals(b, cfg)

    def spoof_observables(self, b, light_time) -> None:
        """The captured rows' observables and satellites (spoofing.Spoofing.observables)."""
        if self.spoofing is not None:
            self.spoofing.observables(b, light_time)

    def clock_offset_s(self, ts) -> np.ndarray | None:
        if not self.faults:
            return None
        return fault_model.clock_offset_s(self.faults, self.t_rel(ts))

    def observations(self, obs):
        """The epoch's observations as the receiver outputs them (satellite faults, then off / stuck)."""
        if not self.faults:
            return obs
        t_rel = float(self.t_rel(obs.t)[0])
        return self.output_faults.observations(t_rel, fault_model.on_ranges(self.faults, t_rel, obs))

    def solution(self, t, sol):
        """The fix as the receiver outputs it (off, stuck, position_offset)."""
        if not self.output_faults.faults:
            return sol
        return self.output_faults.solution(float(self.t_rel(t)[0]), sol)

    def positions_ecef(self, track, t_rel_s) -> np.ndarray:
        """(K, 3) ECEF of a scenario track at run times ``t_rel_s``."""
        p = track.at(t_rel_s)
        if track.frame == "llh":
            return np.stack(geodetic_to_ecef(p[..., 0], p[..., 1], p[..., 2]), axis=-1)
        return self.scene.spherical.world_to_ecef(p)

    def scene_loss_db(self, antenna_ecef_m, source_ecef_m) -> np.ndarray:
        """(K,) loss [dB] of the scene on the segments antenna -> source: inf where an opaque triangle blocks
        it, else the penetrable materials' dB/m along the segment (0 without a scene)."""
        a = np.asarray(antenna_ecef_m, dtype=float).reshape(-1, 3)
        if self.scene is None or self.scene.spherical is None:
            return np.zeros(len(a))
        sph = self.scene.spherical
        aw, sw = sph.ecef_to_world(a), sph.ecef_to_world(np.asarray(source_ecef_m, dtype=float).reshape(-1, 3))
        d = sw - aw
        dist = np.linalg.norm(d, axis=1)
        u = d / np.maximum(dist, 1e-9)[:, None]
        rays = self.scene.rays
        # opaque: the first opaque hit nearer than the source (one cast for every segment of the block)
        loss = np.where(rays.hit_distance(aw, u, tnear_m=1e-3) < dist, np.inf, 0.0)
        if rays.has_penetrable:
            # the segment's penetration: from the antenna on, minus what lies beyond the source
            loss += np.maximum(rays.penetration(aw, u)[0] - rays.penetration(sw, u)[0], 0.0)
        return loss

    def signal_cn0(self, ts, antenna_ecef_ep, epoch_of_row, sv, codes, freq_hz, cn0_dbhz, budget,
                   frontend_bw_hz: float) -> np.ndarray:
        """C/N0 [dB-Hz] of every signal row with the active jammers' interference (jamming.py); the per-band
        jamming indicator and AGC of each epoch kept for :meth:`status`."""
        if not self.jammers:
            return cn0_dbhz
        t_rel = self.t_rel(ts)
        act = [(j, j.active(t_rel)) for j in self.jammers]
        act = [(j, on) for j, on in act if on.any()]
        self._status_by_t = {}
        if not act:
            return cn0_dbhz
        e = np.asarray(epoch_of_row, dtype=np.int64)
        freq = np.asarray(freq_hz, dtype=float)
        n0 = budget.noise_density_dbwhz
        jk = np.zeros(len(freq))                    # sum over jammers of kappa J [W/Hz] per row
        j_in = np.zeros(len(freq))                  # jammer power inside the row's front-end band [W]
        systems = np.char.asarray(np.asarray(sv, dtype="<U3")).astype("<U1")
        codes = np.asarray(codes, dtype="<U2")
        # the signal kinds of the rows (system, code, carrier): kappa and the in-band share once per kind
        key = np.char.add(np.char.add(systems, codes), np.round(freq).astype(np.int64).astype("<U12"))
        _, first, inv = np.unique(key, return_index=True, return_inverse=True)
        half = 0.5 * frontend_bw_hz
        gain = budget.antenna_gain
        for jam, on in act:
            pos = self.positions_ecef(jam.track, t_rel)                               # (K, 3)
            with np.errstate(invalid="ignore", divide="ignore"):     # a jammer on the antenna has no direction:
                _, el, dist = az_el_from_ecef(antenna_ecef_ep, pos)
            el = np.where(np.isfinite(el), el, 90.0)                 # its boresight gain (was NaN C/N0, an error)
            loss = self.scene_loss_db(antenna_ecef_ep, pos)
            kappa_u, share_u = np.zeros(len(first)), np.zeros(len(first))
            for u, r in enumerate(first):
                df = jam.center_hz - freq[r]
                kappa_u[u] = spectra.kappa_per_hz(spectra.components(systems[r], codes[r]), float(frontend_bw_hz),
                                                  float(df), float(jam.bandwidth_hz))
                if jam.bandwidth_hz > 0:
                    lo, hi = max(df - 0.5 * jam.bandwidth_hz, -half), min(df + 0.5 * jam.bandwidth_hz, half)
                    share_u[u] = max(0.0, hi - lo) / jam.bandwidth_hz
                else:
                    share_u[u] = 1.0 if abs(df) <= half else 0.0
            j_dbw = jamming.received_power_dbw(jam.eirp_dbw, dist[e], jam.center_hz, gain(el[e], freq), loss[e])
            j_w = np.where(on[e], 10.0 ** (j_dbw / 10.0), 0.0)
            jk += kappa_u[inv] * j_w
            j_in += share_u[inv] * j_w
        out = jamming.effective_cn0_dbhz(cn0_dbhz, jk, n0)
        # per epoch and band (RINEX band digit): the strongest in-band J/N, the indicator and AGC of it
        jn = jamming.jam_to_noise_db(j_in, n0, frontend_bw_hz)
        bands, b_of_row = np.unique(codes.astype("<U1"), return_inverse=True)
        ts = ts if isinstance(ts, (list, tuple)) else [ts]
        worst = np.full(len(ts) * len(bands), -np.inf)
        np.maximum.at(worst, e * len(bands) + b_of_row, jn)
        worst = worst.reshape(len(ts), len(bands))
        ind, agc = jamming.jamming_indicator(worst), jamming.agc_db(worst)
        for k_e, t in enumerate(ts):
            self._status_by_t[_tkey(t)] = {str(b): {"jamming_indicator": int(ind[k_e, i]), "agc_db": float(agc[k_e, i])}
                                           for i, b in enumerate(bands) if np.isfinite(worst[k_e, i])}
        return out

    def status(self, t) -> dict:
        """{RINEX band digit: {"jamming_indicator", "agc_db"}} of epoch ``t`` (empty: no jammer active)."""
        return self._status_by_t.get(_tkey(t), {})


def _tkey(t):
    return (int(np.asarray(t.sec)), round(float(np.asarray(t.frac)), 9))
