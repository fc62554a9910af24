"""GNSS quality of cells over time steps: one batched cast per chunk of cells x times x satellites.

Each chunk hands ``VisibilityOptions.cast`` (the visibility node's and the offline loop's call) M = cells x
times antenna rows, each with the N satellites of its time, so the states are those the simulator computes
at the same points (test_planning checks it).  A satellite without a record at a time is placed at the
Earth's centre: straight down, below the mask, never cast.

Per cell and time (arrays (C, T)): ``n_los`` (in line of sight above the mask), ``n_attenuated`` (through
foliage / a soft edge), ``n_reflected`` (reflected-only: multipath on only), ``n_blocked``; the DOPs of the
satellites a receiver would use (line of sight, attenuated, reflected-only: solver.dops_from_az_el, one clock
per system); ``nlos_share`` (reflected-only / used); ``h_acc_m``: HDOP x UERE, UERE the RMS of the used
satellites' sigma (ranging.py); ``n_rtk`` and ``rtk`` (rtk_rule.py).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..solver import dops_from_los_enu
from ..vocabulary import VisibilityState
from .ranging import RangingBudget
from .rtk_rule import RtkRule

#: the (C, T) outputs and their dtypes
FIELDS = {"n_los": np.int16, "n_attenuated": np.int16, "n_reflected": np.int16, "n_blocked": np.int16,
          "gdop": np.float32, "pdop": np.float32, "hdop": np.float32, "vdop": np.float32,
          "nlos_share": np.float32, "h_acc_m": np.float32, "n_rtk": np.int16, "rtk": np.bool_}
#: rays per cast call (cells x times x satellites of a chunk): bounds the chunk's memory (about 200 B a ray)
DEFAULT_MAX_RAYS = 1 << 21


@dataclass
class PlanInputs:
    """What every chunk needs (picklable: a Dask worker gets it once)."""

    sat_pos_ecef_m: np.ndarray        # (T, S, 3), NaN where absent
    systems: np.ndarray               # (S,) letters
    budget: RangingBudget
    rule: RtkRule = field(default_factory=RtkRule)
    max_rays: int = DEFAULT_MAX_RAYS


def quality_block(scene, vis, antenna_world_m, inp: PlanInputs, stats=None, states_out=None) -> dict:
    """The (C, T) fields of FIELDS for antennas ``antenna_world_m`` (C, 3) over every time of ``inp``.

    ``vis``: VisibilityOptions (mask, multipath, foliage model).  ``stats``: a dict that receives ``rays``
    (satellites cast) and ``cast_s`` (time inside the casts).  ``states_out``: a (C, T, S) int8 array that
    receives each satellite's VisibilityState where it is above the mask, -1 elsewhere (a path's time line,
    the tests)."""
    import time as _time

    ant = np.asarray(antenna_world_m, float).reshape(-1, 3)
    sat_all = inp.sat_pos_ecef_m
    n_t, n_s = sat_all.shape[:2]
    c = len(ant)
    out = {k: np.zeros((c, n_t), dt) for k, dt in FIELDS.items()}
    sysv = np.asarray(inp.systems)
    letters = sorted(set(sysv.tolist()))
    clock_all = np.array([letters.index(s) for s in sysv.tolist()])
    dual = np.array([inp.budget.dual_frequency.get(s, False) for s in sysv.tolist()])
    if not dual.any():
        dual[:] = True                                # single-frequency profile: rtk_rule.py module doc
    prev = None                                       # (C, S) RTK candidates of the previous step
    mid = 0.5 * (ant.min(axis=0) + ant.max(axis=0))
    centre_ecef = scene.antenna_ecef(mid[None])[0]
    # the vertical turns by (distance / Earth radius) across the block; 0.1 deg more for the world's flatness
    margin_deg = np.degrees(np.max(np.linalg.norm(ant - mid, axis=1)) / 6.371e6) + 0.1
    tc = int(max(1, min(n_t, inp.max_rays // max(1, c * n_s))))
    for t0 in range(0, n_t, tc):
        tt = np.arange(t0, min(n_t, t0 + tc))
        present_t = np.isfinite(sat_all[tt, :, 0])                     # (Tc, S)
        # only the satellites that can be above the mask somewhere in the block (the rest are never cast):
        # elevation at the block's centre, less the largest tilt of the vertical across the block
        el_c = np.nan_to_num(_elevation_deg(centre_ecef, sat_all[tt]), nan=-90.0)
        cols = np.flatnonzero((present_t & (el_c >= vis.mask_deg - margin_deg)).any(axis=0))
        sat = np.where(np.isfinite(sat_all[tt][:, cols]), sat_all[tt][:, cols], 0.0)     # (Tc, S', 3)
        m_rows = c * len(tt)
        ant_rows = np.repeat(ant, len(tt), axis=0)                     # row = cell * Tc + time
        sat_rows = np.broadcast_to(sat[None], (c,) + sat.shape).reshape(m_rows, len(cols), 3)
        t_start = _time.perf_counter()
        state, att, v = vis.cast(scene, ant_rows, sat_rows)
        if stats is not None:
            stats["cast_s"] = stats.get("cast_s", 0.0) + _time.perf_counter() - t_start
            stats["rays"] = stats.get("rays", 0) + int(np.count_nonzero(np.asarray(v.el_deg) >= vis.mask_deg))
        present = np.broadcast_to(present_t[:, cols][None], (c, len(tt), len(cols))).reshape(m_rows, len(cols))
        above = present & (np.asarray(v.el_deg) >= vis.mask_deg)
        if states_out is not None:
            st = np.where(above, state, -1).astype(np.int8).reshape(c, len(tt), len(cols))
            states_out[:, tt[0]:tt[-1] + 1] = -1
            states_out[:, tt[0]:tt[-1] + 1, cols] = st
        vals, cand, los_enu = _rows_quality(state, att, v, above, sysv[cols], clock_all[cols], dual[cols], inp)
        cand = cand.reshape(c, len(tt), len(cols))
        cont = np.zeros_like(cand)
        for j in range(len(tt)):                       # continuity: in line of sight at the previous step too
            cur = np.zeros((c, n_s), bool)
            cur[:, cols] = cand[:, j]
            before = cur if prev is None else prev     # the first step: no earlier step to break the arc
            cont[:, j] = cand[:, j] & before[:, cols]
            prev = cur
        vals["n_rtk"], vals["rtk"] = _rtk_fields(los_enu, cont.reshape(m_rows, len(cols)), clock_all[cols], inp.rule)
        for k, val in vals.items():
            out[k][:, tt] = np.asarray(val).reshape(c, len(tt))
    return out


def _rows_quality(state, att, v, above, sysv, clock, dual, inp: PlanInputs):
    """Per antenna row (M rows x S satellites of one cast): the FIELDS but the RTK ones, the RTK candidates (M, S)
    (dual-frequency, in line of sight above the AR mask) and the line-of-sight unit vectors (e, n, u)."""
    el, az = np.asarray(v.el_deg), np.asarray(v.az_deg)
    los = above & (state == int(VisibilityState.VISIBLE))
    attn = above & (state == int(VisibilityState.ATTENUATED))
    refl = above & (state == int(VisibilityState.REFLECTED_ONLY))
    blocked = above & (state == int(VisibilityState.BLOCKED))
    used = los | attn | refl
    ce, el_r = np.cos(np.radians(el)), np.radians(el)
    los_enu = (ce * np.sin(np.radians(az)), ce * np.cos(np.radians(az)), np.sin(el_r))
    gdop, pdop, hdop, vdop, _ = dops_from_los_enu(los_enu, used, clock)
    excess = np.where(refl, np.nan_to_num(np.asarray(v.extra_path_m, float)), 0.0)
    sigma = inp.budget.sigma_m(sysv, el, np.where(attn, att, 0.0), excess)
    n_used = used.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        uere = np.sqrt(np.where(used, sigma**2, 0.0).sum(axis=1) / n_used)
        nlos = refl.sum(axis=1) / n_used
    cand = los & (el >= inp.rule.ar_mask_deg) & dual
    vals = {"n_los": los.sum(axis=1), "n_attenuated": attn.sum(axis=1), "n_reflected": refl.sum(axis=1),
            "n_blocked": blocked.sum(axis=1), "gdop": gdop, "pdop": pdop, "hdop": hdop, "vdop": vdop,
            "nlos_share": nlos, "h_acc_m": hdop * uere}
    return vals, cand, los_enu


def _rtk_fields(los_enu, cont, clock, rule: RtkRule):
    """(n_rtk, rtk) per row from the continuously visible candidates ``cont`` (M, S) (rtk_rule.py)."""
    n_rtk = cont.sum(axis=1)
    enough = np.flatnonzero(n_rtk >= rule.min_sats)                  # only those can pass: their PDOP
    pdop_rtk = dops_from_los_enu(tuple(x[enough] for x in los_enu), cont[enough], clock)[1]
    rtk = np.zeros(len(n_rtk), bool)
    rtk[enough] = pdop_rtk < rule.max_pdop
    return n_rtk, rtk


def path_quality(scene, vis, antenna_world_m, sat_pos_ecef_m, systems, inp: PlanInputs, states_out=None) -> dict:
    """The FIELDS along a path: pose i at ``antenna_world_m[i]`` (P, 3) sees the satellites ``sat_pos_ecef_m[i]``
    (P, S, 3; NaN where absent) of the time it is there; one cast of P rows.  The RTK indicator's continuity is
    from one pose to the next (a carrier-phase arc held since the previous pose; the first pose: none broken).
    Values (P,) per field.  ``states_out``: a (P, S) int8 array that receives each satellite's VisibilityState
    where it is above the mask, -1 elsewhere."""
    ant = np.asarray(antenna_world_m, float).reshape(-1, 3)
    sat_all = np.asarray(sat_pos_ecef_m, float)
    sysv = np.asarray(systems)
    letters = sorted(set(sysv.tolist()))
    clock = np.array([letters.index(s) for s in sysv.tolist()])
    dual = np.array([inp.budget.dual_frequency.get(s, False) for s in sysv.tolist()])
    if not dual.any():
        dual[:] = True                                # single-frequency profile: rtk_rule.py module doc
    present = np.isfinite(sat_all[..., 0])
    state, att, v = vis.cast(scene, ant, np.where(present[..., None], sat_all, 0.0))
    above = present & (np.asarray(v.el_deg) >= vis.mask_deg)
    if states_out is not None:
        states_out[:] = np.where(above, state, -1)
    vals, cand, los_enu = _rows_quality(state, att, v, above, sysv, clock, dual, inp)
    cont = cand & np.concatenate([cand[:1], cand[:-1]], axis=0)
    vals["n_rtk"], vals["rtk"] = _rtk_fields(los_enu, cont, clock, inp.rule)
    return {k: np.asarray(vals[k]).astype(dt) for k, dt in FIELDS.items()}


def _elevation_deg(rx_ecef_m, sat_ecef_m) -> np.ndarray:
    """Elevation [deg] of satellites (..., 3) seen from one ECEF point (NaN satellites give NaN)."""
    from ..frames import az_el_from_ecef

    with np.errstate(invalid="ignore"):
        return np.asarray(az_el_from_ecef(rx_ecef_m, sat_ecef_m)[1])


def cell_blocks(n_cells: int, n_times: int, n_sats: int, max_rays: int = DEFAULT_MAX_RAYS,
                min_block: int = 1) -> list[slice]:
    """Slices of cells for one task each: about ``max_rays`` x 8 rays a block (the block then steps through
    its times ``max_rays`` at a time), at least ``min_block`` cells."""
    per = max(min_block, int(8 * max_rays // max(1, n_times * n_sats)))
    return [slice(i, min(n_cells, i + per)) for i in range(0, n_cells, per)]
