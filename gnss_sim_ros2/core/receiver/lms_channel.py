"""The land-mobile-satellite layer on the scene's rays (parameter ``lms_environment``): per satellite the state chain
and Loo fading of core/multipath/lms.py, applied to the satellites with a clear line of sight in the scene.

- which class: a choice about the world, the parameter's: ``off`` (its default), ``open``, ``suburban``, ``urban``, or
  ``auto``: per epoch from the scene near the antenna, sampled where the satellites are: the share of the satellites
  above the horizon whose line of sight the scene's opaque walls block (foliage counts as in sight).  Below
  AUTO_SUBURBAN_SHARE the epoch is an open field and the layer does nothing (no random draw); from AUTO_URBAN_SHARE
  on it is urban.  Without a scene every satellite is in sight: open.  The P.681 / Perez-Fontan classes describe the
  whole environment (city centre, traffic, street furniture), and the layer stands for what the 3D model lacks, which
  its geometry cannot tell: the demo courtyard (walls 12-25 m around a 40 x 30 m yard, its trees and ledge modelled,
  no traffic) blocks a median 46 % of the satellites against 29 % along the Hong Kong drive, so no rule on the
  modelled blocking calls the drive urban and the courtyard not (docs/VALIDATION.md).  ``auto`` is for a city model
  of building blocks only (the Hong Kong one: OpenStreetMap-like footprints and heights), where it was fitted;
- the satellites it acts on: clear lines of sight only; a line through the scene's foliage (attenuated) already
  carries that shadowing, and the layer's shadowed state would count it twice;
- the step of the chains: the antenna's distance travelled since the last epoch, at least STATIC_SPEED_MPS x the
  time step (a standing antenna still sees its surroundings change: vehicles and people passing, the satellites
  moving; an assumption, not from the literature);
- per satellite its own random stream seeded from the receiver's seed and the satellite's id (the same seed, the
  same channel; a satellite's draws do not depend on which others are in view): five uniform draws per epoch where
  it applies (chain step, shadowing level, echo amplitude and phase, echo delay); a satellite the scene blocks or
  attenuates keeps its state and draws nothing;
- the effect per satellite (all its signals): the direct signal's level L ~ N(alpha, psi) dB of its state (drawn
  when it enters the state, kept while it stays) and the diffuse echo, through the receiver's DLL
  (multipath.dll.tracking_error with the profile's correlator spacing and front-end bandwidth): a code error and
  the composite amplitude, added to C/N0 (so a blocked state loses the signal where its C/N0 falls below the
  loss threshold).
"""
from __future__ import annotations

import numpy as np

from .. import constants as k
from ..multipath import dll, lms

#: auto: shares of the satellites above the horizon the scene's opaque walls block from which an epoch is suburban /
#: urban (fitted on the Hong Kong drive, docs/VALIDATION.md; ITU-R P.681-10 sec. 6 names the classes by description)
AUTO_SUBURBAN_SHARE = 0.15
AUTO_URBAN_SHARE = 0.35
#: the smallest speed the chains step with [m/s] (module doc)
STATIC_SPEED_MPS = 1.0
#: a constant of the streams' seed: these streams differ from every other one of the receiver
_STREAM = 0x4C4D53


def environment_class(mode: str, blocked_share: float) -> lms.LmsClass | None:
    """The class of one epoch: ``mode`` a class name, or ``auto`` with the share of satellites the scene blocks;
    None: nothing to apply."""
    if mode == "off":
        return None
    if mode != "auto":
        return lms.CLASSES[mode]
    if blocked_share >= AUTO_URBAN_SHARE:
        return lms.CLASSES["urban"]
    if blocked_share >= AUTO_SUBURBAN_SHARE:
        return lms.CLASSES["suburban"]
    return None


def _sv_key(sv: str) -> int:
    return ord(sv[0]) * 1000 + int(sv[1:])


