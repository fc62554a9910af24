"""Precise orbits (SP3-a/c/d) and clocks (RINEX clock ``AS`` records) as a state provider.

Formats:
- SP3-d: IGS "The Extended Standard Product 3 Orbit Format (SP3-d)", 2016
  (SP3-c, 2007; SP3-a, 1998 read as well).  Positions in km, clocks in us,
  ``0.000000`` position = missing, ``999999.999999`` clock = missing.  The time
  system is the ``%c`` line, columns 10-12 (GPS if blank or ``ccc``).
- RINEX clock 3.04 (IGS, 2017) / 3.00 / 2.x: ``AS`` satellite clock records,
  ``TIME SYSTEM ID`` header line (GPS when absent).

georinex 1.16 has an SP3 reader but it stores the n-th ``P`` line of an epoch
into the n-th satellite of the header (a missing line shifts every following
satellite and leaves uninitialised memory), ignores the file's time system and
the bad-value markers, so the files are parsed here by satellite id.

Interpolation: positions by a Lagrange polynomial through ``n_points`` (11 by
default, degree 10) consecutive valid samples, the window centred on the
sample nearest to t (shifted, never beyond the data, near the file edges and
bad samples); velocity and acceleration are the first and second derivatives
of the same polynomial (Newton divided differences, Horner with derivatives).
Clocks: linear between the two samples that bracket t (the clock file when it
has that satellite, else the SP3 clocks); the drift is the slope.
"""
from __future__ import annotations

import datetime as _dt
import gzip
import math
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from ..time import GnssTime
from .states import SatelliteStates

#: SP3 bad/missing clock marker [us] (SP3-d, section "clock")
SP3_BAD_CLOCK_US = 999999.0
#: TAI - GPST [s] (IS-GPS-200N 3.3.4: GPS time is 19 s behind TAI, fixed)
TAI_MINUS_GPST_S = 19

_SP3_TIME_SYSTEMS = {"GPS": "GPS", "GAL": "GST", "GST": "GST", "BDT": "BDT", "BDS": "BDT", "QZS": "QZS",
                     "IRN": "IRN", "GLO": "GLO", "UTC": "UTC", "TAI": "TAI", "CCC": "GPS", "": "GPS"}


def _open_text(path: Path):
    """Open a plain or gzip-compressed text file (by magic bytes)."""
    with open(path, "rb") as fb:
        magic = fb.read(2)
    if magic == b"\x1f\x8b":
        return gzip.open(path, "rt", encoding="ascii", errors="replace")
    if magic == b"\x1f\x9d":  # Unix compress (.Z)
        from ncompress import decompress  # installed with georinex

        return _StringLines(decompress(Path(path).read_bytes()).decode("ascii", errors="replace"))
    return open(path, encoding="ascii", errors="replace")


class _StringLines:
    def __init__(self, text: str):
        self._lines = text.splitlines(keepends=True)

    def __enter__(self):
        return iter(self._lines)

    def __exit__(self, *exc):
        return False


def _time_in_scale(dt_naive: _dt.datetime, frac_s: float, scale: str) -> GnssTime:
    """GnssTime (GPS) of a calendar instant read in ``scale`` (TAI handled here)."""
    if scale == "TAI":
        return GnssTime.from_datetime(dt_naive, "GPS") + (frac_s - TAI_MINUS_GPST_S)
    return GnssTime.from_datetime(dt_naive, scale) + frac_s


def _parse_epoch(fields: Sequence[str], where: str) -> tuple[_dt.datetime, float]:
    """(datetime to whole seconds, fraction) from y m d h mi s.sss fields."""
    try:
        y, mo, d, h, mi = (int(x) for x in fields[:5])
        s = float(fields[5])
    except (ValueError, IndexError) as exc:
        raise ValueError(f"{where}: bad epoch {' '.join(fields[:6])!r}") from exc
    whole = math.floor(s)
    base = _dt.datetime(y, mo, d) + _dt.timedelta(hours=h, minutes=mi, seconds=whole)
    return base, s - whole


def _sv_id(text: str) -> str:
    """'G01' from 'G01', 'G 1', '  1' (SP3-a: blank system = GPS)."""
    text = text.replace(" ", "0")
    if text[0] == "0":
        text = "G" + text[1:]
    return text


