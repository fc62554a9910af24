"""The georeference error of a 3D model estimated from a real recording (issue 27, "Registration").

A finding to report, never applied to anything: the (east, north) offset [m] that, added to the antenna's
placement in the model's world frame, makes the model agree best with what the real receiver saw.

Criterion (from the real recording only, never from a simulated one): over the satellite-epochs above the mask,
the share of the real receiver's strong signals (C/N0 >= ``strong_cn0_dbhz``: taken as line of sight) that the
model blocks, plus the share of the satellites it does not track that the model leaves in the line of sight.
Minimised on a grid of ``step_m`` within +-``span_m``, then of ``step_m`` / 4 within +-``step_m`` around the
best; the criterion counts signals, so its minimum is often flat over several grid points: the estimate is their
centroid, their spread enters the uncertainty.  OpenStreetMap footprints traced on imagery are off by metres;
that is what this measures.

Uncertainty: the moving-block bootstrap over epochs (Kuensch 1989, Ann. Statist. 17(3) 1217-1241; consecutive
epochs see the same walls, so epochs are resampled in blocks of ``block_epochs``, by default n^(1/3) (Hall,
Horowitz and Jing 1995, Biometrika 82(3) 561-574)); the standard error is the standard deviation of the
bootstrap replicates' minimisers (Efron and Tibshirani 1993, An Introduction to the Bootstrap, ch. 6), every
replicate minimised over the grid points the search visited (coarse far from the estimate, fine near it), plus
the variance of the estimate's flat minimum and the finest grid step's quantisation (step^2 / 12, a uniform
rounding error).
"""
from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..calibration.reading import gnss_times
from ..visibility.line_of_sight import line_of_sight
from ..vocabulary import SYSTEMS

#: bootstrap replicates of the uncertainty
N_BOOTSTRAP = 200


@dataclass
class SightEpochs:
    """What the real receiver saw, per epoch: satellite positions the ephemeris serves, tracked or not, strong."""

    epoch: np.ndarray             # (K,) index of each kept epoch in the caller's epochs
    antenna_world_m: np.ndarray   # (K, 3) the antenna placed in the model (before any offset)
    sat_ecef_m: list              # K arrays (N_k, 3)
    tracked: list                 # K arrays (N_k,) bool: a pseudorange in the real file
    strong: list                  # K arrays (N_k,) bool: tracked with C/N0 >= the threshold


@dataclass
class Registration:
    """The estimate and how well it is known (module docstring)."""

    offset_en_m: tuple            # (east, north) [m] to add to the antenna's placement in the world frame
    sigma_en_m: tuple             # (east, north) 1-sigma [m]: bootstrap spread (+) grid quantisation
    corr_en: float                # correlation of the east and north bootstrap replicates
    criterion_zero: float         # criterion without an offset
    criterion_best: float         # criterion at the estimate
    epochs: int                   # epochs used
    sat_epochs: int               # satellite-epochs above the mask that entered the criterion
    strong_sat_epochs: int        # of which strong tracked signals
    untracked_sat_epochs: int     # of which satellites the real receiver did not track
    span_m: float
    step_m: float
    at_edge: bool                 # the estimate is on the border of the search: a larger span_m is needed
    n_bootstrap: int
    block_epochs: int
    strong_cn0_dbhz: float
    mask_deg: float
    wall_s: float = 0.0

    @property
    def offset_m(self) -> float:
        return float(np.hypot(*self.offset_en_m))


def sight_epochs(times, antenna_world_m, provider, sv, tracked, cn0_dbhz, *, strong_cn0_dbhz: float = 38.0,
                 every: int = 1) -> SightEpochs:
    """:class:`SightEpochs` of a real recording: ``times`` (K,) GnssTime or datetime64 (GPS), ``antenna_world_m``
    (K, 3) (rows with NaN are skipped), ``sv`` (S,) the recording's satellites, ``tracked`` (K, S) bool,
    ``cn0_dbhz`` (K, S); the satellites are those ``provider`` serves at each epoch on the recording's systems."""
    if not hasattr(times, "sec"):
        times = gnss_times(times)
    sv = np.asarray(sv)
    col = {s: j for j, s in enumerate(sv.tolist())}
    systems = "".join(sorted({s[0] for s in sv.tolist()} & set(SYSTEMS)))   # SBAS (S) is not simulated
    ant = np.asarray(antenna_world_m, float).reshape(-1, 3)
    keep, sats, trk, strg = [], [], [], []
    for d in range(0, len(ant), max(1, int(every))):
        if not np.all(np.isfinite(ant[d])):
            continue
        st = provider.states(times[d], systems=systems)
        if len(st) == 0:
            continue
        j = np.array([col.get(s, -1) for s in st.sv])
        t = np.where(j >= 0, tracked[d, np.maximum(j, 0)], False)
        c = np.where(j >= 0, cn0_dbhz[d, np.maximum(j, 0)], np.nan)
        keep.append(d)
        sats.append(np.asarray(st.pos_ecef_m, float))
        trk.append(t.astype(bool))
        strg.append(t & (np.nan_to_num(c) >= strong_cn0_dbhz))
    return SightEpochs(np.array(keep, int), ant[keep] if keep else np.zeros((0, 3)), sats, trk, strg)


