"""GNSS quality of cells over time steps: one batched cast per chunk of cells x times x satellites.

Each chunk hands ``VisibilityOptions.cast`` (the visibility node's and the offline loop's call) M = cells x
times antenna rows, each with the N satellites of its time, so the states are those the simulator computes
at the same points (test_planning checks it).  A satellite without a record at a time is placed at the
Earth's centre: straight down, below the mask, never cast.

Per cell and time (arrays (C, T)): ``n_los`` (in line of sight above the mask), ``n_attenuated`` (through
foliage / a soft edge), ``n_reflected`` (reflected-only: multipath on only), ``n_blocked``; the DOPs of the
satellites a receiver would use (line of sight, attenuated, reflected-only: solver.dops_from_az_el, one clock
per system); ``nlos_share`` (reflected-only / used); ``h_acc_m``: HDOP x UERE, UERE the RMS of the used
satellites' sigma (ranging.py); ``n_rtk`` and ``rtk`` (rtk_rule.py); ``n_good``: satellites whose C/N0 predicted
from the profile's link budget is >= ``good_cn0_dbhz`` (predicted_cn0.py; -1 without a predictor).

The lines of sight, the UERE's elevation terms and the open-sky C/N0 are computed once per (tile, time, satellite)
at the centre of square tiles of ``PlanInputs.share_tile_m`` and shared by the tile's cells (shared.py): the
states, counts, RTK indicator and good-satellite counts are those of per-cell terms, the DOPs and the expected
accuracy within a bound of them (docs/PLANNING.md); ``share_tile_m`` 0: per-cell terms (sight_lines.py).
"""
from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from ..solver import dop_moments, dop_moments_of_entries, dops_from_los_enu, dops_from_moments
from ..vocabulary import VisibilityState
from .predicted_cn0 import DEFAULT_GOOD_CN0_DBHZ, Cn0Predictor
from .ranging import RangingBudget
from .rtk_rule import RtkArcs, RtkRule
from .shared import Tiles, enu_moments, moment_terms, row_sums
from .sight_lines import AntennaAxes

#: the (C, T) outputs and their dtypes
FIELDS = {"n_los": np.int16, "n_attenuated": np.int16, "n_reflected": np.int16, "n_blocked": np.int16,
          "gdop": np.float32, "pdop": np.float32, "hdop": np.float32, "vdop": np.float32,
          "nlos_share": np.float32, "h_acc_m": np.float32, "n_rtk": np.int16, "rtk": np.bool_, "n_good": np.int16}
#: rays per cast call (cells x times x satellites of a chunk): bounds the chunk's memory (about 200 B a ray); a
#: quarter of a million keeps the chunk's arrays near the caches: 2,000 Hong Kong cells x 24 h took 9.4 s a block
#: at 1 << 18 against 15.0 s at 1 << 21 (bench_plan.py, docs/BENCHMARKS.md)
DEFAULT_MAX_RAYS = 1 << 18
#: rays of one task's block of cells (cell_blocks): at least this x 8 (a task's fixed cost spread over its cells)
BLOCK_BASE_RAYS = 1 << 21
#: square tiles [m] whose cells share per-(time, satellite) lines of sight, UERE and C/N0 terms (shared.py); the
#: differences this makes against per-cell terms grow with the size: docs/PLANNING.md, test_planning
DEFAULT_SHARE_TILE_M = 250.0
#: largest tile [m]: the differences stay below the bounds test_planning holds
MAX_SHARE_TILE_M = 2000.0


