"""Download of daily broadcast navigation files from public IGS data archives.

    path = fetch_broadcast_nav("2022-01-01")            # -> ~/.cache/gnss_sim/brdc/2022/001/<file>.rnx
    eph = BroadcastEphemeris.from_files([path])

URL templates are tried in order; the first file found wins.  Fields:
``{yyyy}`` year, ``{yy}`` 2-digit year, ``{ddd}`` day of year, ``{mm}`` month,
``{dd}`` day of month, ``{gpsweek}`` GPS week, ``{dow}`` GPS day of week (0 = Sunday).
Compressed files (``.gz``, Unix compress ``.Z``) are decompressed into the
cache, and the result must be a RINEX navigation file (header line
``RINEX VERSION / TYPE``), else a clear error names the URL and the date.

Default templates (no credentials needed), in order:
1. BKG IGS data centre, IGS combined multi-GNSS broadcast ephemeris (RINEX 3/4
   "BRDC00IGS_R" daily merged file, IGS products since 2022); the directory
   layout ``root_ftp/IGS/BRDC/yyyy/ddd/`` is BKG's published IGS archive
   (https://igs.bkg.bund.de/root_ftp/IGS/BRDC/).
2. same archive, DLR/TUM "BRDC00WRD" merged multi-GNSS file (``_R_`` and
   ``_S_`` variants of the RINEX 3 long name, MGEX since 2013).
3. legacy GPS-only RINEX 2 daily file ``brdcddd0.yyn`` in the same directory.
They were composed from the archives' naming conventions and could not be
tried from the development machine (no internet access there): pass
``templates=`` to use another archive (CDDIS needs an Earthdata login).

Robustness: per-request timeout, retries with exponential backoff for network
errors and HTTP 5xx/429; a 404/410 moves on to the next template at once.
"""
from __future__ import annotations

import datetime as _dt
import gzip
import logging
import os
import time
import urllib.error
import urllib.request
import zlib
from collections.abc import Sequence
from pathlib import Path

from ..user_cache import default_cache_dir

log = logging.getLogger(__name__)

#: default URL templates, tried in order (see the module docstring for their source)
DEFAULT_TEMPLATES: tuple[str, ...] = (
    "https://igs.bkg.bund.de/root_ftp/IGS/BRDC/{yyyy}/{ddd}/BRDC00IGS_R_{yyyy}{ddd}0000_01D_MN.rnx.gz",
    "https://igs.bkg.bund.de/root_ftp/IGS/BRDC/{yyyy}/{ddd}/BRDC00WRD_R_{yyyy}{ddd}0000_01D_MN.rnx.gz",
    "https://igs.bkg.bund.de/root_ftp/IGS/BRDC/{yyyy}/{ddd}/BRDC00WRD_S_{yyyy}{ddd}0000_01D_MN.rnx.gz",
    "https://igs.bkg.bund.de/root_ftp/IGS/BRDC/{yyyy}/{ddd}/brdc{ddd}0.{yy}n.gz",
)
_USER_AGENT = "gnss_sim (https://github.com/; broadcast ephemeris fetch)"
_RETRY_STATUS = {408, 425, 429, 500, 502, 503, 504}


class NavDownloadError(RuntimeError):
    """No template gave a usable navigation file; the message lists every attempt."""


def _as_date(date) -> _dt.date:
    if isinstance(date, _dt.datetime):
        return date.date()
    if isinstance(date, _dt.date):
        return date
    if isinstance(date, str):
        try:
            return _dt.date.fromisoformat(date.strip()[:10])
        except ValueError as exc:
            raise ValueError(f"date {date!r}: expected YYYY-MM-DD") from exc
    if hasattr(date, "to_datetime"):  # GnssTime: the GPS day
        return date.to_datetime("GPS").date()
    raise ValueError(f"date {date!r}: expected a datetime.date, datetime, GnssTime or 'YYYY-MM-DD'")


def template_fields(day: _dt.date) -> dict[str, str]:
    """Values of the template fields for one day."""
    days = (day - _dt.date(1980, 1, 6)).days
    return {
        "yyyy": f"{day.year:04d}", "yy": f"{day.year % 100:02d}", "ddd": f"{day.timetuple().tm_yday:03d}",
        "mm": f"{day.month:02d}", "dd": f"{day.day:02d}", "gpsweek": f"{days // 7:04d}", "dow": f"{days % 7}",
    }


def _local_name(url: str) -> str:
    name = url.rstrip("/").rsplit("/", 1)[-1].split("?", 1)[0]
    for ext in (".gz", ".Z", ".z"):
        if name.endswith(ext):
            return name[: -len(ext)]
    return name


