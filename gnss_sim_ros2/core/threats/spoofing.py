"""Spoofing physics: a spoofer's counterfeit signals at the antenna, capture of each signal, the spoofed observables.

Where the counterfeit signals come from.  Every counterfeit signal arrives from the spoofer's position (one
direction for every satellite): received power

    C_sp = EIRP_sig - 20 log10(4 pi d f / c) + G_ant(el_spoofer, f) - L_scene          [dBW]

(free space, the antenna class's gain toward the spoofer, the scene's loss on the segment spoofer -> antenna:
jamming.py and ThreatRuntime.scene_loss_db, the jammers' chain).

How strong the spoofer makes them (``power_advantage_db`` A).  The spoofer aims its power advantage at the
target, as the receiver-spoofer of Humphreys et al. 2008 ("Assessing the spoofing threat: development of a portable
GPS civilian spoofer", ION GNSS 2008: it tracks the authentic signals and its target, and sets each counterfeit a
few dB above the authentic one so that the target's loops are dragged onto it).  Definition used here: the
spoofer's nominal design point is the target antenna where it truly is, in free space: it sets each counterfeit
signal's EIRP so that there its power exceeds the authentic signal's open-sky power (the link budget without the
scene, receiver/cn0.py) by A:

    EIRP_sig = C_auth,open + A + 20 log10(4 pi d f / c) - G_ant(el_spoofer, f)

``eirp_dbw`` is the spoofer's total EIRP (its amplifier): when the sum of its signals' EIRPs would exceed it, every
signal is lowered by the same dB (the advantage falls short, e.g. a spoofer too far away).  What the spoofer does not
know is the scene: a wall between it and the antenna lowers C_sp by its loss; a building shading the authentic
signal raises the advantage actually achieved.  So at the antenna C_sp - C_auth = A - shortfall - L_scene +
(C_auth,open - C_auth).

Capture.  A signal is captured when C_sp - C_auth >= the receiver's capture margin (parameter
``spoof_capture_margin_db``, default 3 dB: a design value.  For a counterfeit aligned within a chip the theoretical
lower limit is a power ratio of 1, i.e. 0 dB (Wang et al., EURASIP J. Wireless Comm. and Networking 2018:50,
eq. 4, after the code-loop analysis cited there); 3 dB covers loop noise and imperfect alignment and is the
advantage Humphreys et al. aim at).  Then the receiver tracks the counterfeit: its C/N0 is C_sp / (N0 + I), its
code, phase and Doppler those below; the capture and the release set the loss-of-lock flag (LLI bit 0).  A captured
loop stays on the counterfeit while it reaches the antenna (dragged off, the authentic signal lies at another code
phase: interference only), whatever their powers do; it is released when the counterfeit is blocked or gone, and
then the authentic signal is acquired again through the tracking thresholds like any lost signal (not trackable at
the release epoch, acquired from the next one at the acquisition threshold): no hand-over below that threshold.
Otherwise both interfere: the authentic signal keeps its observables with C/N0 = C / (N0 + I).  I = kappa_m sum
C_sp over the spoofer's signals of the same kind (system, code, carrier) at the epoch (the captured row's own
counterfeit left out), kappa_m = int G_s^2 / (int G_s)^2 over the front end, the spectral separation coefficient of
a matched spectrum (Betz 2001; spectra.matched_kappa_per_hz); jammers add on top (jamming.py).

What the counterfeits carry (mode simulate): what a receiver at the false position ``p_f`` (static or a path) and
the false time t + dT (``false_time_offset_s``) would measure from the real satellites (their broadcast states, the
receiver's own; no SISRE), plus the spoofer -> antenna distance d, common to every satellite (the fix's clock takes
it):

    P = rho_f + c (dt_r - dT - dts_f) + T_model + I_model + d + B_j + m_j + e_P
    L = [rho_f + c (dt_r - dT - dts_f) + T_model - I_model + d + e_L] / lambda + N
    D = -[rho_dot_f + d_dot + c (ddt_r - ddts)] / lambda + e_D

rho_f, rho_dot_f the light-time range and rate from p_f (moving along the false path) at t + dT, dts_f the
satellite clock at that transmit time, T_model / I_model the troposphere and broadcast ionosphere the receiver
itself corrects (the spoofer simulates them: its signals cross no ionosphere), d_dot the range rate spoofer ->
antenna; the scene's multipath of the authentic signal does not apply.  The satellite positions and clocks the
receiver then solves with are those at its (false) transmit times, so the fix lands on p_f and the receiver
clock absorbs d / c - dT.

Meaconing (mode meacon): the real signals received at the meaconer's own position and re-broadcast delay_s later:
the same equations with p_f the meaconer's position, dT = -delay_s and the true atmosphere and SISRE; every range
grows by c delay_s + d (the clock absorbs it, the fix goes to the meaconer's antenna).

Spoofers send every signal of their ``systems`` of the satellites above the antenna's horizon.  The ground truth
per epoch and satellite (:meth:`Spoofing.truth`): the spoofer, the arrival direction (the same for every
satellite: what a two-antenna or array receiver could measure) and the captured signals.
"""
from __future__ import annotations

