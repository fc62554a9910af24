"""What a code and carrier tracking loop makes of a line of sight plus reflections.

Signal model (one satellite): the composite correlation of LOS (amplitude a_0, 0 when blocked) and
reflections i (relative amplitude a_i, code delay delta_i chips, carrier phase phi_i rad)

    R_c(tau) = sum_i a_i exp(j phi_i) R_B(tau - delta_i)

with R_B the code's autocorrelation after the front-end filter: the BPSK triangle 1 - |tau| (infinite
bandwidth), or its band-limited form for an ideal (brick-wall) double-sided bandwidth B [chips^-1 units:
B / chip rate]:  R_B(tau) = int_{-B/2}^{B/2} sinc^2(f) cos(2 pi f tau) df, in closed form with the sine
integral (_bandlimited_table) (Betz, Engineering
Satellite-Based Navigation and Timing, 2016, ch. 19; the spectrum of a BPSK-R code is sinc^2).

- Carrier: the PLL locks to the composite phase at the code lock point, theta = arg R_c(eps); the carrier
  phase error is theta (relative to the LOS phase 0) and the received amplitude |R_c(eps)| sets C/N0.
- Code: a coherent early-minus-late discriminator with spacing d chips on the in-phase arm,
  D(eps) = Re[(R_c(eps - d/2) - R_c(eps + d/2)) exp(-j theta)]; the loop settles where D = 0.  The zero
  is found by bisection inside [tau_p - d/2, tau_p + d/2] around the composite correlation's peak tau_p
  (a sign change is guaranteed there), so a receiver with the LOS blocked tracks the strongest reflection.

For one reflection in phase (phi = 0) or in anti-phase (phi = pi) at infinite bandwidth the zero has the
closed form of Van Dierendonck, Fenton and Ford (Navigation 39(3), 1992) and Braasch (Parkinson & Spilker,
vol. I, ch. 14), :func:`analytic_envelope_chips`; :func:`tracking_error` is tested against it.
"""
from __future__ import annotations

import functools

import numpy as np

#: tau grid [chips] of the band-limited correlation table
_TAU_MAX = 3.0
_TAU_STEP = 1e-3


def _h(a, half_band):
    """int_{-F}^{F} (1 - cos(2 pi a f)) / (pi f)^2 df = (4|a| / pi) [Si(X) - (1 - cos X) / X], X = 2 pi |a| F."""
    from scipy.special import sici  # scipy.special: 0.15 s of imports a run without multipath never needs

    x = 2.0 * np.pi * np.abs(a) * half_band
    si, _ = sici(x)
    safe = np.where(x > 0, x, 1.0)
    return np.where(x > 0, 4.0 * np.abs(a) / np.pi * (si - (1.0 - np.cos(x)) / safe), 0.0)


@functools.lru_cache(maxsize=16)
def _bandlimited_table(bandwidth_chips: float):
    """R_B on a tau grid, closed form: with sinc^2(f) = (1 - cos 2 pi f) / (2 (pi f)^2),
    R_B(tau) = -H(tau) / 2 + H(tau + 1) / 4 + H(tau - 1) / 4 (H: :func:`_h`, F = B / 2), which tends to
    1 - |tau| as B grows."""
    tau = np.arange(-_TAU_MAX, _TAU_MAX + _TAU_STEP / 2, _TAU_STEP)
    f = bandwidth_chips / 2.0
    r = -0.5 * _h(tau, f) + 0.25 * _h(tau + 1.0, f) + 0.25 * _h(tau - 1.0, f)
    return tau, r / np.interp(0.0, tau, r)         # normalised to R(0) = 1


def correlation(tau_chips, bandwidth_chips: float = np.inf):
    """Code autocorrelation R_B(tau) of a BPSK-R code (module docstring), normalised to 1 at tau = 0."""
    t = np.asarray(tau_chips, dtype=np.float64)
    if not np.isfinite(bandwidth_chips):
        return np.maximum(1.0 - np.abs(t), 0.0)
    if not bandwidth_chips > 0:
        raise ValueError(f"multipath.dll: bandwidth {bandwidth_chips!r} (chip rates) must be > 0")
    tau, r = _bandlimited_table(float(bandwidth_chips))
    return _table_interp(t, tau, r, *_table_slopes(float(bandwidth_chips)))


@functools.lru_cache(maxsize=16)
def _table_slopes(bandwidth_chips: float):
    """(slope per interval, grid step) of the band-limited table, the slopes as np.interp forms them."""
    tau, r = _bandlimited_table(bandwidth_chips)
    return np.diff(r) / np.diff(tau), (tau[-1] - tau[0]) / (len(tau) - 1)