class LmsChannel:
    """The channel states of one receiver's satellites (memory from epoch to epoch)."""

    def __init__(self, mode: str, seed: int):
        if mode not in lms.LMS_ENVIRONMENTS:
            raise ValueError(f"receiver: parameter 'lms_environment' = {mode!r} (one of {lms.LMS_ENVIRONMENTS})")
        self.mode = mode
        self.seed = int(seed)
        self._rng: dict[str, np.random.Generator] = {}
        self._state: dict[str, int] = {}
        self._level_db: dict[str, float] = {}
        self._prev_rx = None

    def _draws(self, svs) -> np.ndarray:
        """(N, 5) uniform draws of the satellites ``svs`` this epoch, each from its own stream."""
        out = np.empty((len(svs), 5))
        for i, sv in enumerate(svs):
            g = self._rng.get(sv)
            if g is None:
                g = self._rng[sv] = np.random.default_rng([self.seed, _STREAM, _sv_key(sv)])
            out[i] = g.random(5)
        return out

    def epoch(self, rx_ecef_m, dt_s: float, svs, el_deg, in_sight, blocked_share: float):
        """One epoch: satellites ``svs`` (N,) at ``el_deg``; ``in_sight`` (N,) bool: the scene leaves the line of
        sight clear (neither blocked nor through foliage).  Returns (rows (M,) of the satellites it applies to,
        level_db (M,), echo amplitude, phase [rad], excess delay [m]) or None (nothing applies this epoch)."""
        rx = np.asarray(rx_ecef_m, float)
        moved_m = 0.0 if self._prev_rx is None else float(np.linalg.norm(rx - self._prev_rx))
        self._prev_rx = rx
        cls = environment_class(self.mode, blocked_share)
        rows = np.flatnonzero(np.asarray(in_sight, bool))
        if cls is None or len(rows) == 0:
            return None
        step_m = max(moved_m, STATIC_SPEED_MPS * max(float(dt_s), 0.0))
        sv_r = [str(svs[i]) for i in rows]
        band = cls.band(np.asarray(el_deg, float)[rows])
        u = self._draws(sv_r)
        old = np.array([self._state.get(s, -1) for s in sv_r], dtype=np.int64)
        new = np.empty(len(rows), dtype=np.int64)
        first = old < 0
        if first.any():
            new[first] = lms.initial_states(cls, band[first], u[first, 0])
        if (~first).any():
            new[~first] = lms.next_states(old[~first], cls, band[~first], step_m, u[~first, 0])
        alpha, psi, mp_db, delay_mean = lms.loo_parameters(cls, new)
        # u[:, 1] -> the state's shadowing level (drawn on entering it), u[:, 2:4] -> the echo (Box-Muller: a complex
        # Gaussian from two uniforms, its phase uniform, its amplitude Rayleigh), u[:, 4] -> the echo's delay
        level = np.empty(len(rows))
        z = np.sqrt(-2.0 * np.log1p(-u[:, 2]))
        for i, s in enumerate(sv_r):
            if new[i] != old[i]:
                self._level_db[s] = float(alpha[i] + psi[i] * _normal(u[i, 1]))
            self._state[s] = int(new[i])
            level[i] = self._level_db[s]
        turn = 2 * np.pi * u[:, 3]
        amp, phase, delay = lms.echo(mp_db, delay_mean, z * np.cos(turn), z * np.sin(turn), u[:, 4])
        return rows, level, amp, phase, delay


def _normal(u: float) -> float:
    """Standard normal quantile of a uniform draw (inverse CDF)."""
    from statistics import NormalDist

    return NormalDist().inv_cdf(min(max(float(u), 1e-12), 1 - 1e-12))


def code_and_amplitude(level_db, amp, phase, delay_m, chip_m, spacing_chips: float, bandwidth_hz: float,
                       calls=None):
    """(code error [m], composite amplitude) of signal rows (J,): the direct signal at ``level_db`` and the echo
    (amplitude, phase, excess delay) through the DLL (multipath/dll.py); ``calls``: (J,) labels (an epoch's rows),
    each label's rows with the bits of a call of its own (dll.tracking_error's ``calls``); None: one call.

    Rows equal bit for bit in every input and label (a satellite's signals of one chip rate in one epoch: the
    same state, echo and DLL bandwidth) go through the DLL once, the first of them in the rows' order: a row's
    result depends on its own inputs and its call's widest delay span only, which a repeated row leaves as it is."""
    chip = np.asarray(chip_m, float)
    cols = [np.asarray(x, float) for x in (level_db, amp, phase, delay_m)]
    label = np.zeros(len(chip), np.int64) if calls is None else np.unique(np.asarray(calls), return_inverse=True)[1]
    if len(chip) == 0:
        return np.empty(0), np.empty(0)
    bits = np.column_stack([label.astype(float).reshape(-1), chip, *cols]).view(np.int64)
    _, first, back = np.unique(bits, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)                     # the distinct rows in the order they come
    rank = np.empty(len(order), np.int64)
    rank[order] = np.arange(len(order))
    keep = first[order]
    code, mag = _code_and_amplitude(*(c[keep] for c in cols), chip[keep], spacing_chips, bandwidth_hz,
                                    None if calls is None else label.reshape(-1)[keep])
    back = rank[back.reshape(-1)]
    return code[back], mag[back]


def _code_and_amplitude(level_db, amp, phase, delay_m, chip, spacing_chips: float, bandwidth_hz: float, calls):
    """:func:`code_and_amplitude` of distinct rows."""
    a0 = 10.0 ** (level_db / 20.0)
    amps = np.column_stack([a0, amp])
    delays = np.column_stack([np.zeros(len(a0)), delay_m / chip])
    phases = np.column_stack([np.zeros(len(a0)), phase])
    code = np.empty(len(a0))
    mag = np.empty(len(a0))
    bw_chips = bandwidth_hz * chip / k.C_MPS
    for bw in np.unique(bw_chips):
        g = np.flatnonzero(bw_chips == bw)
        eps, _, m = dll.tracking_error(amps[g], delays[g], phases[g], spacing_chips, float(bw),
                                       calls=None if calls is None else calls[g])
        code[g], mag[g] = eps * chip[g], m
    return code, mag
