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
from scipy.linalg import lapack as _lapack
from scipy.special import chdtri as _chdtri

from .constants import C_MPS
from .frames import ecef_to_geodetic, enu_rotation

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
    vel_ecef_mps: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    vel_enu_mps: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    clock_drift_mps: float = math.nan
    clock_drift_sps: float = math.nan
    cov_vel_ecef_m2ps2: np.ndarray = field(default_factory=lambda: np.full((3, 3), np.nan))
    #: the velocity's covariance in ENU at the solution [m^2/s^2] (from the a-priori range-rate sigmas)
    cov_vel_enu_m2ps2: np.ndarray = field(default_factory=lambda: np.full((3, 3), np.nan))
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
    chi-square distribution (scipy.special.chdtri, Cephes; as scipy.stats.chi2.ppf(1 - p_fa) without
    importing scipy.stats, about 1 s at start-up); cached: the same few values come back every epoch."""
    return float(_chdtri(dof, prob_false_alarm))


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


def _dops(h_geom: np.ndarray, rot_enu: np.ndarray):
    """GDOP, PDOP, HDOP, VDOP, TDOP from the unweighted design matrix (columns x, y, z, clocks)."""
    try:
        q = _spd_inverse(h_geom.T @ h_geom)
    except np.linalg.LinAlgError:
        return (math.inf,) * 5
    q_enu = rot_enu @ q[:3, :3] @ rot_enu.T
    hdop = math.sqrt(max(q_enu[0, 0] + q_enu[1, 1], 0.0))
    vdop = math.sqrt(max(q_enu[2, 2], 0.0))
    pdop = math.sqrt(max(np.trace(q[:3, :3]), 0.0))
    tdop = math.sqrt(max(q[3, 3], 0.0))
    return math.sqrt(pdop**2 + tdop**2), pdop, hdop, vdop, tdop


def _condition_number(a: np.ndarray) -> float:
    """2-norm condition number (largest / smallest singular value, as np.linalg.cond) of a small square
    matrix; inf when singular, NaN for non-finite input.  LAPACK dgesdd directly: np.linalg.cond's
    Python overhead is larger than the decomposition of a 4x4..9x9 normal matrix."""
    if not np.all(np.isfinite(a)):
        return math.nan
    out = _lapack.dgesdd(a, compute_uv=0)        # (u, s, vt, info); u, vt empty
    s, info = out[1], out[-1]
    if info != 0:
        raise np.linalg.LinAlgError("SVD did not converge")
    return math.inf if s[-1] == 0.0 else float(s[0] / s[-1])


def _spd_inverse(a: np.ndarray) -> np.ndarray:
    """Inverse of a symmetric positive definite matrix (LAPACK Cholesky dpotrf + dpotri); LinAlgError when
    it is not positive definite (singular normal matrix)."""
    c, info = _lapack.dpotrf(a, lower=0, clean=1)
    if info != 0:
        raise np.linalg.LinAlgError("normal matrix not positive definite")
    inv, info = _lapack.dpotri(c, lower=0)
    if info != 0:
        raise np.linalg.LinAlgError("normal matrix singular")
    return inv + np.triu(inv, 1).T      # dpotri fills the upper triangle (the lower one is zero: clean=1)


def _clock_group(sv_list, groups: Mapping[str, str]) -> np.ndarray:
    return np.array([groups.get(s[0], s[0]) for s in sv_list])


_DEFAULT_CONFIG: list = []
_SAT_TABLE_CACHE: dict = {}


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
        if len(_SAT_TABLE_CACHE) > 128:
            _SAT_TABLE_CACHE.clear()
        _SAT_TABLE_CACHE[key] = hit
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
    """
    cfg = config or _default_config()
    sv_arr = np.asarray(sv).astype(str)
    if sv_arr.ndim != 1:
        raise ValueError(f"solve_pvt: sv must be 1-D, got shape {sv_arr.shape}")
    n = sv_arr.size
    groups, fac_all = _satellite_table(sv_arr, cfg)
    sat = _as_array("sat_pos_ecef_m", sat_pos_ecef_m, n, (3,))
    y = _as_array("pseudorange_m", pseudorange_m, n).copy()
    if sat_clock_bias_s is not None:
        y += C_MPS * _as_array("sat_clock_bias_s", sat_clock_bias_s, n)
    if iono_delay_m is not None:
        y -= _as_array("iono_delay_m", iono_delay_m, n)
    if tropo_delay_m is not None:
        y -= _as_array("tropo_delay_m", tropo_delay_m, n)
    sig_given = None if sigma_m is None else _as_array("sigma_m", sigma_m, n)
    cn0 = None if cn0_dbhz is None else _as_array("cn0_dbhz", cn0_dbhz, n)
    if cfg.weighting == "cn0" and cn0 is None and sig_given is None:
        raise ValueError("solve_pvt: SolverConfig.weighting='cn0' needs cn0_dbhz")
    fac = fac_all if sig_given is None else None
    valid = np.isfinite(y) & np.all(np.isfinite(sat), axis=1)
    if sig_given is not None:
        valid &= np.isfinite(sig_given) & (sig_given > 0)
    x0 = np.zeros(3) if prior_ecef_m is None else _as_array("prior_ecef_m", prior_ecef_m, 3)

    excluded: list[str] = []
    notes = []
    x = x0
    while True:
        res = _solve_position(sv_arr, sat, y, valid, groups, sig_given, cn0, x, cfg, fac)
        if res["status"] != "fix" or not cfg.check_residuals or res["dof"] <= 0:
            if res["status"] == "fix" and res["dof"] <= 0:
                notes.append("no redundancy: residual check not possible")
            break
        if res["chi2"] <= res["chi2_threshold"]:
            break
        if len(excluded) >= cfg.max_exclusions or res["dof"] < 2:
            why = ("no exclusion left" if len(excluded) >= cfg.max_exclusions
                   else "too few satellites to identify the faulty one")
            msg = (f"chi-square residual test failed: {res['chi2']:.1f} > {res['chi2_threshold']:.1f} "
                   f"({res['dof']} dof), {why}")
            if cfg.residual_failure == "no_fix":
                res["status"] = "no_fix"
                res["reason"] = msg
            else:
                notes.append(msg + "; solution kept")
            break
        worst = res["worst"]
        excluded.append(str(sv_arr[worst]))
        valid = valid.copy()
        valid[worst] = False
        x = res["pos"]  # restart from the current estimate
    if excluded and res["status"] == "fix":
        notes.append(f"excluded by the residual check: {', '.join(excluded)}")
    if res["status"] == "fix" and res["gdop"] > cfg.max_gdop:
        res["status"] = "no_fix"
        res["reason"] = f"GDOP {res['gdop']:.1f} exceeds max_gdop {cfg.max_gdop}"
    reason = res["reason"] if res["status"] != "fix" else "; ".join(notes)
    sol = _make_solution(sv_arr, res, excluded, reason, n)
    if range_rate_mps is not None or sat_vel_ecef_mps is not None:
        if range_rate_mps is None or sat_vel_ecef_mps is None:
            raise ValueError("solve_pvt: velocity needs both sat_vel_ecef_mps and range_rate_mps")
        _solve_velocity_into(sol, sat, _as_array("sat_vel_ecef_mps", sat_vel_ecef_mps, n, (3,)),
                             _as_array("range_rate_mps", range_rate_mps, n),
                             None if sat_clock_drift_sps is None
                             else _as_array("sat_clock_drift_sps", sat_clock_drift_sps, n), cfg,
                             los=res.get("e_final"), rot=res.get("rot"))
    return sol


