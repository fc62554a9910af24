"""Single-point position, velocity and time from one epoch of pseudoranges and range rates.

Weighted least squares (Gauss-Newton) over every tracked system, with one
receiver clock bias for the reference system and one inter-system bias per
additional clock group (RTKLIB pntpos.c convention; QZSS and SBAS share the
GPS clock by default).  The caller gives satellite ECEF positions already at
transmit time and already rotated into the ECEF frame of the reception
instant (Sagnac effect, IS-GPS-200N 20.3.3.4.3.4), and either corrected
pseudoranges or the corrections as separate arrays:

    y = P + c * dt_sat - I - T = |r_sat - r_rx| + c * dt_rx(system)      (IS-GPS-200N 20.3.3.3.3)

Measurement weights 1/sigma^2 with the RTKLIB-like elevation model
``sigma^2 = f_sys^2 (a^2 + b^2 / sin^2(el))`` (RTKLIB pntpos.c varerr(),
EFACT_GLO = 1.5, EFACT_SBS = 3), or a C/N0 model ``sigma^2 = a^2 + k^2 10^(-C/N0/10)``
(the code tracking jitter of a DLL scales as 1/sqrt(C/N0), Kaplan eq. 5.23;
k = 146 m gives 0.82 m at 45 dB-Hz), or sigmas given by the caller.

Residual check: the weighted sum of squared residuals v^T W v follows a
chi-square law with n - m degrees of freedom when the sigmas are right; it is
tested at the false-alarm probability ``chi2_prob_false_alarm``.  On failure
the satellite with the largest standardised residual (w-test, Baarda) is
excluded and the epoch re-solved, up to ``max_exclusions`` times (RAIM FDE).
If the test still fails (or there is too little redundancy to name the faulty
satellite) the solution is kept and flagged (``residual_failure="fix"``, the
default: a fix wherever four satellites are usable, as receivers report) or
dropped (``"no_fix"``, RTKLIB's valsol()).  The covariance is scaled by the
a-posteriori variance factor max(1, chi2 / dof) (``scale_covariance``), so a
fix from inconsistent ranges reports a larger NavSatFix covariance.

Velocity and clock drift from range rates (Doppler) by least squares:
``rate = e . (v_sat - v_rx) + c (ddt_rx - ddt_sat)`` with e the unit vector
receiver -> satellite (satellite velocities rotated like the positions).
"""
from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from .constants import C_MPS
from .frames import ecef_to_geodetic, ecef_to_geodetic_pointwise, enu_rotation
from .memo import BoundedCache

#: order in which systems become the reference clock (the first present)
SYSTEM_ORDER = "GECRJIS"
#: positions closer than this to the Earth centre [m] are not yet a receiver position:
#: no elevation mask nor elevation weights (RTKLIB satazel() does the same below the surface)
_NEAR_CENTRE_M = 6.0e6
#: Gauss-Newton step [m] below which the position counts as known (mask and weights start)
_PLACED_STEP_M = 1000.0


@dataclass
class SolverConfig:
    """Options of :func:`solve_pvt` (defaults RTKLIB-like)."""

    elevation_mask_deg: float = 10.0
    #: "elevation" (a, b model), "cn0" (needs cn0_dbhz) or "equal"
    weighting: str = "elevation"
    sigma_a_m: float = 0.3          # RTKLIB: err = 0.003 m x eratio 100
    sigma_b_m: float = 0.3
    #: sigma factor per system (RTKLIB pntpos.c EFACT_GLO, EFACT_SBS)
    system_error_factor: Mapping[str, float] = field(default_factory=lambda: {"R": 1.5, "S": 3.0})
    cn0_sigma_k_m: float = 146.0    # C/N0 model: sigma^2 = a^2 + k^2 10^(-cn0/10)
    #: range-rate sigma model [m/s] (elevation model like the code)
    rate_sigma_a_mps: float = 0.05
    rate_sigma_b_mps: float = 0.05
    max_iterations: int = 20
    convergence_m: float = 1e-4
    check_residuals: bool = True
    chi2_prob_false_alarm: float = 1e-3   # RTKLIB valsol(): chi-square at alpha = 0.001
    max_exclusions: int = 2
    #: when the residual test still fails after the exclusions (or cannot name the faulty satellite):
    #: "fix" keeps the solution (flagged in ``reason``, ``chi2_ok`` False, covariance scaled), as u-blox and
    #: other mass-market receivers report a position wherever four satellites are usable; "no_fix" drops it
    #: (RTKLIB valsol() behaviour)
    residual_failure: str = "fix"
    #: scale the covariance by the a-posteriori variance factor max(1, chi2 / dof) (residuals larger than
    #: the sigmas say widen the reported covariance, as receivers' NavSatFix covariances do)
    scale_covariance: bool = True
    max_gdop: float = 30.0                # RTKLIB default maxgdop
    #: systems whose clock is that of another system (QZSST and SBAS network time are GPST)
    clock_groups: Mapping[str, str] = field(default_factory=lambda: {"J": "G", "S": "G"})
    #: the systems a receiver tracks (RINEX letters, e.g. "GRECJI"; "": those of the satellites given): its
    #: epochs are solved with a clock column for each of their clock groups, one without satellites in an
    #: epoch left out of that epoch's unknowns (_filled), so that the epochs of receivers configured alike
    #: (a fleet's robots) are solved together whatever satellites each sees, each with the bits it gets alone
    clock_systems: str = ""


#: templates of the unset velocity fields (copied: np.full's own overhead is larger)
_NAN3 = np.full(3, np.nan)
_NAN33 = np.full((3, 3), np.nan)


@dataclass
class PvtSolution:
    """Result of one epoch.  Per-satellite arrays follow the input order."""

    status: str                     # "fix" | "no_fix"
    reason: str                     # why no fix, or notes on a fix ("" when none)
    pos_ecef_m: np.ndarray          # (3,) ECEF WGS 84 (NaN without fix)
    lat_deg: float
    lon_deg: float
    h_m: float                      # ellipsoidal height
    clock_bias_m: dict[str, float]  # per clock group (reference + inter-system bias), metres
    clock_bias_s: dict[str, float]
    ref_system: str
    cov_ecef_m2: np.ndarray         # (3, 3) position covariance in ECEF
    cov_enu_m2: np.ndarray          # (3, 3) in ENU at the solution
    cov_full: np.ndarray            # (3 + n_clocks) square, order: x, y, z, clocks of ``clock_systems``
    clock_systems: list[str]
    gdop: float
    pdop: float
    hdop: float
    vdop: float
    tdop: float
    sv: np.ndarray                  # (N,) input ids
    used: np.ndarray                # (N,) bool
    excluded: list[str]             # satellites excluded by the residual check
    residuals_m: np.ndarray         # (N,) y - model (NaN where not used)
    el_deg: np.ndarray              # (N,) at the solution (NaN without position)
    az_deg: np.ndarray
    n_used: int
    n_iterations: int
    chi2: float                     # v^T W v
    chi2_threshold: float
    chi2_ok: bool | None            # None when there is no redundancy
    vel_ecef_mps: np.ndarray = field(default_factory=_NAN3.copy)
    vel_enu_mps: np.ndarray = field(default_factory=_NAN3.copy)
    clock_drift_mps: float = math.nan
    clock_drift_sps: float = math.nan
    cov_vel_ecef_m2ps2: np.ndarray = field(default_factory=_NAN33.copy)
    #: the velocity's covariance in ENU at the solution [m^2/s^2] (from the a-priori range-rate sigmas)
    cov_vel_enu_m2ps2: np.ndarray = field(default_factory=_NAN33.copy)
    vel_residuals_mps: np.ndarray | None = None
    vel_status: str = "none"        # "fix" | "no_fix" | "none" (no rates given)
    vel_reason: str = ""

    @property
    def sv_used(self) -> list[str]:
        return [s for s, u in zip(self.sv.tolist(), self.used.tolist()) if u]

    @property
    def is_fix(self) -> bool:
        return self.status == "fix"