import numpy as np

from .. import constants as k
from ..frames import az_el_from_ecef
from ..receiver import cn0 as cn0_model
from . import jamming, spectra

#: default capture margin [dB] (module doc: a design value)
CAPTURE_MARGIN_DB = 3.0
#: half the time step of the finite differences giving the tracks' velocities [s]
_HALF_STEP_S = 0.5


class SpoofedRows:
    """The counterfeit signals of one block of epochs: per signal row whether it is captured and by which
    spoofer; per spoofer and epoch where its counterfeits pretend to be received, when, and how far it is."""

    def __init__(self, captured, which, recv_ecef, recv_vel, dt_s, meacon, dist_m, dist_rate_mps):
        self.captured, self.which = captured, which
        self.recv_ecef, self.recv_vel = recv_ecef, recv_vel          # (Q, K, 3)
        self.dt_s, self.meacon = dt_s, meacon                          # (Q,)
        self.dist_m, self.dist_rate_mps = dist_m, dist_rate_mps        # (Q, K)
        #: captured rows and their satellites as the receiver at the false place and time sees them
        self.rows = np.flatnonzero(captured)
        self.sat_pos = self.sat_vel = None

    def satellites(self, sel, pos, vel):
        """Satellite positions / velocities of the tracked rows ``sel`` with the captured rows' replaced."""
        if self.sat_pos is None or not len(self.rows):
            return pos, vel
        at = np.searchsorted(self.rows, sel)
        hit = (at < len(self.rows)) & (self.rows[np.minimum(at, len(self.rows) - 1)] == sel)
        pos, vel = pos.copy(), vel.copy()
        pos[hit], vel[hit] = self.sat_pos[at[hit]], self.sat_vel[at[hit]]
        return pos, vel