def _table_interp(x, tau, r, slope, step):
    """np.interp(x, tau, r, left=0, right=0) on the uniform table, equal to it bit for bit (test_multipath_dll_batch):
    the interval from the grid step instead of a binary search (one step either way corrected), then np.interp's
    operations: r[j] where x is a table point, else slope[j] (x - tau[j]) + r[j]."""
    n = len(tau)
    k = np.floor((x - tau[0]) / step)
    np.clip(k, 0, n - 2, out=k)
    j = np.nan_to_num(k).astype(np.intp)
    j -= tau[j] > x
    j += (tau[j + 1] <= x) & (j < n - 2)
    np.clip(j, 0, n - 2, out=j)
    tj, rj = tau[j], r[j]
    v = np.where(x == tj, rj, slope[j] * (x - tj) + rj)
    v = np.where(x == tau[-1], r[-1], v)
    return np.where((x >= tau[0]) & (x <= tau[-1]), v, np.where(np.isnan(x), x, 0.0))


def composite(tau_chips, amp, delay_chips, phase_rad, bandwidth_chips=np.inf):
    """R_c at ``tau_chips`` (..., K) for paths (..., P): complex (..., K)."""
    a = np.asarray(amp, dtype=np.float64)
    ph = np.asarray(phase_rad, dtype=np.float64)
    return _composite(tau_chips, a * np.exp(1j * ph), delay_chips, bandwidth_chips)


def _composite(tau_chips, phasor, delay_chips, bandwidth_chips):
    """R_c at ``tau_chips`` (..., K) for paths (..., P) of complex amplitudes ``phasor`` = a exp(j phi)."""
    t = np.asarray(tau_chips, dtype=np.float64)[..., :, None]
    dl = np.asarray(delay_chips, dtype=np.float64)[..., None, :]
    return np.sum(phasor[..., None, :] * correlation(t - dl, bandwidth_chips), axis=-1)


def tracking_error(amp, delay_chips, phase_rad, spacing_chips: float, bandwidth_chips: float = np.inf,
                   iterations: int = 32, calls=None):
    """(code error [chips], carrier phase error [rad], composite amplitude) of signals (N, P paths).

    Path 0 is usually the line of sight (delay 0; amplitude 0 when blocked); delays are relative to it.
    Rows whose amplitudes are all 0 give NaN (nothing to track).  ``iterations`` halvings of the
    discriminator's bracket (d / 2^32).  ``calls``: (N,) labels, rows of one label searched on the peak grid
    their own call would use (its size set by that call's widest span of delays), so the rows of many
    calls computed at once give each call's bits; None: one call."""
    a = np.atleast_2d(np.asarray(amp, dtype=np.float64))
    dl = np.atleast_2d(np.asarray(delay_chips, dtype=np.float64))
    ph = np.atleast_2d(np.asarray(phase_rad, dtype=np.float64))
    d = float(spacing_chips)
    if not 0 < d <= 2:
        raise ValueError(f"multipath.dll: correlator spacing {spacing_chips!r} chips must be in (0, 2]")
    # peak of |R_c| on a grid over the paths' span, then the discriminator zero next to it
    lo, hi = np.min(dl, axis=1) - 1.0, np.max(dl, axis=1) + 1.0
    # grid step below d / 4 (and 0.05 chip): the grid's peak lies within d / 2 of the true one, so the
    # discriminator changes sign inside the bracket below
    step = min(d / 4.0, 0.05)
    if calls is None:
        n_grid = np.full(len(a), _grid_points(np.max(hi - lo), step))
    else:
        _, call = np.unique(np.asarray(calls), return_inverse=True)
        widest = np.full(int(call.max()) + 1, -np.inf)
        np.maximum.at(widest, call, hi - lo)
        n_grid = np.array([_grid_points(w, step) for w in widest.tolist()], dtype=np.int64)[call]
    return _track(a, dl, ph, lo, hi, d, bandwidth_chips, iterations, n_grid)


def _grid_points(span_chips, step: float) -> int:
    """Points of the peak search grid over ``span_chips`` (at most 4001)."""
    return int(min(np.ceil(float(span_chips) / step), 4000)) + 1