def pseudorange_sigma_m(el_deg, sv=None, cn0_dbhz=None, config: SolverConfig | None = None):
    """Pseudorange standard deviation [m] from elevation (and C/N0) per ``config.weighting``."""
    cfg = config or SolverConfig()
    el = np.asarray(el_deg, dtype=np.float64)
    var = _variance(el, cn0_dbhz, cfg)
    if sv is not None:
        var = var * _system_factor(sv, cfg) ** 2
    return np.sqrt(var)


def _variance(el, cn0_dbhz, cfg: SolverConfig):
    if cfg.weighting == "equal":
        return np.full(el.shape, cfg.sigma_a_m**2 + cfg.sigma_b_m**2)
    if cfg.weighting == "elevation":
        s = np.sin(np.radians(np.clip(el, 1.0, 90.0)))  # clip: no infinite sigma at the horizon
        return cfg.sigma_a_m**2 + cfg.sigma_b_m**2 / s**2
    if cfg.weighting == "cn0":
        if cn0_dbhz is None:
            raise ValueError("SolverConfig.weighting='cn0' needs cn0_dbhz")
        return cfg.sigma_a_m**2 + cfg.cn0_sigma_k_m**2 * 10.0 ** (-np.asarray(cn0_dbhz, dtype=np.float64) / 10.0)
    raise ValueError(f"SolverConfig.weighting={cfg.weighting!r}; expected 'elevation', 'cn0' or 'equal'")


def _system_factor(sv, cfg: SolverConfig) -> np.ndarray:
    """sigma factor per satellite from ``cfg.system_error_factor`` (1 for systems not listed)."""
    return np.array([cfg.system_error_factor.get(s[0], 1.0) for s in np.asarray(sv).tolist()])


@functools.lru_cache(maxsize=256)
def _chi2_threshold(prob_false_alarm: float, dof: int) -> float:
    """Chi-square quantile 1 - p_fa for ``dof`` degrees of freedom: the inverse of the complemented
    chi-square distribution (scipy.special.chdtri, Cephes; as scipy.stats.chi2.ppf(1 - p_fa)); the
    default p_fa = 0.001 from a table of chdtri's values (no scipy import at start-up, about 0.25 s);
    cached: the same few values come back every epoch."""
    if prob_false_alarm == 1e-3 and 1 <= dof <= len(CHI2_QUANTILE_P001):
        return CHI2_QUANTILE_P001[dof - 1]
    from scipy.special import chdtri

    return float(chdtri(dof, prob_false_alarm))


#: scipy.special.chdtri(dof, 0.001) for dof = 1..50 (more than a receiver of every system reaches), as
#: round-trip decimals (the same doubles; test_solver.py compares every entry with scipy)
CHI2_QUANTILE_P001 = (
    10.827566170662733, 13.815510557964274, 16.26623619623813, 18.466826952903173, 20.515005652432876,
    22.457744484825323, 24.321886347856854, 26.124481558376143, 27.877164871256575, 29.58829844507442,
    31.26413362023999, 32.90949040736021, 34.52817897487089, 36.12327368039814, 37.69729821835383,
    39.25235479076848, 40.79021670690253, 42.31239633167997, 43.82019596451753, 45.31474661812587,
    46.7970380415613, 48.26794229083519, 49.72823246643151, 51.17859777737739, 52.61965577617283,
    54.051962388576655, 55.47602020574521, 56.892285393353625, 58.30117348979492, 59.703064304429944,
    61.09830608105814, 62.487219057088495, 63.87009852234495, 65.24721746094242, 66.61882884370104,
    67.98516762602424, 69.3464524962412, 70.70288741150503, 72.0546629519878, 73.40195751899103,
    74.74493839842374, 76.08376270770003, 77.41857824131394, 78.74952422804303, 80.07673201081901,
    81.40032565871002, 82.72042251912403, 84.0371337172235, 85.350564608593, 86.66081519040317,
)


def range_rate_from_doppler(doppler_hz, carrier_hz):
    """Range rate [m/s] from a Doppler shift [Hz]: -D c / f (RINEX D: positive approaching)."""
    return -np.asarray(doppler_hz, dtype=np.float64) * C_MPS / np.asarray(carrier_hz, dtype=np.float64)


def _as_array(name, x, n, shape_tail=()):
    a = np.asarray(x, dtype=np.float64)
    if a.ndim == 0 and not shape_tail:
        a = np.full(n, float(a))
    if a.shape != (n,) + shape_tail:
        raise ValueError(f"solve_pvt: {name} has shape {a.shape}, expected {(n,) + shape_tail}")
    return a


def _spd_inverses(a: np.ndarray) -> np.ndarray:
    """Inverses of symmetric positive definite matrices (K, U, U), numpy's batched inverse symmetrised
    (one path for one epoch and many)."""
    return _symmetrised(np.linalg.inv(a))


def _symmetrised(inv: np.ndarray) -> np.ndarray:
    return 0.5 * (inv + np.swapaxes(inv, 1, 2))


def dops_from_az_el(az_deg, el_deg, used, clock_index=None):
    """(gdop, pdop, hdop, vdop, tdop) (K,) of the satellites ``used`` (K, N) bool at ``az_deg``/``el_deg`` (K, N)
    in the receiver's local ENU, without solving: the same unweighted design matrix as the solver's DOPs (unit
    line of sight, one clock column per clock group ``clock_index`` (N,) int, all 0 by default); TDOP of the
    first group present.  NaN where fewer satellites than unknowns (3 + clock groups present) are used."""
    az, el = np.radians(np.asarray(az_deg, np.float64)), np.radians(np.asarray(el_deg, np.float64))
    ce = np.cos(el)
    return dops_from_los_enu((ce * np.sin(az), ce * np.cos(az), np.sin(el)), used, clock_index)


def dops_from_los_enu(los_enu, used, clock_index=None):
    """:func:`dops_from_az_el` from the unit lines of sight (east, north, up), each (K, N) (several sets of
    ``used`` satellites of one geometry pay the sines and cosines once): :func:`dops_from_moments` of
    :func:`dop_moments`."""
    return dops_from_moments(*dop_moments(los_enu, used, clock_index))


#: the pairs (i, j) of the second moments of dop_moments, in their order
_PAIRS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def dop_moments(los_enu, used, clock_index=None):
    """What the DOPs of the satellites ``used`` (K, N) need of their unit lines of sight ``los_enu`` (e, n, u),
    each (K, N): per row, the count (G, K) and the sums of each component (3, G, K) of each clock group
    (``clock_index`` (N,), all 0 by default), and the sums of the products of two components (6, K) in the order
    00 01 02 11 12 22.  One (4, K, N) scratch array holds w and w x los; every other pass is a row sum."""
    use = np.asarray(used, bool)
    k, n = use.shape
    ci = np.zeros(n, np.int64) if clock_index is None else np.asarray(clock_index, np.int64)
    g = int(ci.max(initial=0)) + 1
    wh = np.empty((4, k, n))
    np.copyto(wh[0], use)                                                  # w: 1 for a used satellite
    for i in range(3):
        np.multiply(los_enu[i], wh[0], out=wh[i + 1])                      # w x los (unused satellites 0)
    sums = _clock_group_sums(wh, ci, g)                                    # (4, G, K): n_g, sums of w x los
    s2 = np.stack([np.einsum("ks,ks->k", wh[i + 1], los_enu[j]) for i, j in _PAIRS])
    return sums[0], sums[1:], s2


