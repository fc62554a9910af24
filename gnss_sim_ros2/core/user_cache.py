"""The user's cache folder of gnss_sim (downloaded navigation files, parsed navigation records), and writing a
file there so that readers and concurrent writers only ever see a whole file.

Never an output folder: a command's results go through ``core/output_folder.py``; what lives here can be deleted
at any time and is made again.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

#: environment variable overriding the default cache directory
CACHE_ENV = "GNSS_SIM_CACHE"


def default_cache_dir() -> Path:
    """``$GNSS_SIM_CACHE`` or ``$XDG_CACHE_HOME/gnss_sim`` or ``~/.cache/gnss_sim``."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base).expanduser() / "gnss_sim"


def write_whole(path: Path, write) -> None:
    """``write(binary file)`` into a temporary file beside ``path``, then ``os.replace`` it there: a reader sees the
    old file or the new one, never a part; of two writers at once the last one's whole file stays."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
