"""An input file the user names (CSV, YAML, RINEX), with the errors a user can act on.

``Path.read_text()`` of a binary or UTF-16 file raises ``UnicodeDecodeError: 'utf-8' codec can't decode byte
0xff in position 0`` naming neither the file nor the option; :func:`read_utf8` names them (and drops the byte order
mark that Excel's "CSV UTF-8" puts first: a header '\ufefft_s,...' was refused).  A folder given for a
file was reported "does not exist" / "no such file"; :func:`not_a_file` says which of the two it is.
"""
from __future__ import annotations

from pathlib import Path


def read_utf8(path: str | Path, where: str) -> str:
    """The text of ``path``; ValueError naming ``where`` when it is not UTF-8 text (binary, UTF-16). The OSError
    of a missing file or a folder is left to the caller (each names it its own way)."""
    try:
        return Path(path).read_text(encoding="utf-8-sig")      # a byte order mark (Excel's CSV) is no text
    except UnicodeDecodeError as exc:
        raise ValueError(f"{where}: not a UTF-8 text file (byte {exc.start}: {exc.reason}); save it as UTF-8")\
            from None


def not_a_file(path: str | Path) -> str | None:
    """None when ``path`` is an existing file (or a link to one); else why not: "no such file" or "is a folder, not
    a file" (or "is not a regular file": a device, a pipe; or a broken or looping symbolic link)."""
    path = Path(path).expanduser()
    if path.is_file():
        return None
    if path.is_dir():
        return "is a folder, not a file"
    if path.is_symlink():       # a link to nothing, or to itself (pathlib's resolve: "RuntimeError: Symlink loop")
        return "is a symbolic link to nothing (broken, or a loop)"
    return "is not a regular file" if path.exists() else "no such file"