def read_sp3(path) -> tuple[GnssTime, list[str], np.ndarray, np.ndarray]:
    """Read one SP3 file: (epochs GPS, sv ids, pos_ecef_m [T, S, 3] NaN if missing, clock_s [T, S] NaN if missing)."""
    path = Path(path)
    scale = "GPS"
    epochs: list[GnssTime] = []
    rows: list[dict[str, tuple[float, float, float, float]]] = []
    svs_header: list[str] = []
    seen_c = False
    seen_header = False
    with _open_text(path) as f:
        for lineno, line in enumerate(f, start=1):
            line = line.rstrip("\r\n")
            if not seen_header:
                if not line.strip():
                    continue              # blank lines before the header (seen in IGS files)
                if not line.startswith("#") or len(line) < 3 or line[1] not in "abcd":
                    raise ValueError(f"{path}, line {lineno}: not an SP3 header line (starts {line[:3]!r})")
                seen_header = True
                continue
            if not line:
                continue
            c0 = line[0]
            if c0 == "*":
                if line.startswith("*/"):
                    continue
                dt, frac = _parse_epoch(line[1:].split(), f"{path} line {lineno}")
                epochs.append(_time_in_scale(dt, frac, scale))
                rows.append({})
            elif c0 == "P":
                if not rows:
                    raise ValueError(f"{path} line {lineno}: position record before the first epoch line")
                sv = _sv_id(line[1:4])
                try:
                    x, y, z = float(line[4:18]), float(line[18:32]), float(line[32:46])
                    clk_text = line[46:60].strip()
                    clk = float(clk_text) if clk_text else math.nan
                except ValueError as exc:
                    raise ValueError(f"{path} line {lineno}: bad position/clock record {line[:60]!r}") from exc
                rows[-1][sv] = (x, y, z, clk)
            elif line.startswith("%c") and not epochs and not seen_c:
                # first %c line, columns 10-12: time system (SP3-c/d)
                seen_c = True
                ts = line[9:12].strip().upper()
                if ts not in _SP3_TIME_SYSTEMS:
                    raise ValueError(f"{path} line {lineno}: unknown SP3 time system {ts!r}")
                scale = _SP3_TIME_SYSTEMS[ts]
            elif c0 == "+" and line[1:2] == " " and not epochs:
                for k in range(9, 60, 3):
                    token = line[k:k + 3]
                    if token.strip() and token.strip() != "0":
                        svs_header.append(_sv_id(token))
            elif line.startswith("EOF"):
                break
            # V (velocity), EP/EV (correlations), comments: not used
    if not seen_header:
        raise ValueError(f"{path}: empty file (no SP3 header line)")
    if not epochs:
        raise ValueError(f"{path}: no epoch lines ('*') found")
    svs = list(dict.fromkeys(svs_header + [sv for r in rows for sv in r]))
    index = {sv: k for k, sv in enumerate(svs)}
    pos = np.full((len(epochs), len(svs), 3), np.nan)
    clk = np.full((len(epochs), len(svs)), np.nan)
    for i, r in enumerate(rows):
        for sv, (x, y, z, c) in r.items():
            k = index[sv]
            if not (x == 0.0 and y == 0.0 and z == 0.0):
                pos[i, k] = (x * 1e3, y * 1e3, z * 1e3)
            if math.isfinite(c) and abs(c) < SP3_BAD_CLOCK_US:
                clk[i, k] = c * 1e-6
    return GnssTime.stack(epochs), svs, pos, clk