def _peak(c, dl, lo, hi, n_grid, bandwidth_chips):
    """(N,) the first grid point of largest |R_c| per row; the rows' grids (of their own sizes) laid end to end
    in one evaluation per chunk of rows (each point's value as on a rectangular grid: the same operations,
    element by element; chunks of about _PEAK_CHUNK points keep the temporaries small).  Rows grouped by their
    number of paths with a non-zero amplitude, those paths kept in their order: a zero term adds an exact zero
    to the sum, which changes at most the sign of a zero sum, never |R_c|."""
    n = len(c)
    out = np.zeros(n)
    live = c != 0
    count = live.sum(axis=1)
    for k in np.unique(count).tolist():
        rows = np.flatnonzero(count == k)
        cols = np.argsort(~live[rows], axis=1, kind="stable")[:, :k]       # the non-zero paths, in order
        ck, dk = np.take_along_axis(c[rows], cols, axis=1), np.take_along_axis(dl[rows], cols, axis=1)
        ends = np.cumsum(n_grid[rows])
        cuts = (np.flatnonzero(np.diff(ends // _PEAK_CHUNK)) + 1).tolist()
        for r0, r1 in zip([0, *cuts], [*cuts, len(rows)]):
            r = rows[r0:r1]
            out[r] = _peak_rows(ck[r0:r1], dk[r0:r1], lo[r], hi[r], n_grid[r], bandwidth_chips)
    return out


#: grid points per evaluation of :func:`_peak`
_PEAK_CHUNK = 16384


def _peak_rows(c, dl, lo, hi, n_grid, bandwidth_chips):
    """:func:`_peak` of rows evaluated at once."""
    n = len(c)
    sizes = n_grid.tolist()
    lin = {g: np.linspace(0.0, 1.0, g) for g in set(sizes)}
    row = np.repeat(np.arange(n), n_grid)
    grid = lo[row] + (hi - lo)[row] * np.concatenate([lin[g] for g in sizes])
    mag = np.abs(_composite(grid[:, None], c[row], dl[row], bandwidth_chips)[:, 0])
    start = np.concatenate([[0], np.cumsum(n_grid)[:-1]])
    if np.isnan(mag).any():          # argmax's rule (the first NaN) row by row
        return np.array([grid[s0 + np.argmax(mag[s0:s0 + g])] for s0, g in zip(start.tolist(), sizes)])
    top = np.flatnonzero(mag == np.maximum.reduceat(mag, start)[row])
    _, first = np.unique(row[top], return_index=True)       # the first maximum of each row, as argmax
    return grid[top[first]]


def _track(a, dl, ph, lo, hi, d: float, bandwidth_chips, iterations: int, n_grid):
    """tracking_error of rows (N, P), row i's peak searched on n_grid[i] points from lo[i] to hi[i]; then the
    discriminator's bisection."""
    c = a * np.exp(1j * ph)
    tau_p = _peak(c, dl, lo, hi, n_grid, bandwidth_chips)
    theta = np.angle(_composite(tau_p[:, None], c, dl, bandwidth_chips)[:, 0])
    rot = np.exp(-1j * theta)
    half = np.array([-d / 2, d / 2])

    def disc(eps):
        el = _composite(eps[:, None] + half, c, dl, bandwidth_chips)      # early, late in one call
        return np.real((el[:, 0] - el[:, 1]) * rot)

    left, right = tau_p - d / 2, tau_p + d / 2
    f_left = disc(left)
    for _ in range(iterations):
        mid = 0.5 * (left + right)
        f_mid = disc(mid)
        same = np.sign(f_mid) == np.sign(f_left)
        left = np.where(same, mid, left)
        f_left = np.where(same, f_mid, f_left)
        right = np.where(same, right, mid)
    eps = 0.5 * (left + right)
    rc = _composite(eps[:, None], c, dl, bandwidth_chips)[:, 0]
    dead = ~np.any(a > 0, axis=1)
    eps = np.where(dead, np.nan, eps)
    return eps, np.where(dead, np.nan, np.angle(rc)), np.where(dead, 0.0, np.abs(rc))


def analytic_envelope_chips(amp: float, delay_chips, spacing_chips: float, in_phase: bool = True):
    """Closed-form code error [chips] of one reflection at phase 0 (``in_phase``) or pi, infinite bandwidth,
    coherent early-minus-late with spacing d <= 1 (module docstring references):

    in phase:      a delta / (1 + a)              delta <= d (1 + a) / 2
                   a d / 2                        ... <= 1 - d/2 + a d / 2
                   a (1 + d/2 - delta) / (2 - a)  ... <= 1 + d / 2, then 0
    anti-phase:   -a delta / (1 - a)              delta <= d (1 - a) / 2
                  -a d / 2                        ... <= 1 - d/2 - a d / 2
                  -a (1 + d/2 - delta) / (2 + a)  ... <= 1 + d / 2, then 0
    """
    a, d = float(amp), float(spacing_chips)
    x = np.asarray(delay_chips, dtype=np.float64)
    s = 1.0 if in_phase else -1.0
    b1 = d * (1 + s * a) / 2
    b2 = 1 - d / 2 + s * a * d / 2
    out = np.where(x <= b1, s * a * x / (1 + s * a),
                   np.where(x <= b2, s * a * d / 2,
                            np.where(x <= 1 + d / 2, s * a * (1 + d / 2 - x) / (2 - s * a), 0.0)))
    return out
