"""Compare simulated and real GNSS observations (the thesis's comparison chapter, as a tool).

Inputs are RINEX 3 observation files (read with georinex) or rosbag2 bags
holding ``gnss_sim_msgs/Observations`` (read with rosbags); both become one
:class:`ObsTable`: epochs (GPS time) x satellites, one (epoch, sv) array per
RINEX observation code ("C1C", "L1C", "D1C", "S1C"), NaN where absent.

Method (:func:`compare`):

* Epochs are matched by time (to 1 ms), satellites by id, signals by RINEX
  band and tracking attribute: the same code first, else another attribute of
  the same band ("C1X" real against "C1C" simulated): :func:`pair_signals`.
* Pseudorange: d = P_sim - P_real.  The receiver clocks of both receivers
  differ per epoch; per epoch and system the median of d over the common
  satellites of that system's reference signal (its first paired code) is
  taken; the reference system (GPS when present) gives the clock offset of
  the epoch, every other system one constant inter-system bias (median over
  epochs of its median minus the reference one).  Residuals
  d - clock(epoch) - ISB(system) are what the tables show.  A residual above
  ``gross_m`` counts as a gross error and is left out of the statistics
  (counted separately).
* Carrier phase: the integer ambiguity of each track is arbitrary, so phases
  are compared **time-differenced** (delta range): dL = lambda (L(e) - L(e-1))
  between consecutive common epochs, sim minus real, with the same per-epoch
  median removal (the receiver clock change).  Cycle slips show up as outliers.
* Doppler: as range rate -lambda D [m/s] (so that bands share the receiver
  clock drift), sim minus real, per-epoch median removed (clock drift).
* C/N0: S observations, sim minus real [dB-Hz], nothing removed.
  Doppler and C/N0 are reported *unavailable* when one side has none (the
  OPEC real file has neither): never as zero.
* Visibility: per epoch the satellites with a code observation, on the
  systems both files observe (optionally above an elevation mask computed
  from the navigation data): seen by both / only simulated / only real and
  the Jaccard index |both| / |union| over (epoch, satellite) pairs.
* Positions: single point solutions of both files with the same solver
  (:func:`spp_solutions`: our :func:`~gnss_sim_ros2.core.solver.solve_pvt`
  with the broadcast ephemeris, Klobuchar ionosphere and Saastamoinen/Niell
  troposphere; or RTKLIB rnx2rtkp with the same models), against each other
  and against a ground truth (default: the real file's APPROX POSITION).

:func:`write_report` writes ``report.md`` and PNG figures (matplotlib Agg).
"""
from __future__ import annotations

import csv
import dataclasses
import math
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import constants as k
from .time import GnssTime

#: the GPS epoch as a numpy datetime64 (RINEX GPS time labels, no leap seconds)
GPS_EPOCH_NP = np.datetime64("1980-01-06T00:00:00", "ns")
#: epochs closer than this are the same epoch [ns]
EPOCH_MATCH_NS = 1_000_000
#: order in which a system becomes the reference of the receiver clock
REFERENCE_ORDER = "GECRJI"
#: observation kinds compared and their names in the report
KINDS = {"C": "code", "L": "phase", "D": "doppler", "S": "cn0"}
#: units of the differences per kind
UNITS = {"code": "m", "phase": "m", "doppler": "m/s", "cn0": "dB-Hz"}
DESCRIPTION = {
    "code": "pseudorange, sim - real, receiver clock and inter-system bias removed",
    "phase": "time-differenced carrier phase (delta range between consecutive common epochs), sim - real, "
             "receiver clock change removed",
    "doppler": "range rate from Doppler (-lambda D), sim - real, receiver clock drift removed",
    "cn0": "C/N0 (S observations), sim - real, nothing removed",
}
#: residuals beyond these count as gross errors (left out of the statistics, counted)
GROSS_LIMITS = {"code": 30.0, "phase": 5.0, "doppler": 10.0, "cn0": math.inf}
#: RTKLIB pos1-navsys bits (rtklib.h SYS_GPS 1, SYS_GLO 4, SYS_GAL 8, SYS_QZS 16, SYS_CMP 32, SYS_IRN 64)
RTKLIB_NAVSYS = {"G": 1, "R": 4, "E": 8, "J": 16, "C": 32, "I": 64}
#: single point error budget of RTKLIB pntpos.c (2.4.3): URA of a healthy broadcast (GPS URA index 0 =
#: 2.0 m, IS-GPS-200N 20.3.3.3.1.3), code bias ERR_CBIAS, ionosphere ERR_BRDCI (fraction of the model),
#: troposphere ERR_SAAS [m]
SPP_URA_M = 2.0
SPP_CODE_BIAS_M = 0.3
SPP_IONO_FRACTION = 0.5
SPP_TROPO_M = 0.3
#: RTKLIB solution time tags = epoch - receiver clock bias: matched to epochs within this [ns]
RTKLIB_TAG_NS = 50_000_000
_OBS_RE = re.compile(r"^[CLDS][0-9][A-Z]$")


