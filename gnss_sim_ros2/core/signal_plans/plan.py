"""Signal plans: which signals a satellite transmits on a date (the data file plans.yaml beside this module).

A satellite's signals come from its generation (GPS block, GLONASS-M/M+/K1/K2, Galileo IOV/FOC, BeiDou-2/-3
MEO/IGSO/GEO, QZS, NavIC), and its generation from its PRN and the date, since PRNs are reassigned (G18 was the
IIR-A SVN54 until 2018, a IIA until 2020-03, the GPS III SVN75 since).  A PRN without a row for the date takes
its system's default generation (``defaults`` in the file: GPS III for GPS, GLONASS-M, a Galileo FOC, BeiDou-2 /
BeiDou-3 MEO / BeiDou-3 GEO by PRN range, QZS, NavIC; the reasons are written there).

    plans = default_plans()
    plans.codes("G14", ("1C", "2L", "5Q"), gps_day(t))   # ['1C'] on 2020-06-25 (G14: a IIR-A)
    plans.mask(["G14", "G01"], ["2L", "2L"], t_gps_s)    # [False, True]

The date of an instant is its GPS day (GPS seconds // 86400 from 1980-01-06): the 18 s between GPS time and UTC
are ignored (the table's dates are days).  The file is validated when loaded (``SignalPlanError`` names the
file and the key) and loaded once per path; each satellite's signals are computed once per day (memo).
"""
from __future__ import annotations

import datetime as dt
import functools
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from ..memo import BoundedCache
from ..signals import SIGNALS, SYSTEMS, signal

#: the plans shipped with the package
PLANS_PATH = Path(__file__).with_name("plans.yaml")
#: schema version of the file (its key ``gnss_sim_signal_plans``)
SCHEMA_VERSION = 1
GPS_EPOCH = dt.date(1980, 1, 6)
_SV = re.compile(r"[GRECJI]\d\d")


class SignalPlanError(ValueError):
    """A signal plan file that cannot be used (the message names the file and the key)."""


@dataclass(frozen=True)
class PlanRow:
    """One use of a PRN: from ``start`` to ``end`` (GPS days since 1980-01-06, inclusive; end None: open)."""

    start: int
    end: int | None
    svn: str
    generation: str


def gps_day(t_gps_s) -> int | np.ndarray:
    """GPS day number (days since 1980-01-06) of GPS seconds ``t_gps_s`` (scalar or array)."""
    d = np.floor_divide(np.asarray(t_gps_s, dtype=np.int64), 86400)
    return int(d) if d.ndim == 0 else d


def _day_number(d: dt.date) -> int:
    return (d - GPS_EPOCH).days


class SignalPlans:
    """The generations, defaults and PRN rows of one plan file (see :func:`load_plans`)."""

    def __init__(self, generations: dict, defaults: dict, satellites: dict, path: str = ""):
        #: system -> generation -> frozenset of Signal names
        self.generations = generations
        #: system -> [(first PRN, last PRN, generation)]
        self.defaults = defaults
        #: PRN -> [PlanRow] in start order
        self.satellites = satellites
        self.path = path
        self._names = BoundedCache(4096)
        self._codes = BoundedCache(4096)

    def generation(self, sv: str, day: int) -> str:
        """Generation of satellite ``sv`` ("G05") on GPS day ``day`` (the later row on a day with two)."""
        gen = None
        for row in self.satellites.get(sv, ()):
            if row.start <= day and (row.end is None or day <= row.end):
                gen = row.generation
        if gen is not None:
            return gen
        prn = int(sv[1:])
        for first, last, g in self.defaults.get(sv[0], ()):
            if first <= prn <= last:
                return g
        raise SignalPlanError(f"{self.path}: key 'defaults.{sv[0]}': no default generation covers {sv}")

    def signal_names(self, sv: str, day: int) -> frozenset:
        """Names (core/signals.py ``Signal.name``) of the signals ``sv`` transmits on GPS day ``day``."""
        key = (sv, day)
        hit = self._names.get(key)
        if hit is None:
            hit = self._names.put(key, self.generations[sv[0]][self.generation(sv, day)])
        return hit

    def codes(self, sv: str, codes: tuple, day: int) -> list[str]:
        """The RINEX codes of ``codes`` ("1C", "2L", ...) that ``sv`` transmits on GPS day ``day``, in order."""
        key = (sv, codes, day)
        hit = self._codes.get(key)
        if hit is None:
            names = self.signal_names(sv, day)
            hit = self._codes.put(key, [c for c in codes if _name(sv[0], c) in names])
        return hit

    def mask(self, svs, codes, t_gps_s) -> np.ndarray:
        """Per row, whether satellite ``svs[i]`` transmits signal ``codes[i]`` at GPS seconds ``t_gps_s``
        (scalar, or one per row).  Unknown codes raise ValueError (core/signals.py ``signal``)."""
        svs = np.asarray(svs, dtype="<U3")
        codes = np.asarray(codes, dtype="<U2")
        days = np.broadcast_to(np.asarray(gps_day(t_gps_s)), svs.shape)
        out = np.empty(svs.shape, dtype=bool)
        memo: dict = {}
        for i, (sv, code, day) in enumerate(zip(svs.tolist(), codes.tolist(), days.tolist())):
            k = (sv, code, day)
            v = memo.get(k)
            if v is None:
                v = memo[k] = _name(sv[0], code) in self.signal_names(sv, day)
            out[i] = v
        return out


@functools.cache
def _name(system: str, code: str) -> str:
    """Signal.name of (system, code); a code the table does not know raises ValueError."""
    return signal(system, code).name


