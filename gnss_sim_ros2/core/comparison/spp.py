"""Single point positions from raw pseudoranges and a broadcast ephemeris, with the simulator's conventions
(satellite clock, group delay, Earth rotation) and RTKLIB's single point error budget."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .. import constants as k
from .. import propagation as prop
from ..constants import OMEGA_BY_SYSTEM
from ..frames import az_el_from_ecef, ecef_to_geodetic
from ..receiver.ionosphere import KLOBUCHAR_FALLBACK_ALPHA, KLOBUCHAR_FALLBACK_BETA
from ..rinex.obs_table import ObsTable
from ..signals import frequency_hz, group_delay_factor
from ..solver import SolverConfig, pseudorange_sigma_m, solve_pvt
from ..time import GnssTime

#: single point error budget of RTKLIB pntpos.c (2.4.3): URA of a healthy broadcast (GPS URA index 0 =
#: 2.0 m, IS-GPS-200N 20.3.3.3.1.3), code bias ERR_CBIAS, ionosphere ERR_BRDCI (fraction of the model),
#: troposphere ERR_SAAS [m]
SPP_URA_M = 2.0
SPP_CODE_BIAS_M = 0.3
SPP_IONO_FRACTION = 0.5
SPP_TROPO_M = 0.3


@dataclass
class Solutions:
    """Single point solutions over the common epochs (NaN rows: no fix)."""

    pos_ecef_m: np.ndarray      #: (E, 3)
    n_used: np.ndarray          #: (E,) int
    solver: str                 #: "gnss_sim solve_pvt" | "RTKLIB rnx2rtkp"
    note: str = ""              #: what was done to the input for the solver (rtklib_observation_copy)


def _klobuchar(eph):
    iono = getattr(eph, "iono", None) or {}
    a, b = iono.get("GPSA"), iono.get("GPSB")
    if a is not None and b is not None and len(a) == 4 and len(b) == 4:
        return np.asarray(a, float), np.asarray(b, float)
    return KLOBUCHAR_FALLBACK_ALPHA, KLOBUCHAR_FALLBACK_BETA


def _rotate_earth(pos, theta):
    """Satellite ECEF of the transmit instant into the ECEF frame of reception (IS-GPS-200N 20.3.3.4.3.4)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.column_stack([c * pos[:, 0] + s * pos[:, 1], -s * pos[:, 0] + c * pos[:, 1], pos[:, 2]])


def spp_sigma_m(sv, el_deg, iono_m, config=None):
    """Pseudorange sigma [m] of the RTKLIB single point error budget (pntpos.c rescode()): measurement
    (SolverConfig elevation model, system factors) + broadcast orbit/clock (URA, ``SPP_URA_M``) +
    code bias (ERR_CBIAS 0.3 m) + ionosphere model (ERR_BRDCI: 50 % of the Klobuchar delay) +
    troposphere model (ERR_SAAS 0.3 m / (sin el + 0.1))."""
    el = np.asarray(el_deg, dtype=float)
    var = (pseudorange_sigma_m(el, sv, config=config) ** 2 + SPP_URA_M**2 + SPP_CODE_BIAS_M**2
           + (SPP_IONO_FRACTION * np.asarray(iono_m, dtype=float)) ** 2
           + (SPP_TROPO_M / (np.sin(np.radians(np.clip(el, 0.0, 90.0))) + 0.1)) ** 2)
    return np.sqrt(var)