# ============================================================================ observations
@dataclass
class ObsTable:
    """Observations of one receiver: ``values[code][epoch, sat]`` (NaN = absent)."""

    time: np.ndarray                       #: (E,) datetime64[ns], GPS time labels
    sv: np.ndarray                         #: (S,) str satellite ids ("G05")
    values: dict[str, np.ndarray]          #: obs code "C1C" -> (E, S) float
    source: str = ""                       #: file or bag it came from
    kind: str = "rinex"                    #: "rinex" | "bag"
    approx_pos_ecef_m: np.ndarray | None = None   #: RINEX APPROX POSITION XYZ
    glo_channel: dict[str, int] = field(default_factory=dict)   #: GLONASS slot -> frequency channel
    freq_hz: dict[tuple[str, str], float] = field(default_factory=dict)  #: (sv, "1C") -> carrier (bags)

    @property
    def systems(self) -> str:
        """Systems with at least one observation, in REFERENCE_ORDER."""
        have = {s[0] for j, s in enumerate(self.sv.tolist())
                if any(np.isfinite(a[:, j]).any() for a in self.values.values())}
        return "".join(s for s in REFERENCE_ORDER + "S" if s in have)

    def column(self, code: str) -> np.ndarray:
        """(E, S) array of ``code`` (all NaN when the table has no such code)."""
        a = self.values.get(code)
        return a if a is not None else np.full((len(self.time), len(self.sv)), np.nan)

    def has_data(self, code: str, svs=None) -> bool:
        a = self.values.get(code)
        if a is None:
            return False
        if svs is not None:
            a = a[:, np.isin(self.sv, list(svs))]
        return bool(np.isfinite(a).any())

    def frequency_hz(self, sv: str, code: str) -> float:
        """Carrier of ``code`` ("1C") of ``sv``: from the bag, else the signal table (GLONASS: header channel)."""
        f = self.freq_hz.get((sv, code))
        if f is not None and np.isfinite(f) and f > 0:
            return float(f)
        from .signals import frequency_hz

        if sv[0] == "R":
            ch = self.glo_channel.get(sv)
            if ch is None:
                return math.nan
            return float(frequency_hz("R", code, ch))
        try:
            return float(frequency_hz(sv[0], code))
        except ValueError:
            return math.nan

    def gnss_time(self, i: int) -> GnssTime:
        ns = int((self.time[i] - GPS_EPOCH_NP) / np.timedelta64(1, "ns"))
        return GnssTime(ns // 1_000_000_000, (ns % 1_000_000_000) * 1e-9)

    def subset(self, epochs=None, svs=None) -> ObsTable:
        """A copy restricted to epoch indices and/or satellite ids."""
        e = np.arange(len(self.time)) if epochs is None else np.asarray(epochs)
        cols = np.arange(len(self.sv)) if svs is None else np.array(
            [int(np.flatnonzero(self.sv == s)[0]) for s in svs], dtype=int)
        return ObsTable(self.time[e], self.sv[cols], {c: a[np.ix_(e, cols)] for c, a in self.values.items()},
                        self.source, self.kind, self.approx_pos_ecef_m, dict(self.glo_channel), dict(self.freq_hz))


def is_bag(path) -> bool:
    """A rosbag2 folder (metadata.yaml) or a single .mcap/.db3 file."""
    p = Path(path)
    return (p.is_dir() and (p / "metadata.yaml").is_file()) or p.suffix in (".mcap", ".db3")


def load_observations(path, tlim=None) -> ObsTable:
    """Observations of a RINEX 3 observation file or of a bag (``/gnss/observations``).

    ``tlim``: optional (first, last) numpy datetime64 (GPS time) to read only that span.
    """
    p = Path(path)
    if not p.exists():
        raise ValueError(f"{p}: no such file or bag folder")
    return load_bag(p, tlim) if is_bag(p) else load_rinex(p, tlim)


def _rinex_header(path: Path) -> dict:
    """Fields georinex does not give: APPROX POSITION XYZ and the GLONASS SLOT / FRQ # table."""
    out = {"approx": None, "glo": {}}
    with open(path, errors="replace") as f:
        first = f.readline()
        if "OBSERVATION DATA" not in first[20:60] or not first[:9].strip():
            raise ValueError(f"{path}, line 1: not a RINEX observation file (RINEX VERSION / TYPE is {first!r:.90})")
        try:
            version = float(first[:9])
        except ValueError:
            raise ValueError(f"{path}, line 1: unreadable RINEX version {first[:9]!r}") from None
        if version < 3:
            raise ValueError(f"{path}, line 1: RINEX {version} observation files are not supported (RINEX 3 only)")
        for n, line in enumerate(f, start=2):
            label = line[60:].strip()
            if label == "END OF HEADER":
                break
            if label == "APPROX POSITION XYZ":
                try:
                    out["approx"] = np.array([float(line[i:i + 14]) for i in (0, 14, 28)])
                except ValueError:
                    raise ValueError(f"{path}, line {n}: unreadable APPROX POSITION XYZ {line[:42]!r}") from None
            elif label == "GLONASS SLOT / FRQ #":
                for m in re.finditer(r"(R\s?\d{1,2})\s+(-?\d+)", line[4:60]):
                    sv = "R" + f"{int(m.group(1)[1:]):02d}"
                    out["glo"][sv] = int(m.group(2))
        else:
            raise ValueError(f"{path}: no END OF HEADER")
    if out["approx"] is not None and not np.any(out["approx"]):
        out["approx"] = None
    return out


def load_rinex(path, tlim=None) -> ObsTable:
    """RINEX 3 observation file via georinex (its warnings silenced)."""
    import georinex as gr

    path = Path(path)
    hdr = _rinex_header(path)
    kw = {}
    if tlim is not None:
        kw["tlim"] = tuple(np.datetime_as_string(np.datetime64(t, "us")) for t in tlim)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ds = gr.load(path, **kw)
    except Exception as exc:  # noqa: BLE001  georinex raises many kinds
        raise ValueError(f"{path}: georinex could not read it: {exc}") from exc
    codes = [v for v in ds.data_vars if _OBS_RE.match(str(v))]
    if "time" not in ds.dims or "sv" not in ds.dims:
        times, svs = np.zeros(0, "datetime64[ns]"), np.zeros(0, "<U3")
        values = {}
    else:
        times = ds.time.values.astype("datetime64[ns]")
        svs = np.asarray(ds.sv.values).astype("<U3")
        values = {str(c): np.asarray(ds[c].values, dtype=float) for c in codes}
    return ObsTable(times, svs, values, str(path), "rinex", hdr["approx"], hdr["glo"])


def bag_typestore():
    """rosbags type store with gnss_sim_msgs registered (same as recorder.typestore(), without rclpy)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    msg_dir = Path(__file__).resolve().parents[2] / "msg_pkg" / "msg"
    if not msg_dir.is_dir():
        from ament_index_python.packages import get_package_share_directory

        msg_dir = Path(get_package_share_directory("gnss_sim_msgs")) / "msg"
    store = get_typestore(Stores.ROS2_KILTED)
    add = {}
    for f in sorted(msg_dir.glob("*.msg")):
        add.update(get_types_from_msg(f.read_text(), f"gnss_sim_msgs/msg/{f.stem}"))
    store.register(add)
    return store


def load_bag(path, tlim=None, topic: str | None = None) -> ObsTable:
    """Every ``gnss_sim_msgs/msg/Observations`` message of a bag (or of ``topic``) as an ObsTable.

    Epoch time: ``gps_week`` + ``gps_tow_s`` (the receiver epoch, GPS time).
    """
    from rosbags.highlevel import AnyReader

    path = Path(path)
    rows: dict[tuple[int, str, str], float] = {}
    freq: dict[tuple[str, str], float] = {}
    times: set[int] = set()
    try:
        reader_cm = AnyReader([path], default_typestore=bag_typestore())
        with reader_cm as reader:
            conns = [c for c in reader.connections if c.msgtype == "gnss_sim_msgs/msg/Observations"
                     and (topic is None or c.topic == topic)]
            if not conns:
                have = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})
                raise ValueError(f"{path}: no gnss_sim_msgs/msg/Observations topic"
                                 f"{'' if topic is None else ' ' + topic} in the bag (topics: {', '.join(have)})")
            lo = hi = None
            if tlim is not None:
                lo, hi = (int((np.datetime64(t, "ns") - GPS_EPOCH_NP) / np.timedelta64(1, "ns")) for t in tlim)
            for conn, _, raw in reader.messages(connections=conns):
                msg = reader.deserialize(raw, conn.msgtype)
                t = GnssTime.from_week_tow(int(msg.gps_week), float(msg.gps_tow_s), "GPS")
                ns = int(t.sec) * 1_000_000_000 + int(round(float(t.frac) * 1e9))
                ns = int(round(ns / 1000.0)) * 1000   # microseconds, like RINEX/georinex labels
                if lo is not None and not (lo - EPOCH_MATCH_NS <= ns <= hi + EPOCH_MATCH_NS):
                    continue
                times.add(ns)
                for o in msg.observations:
                    sv, code = str(o.sv), str(o.code)
                    freq[(sv, code)] = float(o.frequency_hz)
                    for kind, v in (("C", o.pseudorange_m), ("L", o.carrier_phase_cycles), ("D", o.doppler_hz),
                                    ("S", o.cn0_dbhz)):
                        if np.isfinite(v):
                            rows[(ns, sv, kind + code)] = float(v)
    except ValueError:
        raise
    except Exception as exc:  # noqa: BLE001  rosbags raises its own kinds
        raise ValueError(f"{path}: could not read the bag: {exc}") from exc
    t_sorted = np.array(sorted(times), dtype=np.int64)
    svs = np.array(sorted({sv for _, sv, _ in rows}), dtype="<U3")
    ti = {t: i for i, t in enumerate(t_sorted.tolist())}
    si = {s: j for j, s in enumerate(svs.tolist())}
    values: dict[str, np.ndarray] = {}
    for (ns, sv, code), v in rows.items():
        a = values.get(code)
        if a is None:
            a = values[code] = np.full((len(t_sorted), len(svs)), np.nan)
        a[ti[ns], si[sv]] = v
    values = {c: values[c] for c in sorted(values, key=lambda c: (c[1], c[2], "CLDS".index(c[0])))}
    return ObsTable(GPS_EPOCH_NP + t_sorted.astype("timedelta64[ns]"), svs, values, str(path), "bag", None, {}, freq)


# ============================================================================ alignment
@dataclass(frozen=True)
class SignalPair:
    """One signal compared: ``sim_code``/``real_code`` are band + attribute ("1C", "1X")."""

    system: str
    sim_code: str
    real_code: str

    @property
    def band(self) -> str:
        return self.sim_code[0]

    @property
    def label(self) -> str:
        return f"{self.system} {self.sim_code}" + ("" if self.sim_code == self.real_code else f"/{self.real_code}")


def _attributes(tab: ObsTable, system: str) -> list[str]:
    """Band+attribute codes with any observation of ``system``, in the table's order."""
    cols = np.array([s[0] == system for s in tab.sv.tolist()], dtype=bool)
    out = []
    for code, a in tab.values.items():
        if np.isfinite(a[:, cols]).any() and code[1:] not in out:
            out.append(code[1:])
    if tab.kind == "bag":   # a bag has no header order: the simulator's geodetic profile order (first = primary)
        from .signals import PROFILES

        order = PROFILES["geodetic"].get(system, [])
        out.sort(key=lambda c: order.index(c) if c in order else len(order))
    return out


def pair_signals(sim: ObsTable, real: ObsTable, systems: str) -> list[SignalPair]:
    """Signals of each system matched by band: the same attribute first, else another of the band
    (each real signal used once; real signals with pseudoranges preferred)."""
    pairs = []
    for s in systems:
        a_sim, a_real = _attributes(sim, s), _attributes(real, s)
        svs = [v for v in real.sv.tolist() if v[0] == s]
        used = set()
        match = {}
        for c in a_sim:
            if c in a_real:
                match[c] = c
                used.add(c)
        for c in a_sim:
            if c in match:
                continue
            cands = [r for r in a_real if r[0] == c[0] and r not in used]
            if cands:
                cands.sort(key=lambda r: -int(np.isfinite(real.column("C" + r)[:, np.isin(real.sv, svs)]).sum()))
                match[c] = cands[0]
                used.add(cands[0])
        pairs += [SignalPair(s, c, match[c]) for c in a_sim if c in match]
    return pairs


def match_epochs(t_sim: np.ndarray, t_real: np.ndarray, tol_ns: int = EPOCH_MATCH_NS):
    """Indices (i_sim, i_real) of epochs whose times agree within ``tol_ns``."""
    a = t_sim.astype("datetime64[ns]").astype(np.int64)
    b = t_real.astype("datetime64[ns]").astype(np.int64)
    j = np.searchsorted(b, a)
    i_sim, i_real = [], []
    for i, (x, jj) in enumerate(zip(a, j)):
        best = None
        for c in (jj - 1, jj):
            if 0 <= c < len(b) and abs(int(b[c]) - int(x)) <= tol_ns and (best is None or
                                                                           abs(b[c] - x) < abs(b[best] - x)):
                best = c
        if best is not None:
            i_sim.append(i)
            i_real.append(int(best))
    return np.array(i_sim, dtype=int), np.array(i_real, dtype=int)


# ============================================================================ differences
@dataclass
class KindResult:
    """Residuals of one kind (code, phase, doppler, cn0) over (common epoch, satellite)."""

    kind: str
    available: bool
    reason: str                                  #: why unavailable ("" when available)
    residuals: dict[SignalPair, np.ndarray]      #: pair -> (E, S) residual (NaN: none; gross ones kept)
    clock: np.ndarray | None = None              #: (E,) removed common offset of the reference system
    isb: dict[str, float] = field(default_factory=dict)   #: system -> constant removed on top of ``clock``
    ref_system: str = ""


def _stats(x: np.ndarray, gross: float) -> dict:
    x = np.asarray(x, dtype=float).ravel()
    x = x[np.isfinite(x)]
    bad = np.abs(x) > gross
    g = x[~bad]
    if g.size == 0:
        return {"n": 0, "n_gross": int(bad.sum()), "mean": math.nan, "rms": math.nan, "std": math.nan,
                "max_abs": math.nan}
    return {"n": int(g.size), "n_gross": int(bad.sum()), "mean": float(g.mean()),
            "rms": float(np.sqrt(np.mean(g**2))), "std": float(g.std()), "max_abs": float(np.abs(g).max())}


def remove_common_offsets(diffs: dict[SignalPair, np.ndarray], sys_of_col: np.ndarray, min_sats: int = 1):
    """Per-epoch receiver offset and per-system constant bias of sim - real differences.

    For each system the first pair in ``diffs`` is its reference signal; m_s(e) = median over the
    system's satellites.  Reference system r: the first of REFERENCE_ORDER with values; clock(e) = m_r(e)
    (epochs where r has none: median over other systems of m_s(e) - ISB_s); ISB_s = median over epochs of
    m_s(e) - m_r(e).  Returns (residuals, clock, isb, r): residual = d - clock(e) - ISB(system).
    """
    ref_pair: dict[str, SignalPair] = {}
    for p in diffs:
        if p.system not in ref_pair and np.isfinite(diffs[p]).any():
            ref_pair[p.system] = p
    if not ref_pair:
        e = next(iter(diffs.values())).shape[0] if diffs else 0
        return {p: d.copy() for p, d in diffs.items()}, np.full(e, np.nan), {}, ""
    n_e = next(iter(diffs.values())).shape[0]
    med = {}
    for s, p in ref_pair.items():
        d = diffs[p][:, sys_of_col == s]
        cnt = np.isfinite(d).sum(axis=1)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            m = np.nanmedian(d, axis=1) if d.shape[1] else np.full(n_e, np.nan)
        med[s] = np.where(cnt >= min_sats, m, np.nan)
    r = max((s for s in REFERENCE_ORDER if s in med), key=lambda s: (np.isfinite(med[s]).sum(),
                                                                     -REFERENCE_ORDER.index(s)))
    isb = {r: 0.0}
    for s, m in med.items():
        if s != r:
            both = np.isfinite(m) & np.isfinite(med[r])
            isb[s] = float(np.median(m[both] - med[r][both])) if both.any() else math.nan
    clock = med[r].copy()
    miss = ~np.isfinite(clock)
    if miss.any():
        others = [med[s] - isb[s] for s in med if s != r and np.isfinite(isb[s])]
        if others:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                fill = np.nanmedian(np.vstack(others), axis=0)
            clock[miss] = fill[miss]
    # a system never seen together with the reference: its own per-epoch median
    res = {}
    for p, d in diffs.items():
        b = isb.get(p.system, math.nan)
        off = clock + b if np.isfinite(b) else med.get(p.system, np.full(n_e, np.nan))
        res[p] = d - off[:, None]
    return res, clock, isb, r


# ============================================================================ positions
@dataclass
class Solutions:
    """Single point solutions over the common epochs (NaN rows: no fix)."""

    pos_ecef_m: np.ndarray      #: (E, 3)
    n_used: np.ndarray          #: (E,) int
    solver: str                 #: "gnss_sim solve_pvt" | "RTKLIB rnx2rtkp"
    note: str = ""              #: what was done to the input for the solver (rtklib_observation_copy)


def _klobuchar(eph):
    from .receiver.engine import KLOBUCHAR_FALLBACK_ALPHA, KLOBUCHAR_FALLBACK_BETA

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
    from .solver import pseudorange_sigma_m

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
    from . import propagation as prop
    from .constants import OMEGA_BY_SYSTEM
    from .frames import az_el_from_ecef, ecef_to_geodetic
    from .receiver.engine import _group_delay_factor as group_delay_factor  # the simulator's convention
    from .signals import frequency_hz
    from .solver import SolverConfig, solve_pvt

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


#: BeiDou B1I observation codes whose tracking attribute RTKLIB 2.4.3 (b34, Debian's rnx2rtkp) mishandles:
#: measured on OPEC 2022-001, it applies the broadcast TGD1 (BDS-SIS-ICD-B1I 5.2.4.10) to "C2I" but not to
#: "C2X" (B1I, I+Q tracking, as a Trimble NETR9 labels it): zeroing TGD1 in the navigation file leaves its
#: solution from C2X unchanged to the last digit, and its BeiDou residuals per satellite follow c*TGD1
#: (2.3 m RMS, up to 5 m).  The attribute names the tracked channel, not another signal or group delay.
RTKLIB_BEIDOU_B1I_ALIASES = ("X", "Q")


def rtklib_observation_copy(obs_path, workdir) -> tuple[Path, list[str]]:
    """The observation file as RTKLIB 2.4.3 should read it: a copy in ``workdir`` whose BeiDou B1I codes
    with attribute X or Q (C2X, L2X, D2X, S2X; ...) are renamed to attribute I in the header's
    SYS / # / OBS TYPES (``RTKLIB_BEIDOU_B1I_ALIASES``), unless the file has a B1I code with attribute I.
    Returns (path, renamed codes); the original path and [] when nothing needs renaming or the file is
    not plain RINEX 3 text (compressed files are passed through unchanged)."""
    obs_path = Path(obs_path)
    try:
        with open(obs_path, encoding="ascii", errors="strict", newline="") as f:
            header = []
            for line in f:
                header.append(line)
                if line[60:].strip() == "END OF HEADER" or len(header) > 2000:
                    break
    except (UnicodeDecodeError, OSError):
        return obs_path, []
    if not header or header[0][60:].strip() != "RINEX VERSION / TYPE" or not header[0][:9].strip().startswith("3"):
        return obs_path, []
    rows = [i for i, ln in enumerate(header) if ln[60:].strip() == "SYS / # / OBS TYPES"]
    beidou, in_c = [], False
    for i in rows:
        if header[i][0] != " ":
            in_c = header[i][0] == "C"
        if in_c:
            beidou.append(i)
    fields = [(i, 7 + 4 * j) for i in beidou for j in range(13)]     # (line, column) of each code (A3, 1X)
    if any(header[i][c + 1: c + 3] == "2I" for i, c in fields):
        return obs_path, []          # B1I already tracked as I: RTKLIB prefers it, nothing to rename
    renamed = []
    for i, c in fields:
        code = header[i][c: c + 3]
        if len(code) == 3 and code[1] == "2" and code[2] in RTKLIB_BEIDOU_B1I_ALIASES:
            header[i] = header[i][:c] + code[:2] + "I" + header[i][c + 3:]
            renamed.append(code)
    if not renamed:
        return obs_path, []
    for i, line in enumerate(header):     # the phase shift records name the same codes
        if line[60:].strip() == "SYS / PHASE SHIFT" and line[:1] == "C" and line[2:5] in renamed:
            header[i] = line[:4] + "I" + line[5:]
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    out = workdir / obs_path.name
    if out.resolve() == obs_path.resolve():
        raise ValueError(f"{obs_path}: the RTKLIB copy would overwrite the original (choose another workdir)")
    with open(obs_path, encoding="ascii", newline="") as src, open(out, "w", encoding="ascii", newline="") as dst:
        for _ in header:
            src.readline()
        dst.writelines(header)
        for chunk in iter(lambda: src.read(1 << 20), ""):
            dst.write(chunk)
    return out, renamed


def rtklib_solutions(obs_path, nav_paths, systems: str, times: np.ndarray, workdir,
                     elevation_mask_deg: float = 10.0) -> Solutions:
    """RTKLIB rnx2rtkp single point solutions (broadcast ionosphere, Saastamoinen) at ``times``."""
    import shutil
    import subprocess

    if shutil.which("rnx2rtkp") is None:
        raise ValueError("solver 'rtklib': rnx2rtkp is not installed")
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    stem = Path(obs_path).name.replace(".", "_")
    conf = workdir / f"{stem}.conf"
    out = workdir / f"{stem}.pos"
    navsys = sum(RTKLIB_NAVSYS[s] for s in set(systems) if s in RTKLIB_NAVSYS)
    opts = {"pos1-posmode": "single", "pos1-elmask": f"{elevation_mask_deg:g}", "pos1-ionoopt": "brdc",
            "pos1-tropopt": "saas", "pos1-navsys": str(navsys), "out-solformat": "xyz", "out-timesys": "gpst"}
    conf.write_text("".join(f"{a}={b}\n" for a, b in opts.items()))
    obs_in, renamed = rtklib_observation_copy(obs_path, workdir / "input")
    note = (f"{Path(obs_path).name}: BeiDou {', '.join(renamed)} given to RTKLIB as attribute I (RTKLIB 2.4.3 "
            "applies TGD1 to C2I only)") if renamed else ""
    subprocess.run(["rnx2rtkp", "-k", str(conf), "-o", str(out), str(obs_in), *map(str, nav_paths)], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=600)
    t_sol, rows = [], []
    for ln in out.read_text().splitlines():
        if not ln.strip() or ln.startswith("%"):
            continue
        f = ln.split()
        t_sol.append(np.datetime64(f[0].replace("/", "-") + "T" + f[1], "ns"))
        rows.append((float(f[2]), float(f[3]), float(f[4]), int(f[6])))
    pos = np.full((len(times), 3), np.nan)
    used = np.zeros(len(times), dtype=int)
    if rows:
        # RTKLIB tags a solution with the receiver time corrected by its clock bias: match within 50 ms
        i_t, i_s = match_epochs(np.asarray(times), np.array(t_sol, dtype="datetime64[ns]"), RTKLIB_TAG_NS)
        arr = np.array(rows)
        pos[i_t] = arr[i_s, :3]
        used[i_t] = arr[i_s, 3].astype(int)
    return Solutions(pos, used, "RTKLIB rnx2rtkp", note)


def truth_from_csv(path, times: np.ndarray) -> np.ndarray:
    """Ground truth (E, 3) ECEF at ``times`` from a CSV with a ``time`` column (ISO 8601, GPS) and either
    ``x_m,y_m,z_m`` (ECEF) or ``lat_deg,lon_deg,h_m``; linear interpolation, NaN outside its span."""
    from .frames import geodetic_to_ecef

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"--truth-csv {path}: no such file")
    t_ns, xyz = [], []
    with open(path, newline="") as f:
        rd = csv.DictReader(f)
        cols = set(rd.fieldnames or [])
        ecef = {"x_m", "y_m", "z_m"} <= cols
        geo = {"lat_deg", "lon_deg", "h_m"} <= cols
        if "time" not in cols or not (ecef or geo):
            raise ValueError(f"{path}, line 1: need columns time and x_m,y_m,z_m or lat_deg,lon_deg,h_m; "
                             f"got {sorted(cols)}")
        for n, row in enumerate(rd, start=2):
            try:
                t = np.datetime64(row["time"].strip().rstrip("Z"), "ns")
                if ecef:
                    v = [float(row["x_m"]), float(row["y_m"]), float(row["z_m"])]
                else:
                    if not row["lat_deg"].strip():
                        continue                    # fix.csv rows without a fix
                    v = list(geodetic_to_ecef(float(row["lat_deg"]), float(row["lon_deg"]), float(row["h_m"])))
            except (ValueError, KeyError) as exc:
                raise ValueError(f"{path}, line {n}: {exc}") from None
            t_ns.append(int((t - GPS_EPOCH_NP) / np.timedelta64(1, "ns")))
            xyz.append(v)
    if not t_ns:
        raise ValueError(f"{path}: no truth rows")
    order = np.argsort(t_ns)
    ts = np.asarray(t_ns, dtype=float)[order]
    xyz = np.asarray(xyz)[order]
    q = ((times.astype("datetime64[ns]") - GPS_EPOCH_NP) / np.timedelta64(1, "ns")).astype(float)
    out = np.column_stack([np.interp(q, ts, xyz[:, i], left=np.nan, right=np.nan) for i in range(3)])
    if len(ts) == 1:
        out[np.abs(q - ts[0]) <= EPOCH_MATCH_NS] = xyz[0]
    return out