def dop_moments_of_entries(los_enu, rows, cols, n_rows: int, clock_index, n_groups: int):
    """:func:`dop_moments` of the entries (``rows``, ``cols``) (E,) of ``los_enu`` (each (K, N)), gathered (a few
    entries: the difference between two sets, whose moments subtract)."""
    ci = np.asarray(clock_index, np.int64)
    n_s = np.shape(los_enu[0])[1]
    flat = np.asarray(rows, np.int64) * n_s + np.asarray(cols, np.int64)
    c = [np.asarray(x).reshape(-1).take(flat) for x in los_enu]
    bin_g = ci[cols] * n_rows + rows
    size = n_groups * n_rows
    cnt = np.bincount(bin_g, minlength=size).astype(np.float64).reshape(n_groups, n_rows)
    s1 = np.stack([np.bincount(bin_g, weights=x, minlength=size).reshape(n_groups, n_rows) for x in c])
    s2 = np.stack([np.bincount(rows, weights=c[i] * c[j], minlength=n_rows) for i, j in _PAIRS])
    return cnt, s1, s2


def dops_from_moments(cnt, s1, s2):
    """(gdop, pdop, hdop, vdop, tdop) (K,) from :func:`dop_moments`.

    Each satellite has one clock column, so the clock block D of the normal matrix [[A, B], [B^T, D]] is
    diagonal (the satellite count n_g of each group): the position block of the inverse is the 3 x 3 inverse of
    the Schur complement S = A - B D^-1 B^T = sum_s h_s h_s^T - sum_g n_g m_g m_g^T (m_g = mean_g h), and a
    clock's variance is 1 / n_g + m_g^T S^-1 m_g (block inversion), all closed form.  The signs of h = -los
    cancel in every product, so the sums of the lines of sight enter as they are."""
    k = cnt.shape[1]
    present = cnt > 0
    inv_n = np.divide(1.0, cnt, out=np.zeros_like(cnt), where=present)
    mean = s1 * inv_n                                                      # (3, G, K): m_g
    # sum_g n_g m_gi m_gj = sum_g (sum_g los_i) m_gj
    a00, a01, a02, a11, a12, a22 = (s2[p] - np.einsum("gk,gk->k", s1[i], mean[j]) for p, (i, j) in enumerate(_PAIRS))
    c00, c01, c02 = a11 * a22 - a12 * a12, a02 * a12 - a01 * a22, a01 * a12 - a02 * a11     # adjugate
    c11, c12, c22 = a00 * a22 - a02 * a02, a01 * a02 - a00 * a12, a00 * a11 - a01 * a01
    det = a00 * c00 + a01 * c01 + a02 * c02
    ok = (np.einsum("gk->k", cnt) >= 3 + np.einsum("gk->k", present.astype(np.float64))) & (det > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_det = np.where(ok, 1.0 / det, np.nan)
        q00, q11, q22 = c00 * inv_det, c11 * inv_det, c22 * inv_det
        q01, q02, q12 = c01 * inv_det, c02 * inv_det, c12 * inv_det
        ref = np.argmax(present, axis=0)                                   # the first group present
        rows = np.arange(k)
        m = [mi[ref, rows] for mi in mean]
        tvar = (inv_n[ref, rows] + q00 * m[0] ** 2 + q11 * m[1] ** 2 + q22 * m[2] ** 2
                + 2.0 * (q01 * m[0] * m[1] + q02 * m[0] * m[2] + q12 * m[1] * m[2]))
        # a degenerate geometry (satellites on one cone): DOPs beyond any use, reported as NaN
        good = ok & (q00 + q11 + q22 < 1e8) & (q00 + q11 + q22 > 0)
        hdop = np.sqrt(np.maximum(q00 + q11, 0.0))
        vdop = np.sqrt(np.maximum(q22, 0.0))
        pdop = np.sqrt(hdop**2 + vdop**2)
        tdop = np.sqrt(np.maximum(tvar, 0.0))
        gdop = np.sqrt(pdop**2 + tdop**2)
    out = np.stack([gdop, pdop, hdop, vdop, tdop])
    out[:, ~good] = np.nan
    return tuple(out)


def _clock_group_sums(x, ci, g: int) -> np.ndarray:
    """(L, G, K) sums of the columns of ``x`` (L, K, N) per clock group ``ci`` (N,): a row sum over each run of
    columns when the groups are runs (satellites sorted by system, as the planner's are: einsum's contiguous sum,
    no reduceat), else a product with the one-hot matrix (a BLAS call, whose threads contend on a loaded
    machine)."""
    n_l, k, n = x.shape
    out = np.zeros((n_l, g, k))
    if n == 0:
        return out
    starts = np.flatnonzero(np.r_[True, ci[1:] != ci[:-1]])
    if len(np.unique(ci[starts])) == len(starts):              # every group one run of columns
        for a, b in zip(starts.tolist(), np.r_[starts[1:], n].tolist()):
            out[:, ci[a]] = np.einsum("lks->lk", x[:, :, a:b])
        return out
    onehot = np.zeros((n, g))
    onehot[np.arange(n), ci] = 1.0
    return np.ascontiguousarray(np.swapaxes(x @ onehot, 1, 2))


#: ||N||_F ||N^-1||_F below which a normal matrix passes the geometry check without its eigenvalues
#: (_solve_positions): 100 times below the limit of 1e14, so that neither the rounding of the computed
#: inverse nor that of the matrix can make a difference
_SURE_COND = 1e12


def _clock_group(sv_list, groups: Mapping[str, str]) -> np.ndarray:
    return np.array([groups.get(s[0], s[0]) for s in sv_list])


_CONFIGURED_GROUPS = BoundedCache(64)


def _configured_groups(cfg: SolverConfig) -> frozenset:
    """The clock groups of ``cfg.clock_systems`` (empty: none configured); checked and kept per value."""
    key = (cfg.clock_systems, tuple(cfg.clock_groups.items()))
    hit = _CONFIGURED_GROUPS.get(key)
    if hit is None:
        bad = [s for s in cfg.clock_systems if s not in SYSTEM_ORDER]
        if bad:
            raise ValueError(f"SolverConfig.clock_systems {cfg.clock_systems!r}: {''.join(bad)!r} are not RINEX "
                             f"system letters ({SYSTEM_ORDER})")
        hit = _CONFIGURED_GROUPS.put(key, frozenset(_clock_group(cfg.clock_systems, cfg.clock_groups).tolist()))
    return hit


_DEFAULT_CONFIG: list = []
_SAT_TABLE_CACHE = BoundedCache(128)


def _default_config() -> SolverConfig:
    """A shared SolverConfig() for calls without one (never handed out, so never changed)."""
    if not _DEFAULT_CONFIG:
        _DEFAULT_CONFIG.append(SolverConfig())
    return _DEFAULT_CONFIG[0]


def _satellite_table(sv_arr: np.ndarray, cfg: SolverConfig):
    """(clock group, sigma factor) per satellite, ids checked; cached per satellite list and config values
    (the same satellites come back epoch after epoch)."""
    key = (sv_arr.dtype.str, sv_arr.tobytes(), tuple(cfg.clock_groups.items()),
           tuple(cfg.system_error_factor.items()))
    hit = _SAT_TABLE_CACHE.get(key)
    if hit is None:
        bad_ids = [s for s in sv_arr.tolist() if len(s) != 3 or s[0] not in SYSTEM_ORDER]
        if bad_ids:
            raise ValueError(f"solve_pvt: sv has ids that are not RINEX satellite ids: {bad_ids[:5]}")
        hit = (_clock_group(sv_arr.tolist(), cfg.clock_groups), _system_factor(sv_arr, cfg))
        _SAT_TABLE_CACHE.put(key, hit)
    return hit


def solve_pvt(sv, sat_pos_ecef_m, pseudorange_m, *, sat_clock_bias_s=None, iono_delay_m=None,
              tropo_delay_m=None, sigma_m=None, cn0_dbhz=None, prior_ecef_m=None,
              sat_vel_ecef_mps=None, range_rate_mps=None, sat_clock_drift_sps=None,
              config: SolverConfig | None = None) -> PvtSolution:
    """Position (and velocity when range rates are given) of one epoch.

    ``sv``: (N,) ids like "G05"; ``sat_pos_ecef_m``: (N, 3) at transmit time,
    rotated to the ECEF frame of reception; ``pseudorange_m``: (N,), NaN =
    not available.  Optional corrections (N,): ``sat_clock_bias_s`` (added
    as c*dt), ``iono_delay_m`` and ``tropo_delay_m`` (subtracted).
    ``sigma_m``: (N,) pseudorange sigmas (override the config model);
    ``cn0_dbhz`` for C/N0 weighting; ``prior_ecef_m`` start point (default
    the Earth centre).  Velocity: ``sat_vel_ecef_mps`` (N, 3),
    ``range_rate_mps`` (N,) and optionally ``sat_clock_drift_sps`` (N,).
    One epoch of :func:`solve_pvt_many`.
    """
    return solve_pvt_many([dict(
        sv=sv, sat_pos_ecef_m=sat_pos_ecef_m, pseudorange_m=pseudorange_m, sat_clock_bias_s=sat_clock_bias_s,
        iono_delay_m=iono_delay_m, tropo_delay_m=tropo_delay_m, sigma_m=sigma_m, cn0_dbhz=cn0_dbhz,
        prior_ecef_m=prior_ecef_m, sat_vel_ecef_mps=sat_vel_ecef_mps, range_rate_mps=range_rate_mps,
        sat_clock_drift_sps=sat_clock_drift_sps)], config)[0]


class _Epoch:
    """One epoch's checked inputs (solve_pvt_many)."""

    __slots__ = ("sv", "n", "groups", "fac", "sat", "y", "sig", "cn0", "valid", "x0", "vel", "rate", "drift")


def _epoch_inputs(e: dict, cfg: SolverConfig) -> _Epoch:
    p = _Epoch()
    sv_arr = np.asarray(e["sv"])
    sv_arr = sv_arr.copy() if sv_arr.dtype.kind == "U" else sv_arr.astype(str)
    if sv_arr.ndim != 1:
        raise ValueError(f"solve_pvt: sv must be 1-D, got shape {sv_arr.shape}")
    n = p.n = sv_arr.size
    p.sv = sv_arr
    p.groups, fac_all = _satellite_table(sv_arr, cfg)
    p.sat = _as_array("sat_pos_ecef_m", e["sat_pos_ecef_m"], n, (3,))
    y = _as_array("pseudorange_m", e["pseudorange_m"], n).copy()
    if e.get("sat_clock_bias_s") is not None:
        y += C_MPS * _as_array("sat_clock_bias_s", e["sat_clock_bias_s"], n)
    if e.get("iono_delay_m") is not None:
        y -= _as_array("iono_delay_m", e["iono_delay_m"], n)
    if e.get("tropo_delay_m") is not None:
        y -= _as_array("tropo_delay_m", e["tropo_delay_m"], n)
    p.y = y
    p.sig = None if e.get("sigma_m") is None else _as_array("sigma_m", e["sigma_m"], n)
    p.cn0 = None if e.get("cn0_dbhz") is None else _as_array("cn0_dbhz", e["cn0_dbhz"], n)
    if cfg.weighting == "cn0" and p.cn0 is None and p.sig is None:
        raise ValueError("solve_pvt: SolverConfig.weighting='cn0' needs cn0_dbhz")
    p.fac = fac_all if p.sig is None else np.ones(n)
    valid = np.isfinite(y) & np.all(np.isfinite(p.sat), axis=1)
    if p.sig is not None:
        valid &= np.isfinite(p.sig) & (p.sig > 0)
    p.valid = valid
    prior = e.get("prior_ecef_m")
    p.x0 = np.zeros(3) if prior is None else _as_array("prior_ecef_m", prior, 3)
    vel, rate = e.get("sat_vel_ecef_mps"), e.get("range_rate_mps")
    if rate is not None or vel is not None:
        if rate is None or vel is None:
            raise ValueError("solve_pvt: velocity needs both sat_vel_ecef_mps and range_rate_mps")
        vel, rate = _as_array("sat_vel_ecef_mps", vel, n, (3,)), _as_array("range_rate_mps", rate, n)
    drift = e.get("sat_clock_drift_sps")
    p.vel, p.rate = vel, rate
    p.drift = None if drift is None else _as_array("sat_clock_drift_sps", drift, n)
    return p


def solve_pvt_many(epochs, config: SolverConfig | None = None) -> list[PvtSolution]:
    """:func:`solve_pvt` of several epochs at once: ``epochs`` is a list of dicts of solve_pvt's arguments
    (``sv``, ``sat_pos_ecef_m``, ``pseudorange_m`` and the optional ones).  The weighted least squares
    iterate on all epochs together (stacked design matrices, batched factorisations), then the residual
    check and its exclusions, epoch by epoch as :func:`solve_pvt` does them; each epoch's result is the
    one solve_pvt gives for it alone, bit for bit: the epochs are solved in sets of the same clock systems
    (an epoch's unknowns are 3 + its clock groups, as alone), and no arithmetic depends on the others
    (_geodetic_at, the per-epoch reductions over the padded satellites)."""
    cfg = config or _default_config()
    ep = [_epoch_inputs(e, cfg) for e in epochs]
    configured = _configured_groups(cfg)
    sets: dict = {}
    for i, p in enumerate(ep):
        sets.setdefault(configured.union(p.groups.tolist()), []).append(i)
    if len(sets) == 1:
        return _solve_epochs(ep, cfg)
    sols: list = [None] * len(ep)
    for idx in sets.values():
        for i, sol in zip(idx, _solve_epochs([ep[i] for i in idx], cfg)):
            sols[i] = sol
    return sols


def _solve_epochs(ep: list, cfg: SolverConfig) -> list[PvtSolution]:
    """solve_pvt_many of checked epochs (_Epoch) of the same clock groups."""
    k_n = len(ep)
    n_of = [p.n for p in ep]
    n_max = max(n_of, default=0)
    # the epochs' rows one after another, then scattered into (K, n_max) padded arrays
    ii = np.repeat(np.arange(k_n), n_of)
    jj = np.arange(len(ii)) - np.repeat(np.cumsum(n_of) - n_of, n_of)

    def flat(arrays, tail=()):
        return np.concatenate(arrays) if arrays else np.zeros((0,) + tail)

    ok = flat([p.valid for p in ep]).astype(bool)
    groups = flat([p.groups for p in ep]).astype(str)
    clock_sys = sorted(_configured_groups(cfg).union(groups.tolist()), key=SYSTEM_ORDER.index)
    sat = np.zeros((k_n, n_max, 3))
    y = np.zeros((k_n, n_max))
    valid = np.zeros((k_n, n_max), dtype=bool)
    col = np.zeros((k_n, n_max), dtype=np.int64)
    fac2 = np.ones((k_n, n_max))
    any_sig = any(p.sig is not None for p in ep)
    any_cn0 = any(p.cn0 is not None for p in ep)
    sig = np.ones((k_n, n_max)) if any_sig else None
    cn0 = np.zeros((k_n, n_max)) if any_cn0 else None
    sat[ii, jj] = np.where(ok[:, None], flat([p.sat for p in ep], (3,)), 0.0)
    y[ii, jj] = np.where(ok, flat([p.y for p in ep]), 0.0)
    valid[ii, jj] = ok
    col_flat = np.zeros(len(ii), dtype=np.int64)
    for j, g in enumerate(clock_sys):
        col_flat[groups == g] = j
    col[ii, jj] = col_flat
    fac2[ii, jj] = flat([p.fac for p in ep]) ** 2
    if any_sig:
        sig[ii, jj] = np.where(ok, flat([p.sig if p.sig is not None else np.ones(p.n) for p in ep]), 1.0)
    if any_cn0:
        c_flat = flat([p.cn0 if p.cn0 is not None else np.zeros(p.n) for p in ep])
        cn0[ii, jj] = np.where(np.isfinite(c_flat), c_flat, 0.0)
    x0 = np.array([p.x0 for p in ep], dtype=np.float64).reshape(k_n, 3)
    layout = _Layout(sat, y, col, clock_sys, fac2, cn0, sig, n_of, [p.sig is not None for p in ep])

    excluded: list[list[str]] = [[] for _ in range(k_n)]
    notes: list[list[str]] = [[] for _ in range(k_n)]
    results: list = [None] * k_n
    pending = np.arange(k_n)
    while pending.size:
        out = _solve_positions(layout, pending, valid[pending], x0[pending], cfg)
        again = []
        for i, res in zip(pending.tolist(), out):
            results[i] = res
            if res["status"] != "fix" or not cfg.check_residuals or res["dof"] <= 0:
                if res["status"] == "fix" and res["dof"] <= 0:
                    notes[i].append("no redundancy: residual check not possible")
                continue
            if res["chi2"] <= res["chi2_threshold"]:
                continue
            if len(excluded[i]) >= cfg.max_exclusions or res["dof"] < 2:
                why = ("no exclusion left" if len(excluded[i]) >= cfg.max_exclusions
                       else "too few satellites to identify the faulty one")
                msg = (f"chi-square residual test failed: {res['chi2']:.1f} > {res['chi2_threshold']:.1f} "
                       f"({res['dof']} dof), {why}")
                if cfg.residual_failure == "no_fix":
                    res["status"] = "no_fix"
                    res["reason"] = msg
                else:
                    notes[i].append(msg + "; solution kept")
                continue
            worst = res["worst"]
            excluded[i].append(str(ep[i].sv[worst]))
            valid[i, worst] = False
            x0[i] = res["pos"]  # restart from the current estimate
            again.append(i)
        pending = np.array(again, dtype=np.int64)

    sols = []
    for i, (p, res) in enumerate(zip(ep, results)):
        if excluded[i] and res["status"] == "fix":
            notes[i].append(f"excluded by the residual check: {', '.join(excluded[i])}")
        if res["status"] == "fix" and res["gdop"] > cfg.max_gdop:
            res["status"] = "no_fix"
            res["reason"] = f"GDOP {res['gdop']:.1f} exceeds max_gdop {cfg.max_gdop}"
        reason = res["reason"] if res["status"] != "fix" else "; ".join(notes[i])
        sol = _make_solution(p.sv, res, excluded[i], reason, p.n)
        sols.append(sol)
    _solve_velocities([(sol, p.sat, p.vel, p.rate, p.drift, res.get("e_final"), res.get("rot"))
                       for p, res, sol in zip(ep, results, sols) if p.rate is not None], cfg)
    return sols


class _Layout:
    """The stacked inputs of solve_pvt_many: (K, N) rows padded, clock column of each row."""

    def __init__(self, sat, y, col, clock_sys, fac2, cn0, sig, n, has_sig):
        self.sat, self.y, self.col, self.clock_sys, self.fac2 = sat, y, col, clock_sys, fac2
        self.cn0, self.sig, self.n, self.has_sig = cn0, sig, n, np.asarray(has_sig, dtype=bool)
        k_n, n_max = y.shape
        self.onehot = np.zeros((k_n, n_max, len(clock_sys)))
        if n_max:
            self.onehot[np.arange(k_n)[:, None], np.arange(n_max)[None, :], col] = 1.0


def _no_fix(n, reason="", it=0) -> dict:
    return {"status": "no_fix", "reason": reason, "pos": np.full(3, np.nan), "clk": {}, "clock_systems": [],
            "used": np.zeros(n, bool), "v": np.full(n, np.nan), "el": np.full(n, np.nan), "az": np.full(n, np.nan),
            "cov": None, "dops": (math.nan,) * 5, "gdop": math.nan, "chi2": math.nan, "chi2_threshold": math.nan,
            "dof": 0, "iter": it, "worst": None}


def _geodetic_at(x: np.ndarray):
    """(lat_deg, lon_deg, h_m) (K,) each and the ENU rotations (K, 3, 3) at ECEF points (K, 3), every point's
    bits those of frames.ecef_to_geodetic's scalar path (ecef_to_geodetic_pointwise for several points), so that
    an epoch's fix does not depend on the epochs or robots solved with it."""
    if len(x) == 1:
        lat, lon, h = ecef_to_geodetic(x[0, 0], x[0, 1], x[0, 2])
        return np.atleast_1d(lat), np.atleast_1d(lon), np.atleast_1d(h), enu_rotation(lat, lon)[None]
    bits = np.ascontiguousarray(x).view(np.uint64)
    if (bits == bits[0]).all():      # one point (a block's epochs started at the same prior): converted once
        lat, lon, h = (np.repeat(v, len(x)) for v in ecef_to_geodetic_pointwise(x[:1, 0], x[:1, 1], x[:1, 2]))
    else:
        lat, lon, h = ecef_to_geodetic_pointwise(x[:, 0], x[:, 1], x[:, 2])
    # C order, as one point's: einsum's summation order follows the operands' memory layout
    return lat, lon, h, np.ascontiguousarray(enu_rotation(lat, lon))


def _rotations_at(x: np.ndarray) -> np.ndarray:
    """ENU rotations (K, 3, 3) at the geodetic positions of ECEF points (K, 3) (_geodetic_at)."""
    return _geodetic_at(x)[3]


def _filled(nmat: np.ndarray, present: np.ndarray) -> np.ndarray:
    """Normal matrices (K, U, U) with the rows/columns of clocks absent from an epoch (all zero) given a
    diagonal element equal to the first one (a value between the present block's extreme eigenvalues, so
    neither its inverse nor its condition number changes)."""
    if present.all():
        return nmat
    absent = np.flatnonzero(~present.ravel())
    if absent.size:
        k, g = np.divmod(absent, present.shape[1])
        nmat[k, 3 + g, 3 + g] = nmat[k, 0, 0]
    return nmat


def _solve_positions(lay: _Layout, rows: np.ndarray, valid: np.ndarray, x0: np.ndarray, cfg) -> list:
    """Gauss-Newton of the epochs ``rows`` of ``lay`` together (valid (K, N), start points (K, 3)).

    The elevation mask and weights start once the position is roughly known: a start point away from
    the Earth centre (a prior) or a Gauss-Newton step below 1 km.  Per epoch as one-epoch iterations
    would do: the same iterations, convergence test and failures (reasons in the results)."""
    k_n, n_max = valid.shape
    sat, y, onehot = lay.sat[rows], lay.y[rows], lay.onehot[rows]
    fac2 = lay.fac2[rows]
    n_of = [lay.n[i] for i in rows.tolist()]
    has_sig = lay.has_sig[rows]
    x = x0.astype(np.float64).copy()
    out: list = [None] * k_n
    last_step = np.where(np.sqrt(np.einsum("ki,ki->k", x, x)) > _NEAR_CENTRE_M, 0.0, np.inf)
    prev_use = np.zeros((k_n, n_max), dtype=bool)
    have_prev = np.zeros(k_n, dtype=bool)
    active = valid.any(axis=1)
    for i in np.flatnonzero(~active).tolist():
        out[i] = _no_fix(n_of[i], "no satellite with a finite pseudorange and position")
    # each iteration's arrays (design matrix, covariance, solution, rows used, elevation, ENU, variance, weight,
    # clocks present) of the epochs it solved; an epoch's final quantities come from its last one
    fin: dict = {}
    mask_deg = cfg.elevation_mask_deg
    it_of = np.zeros(k_n, dtype=np.int64)
    for it in range(1, cfg.max_iterations + 1):
        a = np.flatnonzero(active)
        if a.size == 0:
            break
        whole = a.size == k_n       # every epoch still iterates: their arrays as they are (no copies)

        def at(arr, whole=whole, a=a):
            return arr if whole else arr[a]

        xa = x[a]
        d = at(sat) - xa[:, None, :]
        rho = np.sqrt(np.einsum("kni,kni->kn", d, d))
        rho_safe = np.where(rho > 0, rho, 1.0)
        e = d / rho_safe[..., None]
        placed = (np.sqrt(np.einsum("ki,ki->k", xa, xa)) > _NEAR_CENTRE_M) & (at(last_step) < _PLACED_STEP_M)
        if placed.all():
            enu = np.einsum("kni,kji->knj", d, _rotations_at(xa))
            el = np.degrees(np.arcsin(np.minimum(np.maximum(enu[..., 2] / rho_safe, -1.0), 1.0)))
        else:
            el = np.full(rho.shape, 90.0)
            enu = np.zeros(d.shape)
            if placed.any():
                enu[placed] = np.einsum("kni,kji->knj", d[placed], _rotations_at(xa[placed]))
                el[placed] = np.degrees(np.arcsin(np.minimum(np.maximum(enu[placed, :, 2] / rho_safe[placed],
                                                                        -1.0), 1.0)))
        use = at(valid) & (~placed[:, None] | (el >= mask_deg))
        same = at(have_prev) & np.all(use == at(prev_use), axis=1)
        onehot_a = at(onehot)
        present = np.einsum("kn,kng->kg", use.astype(float), onehot_a) > 0
        n_unk = 3 + present.sum(axis=1)
        n_use = use.sum(axis=1)
        few = n_use < n_unk
        for j in (np.flatnonzero(few).tolist() if few.any() else ()):
            i = int(a[j])
            n_valid = int(valid[i].sum())
            cs = [lay.clock_sys[g] for g in np.flatnonzero(present[j])]
            masked = f"{n_valid - n_use[j]} below the {cfg.elevation_mask_deg:g} deg mask, " if placed[j] else ""
            out[i] = _no_fix(n_of[i], f"too few satellites: {n_use[j]} usable ({masked}{n_of[i] - n_valid} without "
                                      f"data or excluded), need {n_unk[j]} (3 position + {len(cs)} clock"
                                      f"{'s' if len(cs) != 1 else ''}: {'/'.join(cs) or '-'})", it)
            active[i] = False
        h = np.concatenate([-e, onehot_a], axis=2) * use[..., None]
        ai = a
        sig_rows = at(has_sig)
        any_sig = bool(sig_rows.any())
        model = ~sig_rows
        if not any_sig and cfg.weighting == "elevation":     # the usual case, without masks
            sin_el = np.sin(np.radians(np.minimum(np.maximum(el, 1.0), 90.0)))
            var = (cfg.sigma_a_m**2 + cfg.sigma_b_m**2 / sin_el**2) * at(fac2)
            model = None
        else:
            var = np.ones(rho.shape)
        if any_sig:
            var[sig_rows] = lay.sig[rows[ai[sig_rows]]] ** 2
        if model is not None and model.any():
            if cfg.weighting == "elevation":   # pseudorange_sigma_m, inline, system factors looked up once
                sin_el = np.sin(np.radians(np.minimum(np.maximum(el[model], 1.0), 90.0)))
                var[model] = (cfg.sigma_a_m**2 + cfg.sigma_b_m**2 / sin_el**2) * fac2[ai[model]]
            else:
                c = None if lay.cn0 is None else lay.cn0[rows[ai[model]]]
                var[model] = _variance(el[model], c, cfg) * fac2[ai[model]]
        w = np.where(use, 1.0 / var, 0.0)
        hw = h * w[..., None]
        nmat = _filled(np.einsum("kni,knj->kij", hw, h), present)
        resid = np.where(use, at(y) - rho, 0.0)
        ok = ~few
        finite = ok & np.all(np.isfinite(nmat), axis=(1, 2))
        inv_f = None
        bad = ok & ~finite                          # a normal matrix that is not finite: singular geometry
        if finite.any():
            nf = nmat if finite.all() else nmat[finite]
            # the geometry check: the 2-norm condition number of the symmetric normal matrix (inf when not
            # positive definite) must not exceed 1e14.  ||N||_F ||N^-1||_F bounds it from above, so below
            # _SURE_COND the matrix passes (and a Gram matrix that well conditioned is positive definite);
            # the others get their extreme eigenvalues (eigvalsh: its singular values)
            try:
                inv_f = np.linalg.inv(nf)
                bound = np.sqrt(np.einsum("kij,kij->k", nf, nf) * np.einsum("kij,kij->k", inv_f, inv_f))
                sure = bound <= _SURE_COND                      # NaN: not sure
            except np.linalg.LinAlgError:
                inv_f, sure = None, np.zeros(len(nf), dtype=bool)
            if not sure.all():
                eig = np.linalg.eigvalsh(nf[~sure])
                lo, hi = eig[:, 0], eig[:, -1]
                cond_f = np.zeros(len(nf))
                cond_f[~sure] = np.where(lo > 0, hi / np.where(lo > 0, lo, 1.0), np.inf)
                bad[np.flatnonzero(finite)[~(cond_f <= 1e14)]] = True       # also NaN
        for j in (np.flatnonzero(bad).tolist() if bad.any() else ()):
            i = int(a[j])
            out[i] = _no_fix(n_of[i], f"singular geometry with {n_use[j]} satellites (normal matrix not "
                                      f"invertible)", it)
            active[i] = False
        good = np.flatnonzero(ok & ~bad)
        if good.size == 0:
            continue
        gi = a[good]
        try:
            if inv_f is not None and good.size == inv_f.shape[0]:      # good = finite: their inverses
                cov = _symmetrised(inv_f)
            else:
                cov = _spd_inverses(nmat[good])
        except np.linalg.LinAlgError:       # one epoch whose matrix is not positive definite after all
            for i in gi.tolist():
                out[i] = _no_fix(n_of[i], f"singular geometry with {int(n_use[good][0])} satellites (normal "
                                          f"matrix not invertible)", it)
                active[i] = False
            continue
        all_good = good.size == a.size

        def ok_of(arr, all_good=all_good, good=good):
            return arr if all_good else arr[good]

        sol = np.einsum("kij,kj->ki", cov, np.einsum("kni,kn->ki", ok_of(hw), ok_of(resid)))
        dx = sol[:, :3]
        x[gi] = x[gi] + dx
        step = np.sqrt(np.einsum("ki,ki->k", dx, dx))
        last_step[gi] = step
        prev_use[gi] = ok_of(use)
        same_g = ok_of(same)
        have_prev[gi] = True
        it_of[gi] = it
        fin[it] = (gi, good, h, cov, sol, use, el, enu, var, w, present)
        placed_g = ok_of(placed)
        conv = (step < cfg.convergence_m) & (same_g | ~placed_g | (it == 1)) & placed_g
        active[gi[conv]] = False
        for i in gi[conv].tolist():
            out[i] = "converged"
        still = gi[~conv]
        div = ~(np.sqrt(np.einsum("ki,ki->k", x[still], x[still])) <= 1e9) if still.size else conv[:0]
        for i in still[div].tolist():
            out[i] = _no_fix(n_of[i], "the iteration diverged", it)
            active[i] = False
    for i in np.flatnonzero(active).tolist():
        out[i] = _no_fix(n_of[i], f"no convergence in {cfg.max_iterations} iterations (last step "
                                  f"{last_step[i]:.3g} m)", cfg.max_iterations)
    done = [i for i in range(k_n) if isinstance(out[i], str)]
    if done:
        _final_quantities(lay, rows, done, x, fin, it_of, n_of, out, cfg)
    return out


def _final_quantities(lay, rows, done, x, fin, it_of, n_of, out, cfg):
    """Residuals, DOPs, chi-square, w-test and covariance of the converged epochs ``done`` (into ``out``)."""
    d_idx = np.array(done, dtype=np.int64)
    g_rows = rows[d_idx]
    parts = []
    for it in np.unique(it_of[d_idx]).tolist():      # the epochs that ended at iteration it
        gi, good, h, cov, sol, use, el, enu, var, w, present = fin[it]
        sel = np.flatnonzero(it_of[d_idx] == it)
        q = np.searchsorted(gi, d_idx[sel])            # gi is sorted: their places in that iteration
        j = good[q]
        parts.append((sel, (h[j], cov[q], sol[q], use[j], el[j], enu[j], var[j], w[j], present[j])))
    if len(parts) == 1:
        h, cov, sol, use, el, enu, var, w, present = parts[0][1]
    else:
        order = np.argsort(np.concatenate([p[0] for p in parts]))
        h, cov, sol, use, el, enu, var, w, present = (np.concatenate([p[1][k] for p in parts])[order]
                                                      for k in range(9))
    xs = x[d_idx]
    sat, y, col = lay.sat[g_rows], lay.y[g_rows], lay.col[g_rows]
    clk = sol[:, 3:]
    d = sat - xs[:, None, :]
    rho = np.sqrt(np.einsum("kni,kni->kn", d, d))
    e_final = d / np.where(rho > 0, rho, 1.0)[..., None]     # line of sight at the solution (for the velocity)
    v = np.where(use, y - rho - clk[np.arange(len(done))[:, None], col], np.nan)
    lat, lon, hgt, rot = _geodetic_at(xs)
    # DOPs from the unweighted design matrix (columns x, y, z, clocks) of the last iteration
    q = _spd_inverses(_filled(np.einsum("kni,knj->kij", h, h), present))
    q3 = q[:, :3, :3]
    q_enu = rot @ q3 @ np.swapaxes(rot, 1, 2)
    hdop = np.sqrt(np.maximum(q_enu[:, 0, 0] + q_enu[:, 1, 1], 0.0))
    vdop = np.sqrt(np.maximum(q_enu[:, 2, 2], 0.0))
    pdop = np.sqrt(np.maximum(np.trace(q3, axis1=1, axis2=2), 0.0))
    ref = 3 + np.argmax(present, axis=1)
    tdop = np.sqrt(np.maximum(q[np.arange(len(done)), ref, ref], 0.0))
    gdop = np.sqrt(pdop**2 + tdop**2)
    n_use = use.sum(axis=1)
    dof = n_use - 3 - present.sum(axis=1)
    chi2 = _row_dots(w, np.where(use, v, 0.0) ** 2, [n_of[i] for i in done])
    # standardised residuals: v_i / sqrt((Sigma - H N^-1 H^T)_ii)  (Baarda w-test)
    qv = var - np.einsum("kni,kij,knj->kn", h, cov, h)
    wstat = np.abs(np.where(use, v, 0.0)) / np.sqrt(np.maximum(qv, 1e-30))
    # a satellite without redundancy (alone in its clock group: its residual is zero whatever its
    # error) cannot be tested: its statistic would be round-off / round-off
    wstat[qv <= 1e-9 * var] = 0.0
    wstat[~use] = -1.0
    wmax = wstat.max(axis=1, initial=-1.0)
    # ties (the two satellites of a clock group that has only two have equal statistics) go to the
    # first in input order, not to whichever round-off makes larger
    worst = np.argmax(wstat >= (wmax * (1.0 - 1e-6))[:, None], axis=1).tolist()
    az = _azimuth(enu)
    # the epochs' scalars as Python numbers at once, their clock columns per pattern of clocks present
    dops = list(zip(gdop.tolist(), pdop.tolist(), hdop.tolist(), vdop.tolist(), tdop.tolist()))
    chi2_l, dof_l, clk_l = chi2.tolist(), dof.tolist(), clk.tolist()
    lla = list(zip(np.atleast_1d(lat).tolist(), np.atleast_1d(lon).tolist(), np.atleast_1d(hgt).tolist()))
    patterns: dict = {}
    for q_i, i in enumerate(done):
        n = n_of[i]
        k_dof = dof_l[q_i]
        c = cov[q_i]
        if cfg.scale_covariance and k_dof > 0:
            c = c * max(1.0, chi2_l[q_i] / k_dof)   # a-posteriori variance factor (residuals beyond sigmas)
        pk = present[q_i].tobytes()
        pat = patterns.get(pk)
        if pat is None:
            cols = np.flatnonzero(present[q_i])
            keep = np.concatenate([[0, 1, 2], 3 + cols])
            pat = patterns[pk] = (cols.tolist(), [lay.clock_sys[g] for g in cols.tolist()], np.ix_(keep, keep),
                                  len(keep) == c.shape[0])
        cols, cs, sub, whole = pat
        thr = _chi2_threshold(float(cfg.chi2_prob_false_alarm), k_dof) if k_dof > 0 else math.nan
        out[i] = {"status": "fix", "reason": "", "pos": xs[q_i].copy(),
                  "clk": {s: clk_l[q_i][g] for s, g in zip(cs, cols)}, "clock_systems": cs,
                  "used": use[q_i, :n].copy(), "v": v[q_i, :n], "el": el[q_i, :n], "az": az[q_i, :n],
                  "cov": c.copy() if whole else c[sub], "dops": dops[q_i], "gdop": dops[q_i][0], "chi2": chi2_l[q_i],
                  "chi2_threshold": thr, "dof": k_dof, "iter": int(it_of[i]),
                  "worst": worst[q_i] if k_dof > 0 else None, "rot": rot[q_i],
                  "lla": lla[q_i], "e_final": e_final[q_i, :n]}


def _row_dots(a: np.ndarray, b: np.ndarray, n_of: list) -> np.ndarray:
    """sum_n a[k, n] b[k, n] (K,) over each row's own n_of[k] entries of the padded (K, N) arrays: einsum's
    summation order depends on the length summed, so a padded row would not give the bits of the epoch alone."""
    n_max = a.shape[1]
    if all(n == n_max for n in n_of):
        return np.einsum("kn,kn->k", a, b)
    out = np.empty(len(n_of))
    n_arr = np.asarray(n_of)
    for n in set(n_of):
        rows = np.flatnonzero(n_arr == n)
        out[rows] = np.einsum("kn,kn->k", a[rows, :n], b[rows, :n])
    return out


def _azimuth(enu):
    """Azimuth [deg, 0..360) from ENU vectors (..., 3)."""
    az = np.degrees(np.arctan2(enu[..., 0], enu[..., 1])) % 360.0
    return az - 360.0 * (az >= 360.0)      # (-tiny) % 360 rounds to 360.0 (as frames.az_el_at)


def _make_solution(sv, res, excluded, reason, n) -> PvtSolution:
    fix = res["status"] == "fix"
    nan3 = None if fix else np.full((3, 3), np.nan)
    if fix:
        cov = res["cov"]
        rot = res["rot"]
        cov_enu = rot @ cov[:3, :3] @ rot.T
        lat, lon, h = res["lla"]
    else:
        cov, cov_enu, (lat, lon, h) = np.full((0, 0), np.nan), nan3, (math.nan,) * 3
    g, p, hd, vd, td = res["dops"]
    return PvtSolution(
        status="fix" if fix else "no_fix", reason=reason,
        pos_ecef_m=np.asarray(res["pos"]) if fix else np.full(3, np.nan),
        lat_deg=lat, lon_deg=lon, h_m=h, clock_bias_m=dict(res["clk"]),
        clock_bias_s={k: c / C_MPS for k, c in res["clk"].items()},
        ref_system=res["clock_systems"][0] if res["clock_systems"] else "",
        cov_ecef_m2=cov[:3, :3] if fix else nan3, cov_enu_m2=cov_enu, cov_full=cov,
        clock_systems=list(res["clock_systems"]), gdop=g, pdop=p, hdop=hd, vdop=vd, tdop=td,
        sv=sv, used=res["used"] if fix else np.zeros(n, bool), excluded=list(excluded),
        residuals_m=res["v"], el_deg=res["el"], az_deg=res["az"], n_used=int(res["used"].sum()) if fix else 0,
        n_iterations=res["iter"], chi2=res["chi2"], chi2_threshold=res["chi2_threshold"],
        chi2_ok=(None if not fix or res["dof"] <= 0 else bool(res["chi2"] <= res["chi2_threshold"])),
    )


def _solve_velocity_into(sol: PvtSolution, sat, sat_vel, rate, sat_drift, cfg, los=None, rot=None) -> None:
    """Velocity and drift into ``sol``; ``los``: unit vectors receiver -> satellite (N, 3) at sol.pos_ecef_m
    and ``rot``: ENU rotation there, when the position solution has them already."""
    _solve_velocities([(sol, sat, sat_vel, rate, sat_drift, los, rot)], cfg)


def _solve_velocities(items, cfg) -> None:
    """Velocity and clock drift of several epochs (``items``: (solution, sat, sat_vel, rate, sat_drift,
    los, rot) each, as _solve_velocity_into takes them), the least squares of all of them at once:
    rate = e.(v_sat - v_rx) + drift_rx - c ddt_sat, weights from the elevation model of the rates."""
    todo = []
    for sol, sat, sat_vel, rate, sat_drift, los, rot in items:
        if not sol.is_fix:
            sol.vel_status, sol.vel_reason = "no_fix", "no position fix"
            continue
        if los is None:
            d = sat - sol.pos_ecef_m
            los = d / np.sqrt(np.einsum("ij,ij->i", d, d))[:, None]
        todo.append((sol, sat_vel, rate, sat_drift, los, rot))
    if not todo:
        return
    # the epochs' rows one after another
    n_of = [len(t[2]) for t in todo]
    k_n, n_max = len(todo), max(n_of)
    ii = np.repeat(np.arange(k_n), n_of)
    jj = np.arange(len(ii)) - np.repeat(np.cumsum(n_of) - n_of, n_of)
    sat_vel = np.concatenate([t[1] for t in todo])
    rate = np.concatenate([t[2] for t in todo])
    drift = np.concatenate([t[3] if t[3] is not None else np.zeros(len(t[2])) for t in todo])
    los = np.concatenate([t[4] for t in todo])
    ok = (np.concatenate([t[0].used for t in todo]) & np.isfinite(rate) & np.all(np.isfinite(sat_vel), axis=1)
          & np.isfinite(drift))
    # rate - e.v_sat + c ddt_sat = -e.v_rx + drift_rx
    yv = rate - np.einsum("ij,ij->i", los, np.where(np.isfinite(sat_vel), sat_vel, 0.0)) + C_MPS * drift
    n_ok = np.bincount(ii[ok], minlength=k_n).tolist()
    h = np.zeros((k_n, n_max, 4))
    h[ii, jj, :3] = -np.where(ok[:, None], los, 0.0)
    h[ii, jj, 3] = 1.0
    y_p = np.zeros((k_n, n_max))
    y_p[ii, jj] = np.where(ok, yv, 0.0)
    ok_p = np.zeros((k_n, n_max), dtype=bool)
    ok_p[ii, jj] = ok
    el = np.full((k_n, n_max), 90.0)
    el[ii, jj] = np.where(ok, np.concatenate([t[0].el_deg for t in todo]), 90.0)
    good = []
    for i, t in enumerate(todo):
        if n_ok[i] < 4:
            t[0].vel_status = "no_fix"
            t[0].vel_reason = f"too few range rates: {n_ok[i]} of the used satellites, need 4 (3 velocity + 1 drift)"
        else:
            good.append(i)
    if good:
        g = np.array(good)
        _velocity_lsq([todo[i] for i in good], [n_of[i] for i in good], ok_p[g], h[g], y_p[g], el[g], cfg)


def _velocity_lsq(todo, n_of, ok, h, yv, el, cfg) -> None:
    """The velocity least squares of prepared epochs (_solve_velocities: padded (K, N) arrays)."""
    k_n = len(todo)
    s = np.sin(np.radians(np.minimum(np.maximum(el, 1.0), 90.0)))
    w = np.where(ok, 1.0 / (cfg.rate_sigma_a_mps**2 + cfg.rate_sigma_b_mps**2 / s**2), 0.0)
    hw = h * w[..., None]
    nmat = np.einsum("kni,knj->kij", hw, h)
    try:
        cov = _spd_inverses(nmat)
        if not np.all(np.isfinite(cov)):
            raise np.linalg.LinAlgError
    except np.linalg.LinAlgError:
        if k_n > 1:                      # one of them is singular: each on its own
            for i in range(k_n):
                _velocity_lsq(todo[i:i + 1], n_of[i:i + 1], ok[i:i + 1], h[i:i + 1], yv[i:i + 1], el[i:i + 1], cfg)
            return
        todo[0][0].vel_status, todo[0][0].vel_reason = "no_fix", "singular geometry for the velocity"
        return
    xv = np.einsum("kij,kj->ki", cov, np.einsum("kni,kn->ki", hw, yv))
    resid = np.where(ok, yv - np.einsum("kni,ki->kn", h, xv), np.nan)
    # in ENU at each solution, all epochs at once
    rot = np.stack([t[5] if t[5] is not None else enu_rotation(t[0].lat_deg, t[0].lon_deg) for t in todo])
    c3 = cov[:, :3, :3]
    vel_enu = np.einsum("kij,kj->ki", rot, xv[:, :3])
    cov_enu = rot @ c3 @ np.swapaxes(rot, 1, 2)
    drift = xv[:, 3].tolist()
    for i, t in enumerate(todo):
        sol = t[0]
        sol.vel_ecef_mps = xv[i, :3]
        sol.vel_enu_mps = vel_enu[i]
        sol.clock_drift_mps = drift[i]
        sol.clock_drift_sps = drift[i] / C_MPS
        sol.cov_vel_ecef_m2ps2 = c3[i]
        sol.cov_vel_enu_m2ps2 = cov_enu[i]
        sol.vel_residuals_mps = resid[i, :n_of[i]]
        sol.vel_status, sol.vel_reason = "fix", ""


def solve_velocity(sol: PvtSolution, sat_pos_ecef_m, sat_vel_ecef_mps, range_rate_mps, sat_clock_drift_sps=None,
                   config: SolverConfig | None = None) -> PvtSolution:
    """Velocity and clock drift for an existing position solution (fills the velocity fields in place)."""
    n = sol.sv.size
    _solve_velocity_into(sol, _as_array("sat_pos_ecef_m", sat_pos_ecef_m, n, (3,)),
                         _as_array("sat_vel_ecef_mps", sat_vel_ecef_mps, n, (3,)),
                         _as_array("range_rate_mps", range_rate_mps, n),
                         None if sat_clock_drift_sps is None else _as_array("sat_clock_drift_sps",
                                                                            sat_clock_drift_sps, n),
                         config or SolverConfig())
    return sol
