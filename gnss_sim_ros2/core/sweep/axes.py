"""Sweep axes and their run points (the Cartesian product of every axis).

An axis is a list of values of one input of the scenario; an axis not swept has
one value, ``None``: the scenario's own (configuration file or single option).
Run points are numbered in a fixed order (dates, presets, trajectories, worlds,
then seeds innermost), so the same options always give the same numbering.
"""
from __future__ import annotations

import datetime as _dt
import itertools
import math
import re
from dataclasses import asdict, dataclass

#: the axes in the order of the product (seed innermost)
AXES = ("date", "preset", "trajectory", "world", "seed")

#: the most runs one sweep takes (every axis alone and their product): each run's setup is built in the driving
#: process before the first starts and each writes a folder of RINEX (about 30 MB for an hour at 1 Hz); more: split
#: the sweep (e.g. --seeds 1-10000, then 10001-20000 into another folder)
MAX_SWEEP_RUNS = 10_000

_RANGE = re.compile(r"^\s*(\d+)\s*-\s*(\d+)\s*$")
_INT = re.compile(r"^\s*\d+\s*$")
_DATE_ONLY = re.compile(r"^\s*\d{4}-\d{2}-\d{2}\s*$")


@dataclass(frozen=True)
class RunPoint:
    """One run of a sweep: its number and the value of every axis (None: the scenario's own)."""

    index: int
    seed: int | None = None
    date: str | None = None
    preset: str | None = None
    trajectory: str | None = None
    world: str | None = None

    @property
    def name(self) -> str:
        """Folder name of the run (inside the sweep's runs/ folder)."""
        return f"run{self.index:05d}"

    def inputs(self) -> dict:
        return asdict(self)


def parse_seeds(text: str, option: str = "--seeds") -> list[int]:
    """``1-100``, ``1,5,9``, ``1-10,20-29``: non-negative integers, ranges inclusive, order kept,
    repeats refused; ValueError naming ``option``."""
    out: list[int] = []
    for part in str(text).split(","):
        m = _RANGE.match(part)
        if m:
            lo, hi = int(m.group(1)), int(m.group(2))
            if hi < lo:
                raise ValueError(f"option {option}: range {part.strip()!r} goes down (write {hi}-{lo})")
            _check_count(len(out) + hi - lo + 1, option, f"range {part.strip()!r}")
            out.extend(range(lo, hi + 1))
        elif _INT.match(part):
            out.append(int(part))
        else:
            raise ValueError(f"option {option}: {part.strip()!r} is not a seed (non-negative integer) "
                             f"or a range like 1-100")
    _check_count(len(out), option, "the list")
    dup = _repeated(out)
    if dup:
        raise ValueError(f"option {option}: seed {dup[0]} given twice")
    return out


def _check_count(n: int, option: str, what: str) -> None:
    if n > MAX_SWEEP_RUNS:
        raise ValueError(f"option {option}: {what} gives {n} runs; a sweep takes at most {MAX_SWEEP_RUNS} "
                         f"(MAX_SWEEP_RUNS in core/sweep/axes.py): split it into several sweeps")


def _repeated(values: list) -> list:
    """The values that occur more than once, sorted (one pass: the lists may be MAX_SWEEP_RUNS long)."""
    seen, dup = set(), set()
    for v in values:
        (dup if v in seen else seen).add(v)
    return sorted(dup)


def parse_dates(text: str, default_time: str, option: str = "--dates") -> list[str]:
    """Comma-separated ISO 8601 dates or date-times (GPS time); ``A..B``: every day from date A to date B.

    A date without a time of day takes the scenario's time of day ``default_time`` (``hh:mm:ss``)."""
    out: list[str] = []
    for part in str(text).split(","):
        part = part.strip()
        if ".." in part:
            a, b = (s.strip() for s in part.split("..", 1))
            try:
                d0, d1 = _dt.date.fromisoformat(a), _dt.date.fromisoformat(b)
            except ValueError:
                raise ValueError(f"option {option}: {part!r}: a day range is FIRST..LAST with dates "
                                 f"YYYY-MM-DD") from None
            if d1 < d0:
                raise ValueError(f"option {option}: day range {part!r} goes back in time")
            _check_count(len(out) + (d1 - d0).days + 1, option, f"day range {part!r}")
            out.extend(f"{d0 + _dt.timedelta(days=k)}T{default_time}" for k in range((d1 - d0).days + 1))
        elif _DATE_ONLY.match(part):
            out.append(f"{part}T{default_time}")
        elif part:
            out.append(part)       # a date-time: checked as start_time by the parameter table
        else:
            raise ValueError(f"option {option}: empty item in {text!r}")
    _check_count(len(out), option, "the list")
    dup = _repeated(out)
    if dup:
        raise ValueError(f"option {option}: {dup[0]} given twice")
    return out


def parse_names(text: str, option: str) -> list[str]:
    """Comma-separated names (presets), stripped, none empty, no repeats."""
    out = [s.strip() for s in str(text).split(",")]
    if any(not s for s in out):
        raise ValueError(f"option {option}: empty item in {text!r}")
    dup = sorted({s for s in out if out.count(s) > 1})
    if dup:
        raise ValueError(f"option {option}: {dup[0]!r} given twice")
    return out


def run_points(seeds=None, dates=None, presets=None, trajectories=None, worlds=None) -> list[RunPoint]:
    """Every combination of the axes given (None or empty: not swept), numbered from 1."""
    values = {"date": dates, "preset": presets, "trajectory": trajectories, "world": worlds, "seed": seeds}
    lists = [list(values[a]) if values[a] else [None] for a in AXES]
    n = math.prod(len(v) for v in lists)
    if n > MAX_SWEEP_RUNS:
        option = {"date": "--dates", "preset": "--presets", "trajectory": "--trajectories", "world": "--worlds",
                  "seed": "--seeds"}
        given = " x ".join(f"{option[a]} {len(v)}" for a, v in zip(AXES, lists) if values[a])
        raise ValueError(f"options {given} give {n} runs; a sweep takes at most {MAX_SWEEP_RUNS} "
                         f"(MAX_SWEEP_RUNS in core/sweep/axes.py): split it into several sweeps")
    return [RunPoint(index=i + 1, **dict(zip(AXES, combo)))
            for i, combo in enumerate(itertools.product(*lists))]


def swept_axes(points: list[RunPoint]) -> list[str]:
    """The axes that take more than one value (or any value at all) over ``points``."""
    return [a for a in AXES if any(getattr(p, a) is not None for p in points)]
