"""What the receiver makes of its observables: a position fix, RINEX epochs, file names.

Shared by the offline simulation and the receiver node, so both write the
same files and report the same fix.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import constants as k
from ..memo import BoundedCache
from ..multipath.antenna import RINEX_ANTENNA_TYPE
from ..rinex.obs_write import EpochArrays, EpochFormatter, FormattedEpoch, RinexObsHeader, ssi_from_cn0
from ..solver import PvtSolution, SolverConfig, solve_pvt_many
from ..time import GnssTime
from .observations import EpochObservations

#: RINEX observation kinds written for every tracked signal: code, phase, Doppler, strength
OBS_KINDS = ("C", "L", "D", "S")


def obs_types_for(profile: dict[str, list[str]], systems: str) -> dict[str, list[str]]:
    """RINEX 3 observation types per system, e.g. {"G": ["C1C", "L1C", "D1C", "S1C", ...]}."""
    return {s: [kind + code for code in profile[s] for kind in OBS_KINDS] for s in systems if profile.get(s)}


def epoch_arrays(obs: EpochObservations, obs_types: dict[str, list[str]]) -> EpochArrays:
    """One RINEX epoch (rows = satellites with a tracked signal) from the receiver's observables."""
    svs, width, codes, (dest_v, src_v, dest_s, src_s, dest_l, src_l) = _layout(obs.sv, obs.code, obs_types)
    value = np.empty((len(svs), width))      # np.empty + fill: np.full's own overhead is larger here
    value.fill(np.nan)
    lli = np.empty((len(svs), width), dtype=np.int64)
    lli.fill(-1)
    ssi = lli.copy()
    if len(dest_v):
        # C, L, D, S values of every signal in one array, placed at their (row, column) cells in one go
        kinds = np.concatenate([obs.pseudorange_m, obs.carrier_phase_cyc, obs.doppler_hz, obs.cn0_dbhz])
        np.put(value, dest_v, kinds[src_v])
        np.put(ssi, dest_s, ssi_from_cn0(obs.cn0_dbhz)[src_s])      # strength on code and phase
        np.put(lli, dest_l, np.asarray(obs.lli)[src_l])              # loss of lock on phase
    return EpochArrays(sv=svs, codes=codes, value=value, lli=lli, ssi=ssi)


_COLUMNS_CACHE = BoundedCache(16)
_LAYOUT_CACHE = BoundedCache(256)


def _layout(sv, code, obs_types):
    """(satellites in order of appearance, width, codes per system padded to the width, flat places) of one
    epoch's signals, the flat places being (cells of the C/L/D/S values in the (satellites, width) arrays,
    their positions in the four kinds' values one after another, cells of the C and L strengths, their
    signals, cells of the L loss-of-lock flags, their signals); cached (the tracked set changes rarely)."""
    sv, code = np.asarray(sv), np.asarray(code)
    key = (sv.dtype.str, sv.tobytes(), code.dtype.str, code.tobytes(),
           tuple((s, tuple(c)) for s, c in obs_types.items()))
    hit = _LAYOUT_CACHE.get(key)
    if hit is None:
        sv_list = sv.tolist()
        svs = tuple(dict.fromkeys(sv_list))
        row = {s: i for i, s in enumerate(svs)}
        width = max((len(v) for v in obs_types.values()), default=0)
        rows = np.array([row[s] for s in sv_list], dtype=np.int64)
        places = _signal_places(sv_list, code, obs_types, rows * width)
        # shorter systems' code lists padded to the common width with names not in the header (never filled)
        codes = {s: list(v) + [f"X{i}Z" for i in range(width - len(v))] for s, v in obs_types.items()}
        hit = (svs, width, codes, places)
        _LAYOUT_CACHE.put(key, hit)
    return hit


def formatter_for(obs_types: dict[str, list[str]]) -> EpochFormatter:
    """The RINEX EpochFormatter of these observation types (one per obs_types: its layouts cached across epochs)."""
    key = tuple((s, tuple(c)) for s, c in obs_types.items())
    hit = _FORMATTERS.get(key)
    if hit is None:
        hit = EpochFormatter({s: list(c) for s, c in key})
        _FORMATTERS.put(key, hit)
    return hit


_FORMATTERS = BoundedCache(16)