def default_plans() -> SignalPlans:
    """The plans shipped with the package (plans.yaml), loaded once."""
    return load_plans(PLANS_PATH)


def load_plans(path) -> SignalPlans:
    """Read and validate a signal plan file (cached per path); SignalPlanError names the file and key."""
    return _load(str(Path(path)))


@functools.lru_cache(maxsize=8)
def _load(path: str) -> SignalPlans:
    try:
        with open(path, encoding="utf-8") as f:
            doc = yaml.load(f, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))   # libyaml: 10x faster
    except OSError as e:
        raise SignalPlanError(f"{path}: cannot read the signal plan file: {e.strerror}") from None
    except yaml.YAMLError as e:
        raise SignalPlanError(f"{path}: not valid YAML: {e}") from None
    return parse_plans(doc, path)


def parse_plans(doc, path: str = "<plans>") -> SignalPlans:
    """Validate a loaded plan document (see plans.yaml) and build the :class:`SignalPlans`."""
    def fail(key, msg):
        raise SignalPlanError(f"{path}: key '{key}': {msg}")

    if not isinstance(doc, dict):
        raise SignalPlanError(f"{path}: expected a mapping at the top level, found {type(doc).__name__}")
    if doc.get("gnss_sim_signal_plans") != SCHEMA_VERSION:
        fail("gnss_sim_signal_plans", f"expected {SCHEMA_VERSION}, found {doc.get('gnss_sim_signal_plans')!r}")
    unknown = set(doc) - {"gnss_sim_signal_plans", "generations", "defaults", "satellites"}
    if unknown:
        fail(sorted(unknown)[0], "unknown key (expected gnss_sim_signal_plans, generations, defaults, satellites)")
    names_of = {s: {x.name for (ss, _), x in SIGNALS.items() if ss == s} for s in SYSTEMS}

    gens_doc = doc.get("generations")
    if not isinstance(gens_doc, dict):
        fail("generations", "expected a mapping system -> generation -> {signals: [...]}")
    generations: dict[str, dict[str, frozenset]] = {}
    for s, gens in gens_doc.items():
        if s not in SYSTEMS:
            fail(f"generations.{s}", f"not a system letter of {SYSTEMS}")
        if not isinstance(gens, dict) or not gens:
            fail(f"generations.{s}", "expected a mapping generation -> {signals: [...]}")
        generations[s] = {}
        for g, spec in gens.items():
            key = f"generations.{s}.{g}.signals"
            sigs = spec.get("signals") if isinstance(spec, dict) else None
            if not isinstance(sigs, list) or not all(isinstance(x, str) for x in sigs):
                fail(key, "expected a list of signal names")
            bad = [x for x in sigs if x not in names_of[s]]
            if bad:
                fail(key, f"{bad[0]!r} is not a signal of system {s} (known: {', '.join(sorted(names_of[s]))})")
            generations[s][str(g)] = frozenset(sigs)

    defs_doc = doc.get("defaults")
    if not isinstance(defs_doc, dict):
        fail("defaults", "expected a mapping system -> [{prns: [first, last], generation: ...}]")
    defaults: dict[str, list] = {}
    for s in SYSTEMS:
        entries = defs_doc.get(s)
        if not isinstance(entries, list) or not entries:
            fail(f"defaults.{s}", "missing: every system needs a default generation for PRNs without a row")
        defaults[s] = []
        for i, e in enumerate(entries):
            key = f"defaults.{s}[{i}]"
            prns = e.get("prns") if isinstance(e, dict) else None
            if not (isinstance(prns, list) and len(prns) == 2 and all(isinstance(p, int) for p in prns)
                    and 1 <= prns[0] <= prns[1] <= 99):
                fail(key, "expected prns: [first, last] (integers 1..99, first <= last)")
            g = e.get("generation")
            if g not in generations.get(s, {}):
                fail(key, f"generation {g!r} is not one of generations.{s}")
            defaults[s].append((prns[0], prns[1], g))

    sats_doc = doc.get("satellites")
    if not isinstance(sats_doc, dict):
        fail("satellites", "expected a mapping PRN -> [[from, until, SVN, generation], ...]")
    satellites: dict[str, list[PlanRow]] = {}
    for sv, rows in sats_doc.items():
        if not (isinstance(sv, str) and _SV.fullmatch(sv)):
            fail(f"satellites.{sv}", "not a satellite id like G05")
        if not isinstance(rows, list):
            fail(f"satellites.{sv}", "expected a list of rows [from, until, SVN, generation]")
        out = []
        for i, row in enumerate(rows):
            key = f"satellites.{sv}[{i}]"
            if not (isinstance(row, list) and len(row) == 4):
                fail(key, "expected [from, until, SVN, generation]")
            start, end = _date(row[0], key, fail), (None if row[1] is None else _date(row[1], key, fail))
            if end is not None and end < start:
                fail(key, f"until {row[1]} is before from {row[0]}")
            if row[3] not in generations.get(sv[0], {}):
                fail(key, f"generation {row[3]!r} is not one of generations.{sv[0]}")
            out.append(PlanRow(start, end, str(row[2]), row[3]))
        satellites[sv] = sorted(out, key=lambda r: r.start)
    return SignalPlans(generations, defaults, satellites, path)


def _date(v, key, fail) -> int:
    if isinstance(v, dt.datetime):
        v = v.date()
    if isinstance(v, dt.date):
        return _day_number(v)
    try:
        return _day_number(dt.date.fromisoformat(str(v)))
    except ValueError:
        fail(key, f"{v!r} is not a date YYYY-MM-DD")
