"""Land-mobile-satellite (LMS) channel model: what a 3D model lacks (street furniture, vehicles, trees, facade
detail, its registration error) as a statistical layer per environment class.

Structure: the three-state model of Perez-Fontan et al., "Statistical modeling of the LMS channel", IEEE Trans. Veh.
Technol. 50(6), 2001, 1549-1567 (ITU-R P.681-11 sec. 6 recommends a two-state good/bad semi-Markov model with Loo
fading instead, as MathWorks' p681LMSChannel documentation describes it: the structure here is the 2001 paper's):

- three states per satellite: 0 line of sight (A), 1 shadowed (B), 2 blocked / deep shadow (C), a Markov chain in
  the distance travelled with state probabilities W_i and mean state lengths D_i [m] per class and elevation band.
  Here a continuous-distance chain: rate of leaving state i 1/D_i, flows between states symmetric (detailed balance,
  F_ij = F_ji, sum_j F_ij = W_i / D_i: the one choice of a 3-state chain with given W and D), so its stationary
  probabilities are W and its mean sojourns D exactly; the step matrix exp(Q d) from the symmetrised generator;
- in each state the Loo distribution: direct signal lognormal (mean alpha [dB], spread psi [dB]) plus diffuse
  multipath, Rayleigh, of mean power MP [dB] relative to an unobstructed line of sight;
- the diffuse multipath as one echo per epoch whose excess delay is exponential with mean tau [m] (the DLR land
  mobile multipath model: Lehner and Steingass, "A novel channel model for land mobile satellite navigation",
  ION GNSS 2005: echo delays exponentially distributed, echo power decaying with delay).

What the scene's rays already give (buildings: blockage, reflections) is not in these classes: they apply to
satellites the scene leaves in sight.  Loo triplets (alpha, psi, MP) of the states: representative values, NOT
checked against the published tables (written from memory of the L-band urban / suburban / open tables of
Perez-Fontan et al. 2001, 40-60 deg, rounded; do not quote them as the paper's).  Sources searched for the tables,
none holding them: the paper's text (only its first page stored), ITU-R P.681 (table of contents only; its sec. 6
model is the two-state one), MathWorks p681LMSChannel pages (no tables), public code (three-state LMS simulators
carry illustrative sets, one intermediate-tree-shadow set without band or source, DVB-SH preset names without
values, SNS3's Ka-band set without source: none the L-band urban / suburban / open rows).  The published W count
the buildings a 3D model casts, so W of a scene's line-of-sight satellites, the state lengths and the echo power
and delay are fitted on the Hong Kong drive (docs/VALIDATION.md "Urban canyons", a drive: per class, never per
site; the MP and delay values below include that fit, a grid that chose echo delay x0.5 and power +2 dB).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

#: states of the chain
LOS, SHADOWED, BLOCKED = 0, 1, 2
#: upper edges of the elevation bands [deg] a class's rows belong to (low, mid, high)
ELEVATION_BANDS_DEG = (30.0, 60.0, 90.0)


@dataclass(frozen=True)
class LmsState:
    """Loo parameters of one state: direct signal mean and spread [dB], diffuse multipath power [dB] and mean excess
    delay of its echo [m]."""

    alpha_db: float
    psi_db: float
    mp_db: float
    echo_delay_m: float


@dataclass(frozen=True)
class LmsClass:
    """One environment class: per elevation band (rows) the state probabilities W (3,) and mean lengths D (3,) [m];
    the Loo parameters of its three states."""

    name: str
    probability: tuple       # (bands, 3) W per elevation band
    length_m: tuple          # (bands, 3) D per elevation band [m]
    states: tuple            # (3,) LmsState

    def band(self, el_deg) -> np.ndarray:
        """Elevation band index of satellites at ``el_deg``."""
        return np.minimum(np.searchsorted(ELEVATION_BANDS_DEG, np.asarray(el_deg, float)), len(ELEVATION_BANDS_DEG) - 1)


#: the classes (module doc for the sources of the numbers)
CLASSES = {
    "open": LmsClass(
        "open",
        probability=((0.96, 0.03, 0.01), (0.98, 0.015, 0.005), (0.99, 0.008, 0.002)),
        length_m=((200.0, 8.0, 5.0), (300.0, 6.0, 4.0), (500.0, 5.0, 3.0)),
        states=(LmsState(0.0, 0.5, -22.0, 15.0), LmsState(-4.0, 2.0, -20.0, 20.0), LmsState(-15.0, 3.0, -24.0, 20.0))),
    "suburban": LmsClass(
        "suburban",
        probability=((0.80, 0.14, 0.06), (0.86, 0.10, 0.04), (0.92, 0.06, 0.02)),
        length_m=((30.0, 8.0, 6.0), (40.0, 7.0, 5.0), (70.0, 6.0, 4.0)),
        states=(LmsState(-0.5, 1.0, -15.0, 12.5), LmsState(-6.0, 2.5, -14.0, 17.5), LmsState(-16.0, 3.0, -18.0, 17.5))),
    "urban": LmsClass(
        "urban",
        probability=((0.66, 0.22, 0.12), (0.72, 0.19, 0.09), (0.80, 0.14, 0.06)),
        length_m=((18.0, 7.0, 6.0), (24.0, 6.0, 5.0), (32.0, 5.0, 4.0)),
        states=(LmsState(-0.5, 1.0, -10.0, 20.0), LmsState(-7.0, 3.0, -8.0, 30.0), LmsState(-18.0, 3.0, -12.0, 30.0))),
}
#: the values of the parameter lms_environment: off, auto (the class from the scene near the antenna) or a class
LMS_ENVIRONMENTS = ("off", "auto", *CLASSES)


def flows(w, d_m) -> np.ndarray:
    """(3, 3) symmetric flows F_ij [1/m] of a 3-state chain with stationary probabilities ``w`` and mean lengths
    ``d_m``: F_ij = F_ji, sum_j F_ij = f_i = w_i / d_i (module doc); a ValueError when no such chain exists
    (one f_i larger than the other two together)."""
    f = np.asarray(w, float) / np.asarray(d_m, float)
    out = np.zeros((3, 3))
    for i, j, k in ((0, 1, 2), (0, 2, 1), (1, 2, 0)):
        out[i, j] = out[j, i] = (f[i] + f[j] - f[k]) / 2.0
    if (out < -1e-15).any():
        raise ValueError(f"lms: no 3-state chain has probabilities {list(w)} and mean lengths {list(d_m)} m")
    return np.maximum(out, 0.0)


@lru_cache(maxsize=64)
def _eigen(w: tuple, d_m: tuple):
    w_a = np.asarray(w, float)
    q = flows(w, d_m) / w_a[:, None]
    np.fill_diagonal(q, -1.0 / np.asarray(d_m, float))
    s = np.sqrt(w_a)
    lam, v = np.linalg.eigh(s[:, None] * q / s[None, :])     # W^1/2 Q W^-1/2 is symmetric (detailed balance)
    return lam, v, s


def step_matrix(w, d_m, step_m: float) -> np.ndarray:
    """(3, 3) transition probabilities over ``step_m`` metres travelled: exp(Q step) (rows: from, columns: to)."""
    lam, v, s = _eigen(tuple(map(float, w)), tuple(map(float, d_m)))
    p = (v * np.exp(lam * float(step_m))) @ v.T
    p = p / s[:, None] * s[None, :]
    p = np.clip(p, 0.0, 1.0)
    return p / p.sum(axis=1, keepdims=True)


def next_states(state, cls: LmsClass, band, step_m: float, u) -> np.ndarray:
    """The states after ``step_m`` metres of satellites (N,) in ``state`` (their elevation ``band``), from uniform
    draws ``u`` (N,)."""
    state, band, u = (np.asarray(x) for x in (state, band, u))
    out = np.empty(len(state), dtype=np.int64)
    for b in np.unique(band).tolist():
        p = step_matrix(cls.probability[b], cls.length_m[b], step_m)
        sel = band == b
        cum = np.cumsum(p[state[sel]], axis=1)
        out[sel] = np.minimum((u[sel][:, None] > cum).sum(axis=1), 2)
    return out


def initial_states(cls: LmsClass, band, u) -> np.ndarray:
    """States drawn from the stationary probabilities W of each satellite's elevation ``band`` (N,), uniform ``u``."""
    cum = np.cumsum(np.asarray(cls.probability, float)[np.asarray(band)], axis=1)
    return np.minimum((np.asarray(u)[:, None] > cum).sum(axis=1), 2)


def loo_parameters(cls: LmsClass, state) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(alpha_db, psi_db, mp_db, echo_delay_m) arrays of satellites in ``state`` (N,)."""
    tab = np.array([[s.alpha_db, s.psi_db, s.mp_db, s.echo_delay_m] for s in cls.states])[np.asarray(state)]
    return tab[:, 0], tab[:, 1], tab[:, 2], tab[:, 3]


def echo(mp_db, echo_delay_m, z_re, z_im, u_delay) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(amplitude, phase [rad], excess delay [m]) of the diffuse echo: complex Gaussian of mean power 10^(MP/10)
    (Rayleigh amplitude, uniform phase) from standard normal ``z_re``, ``z_im``; delay exponential of mean
    ``echo_delay_m`` from uniform ``u_delay`` (inverse CDF)."""
    sigma = np.sqrt(10.0 ** (np.asarray(mp_db, float) / 10.0) / 2.0)
    c = sigma * (np.asarray(z_re, float) + 1j * np.asarray(z_im, float))
    delay = -np.asarray(echo_delay_m, float) * np.log1p(-np.asarray(u_delay, float))
    return np.abs(c), np.angle(c), delay
