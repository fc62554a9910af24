"""Does an ephemeris provider serve the span to simulate?  Checked before anything is written.

:func:`check_coverage` samples ``provider.states(t)`` over [start, start + duration] (every
``step_s``, 60 s by default, at most ``MAX_SAMPLES`` samples) and

- raises :class:`EphemerisCoverageError` (a ValueError naming the files, the span and why) when
  no satellite of the requested systems is served at any sample: all records unhealthy, records of
  another day, a file without the systems asked for;
- warns (:class:`EphemerisCoverageWarning`) for each span with no satellite at all, for satellites
  served over part of the span only (SP3 gaps, broadcast gaps: the satellites and the spans named),
  for satellites listed in SP3 files without a position, for satellites never served (unhealthy
  over the span, or in the navigation files but not in the SP3 files).

The returned :class:`Coverage` holds the same messages (``warnings``) for a summary.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from ..time import GnssTime

#: sampling step of the check [s] and the most samples taken (longer spans: a coarser step)
STEP_S = 60.0
MAX_SAMPLES = 1000


class EphemerisCoverageError(ValueError):
    """No usable ephemeris for the span asked for."""


class EphemerisCoverageWarning(UserWarning):
    """Part of the span, or some satellites, without ephemeris."""


@dataclass
class Coverage:
    """Which satellites the provider serves at each sample of the span."""

    start: GnssTime
    duration_s: float
    step_s: float
    t_s: np.ndarray                          #: (T,) sample offsets from start [s]
    served: dict[str, np.ndarray]            #: sv -> (T,) bool
    warnings: list[str] = field(default_factory=list)

    @property
    def n_served(self) -> np.ndarray:
        """(T,) satellites served per sample."""
        if not self.served:
            return np.zeros(len(self.t_s), dtype=int)
        return np.sum(np.vstack(list(self.served.values())), axis=0)


def _clock(start: GnssTime, off_s: float) -> str:
    return (start + float(off_s)).isoformat()[:19].replace("T", " ")


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) sample index of each run of True."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), (np.flatnonzero(d == -1) - 1).tolist()))


def _span_text(start: GnssTime, t_s: np.ndarray, i0: int, i1: int) -> str:
    """The span of samples i0..i1 without ephemeris, from the last served sample before to the first after."""
    a = t_s[i0 - 1] if i0 > 0 else t_s[0]
    b = t_s[i1 + 1] if i1 + 1 < len(t_s) else t_s[-1]
    return f"{_clock(start, a)} .. {_clock(start, b)} GPST"


def _why_not(provider, start: GnssTime, t_mid: float, svs) -> str:
    """Reason from the provider's diagnostics (broadcast: unhealthy / gap / stale), else ""."""
    diag = getattr(provider, "diagnostics", None)
    if diag is None or not svs:
        return ""
    try:
        d = diag(start + float(t_mid), svs=list(svs))
    except (TypeError, ValueError):
        return ""
    parts = [f"{len(getattr(d, n))} {label}" for n, label in
             (("unhealthy", "unhealthy"), ("gap", "between records"), ("stale", "after their last record"),
              ("missing", "without any record")) if getattr(d, n)]
    return ", ".join(parts)


def coverage(provider, start: GnssTime, duration_s: float, systems: str = "GRECJI",
             step_s: float | None = None) -> Coverage:
    """Sample the provider over the span (no warnings, no error)."""
    duration_s = max(float(duration_s), 0.0)
    step = float(step_s) if step_s else max(STEP_S, duration_s / MAX_SAMPLES)
    t_s = np.arange(0.0, duration_s + 1e-9, step)
    if t_s[-1] < duration_s:
        t_s = np.append(t_s, duration_s)
    names = list(provider.svs(systems))
    col = {s: j for j, s in enumerate(names)}
    grid = np.zeros((len(t_s), len(names)), dtype=bool)
    for i, off in enumerate(t_s.tolist()):
        st = provider.states(start + off, systems=systems)
        for s in np.asarray(st.sv).tolist():
            j = col.get(s)
            if j is not None:
                grid[i, j] = True
    return Coverage(start, duration_s, step, t_s, {s: grid[:, j] for s, j in col.items()})


def check_coverage(provider, start: GnssTime, duration_s: float, systems: str = "GRECJI", files=(),
                   step_s: float | None = None, warn: bool = True) -> Coverage:
    """:func:`coverage`, then the error or warnings of the module doc (``files``: named in the messages)."""
    cov = coverage(provider, start, duration_s, systems, step_s)
    names = ", ".join(str(f) for f in files) or f"ephemeris source {getattr(provider, 'source', '?')!r}"
    span = f"{_clock(start, 0.0)} .. {_clock(start, cov.duration_s)} GPST"
    n = cov.n_served
    if not n.any():
        known = sorted(cov.served)
        why = _why_not(provider, start, 0.5 * cov.duration_s, known)
        have = getattr(provider, "time_span", lambda: None)()
        detail = [f"{len(known)} satellites of systems {systems} in the data"
                  + (f" ({why} at mid-span)" if why else "") if known else
                  f"no record of systems {systems} within hours of the span (records of other days or systems)"]
        if have is not None:
            detail.append(f"the data serve {_clock(have[0], 0.0)} .. {_clock(have[1], 0.0)} GPST")
        raise EphemerisCoverageError(f"{names}: no usable ephemeris for {span} (systems {systems}): "
                                     + "; ".join(detail))
    msgs = []
    for i0, i1 in _runs(n == 0):
        msgs.append(f"{names}: no satellite has an ephemeris over {_span_text(start, cov.t_s, i0, i1)}")
    never = [s for s, m in cov.served.items() if not m.any()]
    if never:
        why = _why_not(provider, start, 0.5 * cov.duration_s, never)
        msgs.append(f"{names}: {len(never)} satellite{'s' if len(never) > 1 else ''} never served over {span}"
                    + (f" ({why} at mid-span)" if why else "") + f": {' '.join(never)}")
    by_span: dict[str, list[str]] = {}
    for s, m in cov.served.items():
        if m.any() and not m.all():
            for i0, i1 in _runs(~m):
                by_span.setdefault(_span_text(start, cov.t_s, i0, i1), []).append(s)
    if by_span:
        msgs.append(f"{names}: satellites without ephemeris over part of the span: "
                    + "; ".join(f"{' '.join(svs)} {text}" for text, svs in by_span.items()))
    listed = getattr(provider, "missing_svs", None) or getattr(getattr(provider, "precise", None), "missing_svs",
                                                               None)
    if listed is not None and listed(systems):
        msgs.append(f"{names}: satellites listed without any position: {' '.join(listed(systems))}")
    precise, brdc = getattr(provider, "precise", None), getattr(provider, "broadcast", None)
    if precise is not None and brdc is not None:
        only_nav = sorted(set(brdc.svs(systems)) - set(precise.svs(systems)))
        if only_nav:
            msgs.append(f"{names}: in the navigation files but not in the SP3 files (not simulated): "
                        f"{' '.join(only_nav)}")
    cov.warnings = msgs
    if warn:
        for m in msgs:
            warnings.warn(m, EphemerisCoverageWarning, stacklevel=2)
    return cov
