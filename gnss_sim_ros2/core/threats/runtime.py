"""The one object the receiver chain calls for a scenario's events (offline and in the nodes alike):
:class:`ThreatRuntime`.  ``ReceiverChain.threats`` holds it (None: no scenario, nothing changes); the chain hands
it to its ``Receiver``.  Calls per block of epochs, in the chain's order:

1. ``clock_offset_s(ts)`` -- receiver clock faults (Receiver._receiver_clock);
2. ``signal_cn0(...)`` -- jamming on every signal row's C/N0, before tracking (Receiver.epochs);
3. ``on_ranges(obs)`` -- satellite faults on the observables, before the fix;
4. ``outputs(t, obs, sol)`` -- output faults after the fix; ``labels(t)`` the active events (fix.csv, topic).

Spoofing hook: :meth:`ThreatRuntime.active_spoofers` lists the spoofers active at an epoch; the spoofing model
(not built yet) is one function ``spoof(runtime, t_rel_s, spoofers, ...)`` called from ``signal_cn0``'s stage
with the same rows.  Times are relative to the run start: the first epoch seen, unless ``start`` is given.
"""
from __future__ import annotations

import numpy as np

from ..frames import az_el_from_ecef, geodetic_to_ecef
from ..time import GnssTime
from . import faults as fault_model
from . import jamming, spectra
from .scenario import Scenario, SpooferEvent


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

    # ------------------------------------------------------------------ stages
    def clock_offset_s(self, ts) -> np.ndarray | None:
        if not self.faults:
            return None
        return fault_model.clock_offset_s(self.faults, self.t_rel(ts))

    def on_ranges(self, obs):
        if not self.faults:
            return obs
        return fault_model.on_ranges(self.faults, float(self.t_rel(obs.t)[0]), obs)

    def outputs(self, t, obs, sol):
        if not self.output_faults.faults:
            return obs, sol
        return self.output_faults.apply(float(self.t_rel(t)[0]), obs, sol)

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
        loss = np.zeros(len(a))
        for i in range(len(a)):            # tfar per ray: one cast each (a few jammers x epochs of a block)
            if rays.occluded(aw[i], u[i], tnear_m=1e-3, tfar_m=float(dist[i]))[0]:
                loss[i] = np.inf
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
        systems = np.array([s[0] for s in np.asarray(sv).tolist()])
        key = np.char.add(np.char.add(systems, np.asarray(codes, dtype=str)), np.round(freq).astype(np.int64)
                          .astype(str))
        uniq, inv = np.unique(key, return_index=False, return_inverse=True)
        first = np.zeros(len(uniq), dtype=np.int64)
        first[inv[::-1]] = np.arange(len(inv))[::-1]
        half = 0.5 * frontend_bw_hz
        for jam, on in act:
            pos = self.positions_ecef(jam.track, t_rel)                               # (K, 3)
            _, el, dist = az_el_from_ecef(antenna_ecef_ep, pos)
            loss = self.scene_loss_db(antenna_ecef_ep, pos)
            for u, r in enumerate(first):
                rows = (inv == u) & on[e]
                if not rows.any():
                    continue
                df = jam.center_hz - freq[r]
                comps = spectra.components(systems[r], str(codes[r]))
                kappa = spectra.kappa_per_hz(comps, float(frontend_bw_hz), float(df), float(jam.bandwidth_hz))
                if jam.bandwidth_hz > 0:
                    share = max(0.0, min(df + 0.5 * jam.bandwidth_hz, half) - max(df - 0.5 * jam.bandwidth_hz,
                                                                                    -half)) / jam.bandwidth_hz
                else:
                    share = 1.0 if abs(df) <= half else 0.0
                if kappa == 0.0 and share == 0.0:
                    continue
                ee = e[rows]
                j_w = 10.0 ** (jamming.received_power_dbw(jam.eirp_dbw, dist[ee], jam.center_hz,
                                                          budget.antenna_gain(el[ee], freq[r]), loss[ee]) / 10.0)
                jk[rows] += kappa * j_w
                j_in[rows] += share * j_w
        out = jamming.effective_cn0_dbhz(cn0_dbhz, jk, n0)
        jn = jamming.jam_to_noise_db(j_in, n0, frontend_bw_hz)
        band = np.asarray(codes, dtype="<U1")
        for k_e, t in enumerate(ts if isinstance(ts, (list, tuple)) else [ts]):
            sel = e == k_e
            st = {}
            for b in np.unique(band[sel]).tolist():
                x = float(np.max(jn[sel & (band == b)]))
                st[b] = {"jamming_indicator": int(jamming.jamming_indicator(x)), "agc_db": float(jamming.agc_db(x))}
            self._status_by_t[_tkey(t)] = st
        return out

    def status(self, t) -> dict:
        """{RINEX band digit: {"jamming_indicator", "agc_db"}} of epoch ``t`` (empty: no jammer active)."""
        return self._status_by_t.get(_tkey(t), {})


def _tkey(t):
    return (int(np.asarray(t.sec)), round(float(np.asarray(t.frac)), 9))