def read_rinex_clock(path) -> tuple[dict[str, tuple[GnssTime, np.ndarray]], str]:
    """Satellite clocks of a RINEX clock file: ({sv: (epochs GPS, clock_s)}, time system)."""
    path = Path(path)
    scale = "GPS"
    data: dict[str, list[tuple[_dt.datetime, float, float]]] = {}
    in_header = True
    with _open_text(path) as f:
        for lineno, line in enumerate(f, start=1):
            line = line.rstrip("\r\n")
            if in_header:
                label = line[60:].strip()
                if lineno == 1 and "RINEX VERSION" not in label:
                    raise ValueError(f"{path}: line 1 is not a RINEX clock header ('RINEX VERSION / TYPE' missing)")
                if lineno == 1 and line[20:21].upper() != "C":   # RINEX clock 3.04 table A1: file type C (A1)
                    raise ValueError(f"{path}, line 1: not a RINEX clock file (file type {line[20:21]!r}, "
                                     f"{line[20:40].strip()!r}; a clock file's is 'C')")
                if label == "TIME SYSTEM ID":
                    ts = line[:60].strip().upper()
                    if ts not in _SP3_TIME_SYSTEMS:
                        raise ValueError(f"{path} line {lineno}: unknown time system {ts!r}")
                    scale = _SP3_TIME_SYSTEMS[ts]
                elif label == "END OF HEADER":
                    in_header = False
                continue
            if not line.startswith("AS "):
                continue
            parts = line.split()
            # AS name yyyy mm dd hh mi ss.ssssss n value [sigma]  (RINEX clock 3.04 table A5)
            try:
                sv = _sv_id(parts[1].rjust(3))
                dt, frac = _parse_epoch(parts[2:8], f"{path} line {lineno}")
                bias_s = float(parts[9].replace("D", "E"))
            except (ValueError, IndexError) as exc:
                raise ValueError(f"{path} line {lineno}: bad AS record {line!r}") from exc
            data.setdefault(sv, []).append((dt, frac, bias_s))
    if not data:          # a clock file without satellite clocks added nothing, without a word
        raise ValueError(f"{path}: no satellite clock record (AS) after the header")
    out: dict[str, tuple[GnssTime, np.ndarray]] = {}
    for sv, recs in data.items():
        times = GnssTime.stack([_time_in_scale(dt, fr, scale) for dt, fr, _ in recs])
        vals = np.array([b for _, _, b in recs])
        vals[np.abs(vals) >= SP3_BAD_CLOCK_US * 1e-6] = np.nan
        order = np.argsort(times.to_gps_seconds(), kind="stable")
        out[sv] = (times[order], vals[order])
    return out, scale


