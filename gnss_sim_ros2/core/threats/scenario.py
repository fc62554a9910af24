"""The scenario file: timed threat events (jammers, spoofers, receiver faults), read and validated once.

One YAML schema for ``gnss-sim simulate --scenario``, ``gnss-sim run --scenario`` and the launch argument
``scenario:=`` (parameter ``scenario``)::

    version: 1
    events:
      - type: jammer                  # a transmitter in the world
        name: car_ppd                 # optional (default: jammer0, spoofer1, ...; unique)
        position: [30.0, -5.0, 1.0]   # position_type world (x, y, z [m] in the world frame, default) or
        position_type: world          #   llh (latitude [deg], longitude [deg], ellipsoidal height [m])
        path: [[0, -50, -5, 1], [100, 50, -5, 1]]   # optional instead of position: rows t_s, then 3 numbers
        eirp_dbw: -40.0
        center_hz: 1575.42e6
        bandwidth_hz: 2.0e6           # 0: a CW tone at center_hz
        start_s: 10.0                 # seconds after the run start
        end_s: 70.0                   # .inf: to the end of the run
      - type: spoofer
        position: [0, 40, 2]
        eirp_dbw: -60.0
        start_s: 100
        end_s: 200
        false_position: [100, 0, 0]   # or a path of rows t_s, 3 numbers (false_position_type world | llh)
        false_time_offset_s: 0.0
        systems: GE                   # default every system
        power_advantage_db: 3.0
        mode: simulate                # simulate | meacon (meacon: the real signals re-broadcast delay_s later)
        delay_s: 0.0
      - type: fault
        kind: position_offset         # off | stuck | position_offset | clock_jump_s | satellite_clock_step_m
        offset_enu_m: [10, 0, 0]      #   | satellite_ramp_mps | bad_ephemeris (parameters: FAULT_KINDS)
        start_s: 30
        end_s: 60

Every error names the file, the line and the key path (``events[2].eirp_dbw``); unknown keys are refused.
"""
from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..receiver.profile_file import _line, _loader, _path_text, read_yaml
from ..vocabulary import SYSTEMS

SCHEMA_VERSION = 1
POSITION_TYPES = ("world", "llh")
SPOOFER_MODES = ("simulate", "meacon")
#: largest |false_time_offset_s| and delay_s [s]: the receiver here does not re-steer its clock (and its epoch tags)
#: to a false time, so the offset stays in its ranges (c x 10 ms = 3000 km: pseudoranges stay positive)
MAX_SPOOF_TIME_S = 0.01
#: fault kind -> its own keys (besides type, name, kind, start_s, end_s)
FAULT_KINDS = {
    "off": (),                                   # the receiver outputs nothing
    "stuck": (),                                 # the last output repeated, frozen
    "position_offset": ("offset_enu_m",),        # the fix displaced [m] east, north, up
    "clock_jump_s": ("jump_s",),                 # the receiver clock jumps by jump_s [s]
    "satellite_clock_step_m": ("satellite", "step_m"),    # the satellite's clock off by step_m [m] of range
    "satellite_ramp_mps": ("satellite", "ramp_mps"),      # ... drifting by ramp_mps [m/s] from start_s
    "bad_ephemeris": ("satellite", "error_m"),   # the broadcast orbit the receiver uses off radially [m]
}
_COMMON = ("type", "name", "start_s", "end_s")
_PLACED = ("position", "position_type", "path", "eirp_dbw")
_KEYS = {
    "jammer": (*_COMMON, *_PLACED, "center_hz", "bandwidth_hz"),
    "spoofer": (*_COMMON, *_PLACED, "false_position", "false_position_type", "false_time_offset_s", "systems",
                "power_advantage_db", "mode", "delay_s"),
}
#: a satellite id as RINEX 3 writes it: system letter and a two-digit PRN / slot, 01-99 (RINEX 3.05, 4.1)
_SV_RE = re.compile(r"^[GRECJI](?!00)\d{2}$")


class ScenarioError(ValueError):
    """A scenario file that cannot be used; the message names the file, the line and the key."""


@dataclass(frozen=True)
class Track:
    """A position, fixed or along a path: ``t_s`` (P,) seconds after the run start, ``pos`` (P, 3) in ``frame``
    (world: x, y, z [m]; llh: latitude [deg], longitude [deg], height [m]); held before the first and after
    the last row, linear in between."""

    t_s: np.ndarray
    pos: np.ndarray
    frame: str = "world"

    def at(self, t_s):
        """(K, 3) positions at run times ``t_s`` (K,) (or (3,) for a scalar)."""
        t = np.asarray(t_s, dtype=float)
        if len(self.t_s) == 1:
            out = np.broadcast_to(self.pos[0], (*t.shape, 3)).copy()
        else:
            out = np.stack([np.interp(t, self.t_s, self.pos[:, i]) for i in range(3)], axis=-1)
        return out