def _no_fix(n, reason="", it=0) -> dict:
    return {"status": "no_fix", "reason": reason, "pos": np.full(3, np.nan), "clk": {}, "clock_systems": [],
            "used": np.zeros(n, bool), "v": np.full(n, np.nan), "el": np.full(n, np.nan), "az": np.full(n, np.nan),
            "cov": None, "dops": (math.nan,) * 5, "gdop": math.nan, "chi2": math.nan, "chi2_threshold": math.nan,
            "dof": 0, "iter": it, "worst": None}


def _solve_position(sv, sat, y, valid, groups, sig_given, cn0, x, cfg, fac=None) -> dict:
    n = sv.size
    if not valid.any():
        return _no_fix(n, "no satellite with a finite pseudorange and position")
    x = np.asarray(x, dtype=np.float64).copy()
    prev_use = None
    converged = False
    # the elevation mask and weights start once the position is roughly known: a start
    # point away from the Earth centre (a prior) or a Gauss-Newton step below 1 km
    last_step = 0.0 if math.sqrt(x @ x) > _NEAR_CENTRE_M else math.inf
    fac2 = None if fac is None else fac**2
    elevation_weights = sig_given is None and cfg.weighting == "elevation"
    mask_deg = cfg.elevation_mask_deg
    enu = None
    h = idx = col = None       # design-matrix layout, set when the satellite set changes (first iteration)
    for it in range(1, cfg.max_iterations + 1):
        d = sat - x
        rho = np.sqrt(np.einsum("ij,ij->i", d, d))
        e = d / rho[:, None]
        placed = math.sqrt(x @ x) > _NEAR_CENTRE_M and last_step < _PLACED_STEP_M
        if placed:
            # elevation in the ENU frame at the current position (as frames.az_el_from_ecef)
            lat_x, lon_x, _ = ecef_to_geodetic(x[0], x[1], x[2])
            enu = d @ enu_rotation(lat_x, lon_x).T
            el = np.degrees(np.arcsin(np.minimum(np.maximum(enu[:, 2] / rho, -1.0), 1.0)))
            use = valid & (el >= mask_deg)
        else:
            enu, el = None, np.full(n, 90.0)
            use = valid.copy()
        same_set = prev_use is not None and bool((use == prev_use).all())
        if same_set:      # same satellites as the last iteration: same clocks, same design-matrix layout
            h[:, :3] = -e[idx]
        else:
            clock_sys = sorted(set(groups[use].tolist()), key=SYSTEM_ORDER.index)
            n_unk = 3 + len(clock_sys)
            idx = np.flatnonzero(use)
            n_use = idx.size
            if n_use < n_unk:
                n_valid = int(valid.sum())
                masked = f"{n_valid - n_use} below the {cfg.elevation_mask_deg:g} deg mask, " if placed else ""
                return _no_fix(n, f"too few satellites: {n_use} usable ({masked}{n - n_valid} without data or "
                                  f"excluded), need {n_unk} (3 position + {len(clock_sys)} clock"
                                  f"{'s' if len(clock_sys) != 1 else ''}: {'/'.join(clock_sys) or '-'})", it)
            slot = {g: j for j, g in enumerate(clock_sys)}
            col = np.array([slot[g] for g in groups[idx].tolist()], dtype=np.int64)
            h = np.zeros((n_use, n_unk))
            h[:, :3] = -e[idx]
            h[np.arange(n_use), 3 + col] = 1.0
        if sig_given is not None:
            var = sig_given[idx] ** 2
        elif elevation_weights:   # pseudorange_sigma_m, inline, system factors looked up once per solve
            sin_el = np.sin(np.radians(np.minimum(np.maximum(el[idx], 1.0), 90.0)))
            var = (cfg.sigma_a_m**2 + cfg.sigma_b_m**2 / sin_el**2) * fac2[idx]
        else:
            var = _variance(el[idx], None if cn0 is None else cn0[idx], cfg) * fac2[idx]
        w = 1.0 / var
        hwt = h.T * w
        nmat = hwt @ h
        try:
            if not _condition_number(nmat) <= 1e14:      # also NaN
                raise np.linalg.LinAlgError
            cov = _spd_inverse(nmat)       # the covariance at the end, the step now
            sol = cov @ (hwt @ (y[idx] - rho[idx]))
        except np.linalg.LinAlgError:
            return _no_fix(n, f"singular geometry with {idx.size} satellites (normal matrix not invertible)", it)
        dx = sol[:3]
        x = x + dx
        last_step = math.sqrt(dx @ dx)
        prev_use = use
        if last_step < cfg.convergence_m and (same_set or not placed or it == 1):
            if placed:
                converged = True
                break
        if not math.sqrt(x @ x) <= 1e9:      # also NaN
            return _no_fix(n, "the iteration diverged", it)
    if not converged:
        return _no_fix(n, f"no convergence in {cfg.max_iterations} iterations (last step {last_step:.3g} m)", it)
    # final quantities at the converged position (sat set and clocks from the last step)
    clk = sol[3:]
    d = sat - x
    rho = np.sqrt(np.einsum("ij,ij->i", d, d))
    e_final = d / rho[:, None]      # line of sight at the solution (for the velocity)
    v = np.full(n, np.nan)
    v_idx = y[idx] - rho[idx] - clk[col]
    v[idx] = v_idx
    lat, lon, hgt = ecef_to_geodetic(x[0], x[1], x[2])
    rot = enu_rotation(lat, lon)
    dops = _dops(h, rot)
    dof = idx.size - n_unk
    chi2 = float(w @ (v_idx * v_idx))
    thr = _chi2_threshold(float(cfg.chi2_prob_false_alarm), int(dof)) if dof > 0 else math.nan
    worst = None
    if dof > 0:
        # standardised residuals: v_i / sqrt((Sigma - H N^-1 H^T)_ii)  (Baarda w-test)
        qv = var - np.einsum("ij,ij->i", h @ cov, h)
        wstat = np.abs(v_idx) / np.sqrt(np.maximum(qv, 1e-30))
        # a satellite without redundancy (alone in its clock group: its residual is zero whatever its
        # error) cannot be tested: its statistic would be round-off / round-off
        wstat[qv <= 1e-9 * var] = 0.0
        # ties (the two satellites of a clock group that has only two have equal statistics) go to the
        # first in input order, not to whichever round-off makes larger
        worst = int(idx[int(np.argmax(wstat >= np.max(wstat) * (1.0 - 1e-6)))])
    used = np.zeros(n, bool)
    used[idx] = True
    if cfg.scale_covariance and dof > 0:
        cov = cov * max(1.0, chi2 / dof)        # a-posteriori variance factor (residuals beyond the sigmas)
    return {"status": "fix", "reason": "", "pos": x, "clk": {s: float(c) for s, c in zip(clock_sys, clk)},
            "clock_systems": clock_sys, "used": used, "v": v, "el": el, "az": _azimuth(enu, n), "cov": cov,
            "dops": dops, "gdop": dops[0], "chi2": chi2, "chi2_threshold": thr, "dof": dof, "iter": it,
            "worst": worst, "rot": rot, "lla": (float(lat), float(lon), float(hgt)), "e": e, "e_final": e_final}