def enu_errors_m(pos_ecef_m: np.ndarray, ref_ecef_m: np.ndarray) -> np.ndarray:
    """(E, 3) east, north, up of ``pos`` relative to ``ref`` ((3,) or (E, 3)), ENU at each reference point."""
    from .frames import ecef_to_enu, ecef_to_geodetic

    ref = np.broadcast_to(np.asarray(ref_ecef_m, float), pos_ecef_m.shape)
    out = np.full(pos_ecef_m.shape, np.nan)
    ok = np.all(np.isfinite(pos_ecef_m), axis=1) & np.all(np.isfinite(ref), axis=1)
    for i in np.flatnonzero(ok):
        lat, lon, h = ecef_to_geodetic(*ref[i])
        out[i] = ecef_to_enu(pos_ecef_m[i], lat, lon, h)
    return out


def position_stats(enu: np.ndarray) -> dict:
    ok = np.all(np.isfinite(enu), axis=1)
    e = enu[ok]
    if not len(e):
        return {"n": 0}
    hz = np.hypot(e[:, 0], e[:, 1])
    return {"n": int(ok.sum()), "mean_e_m": float(e[:, 0].mean()), "mean_n_m": float(e[:, 1].mean()),
            "mean_u_m": float(e[:, 2].mean()), "rms_h_m": float(np.sqrt(np.mean(hz**2))),
            "rms_v_m": float(np.sqrt(np.mean(e[:, 2] ** 2))), "p95_h_m": float(np.percentile(hz, 95))}