class Spoofing:
    """The spoofers of one receiver's scenario (ThreatRuntime owns it): the capture state between blocks and the
    per-epoch ground truth."""

    def __init__(self, runtime, epoch_key):
        self.rt = runtime
        self._key = epoch_key              # epoch tag -> dict key (the runtime's)
        self.spoofers = runtime.scenario.spoofers
        self._prev = frozenset()           # the (sv, code) captured at the last epoch seen (loss-of-lock flags)
        self._held = frozenset()           # the (sv, code) captured at the last epoch seen (sticky capture)
        self._truth_by_t: dict = {}
        self._truth_args = None            # what the block's truth needs once its tracking is known

    # ---------------------------------------------------------------- before tracking
    def signals(self, b, cfg) -> SpoofedRows | None:
        """C/N0 of every signal row of block ``b`` (receiver/engine.py _Block) with the active spoofers (capture or
        interference, module doc); the captured rows made trackable.  None: no spoofer active in the block."""
        rt = self.rt
        t_rel = rt.t_rel(b.ts)
        act = [(q, s, s.active(t_rel)) for q, s in enumerate(self.spoofers)]
        act = [a for a in act if a[2].any()]
        self._truth_by_t = {}
        self._truth_args = None
        if not act or b.m == 0:
            self._release_all(b)
            return None
        budget = cfg.link_budget
        n0_dbw = budget.noise_density_dbwhz
        e = b.e_sig
        systems = b.rows.signal_rows[4]
        open_cn0 = cn0_model.cn0_dbhz_from_params(b.rows.p_min, b.rows.el_min, b.rho, b.el_j, 0.0, budget=budget,
                                                  frequency_hz=b.freq, signal_keys=b.rows.sig_key)
        c_open = open_cn0 + n0_dbw
        q_n, k_n = len(act), b.k_n
        c_sp = np.full((q_n, b.m), -np.inf)
        recv = np.zeros((q_n, k_n, 3))
        recv_vel = np.zeros((q_n, k_n, 3))
        dist = np.zeros((q_n, k_n))
        dist_rate = np.zeros((q_n, k_n))
        az_sp, el_sp = np.zeros((q_n, k_n)), np.zeros((q_n, k_n))
        for i, (_, s, on) in enumerate(act):
            pos = rt.positions_ecef(s.track, t_rel)
            vel = _velocity(rt, s.track, t_rel)
            az_sp[i], el_sp[i], dist[i] = az_el_from_ecef(b.rx_ep, pos)
            u = (b.rx_ep - pos) / np.maximum(dist[i], 1e-9)[:, None]
            dist_rate[i] = np.einsum("ij,ij->i", u, b.vel_ep - vel)
            loss = rt.scene_loss_db(b.rx_ep, pos)
            rows = np.flatnonzero(on[e] & np.isin(systems, list(s.systems)))
            fsl = jamming.free_space_loss_db(dist[i][e[rows]], b.freq[rows])
            gain = budget.antenna_gain(el_sp[i][e[rows]], b.freq[rows])
            eirp_sig = c_open[rows] + s.power_advantage_db + fsl - gain        # the design point (module doc)
            total = np.zeros(k_n)
            np.add.at(total, e[rows], 10.0 ** (eirp_sig / 10.0))
            short = np.maximum(10.0 * np.log10(np.maximum(total, 1e-300)) - s.eirp_dbw, 0.0)
            c_sp[i, rows] = c_open[rows] + s.power_advantage_db - short[e[rows]] - loss[e[rows]]
            if s.mode == "meacon":
                recv[i], recv_vel[i] = pos, vel
            else:
                recv[i], recv_vel[i] = rt.positions_ecef(s.false_track, t_rel), _velocity(rt, s.false_track, t_rel)
        best = np.argmax(c_sp, axis=0)
        c_best = c_sp[best, np.arange(b.m)]
        c_auth = np.where(b.ok_all, b.cn0 + n0_dbw, -np.inf)
        present = np.isfinite(c_best)
        advantage = np.where(present, c_best - np.where(present, c_auth, 0.0), -np.inf)
        captured, released = self._capture(b, present & (advantage >= cfg.spoof_capture_margin_db), present)
        # interference: kappa_m times the counterfeits of the row's kind at its epoch, its own left out if captured
        w_sp = np.where(np.isfinite(c_sp), 10.0 ** (c_sp / 10.0), 0.0).sum(axis=0)
        kind = np.char.add(np.char.add(systems, b.codes), np.round(b.freq).astype(np.int64).astype("<U12"))
        kinds, first, inv = np.unique(kind, return_index=True, return_inverse=True)
        per = np.zeros(k_n * len(kinds))
        np.add.at(per, e * len(kinds) + inv, w_sp)
        kappa = np.array([spectra.matched_kappa_per_hz(spectra.components(systems[r], b.codes[r]),
                                                       float(cfg.frontend_bandwidth_hz)) for r in first])
        own = np.where(captured, 10.0 ** (np.where(captured, c_best, 0.0) / 10.0), 0.0)
        interference = kappa[inv] * np.maximum(per[e * len(kinds) + inv] - own, 0.0)
        carrier = np.where(captured, c_best - n0_dbw, b.cn0)
        b.cn0 = jamming.effective_cn0_dbhz(carrier, interference, n0_dbw)
        if captured.any() or released.any():
            b.ok_all = (b.ok_all | captured) & ~released
        out = SpoofedRows(captured, best, recv, recv_vel,
                          np.array([-s.delay_s if s.mode == "meacon" else s.false_time_offset_s for _, s, _ in act]),
                          np.array([s.mode == "meacon" for _, s, _ in act]), dist, dist_rate)
        self._truth_args = (act, best, captured, az_sp, el_sp)
        return out

    def _capture(self, b, takes, present):
        """(captured, released) per signal row, epoch by epoch: a row is captured where the counterfeit takes it
        (``takes``: its advantage reaches the capture margin) or where it was captured at the epoch before and its
        counterfeit still reaches the antenna (``present``): the loop dragged onto the counterfeit stays on it, the
        authentic signal, now at another code phase, is interference only (Humphreys et al. 2008, the drag-off).
        Released: captured at the epoch before, not now (the counterfeit blocked or gone): the loop loses it and
        the authentic signal must be acquired again through the tracking thresholds (not trackable at this
        epoch, acquired from the next one when its C/N0 reaches the acquisition threshold)."""
        keys = _signal_keys(b)
        captured, released = takes.copy(), np.zeros(b.m, dtype=bool)
        held = self._held
        for ep in range(b.k_n):
            j0, j1 = b.sig_seg[ep], b.sig_seg[ep + 1]
            was = np.isin(keys[j0:j1], list(held)) if held else np.zeros(j1 - j0, dtype=bool)
            captured[j0:j1] |= was & present[j0:j1]
            released[j0:j1] = was & ~captured[j0:j1]
            held = frozenset(keys[j0:j1][captured[j0:j1]].tolist())
        self._held = held
        return captured, released

    def _release_all(self, b) -> None:
        """No spoofer active in block ``b``: the signals captured at the epoch before are released at its first
        epoch (:meth:`_capture`)."""
        if self._held and b.m:
            j1 = b.sig_seg[1]
            released = np.zeros(b.m, dtype=bool)
            released[:j1] = np.isin(_signal_keys(b)[:j1], list(self._held))
            b.ok_all = b.ok_all & ~released
        self._held = frozenset()

    def _keep_truth(self, b, act, best, captured, az_sp, el_sp):
        """The block's per-epoch truth; a signal counts as captured where the receiver tracks the counterfeit
        (``b.tracked``: below the elevation mask or the tracking thresholds no channel holds it)."""
        captured = captured & b.tracked
        sv_j = b.rows.sv_j
        for ep, t in enumerate(b.ts):
            rows = np.arange(b.sig_seg[ep], b.sig_seg[ep + 1])
            truth = {}
            for i, (_, s, on) in enumerate(act):
                if not on[ep]:
                    continue
                mine = rows[np.isin(b.rows.signal_rows[4][rows], list(s.systems))]
                for r in mine.tolist():
                    d = truth.setdefault(str(sv_j[r]), {"spoofer": s.name, "az_deg": round(float(az_sp[i, ep]), 2),
                                                        "el_deg": round(float(el_sp[i, ep]), 2), "captured": []})
                    if captured[r] and best[r] == i and d["spoofer"] == s.name:
                        d["captured"].append(str(b.codes[r]))
            self._truth_by_t[self._key(t)] = truth

    # ---------------------------------------------------------------- after the observables
    def observables(self, b, light_time) -> None:
        """The captured rows' code, phase and Doppler (module doc) and the satellites the receiver solves them
        with; loss-of-lock flags where a signal is captured or released."""
        sp = getattr(b, "spoofed", None)
        captured = sp.captured if sp is not None else np.zeros(b.m, dtype=bool)
        if self._truth_args is not None:
            self._keep_truth(b, *self._truth_args)
            self._truth_args = None
        self._flag_changes(b, captured)
        if sp is None or not len(sp.rows):
            return
        r = sp.rows
        q, e = sp.which[r], b.e_sig[r]
        sat = b.sat_i[r]
        dt = sp.dt_s[q]
        t_true = b.t_true if b.k_n == 1 else b.t_true[e]
        bias = b.bias_ep[e]
        sol = light_time(sp.recv_ecef[q, e], sp.recv_vel[q, e], t_true + dt, bias - dt, b.st.select(sat),
                         b.rows.omega[sat])
        rel0 = -2.0 * np.einsum("ij,ij->i", b.sol.sat_pos_ecef_m[sat], b.sol.sat_vel_ecef_mps[sat]) / k.C_MPS**2
        rel1 = -2.0 * np.einsum("ij,ij->i", sol.sat_pos_ecef_m, sol.sat_vel_ecef_mps) / k.C_MPS**2
        dts = b.dts[r] + b.ddts[r] * (dt - (sol.tau_s - b.sol.tau_s[sat])) + (rel1 - rel0)
        meacon = sp.meacon[q]
        tropo = np.where(meacon, b.tropo_true[r], b.tropo[r])
        iono = np.where(meacon, b.iono_true[r], b.iono_model[r])
        common = sol.range_m + k.C_MPS * (bias - dt - dts) + tropo + sp.dist_m[q, e]
        if b.sisre_m is not None:
            common = common + np.where(meacon, b.sisre_m[r], 0.0)
        lam = b.rows.lam[r]
        b.pr[r] = common + iono + b.rows.code_bias_m[r] + b.mp[r] + b.e_p[r]
        b.phase[r] = (common - iono + b.e_l[r]) / lam + b.amb[r]
        rate = sol.range_rate_mps + sp.dist_rate_mps[q, e] + k.C_MPS * (b.drift_ep[e] - b.ddts[r])
        b.dop[r] = -rate / lam + b.e_d[r]
        b.dts = b.dts.copy()
        b.dts[r] = dts
        sp.sat_pos, sp.sat_vel = sol.sat_pos_ecef_m, sol.sat_vel_ecef_mps

    def _flag_changes(self, b, captured) -> None:
        """LLI bit 0 on the rows whose signal is captured at their epoch and was not at the one before, or the
        reverse (the loop jumps between the authentic and the counterfeit signal)."""
        if not captured.any() and not self._prev:
            return
        keys = _signal_keys(b)
        prev = self._prev
        lli = None
        for ep in range(b.k_n):
            j0, j1 = b.sig_seg[ep], b.sig_seg[ep + 1]
            now = frozenset(keys[j0:j1][captured[j0:j1]].tolist())
            if now != prev:
                changed = now ^ prev
                hit = j0 + np.flatnonzero(np.isin(keys[j0:j1], list(changed)))
                if len(hit):
                    lli = b.lli.copy() if lli is None else lli
                    lli[hit] |= 1
            prev = now
        self._prev = prev
        if lli is not None:
            b.lli = lli

    def truth(self, t) -> dict:
        """{sv: {"spoofer", "az_deg", "el_deg" (the arrival direction), "captured": [codes]}} at epoch ``t``."""
        return self._truth_by_t.get(self._key(t), {})


def _signal_keys(b) -> np.ndarray:
    """(M,) "G051C": each signal row's satellite and code, the tracking loop's key."""
    return np.char.add(np.asarray(b.rows.sv_j, dtype="<U3"), np.asarray(b.codes, dtype="<U2"))


def _velocity(rt, track, t_rel):
    """(K, 3) ECEF velocity [m/s] of a scenario track (central difference of its positions)."""
    if len(track.t_s) == 1:
        return np.zeros((len(t_rel), 3))
    h = _HALF_STEP_S
    return (rt.positions_ecef(track, t_rel + h) - rt.positions_ecef(track, t_rel - h)) / (2.0 * h)
