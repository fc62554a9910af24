"""Parsed navigation files kept between runs: the start-up of a job on a real navigation file paid once.

Parsing a daily navigation file goes through georinex (xarray, pandas: about half a second of imports) and its
parser (seconds for a mixed file); a second run on the same file loads the records it gave from an ``.npz`` in
the user's cache folder (``core/user_cache.default_cache_dir() / "nav"``) without importing georinex.

- Key: the SHA-256 of the file's bytes (as stored, compressed or not), the name it is read under (messages name
  it), the reading window and systems, the format version and a digest of the reader's own sources and
  georinex's version: a changed file, a changed reader or another window misses.
- An entry is written whole (``user_cache.write_whole``: temporary file, ``os.replace``), so concurrent runs
  (sweep workers) never read half an entry; an entry that cannot be read is ignored with a ``NavCacheWarning``
  and written again.
- What the parse said is said again on a hit: its ``NavDataWarning`` messages are stored and warned again, the
  notes it logged are logged again.
- ``GNSS_SIM_NAV_CACHE=off`` (or ``0``, ``false``, ``no``) disables it; ``GNSS_SIM_CACHE`` moves the folder.
"""
from __future__ import annotations

import functools
import hashlib
import json
import logging
import os
import warnings
from pathlib import Path

import numpy as np

from ...user_cache import default_cache_dir, write_whole
from .containers import NavData, NavDataWarning, SystemTable

#: environment variable: off / 0 / false / no disables the cache
CACHE_SWITCH_ENV = "GNSS_SIM_NAV_CACHE"
#: version of the entries' layout (change it when NavData or this file's layout changes)
FORMAT_VERSION = 1
#: entries kept; the least recently used beyond that are deleted after a write
MAX_ENTRIES = 64
#: the reader's modules: a change in any of them makes every entry miss
_READER_SOURCES = ("read.py", "v2.py", "v3.py", "v4.py", "tables.py", "containers.py", "georinex_adapter.py",
                   "record_text.py", "cache.py", "../nav_write.py", "../../time.py")
#: logger of the notes the reader logs (tables.fix_semicircles) instead of warning them
_TABLES_LOG = logging.getLogger(__name__.rsplit(".", 1)[0] + ".tables")


class NavCacheWarning(UserWarning):
    """A cache entry of parsed navigation records that could not be read or written (the run goes on)."""


def cache_enabled() -> bool:
    return os.environ.get(CACHE_SWITCH_ENV, "").strip().lower() not in ("off", "0", "false", "no")


def cache_folder() -> Path:
    return default_cache_dir() / "nav"


@functools.lru_cache(maxsize=1)
def _reader_digest() -> str:
    h = hashlib.sha256(f"format {FORMAT_VERSION}".encode())
    here = Path(__file__).resolve().parent
    for name in _READER_SOURCES:
        h.update((here / name).read_bytes())
    v = _installed_version("georinex")
    h.update(b"no georinex" if v is None else v.encode())
    return h.hexdigest()


def _installed_version(dist: str) -> str | None:
    """``importlib.metadata.version(dist)`` (None: not installed) read from the first ``dist-*.dist-info`` (or
    ``.egg-info``) folder on ``sys.path`` without importing importlib.metadata (20 ms of a warm run's start-up:
    it imports the email package); any other layout is left to importlib.metadata."""
    import sys

    prefix = dist.lower().replace("-", "_") + "-"
    for entry in sys.path:
        try:
            names = os.listdir(entry or ".")
        except OSError:
            continue
        for name in names:
            low = name.lower()
            if not low.startswith(prefix) or not low.endswith((".dist-info", ".egg-info")):
                continue
            meta = Path(entry or ".", name, "METADATA" if low.endswith(".dist-info") else "PKG-INFO")
            try:
                with open(meta, encoding="utf-8") as f:
                    for line in f:
                        if not line.strip():
                            break
                        if line.startswith("Version:"):
                            return line[len("Version:"):].strip()
            except OSError:
                pass
            return _metadata_version(dist)
    return _metadata_version(dist)


def _metadata_version(dist: str) -> str | None:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(dist)
    except PackageNotFoundError:
        return None