# ============================================================================ comparison
@dataclass
class Comparison:
    """Everything :func:`write_report` needs (arrays over common epochs x ``sv``)."""

    sim: ObsTable
    real: ObsTable
    time: np.ndarray                     #: (E,) common epochs
    sv: np.ndarray                       #: (S,) satellites of the common systems (union of both)
    systems: str                         #: systems observed by both
    systems_only_sim: str
    systems_only_real: str
    epochs_only_sim: int
    epochs_only_real: int
    pairs: list[SignalPair]
    kinds: dict[str, KindResult]         #: "code" | "phase" | "doppler" | "cn0"
    seen_sim: np.ndarray                 #: (E, S) bool, above the mask
    seen_real: np.ndarray
    el_deg: np.ndarray | None            #: (E, S) elevation at the truth position (None without nav)
    mask_deg: float
    sim_cn0: dict[SignalPair, np.ndarray] = field(default_factory=dict)    #: (E, S) raw S of each side
    real_cn0: dict[SignalPair, np.ndarray] = field(default_factory=dict)
    truth_ecef_m: np.ndarray | None = None   #: (E, 3)
    truth_label: str = ""
    sol_sim: Solutions | None = None
    sol_real: Solutions | None = None
    position_note: str = ""

    # ------------------------------------------------------------------ summaries
    def sys_of_col(self) -> np.ndarray:
        return np.array([s[0] for s in self.sv.tolist()])

    def stats(self, kind: str, pair: SignalPair, sv: str | None = None) -> dict:
        kr = self.kinds[kind]
        d = kr.residuals.get(pair)
        if d is None:
            return _stats(np.zeros(0), GROSS_LIMITS[kind])
        d = d[:, self.sv == sv] if sv is not None else d[:, self.sys_of_col() == pair.system]
        return _stats(d, GROSS_LIMITS[kind])

    def system_stats(self, kind: str, system: str) -> dict:
        """Statistics of every pair of ``system`` together."""
        kr = self.kinds[kind]
        cols = self.sys_of_col() == system
        parts = [kr.residuals[p][:, cols].ravel() for p in self.pairs if p.system == system and p in kr.residuals]
        return _stats(np.concatenate(parts) if parts else np.zeros(0), GROSS_LIMITS[kind])

    def per_satellite(self, kind: str, pair: SignalPair) -> dict[str, dict]:
        out = {}
        for s in self.sv.tolist():
            if s[0] == pair.system:
                st = self.stats(kind, pair, s)
                if st["n"] or st["n_gross"]:
                    out[s] = st
        return out

    def visibility(self) -> dict:
        """Jaccard per system and overall, satellites seen by one side only, per-satellite epoch counts."""
        both = self.seen_sim & self.seen_real
        only_s = self.seen_sim & ~self.seen_real
        only_r = self.seen_real & ~self.seen_sim
        sysc = self.sys_of_col()
        jac = {}
        for s in self.systems:
            c = sysc == s
            u = (self.seen_sim | self.seen_real)[:, c].sum()
            jac[s] = float(both[:, c].sum() / u) if u else math.nan
        u = (self.seen_sim | self.seen_real).sum()
        jac["all"] = float(both.sum() / u) if u else math.nan
        per_sv = {s: {"both": int(both[:, j].sum()), "only_sim": int(only_s[:, j].sum()),
                      "only_real": int(only_r[:, j].sum())} for j, s in enumerate(self.sv.tolist())}
        never_real = [s for s, c in per_sv.items() if c["only_sim"] and not c["both"]]
        never_sim = [s for s, c in per_sv.items() if c["only_real"] and not c["both"]]
        return {"jaccard": jac, "per_sv": per_sv, "only_sim_svs": never_real, "only_real_svs": never_sim,
                "n_both": int(both.sum()), "n_only_sim": int(only_s.sum()), "n_only_real": int(only_r.sum())}

    def positions(self) -> dict:
        out = {}
        if self.sol_sim is None or self.sol_real is None:
            return out
        if self.truth_ecef_m is not None:
            out["sim_vs_truth"] = position_stats(enu_errors_m(self.sol_sim.pos_ecef_m, self.truth_ecef_m))
            out["real_vs_truth"] = position_stats(enu_errors_m(self.sol_real.pos_ecef_m, self.truth_ecef_m))
        out["sim_vs_real"] = position_stats(enu_errors_m(self.sol_sim.pos_ecef_m, self.sol_real.pos_ecef_m))
        return out