def sight_from_table(table, times, antenna_world_m, provider, *, strong_cn0_dbhz: float = 38.0,
                     every: int = 1) -> SightEpochs:
    """:func:`sight_epochs` of an ObsTable (core/rinex/obs_table.py) at its epochs matching ``times`` (K,) exactly
    (rows of the table at the other epochs are not used): tracked = any pseudorange; C/N0 = the satellite's
    S observation of its first code (RINEX order, "S1C" before "S2I" before "S5Q") that has one."""
    from ..rinex.obs_table import match_epochs

    times = np.asarray(times, "datetime64[ns]")
    i_t, i_tab = match_epochs(times, table.time)
    shape = (len(times), len(table.sv))
    tracked = np.zeros(shape, bool)
    cn0 = np.full(shape, np.nan)
    for code in sorted(table.values):
        a = table.values[code][i_tab]
        if code[0] == "C":
            tracked[i_t] |= np.isfinite(a) & (a > 0)
        elif code[0] == "S":
            cur = cn0[i_t]
            cn0[i_t] = np.where(np.isfinite(cur), cur, a)
    ant = np.full((len(times), 3), np.nan)
    ant[i_t] = np.asarray(antenna_world_m, float).reshape(-1, 3)[i_t]
    return sight_epochs(times, ant, provider, table.sv, tracked, cn0, strong_cn0_dbhz=strong_cn0_dbhz,
                        every=every)


def _epoch_counts(scene, sight: SightEpochs, off, mask_deg: float) -> np.ndarray:
    """(K, 4) per epoch: strong signals the model blocks, strong signals, untracked satellites it leaves in the
    line of sight, untracked satellites (all above the mask), with the antenna moved by ``off`` (east, north)."""
    out = np.zeros((len(sight.sat_ecef_m), 4), np.int64)
    d_m = np.array([off[0], off[1], 0.0])
    for e, (sat, tracked, strong) in enumerate(zip(sight.sat_ecef_m, sight.tracked, sight.strong)):
        clear, v = line_of_sight(scene, sight.antenna_world_m[e] + d_m, sat, mask_deg)
        above = np.asarray(v.el_deg) >= mask_deg
        blk = above & ~clear
        s_ = strong & above
        lost = ~tracked & above
        out[e] = (np.sum(blk & s_), s_.sum(), np.sum(~blk & lost), lost.sum())
    return out


def _criterion(counts: np.ndarray, weights=None) -> np.ndarray:
    """Criterion of (..., K, 4) epoch counts, epochs weighted by ``weights`` (B, K) (None: all once) -> (..., B)."""
    w = np.ones((1, counts.shape[-2])) if weights is None else np.asarray(weights, float)
    s = np.einsum("bk,...kc->...bc", w, counts)
    return s[..., 0] / np.maximum(s[..., 1], 1) + s[..., 2] / np.maximum(s[..., 3], 1)


def _block_weights(n_epochs: int, block: int, n_boot: int, rng) -> np.ndarray:
    """(n_boot, n_epochs) counts of each epoch in moving-block bootstrap resamples (Kuensch 1989)."""
    if n_boot <= 0:                        # no resampling (drive_check.model_offset_m): no replicate
        return np.zeros((0, n_epochs))
    block = max(1, min(block, n_epochs))
    n_blocks = int(np.ceil(n_epochs / block))
    starts = rng.integers(0, n_epochs - block + 1, size=(n_boot, n_blocks))
    idx = (starts[:, :, None] + np.arange(block)[None, None, :]).reshape(n_boot, -1)[:, :n_epochs]
    w = np.zeros((n_boot, n_epochs))
    np.add.at(w, (np.repeat(np.arange(n_boot), idx.shape[1]), idx.ravel()), 1.0)
    return w


def _minimum(keys: np.ndarray, crit: np.ndarray):
    """(estimate (2,), variance (2,), value): the criterion ``crit`` (G,) of grid points ``keys`` (G, 2) is a step
    function of counts, so its minimum is often flat over several points: their centroid and spread."""
    low = crit <= np.min(crit) + 1e-12
    return keys[low].mean(axis=0), keys[low].var(axis=0), float(np.min(crit))