@dataclass(frozen=True)
class Event:
    """What every event has: its name, type and active window [start_s, end_s) after the run start."""

    name: str
    type: str
    start_s: float
    end_s: float

    def active(self, t_s):
        """Bool (array like ``t_s``): the event is active at run times ``t_s``."""
        t = np.asarray(t_s, dtype=float)
        return (t >= self.start_s) & (t < self.end_s)


@dataclass(frozen=True)
class JammerEvent(Event):
    track: Track = None
    eirp_dbw: float = 0.0
    center_hz: float = 0.0
    #: 0: a continuous-wave tone
    bandwidth_hz: float = 0.0


@dataclass(frozen=True)
class SpooferEvent(Event):
    track: Track = None
    eirp_dbw: float = 0.0
    false_track: Track = None
    false_time_offset_s: float = 0.0
    systems: str = "".join(SYSTEMS)
    power_advantage_db: float = 3.0
    mode: str = "simulate"
    #: meaconing: the delay of the re-broadcast [s]
    delay_s: float = 0.0


@dataclass(frozen=True)
class FaultEvent(Event):
    kind: str = "off"
    offset_enu_m: tuple = (0.0, 0.0, 0.0)
    jump_s: float = 0.0
    satellite: str = ""
    step_m: float = 0.0
    ramp_mps: float = 0.0
    error_m: float = 0.0


@dataclass(frozen=True)
class Scenario:
    """The events of one scenario file, in file order."""

    events: tuple = ()
    source: str = ""
    #: event name -> 1-based line in the file (for messages about an event at run time)
    lines: dict = field(default_factory=dict)
    #: fault event name -> 1-based line of its ``satellite`` key
    satellite_lines: dict = field(default_factory=dict)

    def of_type(self, cls) -> list:
        return [e for e in self.events if isinstance(e, cls)]

    @property
    def jammers(self) -> list[JammerEvent]:
        return self.of_type(JammerEvent)

    @property
    def spoofers(self) -> list[SpooferEvent]:
        return self.of_type(SpooferEvent)

    @property
    def faults(self) -> list[FaultEvent]:
        return self.of_type(FaultEvent)

    def never_active(self, duration_s: float, where: str) -> list[str]:
        """One message (file, the event's line and key) per event that starts at or after the end of a run of
        ``duration_s`` seconds: it will not be active (a typo in start_s, or a run shortened on purpose: the
        caller warns)."""
        return [f"scenario {self.source}, line {self.lines.get(e.name, '?')}: key 'events[{i}].start_s': event "
                f"'{e.name}' starts at {e.start_s:g} s, at or after the end of the run ({where} = {duration_s:g} s): "
                f"it will not be active" for i, e in enumerate(self.events) if e.start_s >= duration_s]

    def absent_satellites(self, systems: str, svs=None) -> list[str]:
        """One message (file, the event's line and key) per satellite fault that will have no effect: without
        ``svs``, its system is not in ``systems`` (known when the configuration is read); with the run's satellites
        ``svs`` (ids, known once the ephemerides are open), a satellite of ``systems`` not among them (G99).  The
        caller warns."""
        out = []
        for i, e in enumerate(self.events):
            sv = getattr(e, "satellite", "")
            if not sv or (svs is None) != (sv[0] not in systems):
                continue
            if svs is None:
                why = f"system {sv[0]} is not simulated (systems {systems})"
            elif sv in set(svs):
                continue
            else:
                why = f"the run's ephemerides have no {sv} ({sum(s[0] == sv[0] for s in svs)} {sv[0]} satellites)"
            line = self.satellite_lines.get(e.name, self.lines.get(e.name, "?"))
            out.append(f"scenario {self.source}, line {line}: key 'events[{i}].satellite': "
                       f"fault '{e.name}' on {sv}, but {why}: it will have no effect")
        return out

    def needs_scene_frame(self) -> bool:
        """An event placed in world coordinates (a jammer or spoofer): the run needs a georeferenced scene."""
        return any(t is not None and t.frame == "world"
                   for e in self.events for t in (getattr(e, "track", None), getattr(e, "false_track", None)))


def load_scenario(path) -> Scenario:
    """The validated scenario of a YAML file; :class:`ScenarioError` naming file, line and key."""
    p = Path(path).expanduser()
    where = f"scenario {p}"
    doc, node = read_yaml(p, where, _scenario_loader(), ScenarioError)
    return parse_scenario(doc, node, where, source=str(p.resolve()))