def rinex_lines(obs_list, obs_types: dict[str, list[str]]) -> list[FormattedEpoch]:
    """The RINEX satellite lines of epochs' observables (each with a tracked signal), all formatted in one pass:
    the bytes a RinexObsWriter with these obs_types writes for their epoch_arrays, the C/L/D/S values, strengths
    and loss-of-lock flags placed straight into the flat layout it formats (no EpochArrays made)."""
    fmt = formatter_for(obs_types)
    if not obs_list:
        return []
    layouts = [_flat_layout(o.sv, o.code, fmt) for o in obs_list]
    cat = np.concatenate
    # each epoch's places shifted by the cells / signals of the epochs before it
    cells = np.array([lay[1] for lay in layouts], dtype=np.int64)
    signals = np.array([len(o.sv) for o in obs_list], dtype=np.int64)
    cell0, signal0 = np.cumsum(cells) - cells, np.cumsum(signals) - signals
    sizes = np.array([lay[3] for lay in layouts], dtype=np.int64).reshape(len(layouts), 3)

    def shifted(k, start, size):
        return cat([lay[2][k] for lay in layouts]) + np.repeat(start, size)

    n_vals, n_ssi, n_lli = sizes[:, 0], sizes[:, 1], sizes[:, 2]
    value = np.empty(int(cells.sum()))
    value.fill(np.nan)
    lli = np.empty(len(value), dtype=np.int64)
    lli.fill(-1)
    ssi = lli.copy()
    kinds = cat([x for o in obs_list for x in (o.pseudorange_m, o.carrier_phase_cyc, o.doppler_hz, o.cn0_dbhz)])
    np.put(value, shifted(0, cell0, n_vals), kinds[shifted(1, 4 * signal0, n_vals)])
    cn0 = cat([o.cn0_dbhz for o in obs_list])
    np.put(ssi, shifted(2, cell0, n_ssi), ssi_from_cn0(cn0)[shifted(3, signal0, n_ssi)])   # strength on C and L
    flags = cat([np.asarray(o.lli) for o in obs_list])
    np.put(lli, shifted(4, cell0, n_lli), flags[shifted(5, signal0, n_lli)])           # loss of lock on phase
    return fmt.format_flat([len(lay[0]) for lay in layouts], [sv for lay in layouts for sv in lay[0]], value, lli,
                           ssi)


_FLAT_CACHE = BoundedCache(256)


def _flat_layout(sv, code, fmt: EpochFormatter):
    """(satellites in order of appearance, their cells, flat places, the numbers of value, strength and loss of lock
    places) of one epoch's signals in the flat layout
    EpochFormatter formats (satellite after satellite, each with its system's codes in header order), the places
    as _layout's (the cells of the C/L/D/S values, their positions in the four kinds' values one after another,
    the cells of the C and L strengths, their signals, the cells of the L loss-of-lock flags, their signals);
    cached (the tracked set changes rarely)."""
    sv, code = np.asarray(sv), np.asarray(code)
    key = (sv.dtype.str, sv.tobytes(), code.dtype.str, code.tobytes(), fmt.key)
    hit = _FLAT_CACHE.get(key)
    if hit is None:
        obs_types = fmt.obs_types
        sv_list = sv.tolist()
        sats = tuple(dict.fromkeys(sv_list))
        bad = [s for s in sats if not isinstance(s, str) or len(s) != 3 or s[0] not in obs_types]
        if bad:
            raise ValueError(f"observations: satellite {bad[0]!r} is not an id like 'G05' of a system in the "
                             f"header obs_types ({list(obs_types)})")
        counts = np.array([len(obs_types[s[0]]) for s in sats], dtype=np.int64)
        start = dict(zip(sats, (np.cumsum(counts) - counts).tolist()))
        base = np.array([start[s] for s in sv_list], dtype=np.int64)
        places = _signal_places(sv_list, code, obs_types, base)
        hit = (list(sats), int(counts.sum()), places, (len(places[0]), len(places[2]), len(places[4])))
        _FLAT_CACHE.put(key, hit)
    return hit