def _merge_grid(epoch_sets: Iterable[GnssTime]) -> GnssTime:
    """Sorted union of epochs (identical to the microsecond merged)."""
    keys = set()
    for ep in epoch_sets:
        for s, fr in zip(np.atleast_1d(ep.sec), np.atleast_1d(ep.frac)):
            keys.add(int(s) * 1_000_000 + int(round(float(fr) * 1e6)))
    k = np.array(sorted(keys), dtype=np.int64)
    return GnssTime(k // 1_000_000, (k % 1_000_000) * 1e-6)


def _grid_index(grid: GnssTime, t: GnssTime) -> np.ndarray:
    """Index of every epoch of ``t`` in ``grid`` (microsecond match)."""
    def key(x: GnssTime):
        us = np.round(np.atleast_1d(x.frac) * 1e6).astype(np.int64)
        return np.atleast_1d(x.sec).astype(np.int64) * 1_000_000 + us

    return np.searchsorted(key(grid), key(t))


class Sp3Ephemeris:
    """Satellite states interpolated from precise orbits (SP3) and clocks (SP3 or RINEX clock)."""

    source = "sp3"

    def __init__(self, epochs: GnssTime, svs: Sequence[str], pos_ecef_m: np.ndarray, clock_s: np.ndarray,
                 clk_files: dict[str, tuple[GnssTime, np.ndarray]] | None = None, n_points: int = 11,
                 require_clock: bool = True, glo_channels: dict[str, int] | None = None,
                 max_gap_factor: float = 1.5):
        """Usually built by :meth:`from_files`.

        ``pos_ecef_m`` [T, S, 3] and ``clock_s`` [T, S] on the sorted ``epochs``
        (NaN where missing).  ``n_points``: samples per interpolation window
        (degree n_points - 1).  ``require_clock``: serve a satellite only when
        its clock is available too.  ``glo_channels``: GLONASS frequency
        channel per satellite (SP3 does not carry it; 0 when not given).
        Consecutive samples further apart than ``max_gap_factor`` times the
        median spacing are a gap that no window or clock interval may span.
        """
        if n_points < 2:
            raise ValueError(f"n_points must be >= 2, got {n_points}")
        self._t = epochs
        self._tsec = np.atleast_1d(epochs.sec).astype(np.int64)
        self._tfrac = np.atleast_1d(epochs.frac).astype(np.float64)
        self._svs = np.array(list(svs), dtype="<U3")
        self._pos = np.asarray(pos_ecef_m, dtype=np.float64)
        self._clk = np.asarray(clock_s, dtype=np.float64)
        T = len(self._tsec)
        if self._pos.shape != (T, len(self._svs), 3) or self._clk.shape != (T, len(self._svs)):
            raise ValueError(f"pos_ecef_m {self._pos.shape} / clock_s {self._clk.shape} do not match "
                             f"{T} epochs x {len(self._svs)} satellites")
        if T < n_points:
            raise ValueError(f"SP3 data have {T} epochs, fewer than the {n_points} interpolation points")
        self.n_points = int(n_points)
        self.require_clock = require_clock
        self.glo_channels = dict(glo_channels or {})
        self._index = {sv: k for k, sv in enumerate(self._svs)}
        dt = np.diff(self._tsec).astype(np.float64) + np.diff(self._tfrac)
        if np.any(dt <= 0):
            raise ValueError("SP3 epochs must be strictly increasing")
        self.spacing_s = float(np.median(dt))
        gap = dt > max_gap_factor * self.spacing_s  # [T-1]
        # cumulative counts for O(1) "window all valid" tests
        bad = ~np.all(np.isfinite(self._pos), axis=2)  # [T, S]
        self._bad_cum = np.vstack([np.zeros((1, bad.shape[1]), np.int64), np.cumsum(bad, axis=0)])
        self._gap_cum = np.concatenate([[0], np.cumsum(gap)])
        self._gap = gap
        self._tf = self._tsec.astype(np.float64) + self._tfrac  # for searchsorted only
        # clock files (denser) per satellite
        self._clkfile: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray, float]] = {}
        for sv, (times, vals) in (clk_files or {}).items():
            s = np.atleast_1d(times.sec).astype(np.int64)
            fr = np.atleast_1d(times.frac).astype(np.float64)
            d = np.diff(s).astype(np.float64) + np.diff(fr)
            max_gap = float(np.median(d)) * max_gap_factor if len(d) else 0.0
            self._clkfile[sv] = (s, fr, vals, max_gap)
        self._max_gap_factor = max_gap_factor

    # ----- construction -----------------------------------------------------
    @classmethod
    def from_files(cls, sp3_paths, clk_paths=(), start: GnssTime | None = None, end: GnssTime | None = None,
                   **kwargs) -> Sp3Ephemeris:
        """Read SP3 files (plain or .gz/.Z; consecutive days merge) and optional RINEX clock files.

        ``start``/``end`` (GnssTime) keep only the epochs needed to serve that
        span (plus an interpolation window on each side).  ``kwargs`` go to
        the constructor (``n_points``, ``require_clock``, ``glo_channels``).
        """
        if isinstance(sp3_paths, (str, Path)):
            sp3_paths = [sp3_paths]
        if isinstance(clk_paths, (str, Path)):
            clk_paths = [clk_paths]
        parts = [read_sp3(p) for p in sp3_paths]
        if not parts:
            raise ValueError("sp3_paths is empty: give at least one SP3 file")
        grid = _merge_grid(p[0] for p in parts)
        svs = list(dict.fromkeys(sv for p in parts for sv in p[1]))
        index = {sv: k for k, sv in enumerate(svs)}
        pos = np.full((len(grid), len(svs), 3), np.nan)
        clk = np.full((len(grid), len(svs)), np.nan)
        for ep, psvs, ppos, pclk in parts:
            rows = _grid_index(grid, ep)
            cols = np.array([index[sv] for sv in psvs])
            # first valid value wins (day boundaries appear in two files)
            cur_p = pos[np.ix_(rows, cols)]
            fill_p = ~np.all(np.isfinite(cur_p), axis=2) & np.all(np.isfinite(ppos), axis=2)
            cur_p[fill_p] = ppos[fill_p]
            pos[np.ix_(rows, cols)] = cur_p
            cur_c = clk[np.ix_(rows, cols)]
            fill_c = ~np.isfinite(cur_c) & np.isfinite(pclk)
            cur_c[fill_c] = pclk[fill_c]
            clk[np.ix_(rows, cols)] = cur_c
        clk_files: dict[str, tuple[GnssTime, np.ndarray]] = {}
        for p in clk_paths:
            data, _ = read_rinex_clock(p)
            for sv, (times, vals) in data.items():
                if sv in clk_files:
                    t0, v0 = clk_files[sv]
                    times = GnssTime.stack([t0, times])
                    vals = np.concatenate([v0, vals])
                    order = np.argsort(times.to_gps_seconds(), kind="stable")
                    times, vals = times[order], vals[order]
                    keep = np.concatenate([[True], np.diff(times.to_gps_seconds()) > 1e-6])
                    times, vals = times[np.flatnonzero(keep)], vals[keep]
                clk_files[sv] = (times, vals)
        n_points = int(kwargs.get("n_points", 11))
        if start is not None or end is not None:
            tf = np.atleast_1d(grid.to_gps_seconds())
            spacing = float(np.median(np.diff(tf))) if len(tf) > 1 else 0.0
            margin = (n_points + 1) * spacing
            keep = np.ones(len(tf), bool)
            if start is not None:
                keep &= tf >= start.to_gps_seconds() - margin
            if end is not None:
                keep &= tf <= end.to_gps_seconds() + margin
            idx = np.flatnonzero(keep)
            if len(idx) == 0 and len(tf):     # was "SP3 data have 0 epochs": the files cover another span
                lo, hi = grid[0], grid[len(tf) - 1]
                asked = " .. ".join(t.isoformat("GPS") for t in (start, end) if t is not None)
                raise ValueError(f"{', '.join(map(str, sp3_paths))}: no epoch near the span asked ({asked} GPS): "
                                 f"the files cover {lo.isoformat('GPS')} .. {hi.isoformat('GPS')}")
            grid, pos, clk = grid[idx], pos[idx], clk[idx]
        try:
            return cls(grid, svs, pos, clk, clk_files=clk_files, **kwargs)
        except ValueError as exc:
            raise ValueError(f"{', '.join(map(str, sp3_paths))}: {exc}") from None

    # ----- queries -------------------------------------------------------------
    def svs(self, systems: str = "GRECJI") -> list[str]:
        """Satellites of ``systems`` with at least one valid position sample."""
        ok = self._bad_cum[-1] < len(self._tsec)
        return [str(s) for s in self._svs[ok] if s[:1] in systems]

    def missing_svs(self, systems: str = "GRECJI") -> list[str]:
        """Satellites of ``systems`` the files list (header or records) without any valid position sample."""
        bad = self._bad_cum[-1] >= len(self._tsec)
        return [str(s) for s in self._svs[bad] if s[:1] in systems]

    def time_span(self) -> tuple[GnssTime, GnssTime]:
        """(first, last) SP3 epoch: states are served inside this span only."""
        return self._t[0], self._t[-1]

    def states(self, t: GnssTime, svs=None, systems: str = "GRECJI") -> SatelliteStates:
        """States of all (or the listed) satellites of ``systems`` at one instant ``t``."""
        if np.ndim(t.sec) != 0:
            raise ValueError("states(t): t must be a scalar GnssTime; use states_at for one instant per satellite")
        cand = self._svs if svs is None else np.array(list(svs), dtype="<U3")
        cand = np.array([s for s in cand if s[:1] in systems], dtype="<U3")
        tt = GnssTime(np.full(len(cand), t.sec, dtype=np.int64), np.full(len(cand), t.frac))
        return self._evaluate(cand, tt, scalar_t=t)

    def states_at(self, svs, t: GnssTime) -> SatelliteStates:
        """One instant per satellite (``t`` an array as long as ``svs``, or a scalar)."""
        cand = np.array(list(svs), dtype="<U3")
        sec = np.broadcast_to(np.asarray(t.sec, dtype=np.int64), cand.shape)
        frac = np.broadcast_to(np.asarray(t.frac, dtype=np.float64), cand.shape)
        return self._evaluate(cand, GnssTime(sec.copy(), frac.copy()), scalar_t=None)

    # ----- core ------------------------------------------------------------------
    def _evaluate(self, cand: np.ndarray, t: GnssTime, scalar_t: GnssTime | None) -> SatelliteStates:
        n = self.n_points
        T = len(self._tsec)
        col = np.array([self._index.get(str(s), -1) for s in cand], dtype=np.int64)
        tsec = np.atleast_1d(t.sec).astype(np.int64)
        tfrac = np.atleast_1d(t.frac).astype(np.float64)
        tf = tsec.astype(np.float64) + tfrac
        # interval i with grid[i] <= t <= grid[i+1]
        i = np.searchsorted(self._tf, tf, side="right") - 1
        d_first = (tsec - self._tsec[0]) + (tfrac - self._tfrac[0])
        d_last = (tsec - self._tsec[-1]) + (tfrac - self._tfrac[-1])
        inside = (d_first >= 0) & (d_last <= 0) & (col >= 0)
        i = np.clip(i, 0, T - 2)
        ok = inside.copy()
        # the bracketing interval must not be a gap
        ok &= ~self._gap[i]
        # window start: centred on the nearest sample, then the closest shift that is valid
        off_i = (tsec - self._tsec[i]) + (tfrac - self._tfrac[i])
        step = (self._tsec[i + 1] - self._tsec[i]) + (self._tfrac[i + 1] - self._tfrac[i])
        nearest = np.where(off_i <= 0.5 * step, i, i + 1)
        s0 = nearest - n // 2
        lo = np.maximum(i + 1 - (n - 1), 0)
        hi = np.minimum(i, T - n)
        best = np.full(len(cand), -1, dtype=np.int64)
        colc = np.maximum(col, 0)
        for d in _shift_order(n):
            s = s0 + d
            valid = (s >= lo) & (s <= hi) & (best < 0)
            sc = np.clip(s, 0, T - n)
            valid &= (self._bad_cum[sc + n, colc] - self._bad_cum[sc, colc]) == 0
            valid &= (self._gap_cum[sc + n - 1] - self._gap_cum[sc]) == 0
            best = np.where(valid, sc, best)
        ok &= best >= 0
        rows = np.flatnonzero(ok)
        s = best[rows]
        c = col[rows]
        win = s[:, None] + np.arange(n)[None, :]  # [R, n]
        # node times relative to t [s], exact to the fraction
        x = (self._tsec[win] - tsec[rows, None]) + (self._tfrac[win] - tfrac[rows, None])
        y = self._pos[win, c[:, None], :]  # [R, n, 3]
        p, dp, ddp = _newton_eval(x, y)
        # clocks
        clk, drift, clk_ok = self._clock(cand[rows], c, tsec[rows], tfrac[rows], i[rows])
        if self.require_clock:
            keep = clk_ok
            rows, p, dp, ddp, clk, drift = rows[keep], p[keep], dp[keep], ddp[keep], clk[keep], drift[keep]
        sv_out = cand[rows]
        # age: t - nearest sample used
        near = nearest[rows]
        age = (tsec[rows] - self._tsec[near]) + (tfrac[rows] - self._tfrac[near])
        nr = len(rows)
        t_out = scalar_t if scalar_t is not None else GnssTime(tsec[rows], tfrac[rows])
        return SatelliteStates(
            t=t_out,
            sv=sv_out.astype(str),
            pos_ecef_m=p.reshape(nr, 3),
            vel_ecef_mps=dp.reshape(nr, 3),
            acc_ecef_mps2=ddp.reshape(nr, 3),
            clock_bias_s=clk,
            clock_drift_sps=drift,
            relativistic_s=np.zeros(nr),
            tgd_s=np.zeros(nr),
            health=np.zeros(nr, dtype=np.int64),
            iode=np.full(nr, -1, dtype=np.int64),
            age_s=age,
            glo_channel=np.array([self.glo_channels.get(str(sv), 0) for sv in sv_out], dtype=np.int64),
            source=self.source,
        )

    def _clock(self, svs, col, tsec, tfrac, i):
        """Linear clock between bracketing samples: (clock_s, drift_sps, ok)."""
        n = len(svs)
        clk = np.full(n, np.nan)
        drift = np.full(n, np.nan)
        from_file = np.array([str(sv) in self._clkfile for sv in svs], dtype=bool)
        # SP3 clocks on the orbit grid
        r = np.flatnonzero(~from_file)
        if len(r):
            ii = i[r]
            c0 = self._clk[ii, col[r]]
            c1 = self._clk[ii + 1, col[r]]
            h = (self._tsec[ii + 1] - self._tsec[ii]) + (self._tfrac[ii + 1] - self._tfrac[ii])
            u = (tsec[r] - self._tsec[ii]) + (tfrac[r] - self._tfrac[ii])
            slope = (c1 - c0) / h
            # exactly on a sample: a missing neighbour does not matter
            val = np.where(u == 0, c0, c0 + slope * u)
            val = np.where(u == h, c1, val)
            good = np.where(u == 0, np.isfinite(c0), np.where(u == h, np.isfinite(c1),
                                                                np.isfinite(c0) & np.isfinite(c1)))
            good &= ~self._gap[ii]
            # drift needs both samples
            slope = np.where(np.isfinite(slope), slope, np.nan)
            clk[r] = np.where(good, val, np.nan)
            drift[r] = np.where(good, slope, np.nan)
        for k in np.flatnonzero(from_file):
            s, fr, vals, max_gap = self._clkfile[str(svs[k])]
            tk = float(tsec[k] - s[0]) + (tfrac[k] - fr[0])
            rel = (s - s[0]).astype(np.float64) + (fr - fr[0])
            j = int(np.searchsorted(rel, tk, side="right")) - 1
            if j < 0 or tk > rel[-1]:
                continue
            if len(rel) == 1:  # a single record serves its own epoch only
                if tk == 0 and np.isfinite(vals[0]):
                    clk[k], drift[k] = vals[0], np.nan
                continue
            if j == len(rel) - 1:
                j -= 1
            h = rel[j + 1] - rel[j]
            u = tk - rel[j]
            c0, c1 = vals[j], vals[j + 1]
            if u == 0 and np.isfinite(c0):
                clk[k] = c0
                drift[k] = (c1 - c0) / h if (np.isfinite(c1) and h <= max_gap) else np.nan
            elif u == h and np.isfinite(c1):
                clk[k] = c1
                drift[k] = (c1 - c0) / h if (np.isfinite(c0) and h <= max_gap) else np.nan
            elif np.isfinite(c0) and np.isfinite(c1) and h <= max_gap:
                clk[k] = c0 + (c1 - c0) * u / h
                drift[k] = (c1 - c0) / h
        ok = np.isfinite(clk)
        drift = np.where(ok & ~np.isfinite(drift), 0.0, drift)
        return clk, drift, ok


def _shift_order(n: int) -> list[int]:
    """0, -1, +1, -2, +2, ... up to +-(n-1): window shifts tried in order."""
    out = [0]
    for k in range(1, n):
        out += [-k, k]
    return out


def _newton_eval(x: np.ndarray, y: np.ndarray):
    """Value, first and second derivative at 0 of the polynomial through (x, y).

    ``x`` [R, n] node abscissae (relative to the evaluation point), ``y``
    [R, n, D].  Newton divided differences, then Horner's scheme carrying the
    derivatives (p'' <- p'' u + 2 p', p' <- p' u + p, p <- p u + c).
    """
    n = x.shape[1]
    c = y.copy()
    for k in range(1, n):
        c[:, k:, :] = (c[:, k:, :] - c[:, k - 1:-1, :]) / (x[:, k:, None] - x[:, :-k, None])
    p = c[:, n - 1, :].copy()
    dp = np.zeros_like(p)
    ddp = np.zeros_like(p)
    for k in range(n - 2, -1, -1):
        u = (0.0 - x[:, k])[:, None]
        ddp = ddp * u + 2.0 * dp
        dp = dp * u + p
        p = p * u + c[:, k, :]
    return p, dp, ddp