@functools.lru_cache(maxsize=1)
def _scenario_loader():
    """The profile files' loader (YAML 1.2 floats) with YAML 1.2 booleans too: only true / false, so that
    ``kind: off`` is the fault kind, not False."""
    base = _loader()
    bool_tag = "tag:yaml.org,2002:bool"

    class Loader(base):
        pass

    Loader.yaml_implicit_resolvers = {c: [(tag, rx) for tag, rx in v if tag != bool_tag]
                                      for c, v in base.yaml_implicit_resolvers.items()}
    Loader.add_implicit_resolver(bool_tag, re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), list("tTfF"))
    return Loader


def parse_scenario(doc, node=None, where: str = "scenario", source: str = "") -> Scenario:
    """The validated scenario of a parsed document (``node``: its composed YAML node, for line numbers)."""
    v = _Validator(node, where)
    if not isinstance(doc, dict):
        v.fail((), "expected a mapping with 'version: 1' and 'events:'")
    v.unknown(doc, (), ("version", "events"))
    if doc.get("version") != SCHEMA_VERSION or isinstance(doc.get("version"), bool):
        v.fail(("version",) if "version" in doc else (),
               f"schema version {doc.get('version')!r}; this gnss_sim reads 'version: {SCHEMA_VERSION}'")
    events = doc.get("events")
    if events is None:
        events = []
    if not isinstance(events, list):
        v.fail(("events",), f"must be a list of events, got {type(events).__name__}")
    out, names, lines, sv_lines = [], set(), {}, {}
    for i, ev in enumerate(events):
        e = _event(v, ev, ("events", i), i)
        if e.name in names:
            v.fail(("events", i, "name"), f"event name {e.name!r} is used twice")
        names.add(e.name)
        lines[e.name] = v.line(("events", i))
        if getattr(e, "satellite", ""):
            sv_lines[e.name] = v.line(("events", i, "satellite"))
        out.append(e)
    return Scenario(tuple(out), source, lines, sv_lines)


class _Validator:
    def __init__(self, node, where: str):
        self.node, self.where = node, where

    def line(self, keys: tuple):
        return _line(self.node, keys) if self.node is not None and keys else None

    def fail(self, keys: tuple, msg: str):
        line = self.line(keys)
        at = f", line {line}" if line else ""
        key = f": key '{_path_text(keys)}'" if keys else ""
        raise ScenarioError(f"{self.where}{at}{key}: {msg}")

    def unknown(self, d: dict, keys: tuple, allowed):
        for k in d:
            if k not in allowed:
                self.fail((*keys, k), f"unknown key {k!r}; allowed here: {', '.join(allowed)}")

    def number(self, d, keys, name, default=None, lo=None, hi=None, finite=True):
        if name not in d:
            if default is None:
                self.fail(keys, f"key {name!r} is missing")
            return float(default)
        x = d[name]
        if isinstance(x, bool) or not isinstance(x, (int, float)) or math.isnan(x):
            self.fail((*keys, name), f"must be a number, got {x!r}")
        x = float(x)
        if finite and not math.isfinite(x):
            self.fail((*keys, name), f"must be finite, got {x!r}")
        if lo is not None and x < lo:
            self.fail((*keys, name), f"is {x!r}; minimum {lo}")
        if hi is not None and x > hi:
            self.fail((*keys, name), f"is {x!r}; maximum {hi}")
        return x

    def choice(self, d, keys, name, choices, default=None):
        x = d.get(name, default)
        if x is None:
            self.fail(keys, f"key {name!r} is missing (one of {', '.join(choices)})")
        if x not in choices:
            self.fail((*keys, name), f"is {x!r}; one of {', '.join(choices)}")
        return x

    def triple(self, d, keys, name):
        x = d[name]
        if (not isinstance(x, list) or len(x) != 3
                or not all(isinstance(a, (int, float)) and not isinstance(a, bool) and math.isfinite(a) for a in x)):
            self.fail((*keys, name), f"must be 3 finite numbers, got {x!r}")
        return tuple(float(a) for a in x)

    def track(self, d, keys, pos_key, path_key, type_key, required=True):
        frame = self.choice(d, keys, type_key, POSITION_TYPES, "world")
        rows_key = path_key if path_key is not None and path_key in d else None
        if rows_key is None and isinstance(d.get(pos_key), list) and d[pos_key] and isinstance(d[pos_key][0], list):
            rows_key = pos_key                       # a path given where a point may be (false_position)
        if rows_key is not None:
            if rows_key != pos_key and pos_key in d:
                self.fail((*keys, path_key), f"give {pos_key!r} or {path_key!r}, not both")
            path_key = rows_key
            rows = d[path_key]
            if not isinstance(rows, list) or not rows:
                self.fail((*keys, path_key), "must be a list of rows [t_s, a, b, c]")
            for r, row in enumerate(rows):
                if (not isinstance(row, list) or len(row) != 4 or not all(
                        isinstance(a, (int, float)) and not isinstance(a, bool) and math.isfinite(a) for a in row)):
                    self.fail((*keys, path_key, r), f"must be 4 finite numbers [t_s, a, b, c], got {row!r}")
            arr = np.array(rows, dtype=float)
            if np.any(np.diff(arr[:, 0]) <= 0):
                self.fail((*keys, path_key), "the times t_s must increase")
            track = Track(arr[:, 0], arr[:, 1:], frame)
        elif pos_key in d:
            track = Track(np.zeros(1), np.array([self.triple(d, keys, pos_key)]), frame)
        elif required:
            self.fail(keys, f"key {pos_key!r} (or {path_key!r}) is missing" if path_key else f"key {pos_key!r} is "
                      "missing")
        else:
            return None
        if frame == "llh" and (np.any(np.abs(track.pos[:, 0]) > 90) or np.any(np.abs(track.pos[:, 1]) > 180)):
            at = path_key if path_key is not None and path_key in d else pos_key
            self.fail((*keys, at), "latitude must be in [-90, 90] and longitude in [-180, 180] degrees")
        return track