def _signal_places(sv_list: list, code, obs_types: dict[str, list[str]], base) -> tuple:
    """Where each signal's C, L, D, S values go in a flat block of the header's columns: ``base[i]`` is signal i's
    satellite's first cell; (dest, src) of every kind (src indexes the (kinds x signals) values), of C and L, of L."""
    cols_of = _columns_of(obs_types)
    no_cols = (-1,) * len(OBS_KINDS)
    m = len(sv_list)
    cols = np.array([cols_of.get((s[0], c), no_cols) for s, c in zip(sv_list, code.tolist())],
                    dtype=np.int64).reshape(m, len(OBS_KINDS))
    dest, src = {}, {}
    for j, kind in enumerate(OBS_KINDS):     # per kind: the signals with a column
        ok = np.flatnonzero(cols[:, j] >= 0)
        dest[kind], src[kind] = base[ok] + cols[ok, j], ok
    return (np.concatenate([dest[x] for x in OBS_KINDS]),
            np.concatenate([j * m + src[x] for j, x in enumerate(OBS_KINDS)]),
            np.concatenate([dest["C"], dest["L"]]), np.concatenate([src["C"], src["L"]]), dest["L"], src["L"])


def _columns_of(obs_types: dict[str, list[str]]) -> dict:
    """{(system, code): columns of its C, L, D, S observations (-1: not in the header)} (cached)."""
    key = tuple((s, tuple(codes)) for s, codes in obs_types.items())
    hit = _COLUMNS_CACHE.get(key)
    if hit is None:
        hit = {}
        for s, codes in obs_types.items():
            col = {c: j for j, c in enumerate(codes)}
            for code in dict.fromkeys(c[1:] for c in codes):
                hit[(s, code)] = tuple(col.get(kind + code, -1) for kind in OBS_KINDS)
        _COLUMNS_CACHE.put(key, hit)
    return hit


#: the profile's ``rinex`` keys: RINEX header text, each at most 20 characters (RINEX 3.05 table A2: A20)
RINEX_NAME_KEYS = ("receiver_type", "antenna_type")


def check_rinex_names(names: dict) -> dict:
    """A profile's ``rinex`` mapping {receiver_type, antenna_type} (text of at most 20 characters each)."""
    if not isinstance(names, dict):
        raise ValueError(f"must map {' / '.join(RINEX_NAME_KEYS)} to text, got {names!r}")
    for key, v in names.items():
        if key not in RINEX_NAME_KEYS:
            raise ValueError(f"unknown key {key!r}; one of {', '.join(RINEX_NAME_KEYS)}")
        if not isinstance(v, str) or len(v) > 20:
            raise ValueError(f"{key} = {v!r} must be text of at most 20 characters (RINEX A20)")
    return dict(names)


def header(obs_types, marker_name: str, approx_pos_ecef_m, interval_s: float, glonass_slots: dict,
           comments=(), antenna: str = "patch", rinex: dict | None = None) -> RinexObsHeader:
    """The RINEX observation header of a simulated receiver; ``antenna``: its pattern (multipath/antenna.py
    PATTERNS, the profile's ReceiverConfig.antenna), named in ANT # / TYPE unless ``rinex`` (the profile's
    {receiver_type, antenna_type}) names it; REC # / TYPE: GNSS_SIM unless ``rinex`` names it."""
    rinex = rinex or {}
    return RinexObsHeader(
        obs_types=obs_types, marker_name=marker_name, marker_type="NON_GEODETIC",
        observer="gnss_sim", agency="gnss_sim", receiver_number="1",
        receiver_type=rinex.get("receiver_type", "GNSS_SIM"), receiver_version="0.1", antenna_number="1",
        antenna_type=rinex.get("antenna_type", RINEX_ANTENNA_TYPE[antenna]),
        approx_pos_ecef_m=tuple(float(v) for v in approx_pos_ecef_m), interval_s=interval_s,
        glonass_slots=glonass_slots, glonass_cod_phs_bis_m={"C1C": 0.0, "C1P": 0.0, "C2C": 0.0, "C2P": 0.0},
        comments=list(comments),
    )