@dataclass
class PlanInputs:
    """What every chunk needs (picklable: a Dask worker gets it once)."""

    sat_pos_ecef_m: np.ndarray        # (T, S, 3), NaN where absent
    systems: np.ndarray               # (S,) letters
    budget: RangingBudget
    rule: RtkRule = field(default_factory=RtkRule)
    max_rays: int = DEFAULT_MAX_RAYS
    cn0: Cn0Predictor | None = None    # the profile's C/N0 prediction (n_good, attenuated RTK candidates); None:
    good_cn0_dbhz: float = DEFAULT_GOOD_CN0_DBHZ    # n_good = -1 and no attenuated satellite counts for RTK
    t_s: np.ndarray | None = None     # (T,) seconds of the steps (RTK outages); None: no outage bridged
    share_tile_m: float = DEFAULT_SHARE_TILE_M    # tiles sharing per-(time, satellite) terms (shared.py); 0: per cell

    def __post_init__(self):
        check_share_tile_m(self.share_tile_m, "planning: share_tile_m")


def check_share_tile_m(value, where: str) -> None:
    """The one rule of the tile size sharing per-(time, satellite) terms; ValueError naming ``where``."""
    if not (isinstance(value, (int, float, np.floating, np.integer)) and np.isfinite(value)
            and 0.0 <= value <= MAX_SHARE_TILE_M):
        raise ValueError(f"{where} is {value!r}: a tile size in 0..{MAX_SHARE_TILE_M:g} m is needed (0: every cell "
                         f"its own lines of sight, C/N0 and UERE terms)")


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
    arcs = RtkArcs(inp.rule, c, n_s)                  # RTK arcs and fixes, step to step
    t_all, gap = _step_times(inp.t_s, n_t, inp.rule)
    mid = 0.5 * (ant.min(axis=0) + ant.max(axis=0))
    centre_ecef = scene.antenna_ecef(mid[None])[0]
    axes = AntennaAxes.of(scene, ant)                 # each cell's ECEF point and ENU axes, once (not per row)
    # the vertical turns by (distance / Earth radius) across the block; 0.1 deg more for the world's flatness
    margin_deg = np.degrees(np.max(np.linalg.norm(ant - mid, axis=1)) / 6.371e6) + 0.1
    # only the satellites that can be above the mask somewhere in the block (the rest are never cast):
    # elevation at the block's centre, less the largest tilt of the vertical across the block
    el_c = np.nan_to_num(_elevation_deg(centre_ecef, sat_all), nan=-90.0)
    up_all = np.isfinite(sat_all[..., 0]) & (el_c >= vis.mask_deg - margin_deg)                 # (T, S)
    tiles = Tiles.of(scene, ant, axes, inp.share_tile_m) if inp.share_tile_m > 0 else None
    n_groups = len(letters)

    def finish(tt, cols, sat, present_t, state, att, v):
        """Everything after a window's cast, in order (the RTK arcs step from window to window)."""
        m_rows = c * len(tt)
        above = np.asarray(v.el_deg) >= vis.mask_deg
        above.reshape(c, len(tt), len(cols))[:] &= present_t[:, cols][None]     # present: broadcast, no copy
        if states_out is not None:
            st = np.where(above, state, -1).astype(np.int8).reshape(c, len(tt), len(cols))
            states_out[:, tt[0]:tt[-1] + 1] = -1
            states_out[:, tt[0]:tt[-1] + 1, cols] = st
        if tiles is None:                              # per cell
            rng, los_enu = axes.to_satellites(sat, per_time=True)        # cell x time x satellite, broadcast
            cn0 = _predicted_cn0(inp, sysv[cols], state, att, v, above, rng)
            vals, cand, used = _rows_quality(state, att, v, above, los_enu, sysv[cols], clock_all[cols], dual[cols],
                                             inp, cn0)
            rtk_geometry = lambda cont: _rtk_geometry(los_enu, cont, clock_all[cols], inp.rule, used)   # noqa: E731
        else:                                          # per tile and (time, satellite): shared.py
            vals, cand, rtk_geometry = _rows_quality_shared(tiles, axes, sat, state, att, v, above, sysv[cols],
                                                            clock_all[cols], n_groups, dual[cols], inp)
        cand = cand.reshape(c, len(tt), len(cols))
        cont = np.zeros_like(cand)
        for j in range(len(tt)):                       # unbroken arcs (rtk_rule.py)
            cont[:, j] = arcs.unbroken(cand[:, j], t_all[tt[j]], gap, cols)
        n_rtk, pdop_rtk = rtk_geometry(cont.reshape(m_rows, len(cols)))
        n_rtk, pdop_rtk = n_rtk.reshape(c, len(tt)), pdop_rtk.reshape(c, len(tt))
        rtk = np.stack([arcs.fix(n_rtk[:, j], pdop_rtk[:, j]) for j in range(len(tt))], axis=1)
        vals["n_rtk"], vals["rtk"] = n_rtk, rtk
        if tiles is None:
            vals["n_good"] = _n_good(cn0, inp, m_rows)
        for k, val in vals.items():
            out[k][:, tt] = np.asarray(val).reshape(c, len(tt))

    # OVERLAP_FINISH: a window's casts overlap the previous window's finish, which runs on one thread in window order
    # (numpy and Open3D release the GIL): the same arithmetic in the same order as one after the other
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="plan-finish") if OVERLAP_FINISH else _InOrder() as pool:
        pending = None
        rows_buf = [np.empty(0), np.empty(0)]       # the rows' satellites, written in place: alternate windows'
        for w, tt in enumerate(_time_windows(up_all, c, inp.max_rays)):
            cols = np.flatnonzero(up_all[tt].any(axis=0))
            present_t = np.isfinite(sat_all[tt, :, 0])                     # (Tc, S)
            sat = np.where(np.isfinite(sat_all[tt][:, cols]), sat_all[tt][:, cols], 0.0)     # (Tc, S', 3)
            m_rows = c * len(tt)
            ant_rows = np.repeat(ant, len(tt), axis=0)                     # row = cell * Tc + time
            if rows_buf[w % 2].size < m_rows * sat[0].size:                # (no fresh pages per window)
                rows_buf[w % 2] = np.empty(m_rows * sat[0].size)
            sat_rows = rows_buf[w % 2][:m_rows * sat[0].size].reshape((c,) + sat.shape)
            sat_rows[:] = sat[None]
            sat_rows = sat_rows.reshape(m_rows, len(cols), 3)
            t_start = _time.perf_counter()
            state, att, v = vis.cast(scene, ant_rows, sat_rows, azimuth=False)     # the elevations only
            if stats is not None:
                stats["cast_s"] = stats.get("cast_s", 0.0) + _time.perf_counter() - t_start
                stats["rays"] = stats.get("rays", 0) + int(np.count_nonzero(np.asarray(v.el_deg) >= vis.mask_deg))
            if pending is not None:
                pending.result()                       # at most one window waiting: two windows' arrays at a time
            pending = pool.submit(finish, tt, cols, sat, present_t, state, att, v)
        if pending is not None:
            pending.result()
    return out


