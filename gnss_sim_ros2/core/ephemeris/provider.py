"""Open the ephemeris source a configuration names: the one entry point that
the ephemeris node, ``gnss-sim simulate`` and the benchmarks share.

Sources: ``synthetic`` (nominal constellation as broadcast records with a
RINEX file's rounding, served by the broadcast path; no file read), ``broadcast`` (RINEX navigation
files), ``sp3`` (precise orbits and clocks; with navigation files, their
group delays and health on top), ``download`` (daily broadcast
files from public IGS archives, cached).  Only the time span simulated is
loaded (with a margin for the fit intervals).  The provider is then checked
against the span (coverage.check_coverage): no usable ephemeris is an error
naming the files and the span, gaps and missing satellites are warnings.
"""
from __future__ import annotations

from pathlib import Path

from ..input_file import not_a_file
from ..time import GnssTime
from .coverage import check_coverage

#: loaded before/after the simulated span [s]: a 4 h fit interval plus GLONASS/BeiDou records
LOAD_MARGIN_S = 4 * 3600.0


def open_ephemeris(source: str, start: GnssTime, duration_s: float, systems: str = "GRECJI",
                   nav_files=(), sp3_files=(), clk_files=(), workdir: str | Path | None = None,
                   cache_dir: str | Path | None = None, check: bool = True):
    """A provider with ``states(t, svs, systems)``/``states_at(svs, t)`` for the span.

    Returns (provider, nav_paths) where ``nav_paths`` are the RINEX navigation
    files behind it (to copy next to the RINEX observations); for sp3 with
    navigation files the precise orbits carry the broadcast group delays
    (precise_broadcast.PreciseWithBroadcastGroupDelay), without them none (and
    no navigation file to write); the synthetic source returns none either (its records never go
    through text).  ``workdir``: a folder for files a source may need (none does today).
    ``check``: raise EphemerisCoverageError when nothing of ``systems`` is served over the span, warn
    about gaps (coverage.check_coverage).
    """
    provider, paths, files = _open(source, start, duration_s, systems, nav_files, sp3_files, clk_files, workdir,
                                   cache_dir)
    if check:
        check_coverage(provider, start, duration_s, systems, files)
    return provider, paths


def _open(source, start, duration_s, systems, nav_files, sp3_files, clk_files, workdir, cache_dir):
    """(provider, navigation paths, every file read) of ``source``."""
    from .broadcast import BroadcastEphemeris

    end = start + float(duration_s)
    lo, hi = start - LOAD_MARGIN_S, end + LOAD_MARGIN_S
    if source == "synthetic":
        from .sanity import drop_outliers
        from .synthetic import SyntheticConstellation

        # the records as the RINEX file would hold them, without writing and parsing it (synthetic.py)
        syn = SyntheticConstellation(start - 7200.0, float(duration_s) + 4 * 3600.0, systems=systems)
        nav = drop_outliers(syn.nav())
        return BroadcastEphemeris(nav), [], list(nav.paths)
    if source == "broadcast":
        if not nav_files:
            raise ValueError("ephemeris source 'broadcast' needs nav_files (RINEX navigation files)")
        for f in nav_files:
            if (why := not_a_file(f)) is not None:
                raise ValueError(f"navigation file {f}: {why} (parameter nav_files)")
        paths = [Path(f) for f in nav_files]
        return BroadcastEphemeris.from_files(list(nav_files), start=lo, end=hi), paths, paths
    if source == "sp3":
        from .sp3 import Sp3Ephemeris

        if not sp3_files:
            raise ValueError("ephemeris source 'sp3' needs sp3_files")
        for f in list(sp3_files) + list(clk_files):
            if (why := not_a_file(f)) is not None:
                raise ValueError(f"file {f}: {why} (parameter sp3_files/clk_files)")
        precise = Sp3Ephemeris.from_files(list(sp3_files), list(clk_files), start=lo, end=hi)
        files = [Path(f) for f in list(sp3_files) + list(clk_files)]
        if not nav_files:
            return precise, [], files
        # with navigation files: their group delays, clock references and health on top (precise_broadcast)
        from .precise_broadcast import PreciseWithBroadcastGroupDelay

        brdc, paths = open_ephemeris("broadcast", start, duration_s, systems, nav_files, check=False)
        return PreciseWithBroadcastGroupDelay(precise, brdc, start, duration_s), paths, files + paths
    if source == "download":
        import datetime as _dt

        from .download import fetch_broadcast_nav

        paths = []
        day = start.to_datetime().date()
        while day <= end.to_datetime().date():
            paths.append(fetch_broadcast_nav(day, cache_dir=cache_dir))
            day += _dt.timedelta(days=1)
        return BroadcastEphemeris.from_files(paths, start=lo, end=hi), paths, paths
    raise ValueError(f"unknown ephemeris source {source!r} (parameter source: synthetic, broadcast, sp3, download)")