def _elevations(eph, times: np.ndarray, svs: np.ndarray, rx_ecef: np.ndarray) -> np.ndarray:
    """(E, S) elevation [deg] from the broadcast ephemeris at ``rx_ecef`` ((E, 3)); NaN without a record."""
    from .frames import az_el_from_ecef

    col = {s: j for j, s in enumerate(svs.tolist())}
    el = np.full((len(times), len(svs)), np.nan)
    systems = "".join(sorted({s[0] for s in svs.tolist()} & set("GRECJI")))
    if not systems:
        return el
    for i, t in enumerate(times):
        if not np.all(np.isfinite(rx_ecef[i])):
            continue
        ns = int((t.astype("datetime64[ns]") - GPS_EPOCH_NP) / np.timedelta64(1, "ns"))
        st = eph.states(GnssTime(ns // 1_000_000_000, (ns % 1_000_000_000) * 1e-9), systems=systems)
        if not len(st):
            continue
        _, e, _ = az_el_from_ecef(rx_ecef[i], st.pos_ecef_m)
        for s, v in zip(st.sv.tolist(), np.atleast_1d(e)):
            if s in col:
                el[i, col[s]] = v
    return el


def _kind_diffs(c: str, sim: ObsTable, real: ObsTable, pairs, svs, i_sim, i_real) -> dict[SignalPair, np.ndarray]:
    """Raw sim - real of observation kind ``c`` per pair over (common epoch, svs) (phase: time-differenced,
    metres; Doppler: range rate m/s)."""
    js = {s: j for j, s in enumerate(sim.sv.tolist())}
    jr = {s: j for j, s in enumerate(real.sv.tolist())}
    out = {}
    for p in pairs:
        a = np.full((len(i_sim), len(svs)), np.nan)
        b = np.full((len(i_sim), len(svs)), np.nan)
        cs, cr = sim.values.get(c + p.sim_code), real.values.get(c + p.real_code)
        if cs is None or cr is None:
            continue
        for j, s in enumerate(svs.tolist()):
            if s[0] != p.system or s not in js or s not in jr:
                continue
            x, y = cs[i_sim, js[s]], cr[i_real, jr[s]]
            if c in "LD":   # to metres (phase) and m/s (Doppler, as -lambda D)
                lam_s = k.C_MPS / sim.frequency_hz(s, p.sim_code)
                lam_r = k.C_MPS / real.frequency_hz(s, p.real_code)
                x, y = x * lam_s, y * lam_r
                if c == "D":
                    x, y = -x, -y
            a[:, j], b[:, j] = x, y
        if c == "L":
            a = np.vstack([np.full((1, a.shape[1]), np.nan), np.diff(a, axis=0)])
            b = np.vstack([np.full((1, b.shape[1]), np.nan), np.diff(b, axis=0)])
        out[p] = a - b
    return out


def compare(sim_path, real_path, nav_paths=None, truth_ecef_m=None, truth_csv=None, mask_deg: float = 0.0,
            solver: str = "ours", restrict_real_to_sim_span: bool = True, workdir=None) -> Comparison:
    """Compare two observation sources (RINEX or bag).  ``nav_paths``: broadcast navigation files for
    elevations and positions (none: no positions, no elevations); ``truth_ecef_m`` (3,) or ``truth_csv``
    (default truth: the real file's APPROX POSITION, else the simulated one's); ``mask_deg`` applies to
    the visibility sets where an elevation is known; ``solver`` "ours" | "rtklib" (RINEX inputs only)."""
    if solver not in ("ours", "rtklib"):
        raise ValueError(f"solver {solver!r}: expected 'ours' or 'rtklib'")
    if truth_ecef_m is not None and truth_csv is not None:
        raise ValueError("give either truth_ecef_m or truth_csv, not both")
    sim = load_observations(sim_path)
    if not len(sim.time):
        raise ValueError(f"{sim_path}: no observation epochs")
    tlim = (sim.time[0] - np.timedelta64(1, "s"), sim.time[-1] + np.timedelta64(1, "s")) \
        if restrict_real_to_sim_span else None
    real = load_observations(real_path, tlim)
    if not len(real.time):
        raise ValueError(f"{real_path}: no observation epochs"
                         + (" within the simulated span" if restrict_real_to_sim_span else ""))
    i_sim, i_real = match_epochs(sim.time, real.time)
    if not len(i_sim):
        raise ValueError(f"{sim_path} ({sim.time[0]} .. {sim.time[-1]}) and {real_path} "
                         f"({real.time[0]} .. {real.time[-1]}) have no common epoch")
    sys_s, sys_r = sim.systems, real.systems
    systems = "".join(s for s in sys_s if s in sys_r)
    svs = np.array(sorted({s for s in sim.sv.tolist() + real.sv.tolist() if s[0] in systems}), dtype="<U3")
    pairs = pair_signals(sim, real, systems)
    sysc = np.array([s[0] for s in svs.tolist()])
    times = sim.time[i_sim]

    kinds = {}
    for c, name in KINDS.items():
        ps = [p for p in pairs if sim.has_data(c + p.sim_code) and real.has_data(c + p.real_code)]
        if not ps:
            lacking = [lab for lab, t in (("simulated", sim), ("real", real))
                       if not any(t.has_data(c + (p.sim_code if t is sim else p.real_code)) for p in pairs)]
            why = (f"the {' and the '.join(lacking)} file{'s have' if len(lacking) > 1 else ' has'} no "
                   f"{c} ({name}) observations" if lacking else f"no signal has {c} observations on both sides")
            kinds[name] = KindResult(name, False, why, {})
            continue
        raw = _kind_diffs(c, sim, real, ps, svs, i_sim, i_real)
        if name == "cn0":
            kinds[name] = KindResult(name, True, "", raw)
        else:
            res, clock, isb, ref = remove_common_offsets(raw, sysc)
            kinds[name] = KindResult(name, True, "", res, clock, isb, ref)

    def seen(tab: ObsTable, idx):
        j = {s: i for i, s in enumerate(tab.sv.tolist())}
        out = np.zeros((len(idx), len(svs)), dtype=bool)
        codes = [c for c in tab.values if c[0] == "C"]
        for col, s in enumerate(svs.tolist()):
            if s in j:
                out[:, col] = np.any([np.isfinite(tab.values[c][idx, j[s]]) for c in codes], axis=0) if codes else False
        return out

    seen_sim, seen_real = seen(sim, i_sim), seen(real, i_real)

    # truth
    truth_label = ""
    truth = None
    if truth_csv is not None:
        truth = truth_from_csv(truth_csv, times)
        truth_label = f"CSV {truth_csv}"
    elif truth_ecef_m is not None:
        truth = np.tile(np.asarray(truth_ecef_m, float).reshape(1, 3), (len(times), 1))
        truth_label = "given ECEF " + ", ".join(f"{v:.3f}" for v in np.ravel(truth_ecef_m))
    elif real.approx_pos_ecef_m is not None:
        truth = np.tile(real.approx_pos_ecef_m, (len(times), 1))
        truth_label = "real file header APPROX POSITION XYZ"
    elif sim.approx_pos_ecef_m is not None:
        truth = np.tile(sim.approx_pos_ecef_m, (len(times), 1))
        truth_label = "simulated file header APPROX POSITION XYZ"

    cmp = Comparison(sim, real, times, svs, systems, "".join(s for s in sys_s if s not in sys_r),
                     "".join(s for s in sys_r if s not in sys_s), len(sim.time) - len(i_sim),
                     len(real.time) - len(i_real), pairs, kinds, seen_sim, seen_real, None, mask_deg,
                     truth_ecef_m=truth, truth_label=truth_label)
    # raw C/N0 for the figure
    for p in pairs:
        for tab, idx, dst, code in ((sim, i_sim, cmp.sim_cn0, p.sim_code), (real, i_real, cmp.real_cn0, p.real_code)):
            a = tab.values.get("S" + code)
            if a is None or not np.isfinite(a).any():
                continue
            j = {s: i for i, s in enumerate(tab.sv.tolist())}
            m = np.full((len(idx), len(svs)), np.nan)
            for col, s in enumerate(svs.tolist()):
                if s in j and s[0] == p.system:
                    m[:, col] = a[idx, j[s]]
            dst[p] = m

    if nav_paths:
        from .ephemeris.broadcast import BroadcastEphemeris

        nav_paths = [str(p) for p in nav_paths]
        for p in nav_paths:
            if not Path(p).is_file():
                raise ValueError(f"--nav {p}: no such file")
        eph = BroadcastEphemeris.from_files(nav_paths)
        rx = truth if truth is not None else None
        sys_nav = "".join(s for s in systems if s in "GRECJI" and eph.svs(s))
        ref = {}        # per system its first signal with pseudoranges on both sides
        for p in pairs:
            if (p.system in sys_nav and p.system not in ref and sim.has_data("C" + p.sim_code)
                    and real.has_data("C" + p.real_code)):
                ref[p.system] = p
        code_sim = {s: p.sim_code for s, p in ref.items()}
        code_real = {s: p.real_code for s, p in ref.items()}
        if solver == "rtklib" and not (sim.kind == real.kind == "rinex"):
            cmp.position_note = "RTKLIB needs RINEX inputs: gnss_sim solve_pvt used instead"
            solver = "ours"
        if solver == "rtklib":
            from .receiver.outputs import write_navigation

            wd = Path(workdir) if workdir is not None else Path(sim_path).parent
            wd.mkdir(parents=True, exist_ok=True)
            # RTKLIB gets the navigation data as our reader understood it (one merged RINEX 3.04 file):
            # some published files need repairs it does not make (BeiDou angles in semicircles)
            merged = write_navigation(wd / "rtklib_nav.rnx", eph, "".join(ref))
            cmp.sol_sim = rtklib_solutions(sim_path, [merged], "".join(ref), times, wd / "rtklib_sim")
            cmp.sol_real = rtklib_solutions(real_path, [merged], "".join(ref), times, wd / "rtklib_real")
            cmp.position_note = "; ".join(n for n in (cmp.sol_sim.note, cmp.sol_real.note) if n)
        elif ref:
            prior = truth[0] if truth is not None and np.all(np.isfinite(truth[0])) else None
            cmp.sol_sim = spp_solutions(sim, eph, code_sim, i_sim, prior)
            cmp.sol_real = spp_solutions(real, eph, code_real, i_real, prior)
        if rx is None and cmp.sol_real is not None:
            rx = cmp.sol_real.pos_ecef_m
        if rx is not None:
            cmp.el_deg = _elevations(eph, times, svs, rx)
            if mask_deg > 0:
                low = np.isfinite(cmp.el_deg) & (cmp.el_deg < mask_deg)
                cmp.seen_sim = cmp.seen_sim & ~low
                cmp.seen_real = cmp.seen_real & ~low
    return cmp


# ============================================================================ report
def _f(v, digits=3) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return f"{0.0 if abs(v) < 0.5 * 10.0**-digits else v:.{digits}f}"


def _md_table(header: list[str], rows: list[list]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return out + [""]


def write_figures(cmp: Comparison, out_dir) -> dict[str, Path]:
    """PNG figures; returns name -> path of those written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.dates as mdates
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    out_dir = Path(out_dir)
    figs: dict[str, Path] = {}
    t = cmp.time.astype("datetime64[ms]").astype(object)
    sysc = cmp.sys_of_col()

    # pseudorange residual vs time per satellite (reference signal of each system)
    code = cmp.kinds["code"]
    if code.available:
        refs = []
        for p in cmp.pairs:
            if p in code.residuals and p.system not in [q.system for q in refs]:
                refs.append(p)
        if refs:
            fig, axes = plt.subplots(len(refs), 1, figsize=(10, 3.0 * len(refs)), sharex=True, squeeze=False)
            for ax, p in zip(axes[:, 0], refs):
                d = code.residuals[p]
                for j in np.flatnonzero(sysc == p.system):
                    if np.isfinite(d[:, j]).any():
                        ax.plot(t, d[:, j], ".-", ms=3, lw=0.8, label=cmp.sv[j])
                ax.set_ylabel(f"{p.label} [m]")
                ax.grid(alpha=0.3)
                ax.legend(fontsize=6, ncol=8, loc="upper right")
            axes[0, 0].set_title("pseudorange sim - real (receiver clock and ISB removed)")
            axes[-1, 0].xaxis.set_major_formatter(mdates.DateFormatter("%H:%M"))
            axes[-1, 0].set_xlabel("GPS time")
            fig.tight_layout()
            figs["code"] = out_dir / "code_difference.png"
            fig.savefig(figs["code"], dpi=110)
            plt.close(fig)

    # C/N0 vs elevation
    if (cmp.sim_cn0 or cmp.real_cn0) and cmp.el_deg is not None:
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for lab, dd, mk in (("simulated", cmp.sim_cn0, "o"), ("real", cmp.real_cn0, "x")):
            seen_sys = set()
            for p, m in dd.items():
                if p.system in seen_sys:
                    continue            # the first (reference) signal of each system
                seen_sys.add(p.system)
                ok = np.isfinite(m) & np.isfinite(cmp.el_deg)
                ax.plot(cmp.el_deg[ok], m[ok], mk, ms=3, alpha=0.5, label=f"{lab} {p.label}")
        ax.set_xlabel("elevation [deg]")
        ax.set_ylabel("C/N0 [dB-Hz]")
        if not cmp.real_cn0:
            ax.set_title("C/N0 vs elevation (the real file has no C/N0)")
        elif not cmp.sim_cn0:
            ax.set_title("C/N0 vs elevation (the simulated file has no C/N0)")
        else:
            ax.set_title("C/N0 vs elevation, simulated and real")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        figs["cn0"] = out_dir / "cn0_elevation.png"
        fig.savefig(figs["cn0"], dpi=110)
        plt.close(fig)

    # visibility timeline: 0 none, 1 both, 2 only sim, 3 only real
    state = np.zeros(cmp.seen_sim.shape, dtype=int)
    state[cmp.seen_sim & cmp.seen_real] = 1
    state[cmp.seen_sim & ~cmp.seen_real] = 2
    state[~cmp.seen_sim & cmp.seen_real] = 3
    keep = state.any(axis=0)
    if keep.any():
        st = state[:, keep].T
        fig, ax = plt.subplots(figsize=(10, max(3.0, 0.18 * st.shape[0] + 1.2)))
        cmap = ListedColormap(["white", "tab:green", "tab:blue", "tab:red"])
        x0, x1 = mdates.date2num(t[0]), mdates.date2num(t[-1])
        if x1 == x0:
            x1 = x0 + 1e-5
        ax.imshow(st, aspect="auto", interpolation="nearest", cmap=cmap, vmin=0, vmax=3,
                  extent=(x0, x1, st.shape[0] - 0.5, -0.5))
        ax.xaxis_date()
        ax.xaxis.set_major_formatter(mdates.DateFormatter("%H:%M"))
        ax.set_yticks(range(st.shape[0]))
        ax.set_yticklabels(cmp.sv[keep], fontsize=6)
        from matplotlib.patches import Patch

        ax.legend(handles=[Patch(color="tab:green", label="both"), Patch(color="tab:blue", label="only simulated"),
                           Patch(color="tab:red", label="only real")], fontsize=7, loc="upper right",
                  bbox_to_anchor=(1.0, 1.12), ncol=3)
        ax.set_xlabel("GPS time")
        ax.set_title("tracked satellites" + (f" above {cmp.mask_deg:g} deg" if cmp.mask_deg > 0 else ""), loc="left")
        fig.tight_layout()
        figs["visibility"] = out_dir / "visibility.png"
        fig.savefig(figs["visibility"], dpi=110)
        plt.close(fig)

    # horizontal positions
    if cmp.sol_sim is not None and cmp.sol_real is not None:
        ref = cmp.truth_ecef_m if cmp.truth_ecef_m is not None else cmp.sol_real.pos_ecef_m
        fig, ax = plt.subplots(figsize=(6, 6))
        for lab, sol, mk in (("simulated", cmp.sol_sim, "o"), ("real", cmp.sol_real, "x")):
            enu = enu_errors_m(sol.pos_ecef_m, ref)
            ok = np.all(np.isfinite(enu), axis=1)
            ax.plot(enu[ok, 0], enu[ok, 1], mk, ms=4, alpha=0.7, label=f"{lab} ({ok.sum()} fixes)")
        ax.plot([0], [0], "k+", ms=14, mew=2, label="truth" if cmp.truth_ecef_m is not None else "real solution")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("east [m]")
        ax.set_ylabel("north [m]")
        ax.set_title(f"single point solutions ({cmp.sol_sim.solver})")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        figs["positions"] = out_dir / "positions.png"
        fig.savefig(figs["positions"], dpi=110)
        plt.close(fig)
    return figs


def write_report(cmp: Comparison, out_dir) -> Path:
    """``out_dir/report.md`` with its figures; returns the report path."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    figs = write_figures(cmp, out_dir)
    L = ["# Simulated vs real observations", ""]
    L += [f"- simulated: `{cmp.sim.source}` ({cmp.sim.kind}, {len(cmp.sim.time)} epochs, systems {cmp.sim.systems})",
          f"- real: `{cmp.real.source}` ({cmp.real.kind}, {len(cmp.real.time)} epochs read, systems "
          f"{cmp.real.systems})",
          f"- common epochs: {len(cmp.time)} ({str(cmp.time[0])[:19]} .. {str(cmp.time[-1])[:19]} GPS); "
          f"only simulated {cmp.epochs_only_sim}, only real {cmp.epochs_only_real} (real read over the simulated "
          f"span)",
          f"- systems compared: {cmp.systems or '-'}; only simulated: {cmp.systems_only_sim or '-'}; "
          f"only real: {cmp.systems_only_real or '-'}", ""]
    L += ["## Signals", ""]
    L += _md_table(["system", "simulated", "real"], [[p.system, p.sim_code, p.real_code] for p in cmp.pairs])
    L += ["## Method", ""]
    for name, kr in cmp.kinds.items():
        L.append(f"- **{name}** [{UNITS[name]}]: {DESCRIPTION[name]}."
                 + ("" if kr.available else f" **Unavailable**: {kr.reason}."))
    code = cmp.kinds["code"]
    if code.available:
        L.append(f"- Receiver clock reference system: {code.ref_system}; inter-system biases (code, m): "
                 + ", ".join(f"{s} {_f(v)}" for s, v in code.isb.items()) + ".")
        clk = code.clock[np.isfinite(code.clock)]
        if clk.size:
            L.append(f"- Removed per-epoch code offset (sim - real receiver clock): median {_f(np.median(clk))} m, "
                     f"span {_f(clk.max() - clk.min())} m.")
    L.append("- Signals other than the first of each system keep the inter-frequency (differential code) bias "
             "between the two receivers: it shows as their mean.")
    if cmp.mask_deg > 0:
        L.append(f"- Tracked-satellite sets: above {cmp.mask_deg:g} deg where the broadcast ephemeris gives an "
                 "elevation; satellites without a healthy record keep every epoch.")
    L.append("- Statistics leave out gross errors (|residual| above "
             + ", ".join(f"{k_} {v:g} {UNITS[k_]}" for k_, v in GROSS_LIMITS.items() if math.isfinite(v))
             + "), counted in column 'gross'.")
    L.append("")

    L += ["## Differences per system and signal", ""]
    rows = []
    for name, kr in cmp.kinds.items():
        if not kr.available:
            rows.append([name, "all", "unavailable", "", "", "", "", ""])
            continue
        for s in cmp.systems:
            for p in cmp.pairs:
                if p.system != s or p not in kr.residuals:
                    continue
                st = cmp.stats(name, p)
                rows.append([name, p.label, st["n"], st["n_gross"], _f(st["mean"]), _f(st["rms"]), _f(st["std"]),
                             UNITS[name]])
            st = cmp.system_stats(name, s)
            if st["n"] or st["n_gross"]:
                rows.append([name, f"**{s} all**", st["n"], st["n_gross"], _f(st["mean"]), _f(st["rms"]),
                             _f(st["std"]), UNITS[name]])
    L += _md_table(["kind", "signal", "count", "gross", "mean", "RMS", "std", "unit"], rows)

    L += ["## Differences per satellite", ""]
    for s in cmp.systems:
        rows = []
        for p in cmp.pairs:
            if p.system != s:
                continue
            for sv in [v for v in cmp.sv.tolist() if v[0] == s]:
                cells = [sv, p.label]
                any_ = False
                for name, kr in cmp.kinds.items():
                    if not kr.available or p not in kr.residuals:
                        cells += ["-", "-", "-"]
                        continue
                    st = cmp.stats(name, p, sv)
                    any_ |= bool(st["n"] or st["n_gross"])
                    cells += [st["n"] + st["n_gross"], _f(st["mean"]), _f(st["rms"])]
                if any_:
                    rows.append(cells)
        if rows:
            L += [f"### {s}", ""]
            hdr = ["sv", "signal"]
            for name in cmp.kinds:
                hdr += [f"{name} n", f"{name} mean", f"{name} RMS"]
            L += _md_table(hdr, rows)

    vis = cmp.visibility()
    L += ["## Tracked satellites", ""]
    L.append("Satellite-epochs with a code observation" + (f", above {cmp.mask_deg:g} deg elevation where the "
                                                           "ephemeris gives one" if cmp.mask_deg > 0 else "")
             + f": both {vis['n_both']}, only simulated {vis['n_only_sim']}, only real {vis['n_only_real']}.")
    L.append("")
    L += _md_table(["system", "Jaccard"], [[s, _f(v)] for s, v in vis["jaccard"].items()])
    L.append(f"- Seen only by the simulation (never by the real receiver): {', '.join(vis['only_sim_svs']) or 'none'}")
    L.append(f"- Seen only by the real receiver (never simulated): {', '.join(vis['only_real_svs']) or 'none'}")
    L.append("")
    rows = [[s, c["both"], c["only_sim"], c["only_real"]] for s, c in vis["per_sv"].items()
            if c["only_sim"] or c["only_real"]]
    if rows:
        L += ["Satellites with epochs seen by one side only:", ""]
        L += _md_table(["sv", "both", "only sim", "only real"], rows)

    L += ["## Positions", ""]
    if cmp.sol_sim is None:
        L += ["No position solutions (give broadcast navigation files with --nav).", ""]
    else:
        L.append(f"Single point solutions of both files by {cmp.sol_sim.solver} (broadcast ephemeris, Klobuchar "
                 "ionosphere, Saastamoinen troposphere, 10 deg mask) over the common epochs. "
                 + (f"Truth: {cmp.truth_label}." if cmp.truth_label else "No truth."))
        if cmp.position_note:
            L.append(cmp.position_note)
        L.append("")
        rows = []
        for lab, st in cmp.positions().items():
            if st.get("n"):
                rows.append([lab.replace("_", " "), st["n"], _f(st["mean_e_m"]), _f(st["mean_n_m"]),
                             _f(st["mean_u_m"]), _f(st["rms_h_m"]), _f(st["rms_v_m"]), _f(st["p95_h_m"])])
            else:
                rows.append([lab.replace("_", " "), 0, "-", "-", "-", "-", "-", "-"])
        L += _md_table(["solutions", "epochs", "mean E [m]", "mean N [m]", "mean U [m]", "RMS horizontal [m]",
                        "RMS vertical [m]", "95 % horizontal [m]"], rows)

    L += ["## Figures", ""]
    captions = {"code": "Pseudorange difference per satellite", "cn0": "C/N0 against elevation",
                "visibility": "Tracked satellites (green both, blue only simulated, red only real)",
                "positions": "Horizontal positions"}
    for key, path in figs.items():
        L += [f"![{captions[key]}]({path.name})", ""]
    if "cn0" not in figs:
        L += ["(No C/N0 figure: " + ("no C/N0 on either side" if not (cmp.sim_cn0 or cmp.real_cn0)
                                     else "no elevations without --nav") + ".)", ""]
    path = out_dir / "report.md"
    path.write_text("\n".join(L))
    return path