def rinex_name(marker: str, start: GnssTime, duration_s: float | None, interval_s: float, kind: str) -> str:
    """RINEX 3 long file name (RINEX 3.04 section 4.1), ``kind`` "MO" or "MN";
    ``duration_s`` None: period unknown while writing ("00U")."""
    d = start.to_datetime()
    mk = (marker.upper() + "XXXX")[:4]
    period = ("00U" if duration_s is None else
              f"{int(round(duration_s / 86400)):02d}D" if duration_s >= 86400 else
              f"{int(round(duration_s / 3600)):02d}H" if duration_s >= 3600 else
              f"{max(1, int(round(duration_s / 60))):02d}M")
    if kind == "MN":
        return f"{mk}00XXX_S_{d.year:04d}{d.timetuple().tm_yday:03d}{d.hour:02d}{d.minute:02d}_{period}_MN.rnx"
    freq = f"{int(round(interval_s)):02d}S" if interval_s >= 1 else f"{int(round(1 / interval_s)):02d}Z"
    return f"{mk}00XXX_S_{d.year:04d}{d.timetuple().tm_yday:03d}{d.hour:02d}{d.minute:02d}_{period}_{freq}_MO.rnx"


def spp_rows(obs: EpochObservations, profile: dict[str, list[str]]) -> np.ndarray:
    """Row index of the signal each satellite's position fix uses: its system's first profile code."""
    sv = np.asarray(obs.sv)
    code = np.asarray(obs.code)
    key = (sv.dtype.str, sv.tobytes(), code.dtype.str, code.tobytes(),
           tuple((s, codes[0]) for s, codes in profile.items() if codes))
    hit = _SPP_ROWS_CACHE.get(key)
    if hit is None:
        systems = sv.astype("<U1")    # the system letter: first character of each id
        pick = np.zeros(systems.shape, dtype=bool)
        for s, first in key[-1]:
            pick |= (systems == s) & (code == first)
        hit = np.flatnonzero(pick)
        _SPP_ROWS_CACHE.put(key, hit)
    return hit.copy()


#: spp_rows per (signals, profile): the tracked set changes rarely from one epoch to the next
_SPP_ROWS_CACHE = BoundedCache(256)


def position_fix(obs: EpochObservations, profile: dict[str, list[str]], prior_ecef_m=None,
                 config: SolverConfig | None = None) -> PvtSolution:
    """Single point position and velocity from the observables, as a receiver computes it:
    broadcast satellite clock (with group delay), broadcast ionosphere, troposphere model."""
    return position_fixes([obs], profile, prior_ecef_m, config)[0]


def position_fixes(obs_list, profile: dict[str, list[str]], prior_ecef_m=None,
                   config: SolverConfig | None = None) -> list[PvtSolution]:
    """:func:`position_fix` of several epochs in one solve (solver.solve_pvt_many), each started at
    ``prior_ecef_m``."""
    return solve_pvt_many([fix_inputs(obs, profile, prior_ecef_m) for obs in obs_list], config)


def fix_inputs(obs: EpochObservations, profile, prior_ecef_m) -> dict:
    """One epoch of solver.solve_pvt_many from the observables: each satellite's first profile signal (spp_rows),
    its broadcast corrections, range rates from Doppler, started at ``prior_ecef_m``."""
    rows = spp_rows(obs, profile)
    lam = k.C_MPS / obs.frequency_hz[rows]
    return dict(
        sv=obs.sv[rows], sat_pos_ecef_m=obs.sat_pos_ecef_m[rows], pseudorange_m=obs.pseudorange_m[rows],
        sat_clock_bias_s=obs.sat_clock_s[rows], iono_delay_m=obs.iono_model_m[rows],
        tropo_delay_m=obs.tropo_model_m[rows], cn0_dbhz=obs.cn0_dbhz[rows], prior_ecef_m=prior_ecef_m,
        sat_vel_ecef_mps=obs.sat_vel_ecef_mps[rows], range_rate_mps=-obs.doppler_hz[rows] * lam,
        sat_clock_drift_sps=obs.sat_clock_drift_sps[rows])


def write_navigation(path: Path, provider, systems: str) -> Path | None:
    """The navigation data used, as one RINEX 3.04 mixed navigation file (None for SP3 sources)."""
    nav = getattr(provider, "nav", None)
    if nav is None:
        return None
    from ..rinex.nav import header_dict, records_as_dicts
    from ..rinex.nav_write import write_rinex3_nav

    return write_rinex3_nav(path, records_as_dicts(nav, systems), header_dict(nav))