def _decompress(data: bytes, url: str, day: _dt.date) -> bytes:
    if data[:2] == b"\x1f\x8b":
        try:
            return gzip.decompress(data)
        except (OSError, EOFError, zlib.error) as exc:
            raise NavDownloadError(f"corrupt gzip data from {url} (date {day}): {exc}") from exc
    if data[:2] == b"\x1f\x9d":
        from ncompress import decompress  # installed with georinex

        try:
            return decompress(data)
        except Exception as exc:  # ncompress raises assorted types
            raise NavDownloadError(f"corrupt Unix-compress (.Z) data from {url} (date {day}): {exc}") from exc
    if url.endswith((".gz", ".Z")):
        raise NavDownloadError(f"{url} (date {day}): expected compressed data, got {data[:20]!r}...")
    return data


def _check_rinex_nav(text: bytes, url: str, day: _dt.date):
    first = text[:200].split(b"\n", 1)[0].decode("ascii", errors="replace")
    if "RINEX VERSION / TYPE" not in first or first[20:21] not in ("N", "G", "H", "n", "g", "h"):
        raise NavDownloadError(f"{url} (date {day}) is not a RINEX navigation file (first line {first[:80]!r})")


def _get(opener, url: str, timeout_s: float) -> bytes:
    req = urllib.request.Request(url, headers={"User-Agent": _USER_AGENT})
    with opener.open(req, timeout=timeout_s) as resp:
        return resp.read()


def fetch_broadcast_nav(date, cache_dir=None, templates: Sequence[str] | None = None, retries: int = 3,
                        timeout_s: float = 30.0, backoff_s: float = 2.0,
                        opener: urllib.request.OpenerDirector | None = None) -> Path:
    """Daily broadcast navigation file of ``date`` (decompressed, cached); returns its path.

    ``date``: ``datetime.date``/``datetime``/``GnssTime``/``"YYYY-MM-DD"``.
    ``cache_dir``: default :func:`default_cache_dir`; files go to
    ``<cache_dir>/brdc/<yyyy>/<ddd>/``; a cached file is returned without any
    request.  ``templates``: URL templates tried in order (default
    ``DEFAULT_TEMPLATES``).  ``retries``: attempts per URL for network errors
    and HTTP 408/429/5xx, waiting ``backoff_s * 2**k`` between them.
    ``opener``: a urllib opener (default: ``build_opener()``, honouring the
    usual proxy environment variables).
    Raises :class:`NavDownloadError` naming each URL and its HTTP status or error.
    """
    day = _as_date(date)
    if retries < 1:
        raise ValueError(f"retries must be >= 1, got {retries}")
    templates = list(DEFAULT_TEMPLATES if templates is None else templates)
    if not templates:
        raise ValueError("templates is empty: give at least one URL template")
    fields = template_fields(day)
    try:
        urls = [t.format(**fields) for t in templates]
    except (KeyError, IndexError, ValueError) as exc:
        raise ValueError(f"bad URL template ({exc}); fields: {sorted(fields)}") from exc
    folder = Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()
    folder = folder / "brdc" / fields["yyyy"] / fields["ddd"]
    for url in urls:  # cache hit: no request at all
        cached = folder / _local_name(url)
        if cached.is_file() and cached.stat().st_size > 0:
            log.debug("broadcast navigation %s from cache %s", day, cached)
            return cached
    opener = opener or urllib.request.build_opener()
    attempts: list[str] = []
    for url in urls:
        data = None
        for k in range(retries):
            try:
                data = _get(opener, url, timeout_s)
                break
            except urllib.error.HTTPError as exc:
                attempts.append(f"{url}: HTTP {exc.code} {exc.reason}")
                if exc.code not in _RETRY_STATUS:
                    break
            except (urllib.error.URLError, TimeoutError, ConnectionError, OSError) as exc:
                reason = getattr(exc, "reason", exc)
                attempts.append(f"{url}: {type(exc).__name__}: {reason}")
            if k + 1 < retries:
                time.sleep(backoff_s * 2**k)
        if data is None:
            continue
        try:
            text = _decompress(data, url, day)
            _check_rinex_nav(text, url, day)
        except NavDownloadError as exc:  # corrupt or not a navigation file: try the next template
            attempts.append(str(exc))
            continue
        folder.mkdir(parents=True, exist_ok=True)
        out = folder / _local_name(url)
        tmp = out.with_name(out.name + f".part{os.getpid()}")
        tmp.write_bytes(text)
        os.replace(tmp, out)
        log.info("broadcast navigation %s downloaded from %s -> %s", day, url, out)
        return out
    raise NavDownloadError(f"no broadcast navigation file for {day} (GPS day {fields['ddd']} of {fields['yyyy']}); "
                           "tried:\n  " + "\n  ".join(attempts))