#: finish a window (states, C/N0, DOPs, RTK rule) on a second thread while the next window is cast.  Off: at load
#: 7-10 on the 2-core machine (other processes on both cores) it gave no gain (2,000 HK cells x 24 h, alternated with
#: it off: 8.2-15.8 s against 9.3-10.9 s, the same CPU seconds); to be measured on a quiet machine
#: (``bench_plan.py --overlap``)
OVERLAP_FINISH = False


class _InOrder:
    """ThreadPoolExecutor's submit / result, run at once in the caller's thread."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def submit(self, fn, *args):
        fut = Future()
        fut.set_result(fn(*args))
        return fut


#: a chunk's times share one set of satellite columns: a step joins the chunk while the union of the satellites up
#: stays within this factor of the most up at one step (the casts and the per-row work scale with the columns)
WINDOW_UNION_FACTOR = 1.25


def _time_windows(up, n_cells: int, max_rays: int) -> list[np.ndarray]:
    """Consecutive time steps in chunks (indices): at most ``max_rays`` cells x steps x union columns, and the union
    of the satellites ``up`` (T, S) within WINDOW_UNION_FACTOR of the largest count of one step."""
    out, n_t = [], len(up)
    t0 = 0
    while t0 < n_t:
        union, most, t1 = up[t0].copy(), int(up[t0].sum()), t0 + 1
        while t1 < n_t:
            u = union | up[t1]
            n_u, most_1 = int(u.sum()), max(most, int(up[t1].sum()))
            if n_u > WINDOW_UNION_FACTOR * most_1 or n_cells * (t1 + 1 - t0) * n_u > max_rays:
                break
            union, most, t1 = u, most_1, t1 + 1
        out.append(np.arange(t0, t1))
        t0 = t1
    return out


def _states(state, above):
    """(line of sight, attenuated, reflected-only, blocked, used) (M, S) of the satellites ``above`` the mask."""
    los = above & (state == int(VisibilityState.VISIBLE))
    attn = above & (state == int(VisibilityState.ATTENUATED))
    refl = above & (state == int(VisibilityState.REFLECTED_ONLY))
    blocked = above & (state == int(VisibilityState.BLOCKED))
    return los, attn, refl, blocked, los | attn | refl


def _rows_quality_shared(tiles: Tiles, axes, sat, state, att, v, above, sysv, clock, n_groups, dual, inp: PlanInputs):
    """:func:`_rows_quality` of a window's rows (cell * T + time) from per-(tile, time, satellite) terms (shared.py):
    (the FIELDS but the RTK ones, with n_good; the RTK candidates (M, S); a function of the unbroken candidates
    (M, S) giving (n_rtk, PDOP))."""
    n_t, n_s = sat.shape[:2]
    el = np.asarray(v.el_deg)
    los, attn, refl, blocked, used = _states(state, above)
    u, rng0, sin0 = tiles.sky(sat)                                  # (n, T, S) at each tile's centre
    el0 = np.degrees(np.arcsin(np.clip(sin0, -1.0, 1.0)))
    col = np.broadcast_to(np.arange(n_s), el0.shape).reshape(-1)
    var0 = inp.budget.variance_of_columns_m2(sysv, col, el0.reshape(-1), np.zeros(col.shape), 0.0,
                                             sin_el=sin0.reshape(-1)).reshape(el0.shape)
    untracked = ~np.isfinite(var0)                   # a system the profile does not track: infinite sigma
    terms = moment_terms(u, clock, n_groups, extra=np.where(untracked, 0.0, var0))
    sums = row_sums(used, tiles, terms)
    moments = enu_moments(sums, axes, n_t, n_groups)
    gdop, pdop, hdop, vdop, _ = dops_from_moments(*moments)
    var_sum = sums[:, -1].copy()
    if untracked.any():                             # as the per-entry sum: infinite with one of them used
        var_sum[_count(used & tiles.rows(untracked)) > 0] = np.inf
    # per entry on top: an attenuated satellite's thermal noise at its lower C/N0, a reflected-only one's excess
    e = np.flatnonzero(attn & (att != 0.0))
    if len(e):
        r, k = np.divmod(e, n_s)
        t_e, tile_e = r % n_t, tiles.index[r // n_t]
        keep = ~untracked[tile_e, t_e, k]           # (an untracked system's row is infinite already)
        e, r, k, t_e, tile_e = e[keep], r[keep], k[keep], t_e[keep], tile_e[keep]
        el_e, sin_e = el0[tile_e, t_e, k], sin0[tile_e, t_e, k]
        att_e = np.asarray(att, float).reshape(-1).take(e)
        d = (inp.budget.variance_of_columns_m2(sysv, k, el_e, att_e, 0.0, sin_el=sin_e)
             - inp.budget.variance_of_columns_m2(sysv, k, el_e, np.zeros(len(e)), 0.0, sin_el=sin_e))
        var_sum += np.bincount(r, weights=d, minlength=len(var_sum))
    if refl.any():
        e = np.flatnonzero(refl)
        ex = np.nan_to_num(np.asarray(v.extra_path_m, float).reshape(-1).take(e))
        var_sum += np.bincount(e // n_s, weights=ex * ex, minlength=len(var_sum))
    n_used = _count(used)
    n_refl = _count(refl)
    with np.errstate(invalid="ignore", divide="ignore"):
        uere = np.sqrt(var_sum / n_used)
        nlos = n_refl / n_used
    tracked, n_good = los, np.full(len(used), -1)
    if inp.cn0 is not None:
        n_good, tracked = _shared_cn0(tiles, axes, sat, state, att, v, above, los, attn, rng0, el0, sysv, inp)
    cand = tracked & (el >= inp.rule.ar_mask_deg) & dual
    vals = {"n_los": _count(los), "n_attenuated": _count(attn), "n_reflected": n_refl,
            "n_blocked": _count(blocked), "gdop": gdop, "pdop": pdop, "hdop": hdop, "vdop": vdop,
            "nlos_share": nlos, "h_acc_m": hdop * uere, "n_good": n_good}

    def rtk_geometry(cont):                         # the PDOP does not depend on the axes: ECEF moments as they are
        n_rtk = _count(cont)
        sums_c = row_sums(cont, tiles, terms)
        pdop_rtk = dops_from_moments(sums_c[:, :n_groups].T, sums_c[:, n_groups:4 * n_groups].reshape(
            -1, 3, n_groups).transpose(1, 2, 0), sums_c[:, 4 * n_groups:4 * n_groups + 6].T)[1]
        return n_rtk, _rtk_pdop(n_rtk, pdop_rtk, inp.rule)
    return vals, cand, rtk_geometry


def _shared_cn0(tiles: Tiles, axes, sat, state, att, v, above, los, attn, rng0, el0, sysv, inp: PlanInputs):
    """(n_good (M,), tracked (M, S)) of a window's rows from the predicted C/N0 (the satellites at or above
    ``good_cn0_dbhz``; in line of sight, or attenuated at or above the profile's tracking threshold when the rule
    counts those): an entry's C/N0 is its tile centre's open-sky C/N0 less its attenuation (an entry without
    attenuation: the centre's decision, bool arrays broadcast to the cells), computed per entry (its own range and
    elevation, predicted_cn0's arithmetic) where the centre's is within the sharing's error bound of a threshold
    (shared.py): the decisions of the per-cell C/N0."""
    pred = inp.cn0
    count_att = inp.rule.count_attenuated
    good, trk = inp.good_cn0_dbhz, pred.tracking_cn0_dbhz
    if getattr(v, "paths", None) is not None:       # reflected paths: the composite amplitudes, per entry
        rng, _ = axes.to_satellites(sat, per_time=True)
        cn0 = _predicted_cn0(inp, sysv, state, att, v, above, rng)
        with np.errstate(invalid="ignore"):
            return _count(cn0 >= good), (los | (attn & (cn0 >= trk))) if count_att else los
    n_t, n_s = sat.shape[:2]
    open0 = np.full(rng0.shape, -np.inf)            # (n, T, S) at the tiles' centres
    for s in np.unique(sysv).tolist():
        k = np.flatnonzero(sysv == s)
        open0[..., k] = pred.open_sky_dbhz(s, rng0[..., k].reshape(-1), el0[..., k].reshape(-1)).reshape(
            rng0[..., k].shape)
    margin = tiles.cn0_margin_db(pred, sysv, float(np.min(rng0)))[:, None, :]      # (n, 1, S)
    att_f = np.asarray(att, float)
    need = los | attn
    own = need & (att_f != 0.0)                     # attenuated entries: their own value, per entry
    near = np.abs(open0 - good) <= margin
    e_mask = own | (need & tiles.rows(near))
    if count_att:
        near_t = np.abs(open0 - trk) <= margin
        e_mask |= attn & tiles.rows(near_t)
    common = need & ~e_mask                        # the centre's decisions hold
    n_good = _count(common & tiles.rows(open0 >= good))
    tracked = los | (attn & common & tiles.rows(open0 >= trk)) if count_att else los.copy()
    e = np.flatnonzero(e_mask)
    if len(e):
        r, k = np.divmod(e, n_s)
        t_e, tile_e = r % n_t, tiles.index[r // n_t]
        att_e = att_f.reshape(-1).take(e)
        val = open0[tile_e, t_e, k] - att_e
        m_e = margin[tile_e, 0, k]
        is_att = attn.reshape(-1).take(e)
        close = (np.abs(val - good) <= m_e) | (count_att & is_att & (np.abs(val - trk) <= m_e))
        x = e[close]
        if len(x):                                  # per entry, as predicted_cn0 and sight_lines compute it
            rx = axes.ecef_m[r[close] // n_t]
            pos = sat[t_e[close], k[close]]
            d = [pos[:, i] - rx[:, i] for i in range(3)]
            rng = d[0] * d[0]
            rng += d[1] * d[1]
            rng += d[2] * d[2]
            rng = np.sqrt(rng)
            el_x = np.asarray(v.el_deg, float).reshape(-1).take(x)
            kx = k[close]
            exact = np.empty(len(x))
            for s in np.unique(sysv[kx]).tolist():
                w = np.flatnonzero(sysv[kx] == s)
                exact[w] = pred.open_sky_dbhz(s, rng[w], el_x[w]) - att_e[close][w]
            val[close] = exact
        n_good += np.bincount(r, weights=val >= good, minlength=len(n_good)).astype(n_good.dtype)
        if count_att:
            tracked.reshape(-1)[e] |= is_att & (val >= trk)
    return n_good, tracked


def _rows_quality(state, att, v, above, los_enu, sysv, clock, dual, inp: PlanInputs, cn0=None):
    """Per antenna row (M rows x S satellites of one cast; ``los_enu`` their unit lines of sight (e, n, u), each
    (M, S), sight_lines.py): the FIELDS but the RTK ones, the RTK candidates (M, S) (dual-frequency, tracked
    above the AR mask: rtk_rule.py; ``cn0`` the predicted C/N0 or None) and the used satellites (M, S) with
    their DOP moments (solver.dop_moments: the RTK set's are those less the few used satellites not in it)."""
    el = np.asarray(v.el_deg)
    los, attn, refl, blocked, used = _states(state, above)
    moments = dop_moments(los_enu, used, clock)
    gdop, pdop, hdop, vdop, _ = dops_from_moments(*moments)
    # the used satellites only (sigma ignores the others), gathered by flat index (row-major: r, k ascending)
    flat = np.flatnonzero(used)
    n_used = _count(used)
    r = np.repeat(np.arange(len(used)), n_used)                 # each entry's row, its column: no integer division
    k = flat - r * used.shape[1]

    def entries(x, dtype=None):
        return np.asarray(x, dtype).reshape(-1).take(flat)

    excess = np.where(entries(refl), np.nan_to_num(entries(v.extra_path_m, float)), 0.0) if refl.any() else 0.0
    var = inp.budget.variance_of_columns_m2(sysv, k, entries(el), np.where(entries(attn), entries(att), 0.0), excess,
                                            sin_el=entries(los_enu[2]))      # the up component: no sine per entry
    var_sum = _row_sums(var, n_used)
    n_refl = _count(refl)
    with np.errstate(invalid="ignore", divide="ignore"):
        uere = np.sqrt(var_sum / n_used)
        nlos = n_refl / n_used
    tracked = los
    if cn0 is not None and inp.rule.count_attenuated:         # through foliage, strong enough to stay in lock
        with np.errstate(invalid="ignore"):
            tracked = los | (attn & (cn0 >= inp.cn0.tracking_cn0_dbhz))
    cand = tracked & (el >= inp.rule.ar_mask_deg) & dual
    vals = {"n_los": _count(los), "n_attenuated": _count(attn), "n_reflected": n_refl,
            "n_blocked": _count(blocked), "gdop": gdop, "pdop": pdop, "hdop": hdop, "vdop": vdop,
            "nlos_share": nlos, "h_acc_m": hdop * uere}
    return vals, cand, (used, moments)


def _row_sums(x, n_per_row) -> np.ndarray:
    """Sums of ``x`` (E,), entries in row order, ``n_per_row`` (M,) of them per row (0 for a row without any)."""
    if not len(x):
        return np.zeros(len(n_per_row))
    starts = np.cumsum(n_per_row) - n_per_row
    return np.where(n_per_row > 0, np.add.reduceat(x, np.minimum(starts, len(x) - 1)), 0.0)


def _count(mask) -> np.ndarray:
    """True entries per row of a bool (M, S) array (einsum over its bytes: numpy's row sum of a short bool row is
    slower)."""
    return np.einsum("ks->k", np.asarray(mask, bool).view(np.uint8), dtype=np.int64)


def _rtk_geometry(los_enu, cont, clock, rule: RtkRule, used=None):
    """(n_rtk, PDOP) per row of the unbroken candidates ``cont`` (M, S) (rtk_rule.py; PDOP inf under the hold
    count).  ``used``: (the used satellites, their solver.dop_moments) of _rows_quality, of which ``cont`` is a
    subset: the candidates' moments are theirs less those of the few used satellites not in ``cont``."""
    n_rtk = _count(cont)
    if used is not None and not (cont & ~used[0]).any():
        cnt, s1, s2 = used[1]
        drop_r, drop_s = np.divmod(np.flatnonzero(used[0] & ~cont), cont.shape[1])
        d_cnt, d_s1, d_s2 = dop_moments_of_entries(los_enu, drop_r, drop_s, len(cont), clock, cnt.shape[0])
        return n_rtk, _rtk_pdop(n_rtk, dops_from_moments(cnt - d_cnt, s1 - d_s1, s2 - d_s2)[1], rule)
    enough = np.flatnonzero(n_rtk >= min(rule.min_sats, rule.min_hold_sats))     # only those can pass: their PDOP
    if 2 * len(enough) >= len(n_rtk):               # most rows: all of them, no gathered copies (each row's DOPs
        return n_rtk, _rtk_pdop(n_rtk, dops_from_los_enu(los_enu, cont, clock)[1], rule)   # are its own)
    pdop = np.full(len(n_rtk), np.inf)
    pdop[enough] = dops_from_los_enu(tuple(x[enough] for x in los_enu), cont[enough], clock)[1]
    return n_rtk, np.nan_to_num(pdop, nan=np.inf)


def _rtk_pdop(n_rtk, pdop, rule: RtkRule) -> np.ndarray:
    """``pdop`` (M,) with the rows under the hold count and the degenerate ones (NaN) set to inf (no fix)."""
    pdop[n_rtk < min(rule.min_sats, rule.min_hold_sats)] = np.inf
    return np.nan_to_num(pdop, nan=np.inf)


def _step_times(t_s, n: int, rule: RtkRule):
    """(times of the n steps [s], the outage bridged [s]): ``t_s`` and the rule's, or the step index and none."""
    if t_s is None:
        return np.arange(n, dtype=float), 0.0
    t = np.asarray(t_s, float).reshape(-1)
    if len(t) != n:
        raise ValueError(f"planning: {len(t)} step times for {n} steps")
    return t, rule.max_outage_s


def path_quality(scene, vis, antenna_world_m, sat_pos_ecef_m, systems, inp: PlanInputs, states_out=None,
                 cn0_out=None, t_s=None) -> dict:
    """The FIELDS along a path: pose i at ``antenna_world_m[i]`` (P, 3) sees the satellites ``sat_pos_ecef_m[i]``
    (P, S, 3; NaN where absent) of the time it is there; one cast of P rows.  The RTK indicator's continuity is
    from one pose to the next (a carrier-phase arc held since the previous pose; the first pose: none broken).
    Values (P,) per field.  ``states_out``: a (P, S) int8 array that receives each satellite's VisibilityState
    where it is above the mask, -1 elsewhere.  ``cn0_out``: a (P, S) float array that receives the predicted C/N0
    (predicted_cn0.py; NaN below the mask or absent, -inf not received; needs ``inp.cn0``).  ``t_s``: (P,) times
    of the poses [s] (RTK outages bridged up to the rule's ``max_outage_s``); None: none bridged."""
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
    rng, los_enu = AntennaAxes.of(scene, ant).to_satellites(np.where(present[..., None], sat_all, 0.0),
                                                            per_time=False)
    cn0 = _predicted_cn0(inp, sysv, state, att, v, above, rng)
    vals, cand, used = _rows_quality(state, att, v, above, los_enu, sysv, clock, dual, inp, cn0)
    arcs = RtkArcs(inp.rule, 1, len(sysv))            # the path is one row stepping pose to pose
    t_all, gap = _step_times(t_s, len(ant), inp.rule)
    cont = np.concatenate([arcs.unbroken(cand[i:i + 1], t_all[i], gap) for i in range(len(ant))]) if len(ant) else cand
    n_rtk, pdop_rtk = _rtk_geometry(los_enu, cont, clock, inp.rule, used)
    vals["n_rtk"] = n_rtk
    vals["rtk"] = np.array([arcs.fix(n_rtk[i:i + 1], pdop_rtk[i:i + 1])[0] for i in range(len(ant))], bool)
    vals["n_good"] = _n_good(cn0, inp, len(ant))
    if cn0_out is not None:
        if cn0 is None:
            raise ValueError("path_quality: cn0_out needs PlanInputs.cn0 (a Cn0Predictor)")
        cn0_out[:] = cn0
    return {k: np.asarray(vals[k]).astype(dt) for k, dt in FIELDS.items()}


def _predicted_cn0(inp: PlanInputs, sysv, state, att, v, above, range_m):
    """(M, S) C/N0 predicted by ``inp.cn0`` (predicted_cn0.py) at distances ``range_m`` (M, S), NaN off ``above``;
    None without a predictor."""
    if inp.cn0 is None:
        return None
    return inp.cn0.cn0_dbhz(sysv, state, att, v, range_m, where=above)


def _n_good(cn0, inp: PlanInputs, n_rows: int) -> np.ndarray:
    """Satellites per row with a predicted C/N0 >= ``inp.good_cn0_dbhz`` (-1 without a prediction)."""
    if cn0 is None:
        return np.full(n_rows, -1)
    with np.errstate(invalid="ignore"):
        return _count(cn0 >= inp.good_cn0_dbhz)


def _elevation_deg(rx_ecef_m, sat_ecef_m) -> np.ndarray:
    """Elevation [deg] of satellites (..., 3) seen from one ECEF point (NaN satellites give NaN)."""
    from ..frames import az_el_from_ecef

    with np.errstate(invalid="ignore"):
        return np.asarray(az_el_from_ecef(rx_ecef_m, sat_ecef_m)[1])


def cell_blocks(n_cells: int, n_times: int, n_sats: int, max_rays: int = DEFAULT_MAX_RAYS,
                min_block: int = 1) -> list[slice]:
    """Slices of cells for one task each: about max(``max_rays``, BLOCK_BASE_RAYS) x 8 rays a block (the block
    then steps through its times ``max_rays`` at a time), at least ``min_block`` cells."""
    per = max(min_block, int(8 * max(max_rays, BLOCK_BASE_RAYS) // max(1, n_times * n_sats)))
    return [slice(i, min(n_cells, i + per)) for i in range(0, n_cells, per)]