def entry_key(data: bytes, name: str, window: tuple) -> str:
    """Key of the records that parsing ``data`` (read as ``name``) with ``window`` (start, end, systems,
    margin: plain values) gives."""
    h = hashlib.sha256(_reader_digest().encode())
    h.update(hashlib.sha256(data).digest())
    h.update(json.dumps([name, *window]).encode())
    return h.hexdigest()


def load(key: str) -> NavData | None:
    """The NavData stored under ``key`` (its warnings warned and notes logged again), or None."""
    path = cache_folder() / f"{key}.npz"
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            if meta.get("key") != key:
                raise ValueError(f"entry of key {meta.get('key')!r}")
            tables = {s: SystemTable(s, z[f"{s}_rec"], z[f"{s}_raw"], list(fields), z[f"{s}_epoch"])
                      for s, fields in meta["fields"].items()}
    except FileNotFoundError:
        return None
    except Exception as e:  # a truncated or foreign file: zipfile, numpy, JSON and key errors alike
        warnings.warn(f"navigation cache entry {path} cannot be read ({type(e).__name__}: {e}): ignored, "
                      "the file is parsed and the entry written again", NavCacheWarning, stacklevel=3)
        return None
    try:
        os.utime(path)              # recently used: kept by the pruning
    except OSError:
        pass
    nav = NavData(tables=tables, iono=meta["iono"], leap_seconds=meta["leap_seconds"], versions=meta["versions"],
                  paths=meta["paths"], skipped=meta["skipped"], notes=meta["notes"], dropped=meta["dropped"],
                  origin={tuple(k): v for k, v in meta["origin"]})
    for msg in meta["warned"]:
        warnings.warn(msg, NavDataWarning, stacklevel=3)
    for msg in meta["logged"]:
        _TABLES_LOG.warning(msg)
    return nav


def store(key: str, nav: NavData, warned: list[str]) -> None:
    """Write ``nav`` (and the ``warned`` messages its parse gave) under ``key``; a failure only warns."""
    folder = cache_folder()
    path = folder / f"{key}.npz"
    arrays = {}
    for s, tab in nav.tables.items():
        arrays.update({f"{s}_rec": tab.rec, f"{s}_raw": tab.raw, f"{s}_epoch": tab.epoch})
    meta = {"key": key, "format": FORMAT_VERSION, "fields": {s: list(t.fields) for s, t in nav.tables.items()},
            "iono": nav.iono, "leap_seconds": nav.leap_seconds, "versions": nav.versions, "paths": nav.paths,
            "skipped": nav.skipped, "notes": nav.notes, "dropped": nav.dropped,
            "origin": [[list(k), v] for k, v in nav.origin.items()],
            "warned": warned, "logged": [m for m in nav.notes if m not in warned]}
    try:
        write_whole(path, lambda f: np.savez(f, meta=np.array(json.dumps(meta)), **arrays))
        _prune(folder)
    except OSError as e:
        warnings.warn(f"navigation cache: cannot write {path} ({e}); {CACHE_SWITCH_ENV}=off turns the cache off",
                      NavCacheWarning, stacklevel=3)


def _prune(folder: Path) -> None:
    entries = []
    for p in folder.glob("*.npz"):
        try:
            entries.append((p.stat().st_mtime, p))
        except OSError:         # deleted by another process meanwhile
            pass
    for _, p in sorted(entries)[:-MAX_ENTRIES]:
        try:
            p.unlink()
        except OSError:
            pass


def parse_cached(path: Path, window: tuple, parse) -> NavData:
    """``parse()`` (the NavData of the file at ``path`` read with ``window``: start, end, systems, margin as
    plain values), or the stored result of an earlier identical parse."""
    if not cache_enabled():
        return parse()
    try:
        data = path.read_bytes()
    except OSError as e:
        raise ValueError(f"{path}: cannot read the navigation file ({e})") from e
    key = entry_key(data, str(path), window)
    nav = load(key)
    if nav is not None:
        return nav
    caught: list = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            nav = parse()
        store(key, nav, [str(w.message) for w in caught if issubclass(w.category, NavDataWarning)])
    finally:
        for w in caught:        # said as the parse said it (after the entry is written)
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno, source=w.source)
    return nav