def _event(v: _Validator, ev, keys: tuple, i: int) -> Event:
    if not isinstance(ev, dict):
        v.fail(keys, f"an event is a mapping with 'type: jammer | spoofer | fault', got {ev!r}")
    kind_of = v.choice(ev, keys, "type", ("jammer", "spoofer", "fault"))
    name = ev.get("name", f"{kind_of}{i}")
    if not isinstance(name, str) or not name.strip() or not re.fullmatch(r"[A-Za-z0-9_.\-]+", name):
        v.fail((*keys, "name"), f"must be a name of letters, digits, _ . - (no spaces, no comma), got {name!r}")
    start = v.number(ev, keys, "start_s", lo=0.0)
    end = v.number(ev, keys, "end_s", finite=False)
    if end <= start:
        v.fail((*keys, "end_s"), f"end_s = {end} must be after start_s = {start}")
    common = {"name": name, "type": kind_of, "start_s": start, "end_s": end}
    if kind_of == "fault":
        kind = v.choice(ev, keys, "kind", tuple(FAULT_KINDS))
        v.unknown(ev, keys, (*_COMMON, "kind", *FAULT_KINDS[kind]))
        kw = {}
        for key in FAULT_KINDS[kind]:
            if key not in ev:
                v.fail(keys, f"fault {kind!r} needs key {key!r}")
            if key == "offset_enu_m":
                kw[key] = v.triple(ev, keys, key)
            elif key == "satellite":
                sv = ev[key]
                if not isinstance(sv, str) or not _SV_RE.match(sv):
                    v.fail((*keys, key), f"must be a satellite id as RINEX writes it (G05, E11), got {sv!r}")
                kw[key] = sv
            else:
                kw[key] = v.number(ev, keys, key)
        return FaultEvent(**common, kind=kind, **kw)
    v.unknown(ev, keys, _KEYS[kind_of])
    track = v.track(ev, keys, "position", "path", "position_type")
    eirp = v.number(ev, keys, "eirp_dbw", lo=-200.0, hi=100.0)
    if kind_of == "jammer":
        center = v.number(ev, keys, "center_hz", lo=1.0e8, hi=1.0e10)
        bw = v.number(ev, keys, "bandwidth_hz", lo=0.0, hi=1.0e9)
        return JammerEvent(**common, track=track, eirp_dbw=eirp, center_hz=center, bandwidth_hz=bw)
    false_track = v.track(ev, keys, "false_position", None, "false_position_type", required=False)
    mode = v.choice(ev, keys, "mode", SPOOFER_MODES, "simulate")
    if mode == "simulate" and false_track is None:
        v.fail(keys, "a spoofer in mode simulate needs key 'false_position' (a point or a path)")
    systems = ev.get("systems", "".join(SYSTEMS))
    if not isinstance(systems, str) or not systems or any(s not in SYSTEMS for s in systems):
        v.fail((*keys, "systems"), f"must be letters of {''.join(SYSTEMS)}, got {systems!r}")
    return SpooferEvent(**common, track=track, eirp_dbw=eirp, false_track=false_track,
                        false_time_offset_s=v.number(ev, keys, "false_time_offset_s", 0.0, lo=-MAX_SPOOF_TIME_S,
                                                     hi=MAX_SPOOF_TIME_S),
                        systems=systems, power_advantage_db=v.number(ev, keys, "power_advantage_db", 3.0),
                        mode=mode, delay_s=v.number(ev, keys, "delay_s", 0.0, lo=0.0, hi=MAX_SPOOF_TIME_S))