def spp_epoch(eph, t_rx: GnssTime, sv, pseudorange_m, code_of_system: dict[str, str], prior_ecef_m=None,
              glo_channel=None, config=None):
    """Single point position of one epoch from raw pseudoranges (receiver time tags) and a broadcast
    ephemeris: transmit time t_rx - P/c - dt_sat (IS-GPS-200N 20.3.3.3.3.1), satellite clock with the
    relativistic term and group delay as the simulator applies it, Earth rotation over the light time,
    Klobuchar ionosphere scaled by (f_L1/f)^2 (IS-GPS-200N 20.3.3.5.2.5), Saastamoinen zenith delays
    with Niell mapping.  A first solution without atmosphere and without residual test, then twice:
    light time, ionosphere and troposphere at the previous solution, sigmas of :func:`spp_sigma_m`,
    with solve_pvt's residual test.  Returns a PvtSolution or None (fewer than 4 satellites)."""
    sv = np.asarray(sv, dtype="<U3")
    pr = np.asarray(pseudorange_m, dtype=float)
    ok = np.isfinite(pr)
    sv, pr = sv[ok], pr[ok]
    if sv.size < 4:
        return None
    n = sv.size
    t0 = GnssTime(np.full(n, t_rx.sec, dtype=np.int64), np.full(n, float(t_rx.frac)))
    t_tx = t0 + (-pr / k.C_MPS)
    st = eph.states_at(sv, t_tx)
    if len(st) == 0:
        return None
    have = np.isin(sv, st.sv)
    sv, pr, t_tx = sv[have], pr[have], t_tx[np.flatnonzero(have)]
    t_tx = t_tx + (-np.asarray(st.clock_bias_s))
    st = eph.states_at(sv, t_tx)
    if len(st) != sv.size:       # a record boundary between the two instants: drop that satellite
        have = np.isin(sv, st.sv)
        sv, pr = sv[have], pr[have]
    if sv.size < 4:
        return None
    ch = np.asarray(st.glo_channel)
    codes = np.array([code_of_system[s[0]] for s in sv.tolist()])
    freq = np.array([frequency_hz(s[0], c, int(g) if s[0] == "R" else 0) for s, c, g in zip(sv.tolist(), codes, ch)],
                    dtype=float)
    systems = np.array([s[0] for s in sv.tolist()])
    dts = (np.asarray(st.clock_bias_s) + np.asarray(st.relativistic_s)
           - group_delay_factor(systems, codes, freq) * np.asarray(st.tgd_s))
    omega = np.array([OMEGA_BY_SYSTEM.get(s, k.OMEGA_E_GPS_RADPS) for s in systems.tolist()])
    pos_tx = np.asarray(st.pos_ecef_m)
    sat = _rotate_earth(pos_tx, omega * pr / k.C_MPS)
    cfg = config or SolverConfig()
    # first pass: no atmosphere yet, so no residual test (its errors are those of the missing models)
    sol = solve_pvt(sv, sat, pr, sat_clock_bias_s=dts, prior_ecef_m=prior_ecef_m,
                    config=dataclasses.replace(cfg, check_residuals=False))
    if not sol.is_fix:
        return sol
    alpha, beta = _klobuchar(eph)
    doy = prop.day_of_year(t_rx)
    for _ in range(2):
        x = sol.pos_ecef_m
        rng = np.linalg.norm(sat - x, axis=1)
        sat = _rotate_earth(pos_tx, omega * rng / k.C_MPS)
        lat, lon, h = ecef_to_geodetic(*x)
        az, el, _ = az_el_from_ecef(x, sat)
        iono = prop.iono_code_delay_m(prop.klobuchar_l1_delay_s(t_rx, lat, lon, az, el, alpha, beta), freq)
        tropo = prop.tropo_slant_delay_m(np.maximum(el, 1.0), lat, h, doy)
        sigma = spp_sigma_m(sv, el, iono, cfg)
        sol = solve_pvt(sv, sat, pr, sat_clock_bias_s=dts, iono_delay_m=iono, tropo_delay_m=tropo,
                        sigma_m=sigma, prior_ecef_m=x, config=cfg)
        if not sol.is_fix:
            break
    return sol


def spp_solutions(tab: ObsTable, eph, code_of_system: dict[str, str], epochs=None, prior_ecef_m=None,
                  config=None) -> Solutions:
    """:func:`spp_epoch` on each epoch (indices ``epochs``) of ``tab`` with the code of each system."""
    idx = np.arange(len(tab.time)) if epochs is None else np.asarray(epochs, dtype=int)
    pos = np.full((idx.size, 3), np.nan)
    used = np.zeros(idx.size, dtype=int)
    cols = np.array([s[0] in code_of_system for s in tab.sv.tolist()], dtype=bool)
    svs = tab.sv[cols]
    pr_all = np.full((len(tab.time), cols.sum()), np.nan)
    for j, s in enumerate(svs.tolist()):
        pr_all[:, j] = tab.column("C" + code_of_system[s[0]])[:, np.flatnonzero(cols)[j]]
    prior = prior_ecef_m
    for out_i, e in enumerate(idx.tolist()):
        sol = spp_epoch(eph, tab.gnss_time(e), svs, pr_all[e], code_of_system, prior, config=config)
        if sol is not None and sol.is_fix:
            pos[out_i] = sol.pos_ecef_m
            used[out_i] = sol.n_used
            prior = sol.pos_ecef_m
    return Solutions(pos, used, "gnss_sim solve_pvt")