def _azimuth(enu, n):
    """Azimuth [deg, 0..360) from ENU vectors (NaN when there are none: position not yet placed)."""
    if enu is None:
        return np.full(n, np.nan)
    az = np.degrees(np.arctan2(enu[:, 0], enu[:, 1])) % 360.0
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
    if not sol.is_fix:
        sol.vel_status, sol.vel_reason = "no_fix", "no position fix"
        return
    ok = sol.used & np.isfinite(rate) & np.all(np.isfinite(sat_vel), axis=1)
    if sat_drift is not None:
        ok &= np.isfinite(sat_drift)
    idx = np.flatnonzero(ok)
    if idx.size < 4:
        sol.vel_status = "no_fix"
        sol.vel_reason = f"too few range rates: {idx.size} of the used satellites, need 4 (3 velocity + 1 drift)"
        return
    if los is None:
        d = sat[idx] - sol.pos_ecef_m
        e = d / np.sqrt(np.einsum("ij,ij->i", d, d))[:, None]
    else:
        e = los[idx]
    # rate = e.(v_sat - v_rx) + drift_rx - c ddt_sat  ->  rate - e.v_sat + c ddt_sat = -e.v_rx + drift_rx
    yv = rate[idx] - np.einsum("ij,ij->i", e, sat_vel[idx])
    if sat_drift is not None:
        yv = yv + C_MPS * sat_drift[idx]
    h = np.empty((idx.size, 4))
    h[:, :3] = -e
    h[:, 3] = 1.0
    s = np.sin(np.radians(np.minimum(np.maximum(sol.el_deg[idx], 1.0), 90.0)))
    w = 1.0 / (cfg.rate_sigma_a_mps**2 + cfg.rate_sigma_b_mps**2 / s**2)
    hwt = h.T * w
    nmat = hwt @ h
    try:
        cov = _spd_inverse(nmat)
        xv = cov @ (hwt @ yv)
    except np.linalg.LinAlgError:
        sol.vel_status, sol.vel_reason = "no_fix", "singular geometry for the velocity"
        return
    if rot is None:
        rot = enu_rotation(sol.lat_deg, sol.lon_deg)
    resid = np.full(sol.sv.size, np.nan)
    resid[idx] = yv - h @ xv
    sol.vel_ecef_mps = xv[:3]
    sol.vel_enu_mps = rot @ xv[:3]
    sol.clock_drift_mps = float(xv[3])
    sol.clock_drift_sps = float(xv[3] / C_MPS)
    sol.cov_vel_ecef_m2ps2 = cov[:3, :3]
    sol.cov_vel_enu_m2ps2 = rot @ cov[:3, :3] @ rot.T
    sol.vel_residuals_mps = resid
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
