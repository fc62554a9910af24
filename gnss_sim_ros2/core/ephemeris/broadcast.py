"""Broadcast ephemeris provider: RINEX navigation files -> satellite states at any instant.

Layers (as RTKLIB): records (core/rinex/nav/) -> selection per satellite and
instant (select.py) -> states (kepler.py, glonass.py) -> SatelliteStates.

    eph = BroadcastEphemeris.from_files(["brdc.rnx"], start=t0, end=t1)
    st = eph.states(GnssTime.from_iso("2022-01-01T00:05:00"))     # every valid satellite
    st = eph.states_at(["G05", "E11"], t_transmit)                  # one instant per satellite
    print(eph.diagnostics(t))

Everything per call is vectorised over satellites: the record choice is a
precomputed timeline (one searchsorted), Keplerian orbits are evaluated for all
rows at once and GLONASS orbits come from per-record integrated nodes.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..memo import BoundedCache
from ..rinex.nav import KEPLER_SYSTEMS, SUPPORTED_SYSTEMS, NavData, read_nav_files
from ..time import GnssTime
from . import glonass as glo
from .health import record_usable
from .kepler import KeplerParams
from .sanity import drop_outliers
from .select import EphemerisDiagnostics, build_timeline, validity_windows_s
from .states import SatelliteStates

_GALILEO_NAV = ("inav", "fnav", "any")


def _check_systems(systems: str) -> str:
    systems = systems.upper()
    bad = set(systems) - set(SUPPORTED_SYSTEMS)
    if bad:
        raise ValueError(f"systems={systems!r}: unknown system letters {''.join(sorted(bad))} "
                         f"(expected letters of {SUPPORTED_SYSTEMS})")
    return systems


class BroadcastEphemeris:
    """Satellite states from broadcast navigation records.

    ``galileo_nav``: which Galileo records serve: "inav" (default: I/NAV, clock
    referred to E1/E5b, what an E1 receiver decodes; F/NAV only for satellites
    without any I/NAV record), "fnav" (the reverse; clock referred to E1/E5a as
    IGS/CODE products), "any" (nearest toe of both).
    ``windows_s``: override validity windows per system (select.WINDOW_S), e.g.
    {"C": 6*3600} (symmetric) or {"E": (0, 14400)} (before, after toe).
    """

    source = "broadcast"

    def __init__(self, nav: NavData, galileo_nav: str = "inav", windows_s: dict | None = None,
                 glonass_step_s: float = glo.STEP_S):
        if galileo_nav not in _GALILEO_NAV:
            raise ValueError(f"galileo_nav={galileo_nav!r}: expected one of {_GALILEO_NAV}")
        self.nav = nav
        self.galileo_nav = galileo_nav
        kep_parts = [nav.tables[s].rec for s in KEPLER_SYSTEMS if s in nav.tables]
        kep = np.concatenate(kep_parts) if kep_parts else nav.records("G")
        if galileo_nav != "any" and len(kep):
            kep = kep[_galileo_filter(kep, galileo_nav)]
        gl = nav.records("R")
        self.kepler_rec = kep
        self.glonass_rec = gl
        self.n_kep = len(kep)
        self._kp = KeplerParams(kep)
        # satellites
        all_sv = np.concatenate([kep["sv"], gl["sv"]]).astype("U3")
        self._sv_names = np.array(sorted(set(all_sv.tolist())), dtype="U3")
        self._sv_pos = {s: i for i, s in enumerate(self._sv_names.tolist())}
        rec_sv_idx = np.array([self._sv_pos[s] for s in all_sv.tolist()], dtype=np.int64)
        # per-record columns over the global record index (Keplerian first, then GLONASS)
        self._toe_sec = np.concatenate([kep["toe_sec"], gl["toe_sec"]]).astype(np.int64)
        self._toe_frac = np.concatenate([kep["toe_frac"], gl["toe_frac"]])
        self._health = np.concatenate([kep["health"], gl["health"]]).astype(np.int64)
        self._iode = np.concatenate([kep["iode"], gl["iode"]]).astype(np.int64)
        self._tgd = np.concatenate([kep["tgd_s"], np.zeros(len(gl))])
        self._channel = np.concatenate([np.zeros(len(kep), np.int64), gl["channel"].astype(np.int64)])
        systems = np.concatenate([kep["sys"], gl["sys"]]).astype("U1")
        fit_h = np.concatenate([kep["fit_h"], np.full(len(gl), np.nan)])
        self._before_s, self._after_s = validity_windows_s(systems, fit_h, windows_s)
        self._rec_sv_idx = rec_sv_idx
        n = len(rec_sv_idx)
        self._ref_sec = int(np.median(self._toe_sec)) if n else 0
        tiebreak = np.concatenate([kep["tot_s"], gl["tk_s"]])
        ids = np.arange(n)
        # QZSS: usable while any of its signals is healthy (health.py, IS-QZSS-PNT-005 5.4.1); others: health 0
        healthy = record_usable(systems, self._health)
        self._timeline = build_timeline(self._ref_sec, rec_sv_idx[healthy], self._toe_sec[healthy],
                                        self._toe_frac[healthy], self._before_s[healthy],
                                        self._after_s[healthy], ids[healthy], tiebreak[healthy])
        self._timeline_any = build_timeline(self._ref_sec, rec_sv_idx, self._toe_sec, self._toe_frac,
                                            self._before_s, self._after_s, ids, tiebreak)
        # GLONASS dense orbits over each record's window
        if len(gl):
            self._glo = glo.GlonassOrbits(gl["pos_m"], gl["vel_mps"], gl["acc_mps2"],
                                          np.maximum(self._before_s, self._after_s)[self.n_kep:] + 1.0,
                                          glonass_step_s)
        else:
            self._glo = None
        self._sys_cache: dict[str, np.ndarray] = {}
        self._sv_rows_cache = BoundedCache(256)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_files(cls, paths, start: GnssTime | None = None, end: GnssTime | None = None,
                   systems: str = SUPPORTED_SYSTEMS, **kwargs) -> BroadcastEphemeris:
        """Read RINEX 2/3/4 navigation files (plain or compressed); with ``start``/``end``
        (GPS time) only records that can serve that window are kept.  Records inconsistent with the
        satellite's other records are dropped with a warning (sanity.drop_outliers)."""
        if isinstance(paths, (str, Path)):
            paths = [paths]
        systems = _check_systems(systems)
        if start is not None and end is not None and end < start:
            raise ValueError(f"end {end} is before start {start}")
        nav = drop_outliers(read_nav_files(paths, start=start, end=end, systems=systems))
        return cls(nav, **kwargs)

    # ------------------------------------------------------------------ information
    @property
    def iono(self) -> dict[str, list[float]]:
        """Header ionospheric coefficients: GPSA/GPSB (Klobuchar alpha, beta), GAL (NeQuick-G ai0..ai2),
        BDSA/BDSB, QZSA/QZSB, IRNA/IRNB (RINEX 3 IONOSPHERIC CORR names)."""
        return self.nav.iono

    @property
    def leap_seconds(self) -> int | None:
        """GPS - UTC from the file header (None when absent)."""
        return self.nav.leap_seconds

    def svs(self, systems: str = SUPPORTED_SYSTEMS) -> list[str]:
        """Satellites with at least one record (healthy or not)."""
        systems = _check_systems(systems)
        return [s for s in self._sv_names.tolist() if s[0] in systems]

    def time_span(self) -> tuple[GnssTime, GnssTime] | None:
        """(first, last) instant served by any healthy record (None without records)."""
        tl = self._timeline
        if not tl.start_key.size:
            return None
        rel_start = (tl.start_key % (1 << 52)) - (1 << 51)
        rel_end = (tl.end_key % (1 << 52)) - (1 << 51)
        lo, hi = int(rel_start.min()), int(rel_end.max()) - 1
        return (GnssTime(self._ref_sec + lo // 1_000_000, (lo % 1_000_000) * 1e-6),
                GnssTime(self._ref_sec + hi // 1_000_000, (hi % 1_000_000) * 1e-6))

    def records(self, system: str) -> np.ndarray:
        """Record table of one system as used (after the Galileo message choice)."""
        if system == "R":
            return self.glonass_rec
        return self.kepler_rec[self.kepler_rec["sys"] == system]

    # ------------------------------------------------------------------ states
    def _sv_indices(self, svs, systems: str) -> np.ndarray:
        if svs is None:
            key = systems
            idx = self._sys_cache.get(key)
            if idx is None:
                systems = _check_systems(systems)
                first = np.array([s[0] for s in self._sv_names.tolist()], dtype="U1")
                idx = np.flatnonzero(np.isin(first, list(systems))).astype(np.int64)
                self._sys_cache[key] = idx
            return idx
        if isinstance(svs, str):
            svs = [svs]
        return np.array([self._sv_pos[s] for s in svs if s in self._sv_pos and s[0] in systems], dtype=np.int64)

    def states(self, t: GnssTime, svs=None, systems: str = SUPPORTED_SYSTEMS) -> SatelliteStates:
        """States at one instant ``t`` (GPS time) of every satellite (or of ``svs``) with a
        healthy record valid at t; rows sorted by satellite id."""
        if np.ndim(t.sec) != 0:
            raise ValueError("states(t): t must be a single instant; use states_at(svs, t_array) for many")
        sv_idx = self._sv_indices(svs, systems)
        t_us = self._timeline.t_us(t.sec, t.frac)
        rec = self._timeline.lookup(sv_idx, t_us)
        ok = rec >= 0
        return self._evaluate(rec[ok], sv_idx[ok], t, t.sec, t.frac)

    def states_at(self, svs, t: GnssTime) -> SatelliteStates:
        """One instant per satellite (``svs`` (N,) names, ``t`` (N,) or scalar GnssTime).

        Rows keep the input order; rows without a healthy valid record (or unknown
        satellites) are left out, so match rows by ``sv`` and ``t``.
        """
        svs = np.atleast_1d(np.asarray(svs, dtype="U3"))
        n = svs.size
        t_sec = np.broadcast_to(np.asarray(t.sec, dtype=np.int64), (n,))
        t_frac = np.broadcast_to(np.asarray(t.frac, dtype=np.float64), (n,))
        known, sv_idx = self._sv_rows(svs)
        rec = np.where(known, self._timeline.lookup(sv_idx, self._timeline.t_us(t_sec, t_frac)), -1)
        ok = rec >= 0
        tt = GnssTime(t_sec[ok].copy(), t_frac[ok].copy())
        return self._evaluate(rec[ok], sv_idx[ok], tt, t_sec[ok], t_frac[ok])

    def _sv_rows(self, svs: np.ndarray):
        """(known (N,) bool, satellite index (N,)) of ids; cached per list (the receiver asks for the same
        satellites epoch after epoch)."""
        key = svs.tobytes()
        hit = self._sv_rows_cache.get(key)
        if hit is None:
            names = svs.tolist()
            hit = (np.array([s in self._sv_pos for s in names], dtype=bool),
                   np.array([self._sv_pos.get(s, 0) for s in names], dtype=np.int64))
            self._sv_rows_cache.put(key, hit)
        return hit

    def _evaluate(self, rec, sv_idx, t_out, t_sec, t_frac) -> SatelliteStates:
        n = rec.size
        pos = np.empty((n, 3))
        vel = np.empty((n, 3))
        acc = np.empty((n, 3))
        clk = np.empty(n)
        drift = np.empty(n)
        rel = np.zeros(n)
        is_kep = rec < self.n_kep
        scalar_t = np.ndim(t_sec) == 0
        if np.any(is_kep):
            rk = rec[is_kep]
            ts, tf = (t_sec, t_frac) if scalar_t else (t_sec[is_kep], t_frac[is_kep])
            o = self._kp.evaluate(rk, ts, tf)
            pos[is_kep], vel[is_kep], acc[is_kep] = o["pos_ecef_m"], o["vel_ecef_mps"], o["acc_ecef_mps2"]
            clk[is_kep], drift[is_kep], rel[is_kep] = o["clock_bias_s"], o["clock_drift_sps"], o["relativistic_s"]
        is_glo = ~is_kep
        if np.any(is_glo):
            rg = rec[is_glo] - self.n_kep
            ts, tf = (t_sec, t_frac) if scalar_t else (t_sec[is_glo], t_frac[is_glo])
            gr = self.glonass_rec
            dt = (np.asarray(ts, dtype=np.int64) - gr["toe_sec"][rg]).astype(np.float64) + (tf - gr["toe_frac"][rg])
            p, v, a = self._glo.evaluate(rg, dt)
            pos[is_glo], vel[is_glo], acc[is_glo] = p, v, a
            clk[is_glo], drift[is_glo] = glo.glonass_clock(gr["tau_n_s"][rg], gr["gamma_n"][rg], dt)
        age = ((np.asarray(t_sec, dtype=np.int64) - self._toe_sec[rec]).astype(np.float64)
               + (t_frac - self._toe_frac[rec]))
        return SatelliteStates(
            t=t_out,
            sv=self._sv_names[sv_idx],
            pos_ecef_m=pos,
            vel_ecef_mps=vel,
            acc_ecef_mps2=acc,
            clock_bias_s=clk,
            clock_drift_sps=drift,
            relativistic_s=rel,
            tgd_s=self._tgd[rec],
            health=self._health[rec],
            iode=self._iode[rec],
            age_s=np.broadcast_to(age, (n,)).copy(),
            glo_channel=self._channel[rec],
            source=self.source,
        )

    # ------------------------------------------------------------------ diagnostics
    def diagnostics(self, t: GnssTime, svs=None, systems: str = SUPPORTED_SYSTEMS) -> EphemerisDiagnostics:
        """Status of each satellite at ``t``: ok / unhealthy / gap / stale, and ``missing`` for
        requested satellites (``svs``) without any ephemeris."""
        systems = _check_systems(systems)
        out = EphemerisDiagnostics(t=t)
        if svs is None:
            names = self.svs(systems)
        else:
            names = [svs] if isinstance(svs, str) else list(svs)
        known = [s for s in names if s in self._sv_pos]
        out.missing = sorted(s for s in names if s not in self._sv_pos)
        if not known:
            return out
        sv_idx = np.array([self._sv_pos[s] for s in known], dtype=np.int64)
        t_us = self._timeline.t_us(t.sec, t.frac)
        rec_h = self._timeline.lookup(sv_idx, t_us)
        rec_a = self._timeline_any.lookup(sv_idx, t_us)
        for k, s in enumerate(known):
            if rec_h[k] >= 0:
                out.ok.append(s)
                r = rec_h[k]
                out.age_s[s] = float((t.sec - self._toe_sec[r]) + (t.frac - self._toe_frac[r]))
            elif rec_a[k] >= 0:
                out.unhealthy.append(s)
            else:
                recs = np.flatnonzero(self._rec_sv_idx == sv_idx[k])
                later = (self._toe_sec[recs] - t.sec) + self._after_s[recs] >= 0
                (out.gap if np.any(later) else out.stale).append(s)
        return out


def _galileo_filter(kep: np.ndarray, galileo_nav: str) -> np.ndarray:
    """Mask of Keplerian records kept under the Galileo message preference."""
    keep = np.ones(len(kep), dtype=bool)
    is_e = kep["sys"] == "E"
    if not np.any(is_e):
        return keep
    want = "INAV" if galileo_nav == "inav" else "FNAV"
    sv_with_want = set(kep["sv"][is_e & (kep["nav"] == want)].tolist())
    for k in np.flatnonzero(is_e):
        if kep["nav"][k] != want and kep["sv"][k] in sv_with_want:
            keep[k] = False
    return keep


def precise_to_broadcast_clock_s(eph: BroadcastEphemeris, st: SatelliteStates) -> np.ndarray:
    """Per row of broadcast states ``st`` (from ``eph``): what to add to an IGS/MGEX precise clock to
    refer it to the broadcast record's own signal reference, so that the record's group delay applies
    to the precise clock as it does to the broadcast one [s].

    Precise clocks refer to ionosphere-free combinations (IGS conventions: GPS/QZSS L1/L2 P(Y), Galileo
    E1/E5a, BeiDou B1I/B3I); the broadcast ones:
    - GPS, QZSS: L1/L2 P(Y) as well (IS-GPS-200N 20.3.3.3.3.2): 0;
    - Galileo F/NAV: E1/E5a: 0; I/NAV: E1/E5b, dt(E1,E5b) = dt(E1,E5a) + BGD(E1,E5b) - BGD(E1,E5a)
      (OS SIS ICD 2.1 5.1.5);
    - BeiDou D1/D2: B3I, TGD1 = B1I - B3I: dt_B3I = dt_IF + f1^2/(f1^2 - f3^2) TGD1
      (BDS-SIS-ICD-B1I 3.0 5.2.4.10);
    - GLONASS and others: 0 (no group delay in the message).
    """
    from ..constants import F_B1I_HZ, F_B3I_HZ

    names = np.asarray(st.sv).tolist()
    out = np.zeros(len(names))
    beidou = np.array([sv[0] == "C" for sv in names], dtype=bool)
    out[beidou] = F_B1I_HZ**2 / (F_B1I_HZ**2 - F_B3I_HZ**2) * np.asarray(st.tgd_s, dtype=float)[beidou]
    gal = np.flatnonzero([sv[0] == "E" for sv in names])
    if gal.size:
        rec = eph.records("E")
        bgd = {(str(s), int(i)): (a, b) for s, i, a, b in zip(rec["sv"], rec["iode"], rec["bgd_e1e5a_s"],
                                                                rec["bgd_e1e5b_s"])}
        for j in gal.tolist():
            pair = bgd.get((names[j], int(st.iode[j])))
            if pair is not None and np.isfinite(pair[0]) and np.isfinite(pair[1]):
                # the record's TGD is BGD(E1,E5a) for F/NAV (shift 0) and BGD(E1,E5b) for I/NAV
                out[j] = float(st.tgd_s[j]) - pair[0]
    return out