def fit_offset(scene, sight: SightEpochs, *, mask_deg: float = 15.0, span_m: float = 6.0, step_m: float = 2.0,
               n_bootstrap: int = N_BOOTSTRAP, block_epochs: int | None = None, seed: int = 0,
               strong_cn0_dbhz: float = float("nan")) -> Registration:
    """The model's georeference offset from ``sight`` (module docstring); ``strong_cn0_dbhz``: only reported
    (the threshold ``sight`` was made with)."""
    import time

    t0 = time.perf_counter()
    n = len(sight.sat_ecef_m)
    if n == 0:
        raise ValueError("registration: no epoch with an antenna position and satellites the ephemeris serves")
    counts: dict = {}

    def at(p):
        key = (round(float(p[0]), 6), round(float(p[1]), 6))
        if key not in counts:
            counts[key] = _epoch_counts(scene, sight, key, mask_deg)
        return key

    def search(centre, half, step):
        ax = np.arange(-half, half + step / 2, step)
        keys = [at((centre[0] + x, centre[1] + y)) for x in ax for y in ax]
        est, var, val = _minimum(np.array(keys), _criterion(np.stack([counts[q] for q in keys]))[:, 0])
        return est, var, val

    best, _, _ = search((0.0, 0.0), span_m, step_m)
    best, tie_var, val = search(best, step_m, step_m / 4)
    zero = counts[at((0.0, 0.0))]
    keys = np.array(list(counts))
    stack = np.stack([counts[tuple(q)] for q in keys])      # (G, K, 4)
    block = int(block_epochs) if block_epochs else max(1, int(round(n ** (1.0 / 3.0))))
    rng = np.random.default_rng(seed)
    w = _block_weights(n, block, int(n_bootstrap), rng)
    crit = _criterion(stack, w)                              # (G, B)
    reps = np.array([_minimum(keys, crit[:, b])[0] for b in range(crit.shape[1])]).reshape(-1, 2)
    # spread of the replicates + the flat bottom of the estimate's own minimum + the finest grid's rounding
    var = tie_var + (step_m / 4) ** 2 / 12.0
    if len(reps) > 1:
        var = var + reps.var(axis=0, ddof=1)
    sd = np.sqrt(var)
    corr = float(np.corrcoef(reps.T)[0, 1]) if len(reps) > 1 and np.all(reps.std(axis=0) > 0) else 0.0
    tot = zero.sum(axis=0)
    return Registration(
        (float(best[0]), float(best[1])), (float(sd[0]), float(sd[1])), corr,
        float(_criterion(zero)[0]), val, n, int(tot[1] + tot[3]), int(tot[1]), int(tot[3]), float(span_m),
        float(step_m), bool(max(abs(best[0]), abs(best[1])) >= span_m - 1e-9),
        int(n_bootstrap), block, float(strong_cn0_dbhz), float(mask_deg), time.perf_counter() - t0)


def registration_markdown(reg: Registration, scene_name: str, apply_hint: str) -> str:
    """The "Registration" section of a report: the estimate as a finding, with how to apply it."""
    e, n = reg.offset_en_m
    se, sn = reg.sigma_en_m
    lines = [
        "## Registration", "",
        f"The georeference error of {scene_name}, estimated from the real recording "
        "(core/comparison/registration.py): **a finding, not applied to anything in this report**.", "",
        f"- offset to add to the antenna's placement in the world frame: east **{e:+.2f} +- {se:.2f} m**, "
        f"north **{n:+.2f} +- {sn:.2f} m** (1 sigma; |offset| {reg.offset_m:.2f} m; east/north correlation "
        f"{reg.corr_en:+.2f})",
        f"- criterion (share of strong real signals the model blocks + share of untracked satellites it leaves "
        f"in sight): {reg.criterion_zero:.3f} without an offset, {reg.criterion_best:.3f} at the estimate",
        f"- data: {reg.epochs} epochs, {reg.sat_epochs} satellite-epochs above the {reg.mask_deg:g} deg mask "
        f"({reg.strong_sat_epochs} strong tracked signals, C/N0 >= {reg.strong_cn0_dbhz:g} dB-Hz; "
        f"{reg.untracked_sat_epochs} untracked)",
        f"- search: grid of {reg.step_m:g} m within +-{reg.span_m:g} m, then {reg.step_m / 4:g} m around the best; "
        f"uncertainty: moving-block bootstrap over epochs ({reg.n_bootstrap} resamples, blocks of "
        f"{reg.block_epochs} epochs), plus the spread of a flat minimum and the grid's quantisation",
    ]
    if reg.at_edge:
        lines.append(f"- **the estimate is on the border of the search (+-{reg.span_m:g} m)**: the error may be "
                     "larger; not a minimum")
    if reg.criterion_best >= reg.criterion_zero - 1e-12:
        lines.append("- the offset does not improve the agreement: no evidence of a georeference error")
    lines += ["", f"To apply it: {apply_hint}", ""]
    return "\n".join(lines)


def apply_hint(reg: Registration) -> str:
    """How a user applies the estimate (nothing does it for them)."""
    e, n = reg.offset_en_m
    return (f"the antenna sits at (east {e:+.2f}, north {n:+.2f}) m from where the truth places it in the model, "
            f"so move the model by ({-e:+.2f}, {-n:+.2f}) m: set the visibility parameter world_offset_enu_m: "
            f"[{-e:.2f}, {-n:.2f}, 0.0] (core/visibility/world_offset.py; simulate, run and the visibility node "
            "say so when it is set), or edit the models' <pose> in the SDF world or the mesh's vertices.")


def write_registration(reg: Registration, folder, scene_name: str) -> Path:
    """``registration.json`` in ``folder``; returns its path."""
    path = Path(folder) / "registration.json"
    d = asdict(reg)
    d.update(scene=scene_name, applied=False, how_to_apply=apply_hint(reg))
    path.write_text(json.dumps(d, indent=2, default=float) + "\n")
    return path
