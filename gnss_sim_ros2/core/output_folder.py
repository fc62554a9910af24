"""Outputs never destroy what the command did not write (ROS-free; issue 25).

The one rule, for every command that writes a folder (``run``, ``simulate``, ``sweep``, ``compare``)
or named files (``export-world``, ``skyplot``, ``satpos``):

- gnss_sim owns exactly the files listed in the manifest it wrote into a folder
  (:data:`MANIFEST_NAME`, ``{"written_by": "gnss-sim simulate", "files": [relative paths]}``; a
  subfolder's manifest lists that subfolder's files, e.g. a sweep's runs).  An existing folder holding
  any other file (a user's, or another command's results) is refused (:class:`OutputNotOurs` names the
  folder and one such file); ``--out .`` and the folder of an input file are no exception.  Nothing but
  the files of the same command's previous manifest is ever replaced or deleted.
- :class:`OutputFolder`: one run per folder (an advisory lock beside it, ``fcntl.flock``, released by
  the kernel when the process dies, even by SIGKILL); the run writes into a staging folder beside it
  (``.<name>.partial-<pid>``); :meth:`OutputFolder.commit` moves its files into place (``os.replace``,
  same file system), removes the previous manifest's files it did not write again and writes the new
  manifest; :meth:`OutputFolder.abandon` (a failed run) removes the staging folder only, so the previous
  results stay as they were and nothing half-written is left under a final name; a run stopped by Ctrl-C or
  SIGTERM (:meth:`OutputFolder.keep_stopped`) replaces no earlier results either: its own stay staged.
- :func:`staged_files`: named output files are written under a staging folder beside each and renamed
  into place when the command succeeds (a file the user names is replaced: naming it says so); an output that
  is one of the command's inputs is refused.  An output the user did not name (a default beside a named one)
  replaces only a file of the same kind (:func:`check_unnamed_output`).
"""
from __future__ import annotations

import fcntl
import json
import os
import re
import shutil
from collections.abc import Iterable
from contextlib import contextmanager
from pathlib import Path, PurePosixPath

MANIFEST_NAME = ".gnss_sim_manifest.json"
#: what gnss_sim itself leaves beside or inside an output folder that is no result: locks, staging
#: folders (of a running or a killed run), temporary files renamed into place (never deleted as foreign
#: either: only ever what a manifest lists)
_TRANSIENT = re.compile(r"^\..+\.(lock|partial-\d+|\d+\.tmp|tmp-\d+)$")


class OutputBusy(RuntimeError):
    pass


class OutputNotOurs(ValueError):
    """An output folder with files gnss_sim did not write there, or an output that is an input."""


def _lock(path: Path):
    """An open file holding an exclusive flock on ``path``, or None when another process holds it."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        return None
    os.ftruncate(fd, 0)
    os.write(fd, f"{os.getpid()}\n".encode())
    return fd


def _holder(path: Path) -> str:
    try:
        return path.read_text().strip() or "?"
    except OSError:
        return "?"


def _plain_relative(rel) -> bool:
    """A normalised relative path inside its folder (a manifest never names anything outside it)."""
    if not isinstance(rel, str) or not rel:
        return False
    p = PurePosixPath(rel)
    return not p.is_absolute() and ".." not in p.parts and str(p) == rel


def read_manifest(folder) -> tuple[str | None, set[str]]:
    """(written_by, relative paths) of the manifest in ``folder``; (None, empty) without a readable one."""
    try:
        data = json.loads((Path(folder) / MANIFEST_NAME).read_text())
    except (OSError, ValueError):
        return None, set()
    if not isinstance(data, dict) or not isinstance(data.get("files"), list):
        return None, set()
    return data.get("written_by"), {f for f in data["files"] if _plain_relative(f)}


def write_manifest(folder, files: Iterable[str], command: str) -> None:
    """Write (atomically) the manifest of ``folder``: the files ``command`` wrote there."""
    folder = Path(folder)
    tmp = folder / f"{MANIFEST_NAME}.tmp-{os.getpid()}"
    tmp.write_text(json.dumps({"written_by": command, "files": sorted(set(files))}, indent=1) + "\n")
    os.replace(tmp, folder / MANIFEST_NAME)


def _raise(exc: OSError):
    raise exc


def foreign_file(folder, command: str, ignore_dirs: Iterable[str] = ()) -> Path | None:
    """The first file (or symbolic link) under ``folder`` that is not ``command``'s (its manifest there)
    nor a subfolder's result (a subfolder's own manifest), or None."""
    folder = Path(folder)
    ignore_dirs = set(ignore_dirs)
    owned: set[Path] = set()
    for dirpath, dirnames, filenames in os.walk(folder, onerror=_raise):
        here = Path(dirpath)
        writer, files = read_manifest(here)
        if here != folder or writer == command:
            owned.update(here / f for f in files)
        # a symbolic link to a folder is content: never walked into, never ours
        dirnames[:] = sorted(d for d in dirnames if not _TRANSIENT.match(d)
                             and not (here == folder and d in ignore_dirs))
        links = [d for d in dirnames if (here / d).is_symlink()]
        for name in sorted(filenames) + links:
            if name == MANIFEST_NAME or _TRANSIENT.match(name):
                continue
            if here / name not in owned:
                return here / name
    return None


def check_output_folder(folder, command: str, ignore_dirs: Iterable[str] = ()) -> None:
    """OutputNotOurs when ``folder`` exists and holds a file ``command`` did not write there."""
    folder = Path(folder)
    if not folder.exists() and not folder.is_symlink():
        return
    if not folder.is_dir():
        raise OutputNotOurs(f"output folder {folder} is a file: give a folder with --out")
    bad = foreign_file(folder, command, ignore_dirs)
    if bad is not None:
        raise OutputNotOurs(f"output folder {folder} holds {bad.relative_to(folder)}, which {command} did not "
                            f"write; gnss-sim never replaces or deletes files it did not write: give a new or "
                            f"empty folder with --out")


def _under_any(path: Path, roots: set[Path]) -> bool:
    return any(path == r or r in path.parents for r in roots)


class OutputFolder:
    """The ``--out`` folder of one run: checked, locked, staged, its own files moved into place at the end."""

    def __init__(self, final, command: str = "gnss-sim run", inputs: Iterable = ()):
        self.final = Path(final).resolve()
        self.command = command
        #: input files and folders of the run: never removed, even when a previous manifest lists them
        self.inputs = {_real(p) for p in inputs if p}
        self.lock_path = self.final.parent / f".{self.final.name}.lock"
        self.staging = self.final.parent / f".{self.final.name}.partial-{os.getpid()}"
        self.stale: list[Path] = []
        self._fd = None

    def check(self) -> None:
        check_output_folder(self.final, self.command)

    def acquire(self) -> Path:
        """Lock the folder, check it holds nothing foreign, create the staging folder (returned);
        OutputBusy when another run has it, OutputNotOurs when it holds another's file."""
        self.check()                       # a refused folder: not even a lock file beside it
        self.final.parent.mkdir(parents=True, exist_ok=True)
        fd = _lock(self.lock_path)
        if fd is None:
            raise OutputBusy(f"output folder {self.final} is in use by another gnss-sim run (pid "
                             f"{_holder(self.lock_path)}); give another --out")
        self._fd = fd
        try:
            self.check()
        except BaseException:
            self.release()
            raise
        self.stale = sorted(p for p in self.final.parent.glob(f".{self.final.name}.partial-*") if p != self.staging)
        if self.staging.exists():          # a staging folder of this very pid: an earlier process's, dead
            shutil.rmtree(self.staging)
        self.staging.mkdir()
        return self.staging

    def staged_files(self) -> list[str]:
        return sorted(p.relative_to(self.staging).as_posix() for p in self.staging.rglob("*")
                      if p.is_file() or p.is_symlink())

    def commit(self) -> list[str]:
        """Move the staged files into the folder (replacing the previous run's files of the same names), remove
        the previous manifest's files not written again (never an input), write the manifest; the files."""
        writer, old = read_manifest(self.final) if self.final.is_dir() else (None, set())
        if writer != self.command:
            old = set()
        new = self.staged_files()
        clash = next((r for r in new if r not in old and os.path.lexists(self.final / r)), None)
        if clash is not None:        # appeared while the run went: leave it, keep the results staged
            raise OutputNotOurs(f"output folder {self.final}: {clash} appeared during the run and is not "
                                f"gnss-sim's; the results are left in {self.staging}")
        self.final.mkdir(parents=True, exist_ok=True)
        # the manifest names old and new first: a commit cut short leaves nothing unaccounted for
        write_manifest(self.final, old | set(new), self.command)
        for rel in new:
            dst = self.final / rel
            dst.parent.mkdir(parents=True, exist_ok=True)
            os.replace(self.staging / rel, dst)
        kept = set()
        for rel in sorted(old - set(new)):
            p = self.final / rel
            if _under_any(p.resolve(), self.inputs):
                kept.add(rel)
                continue
            p.unlink(missing_ok=True)
            d = p.parent
            while d != self.final and self.final in d.parents:     # folders the run's files emptied
                try:
                    d.rmdir()
                except OSError:
                    break
                d = d.parent
        write_manifest(self.final, set(new) | kept, self.command)
        shutil.rmtree(self.staging, ignore_errors=True)           # only empty folders are left in it
        self.release()
        return new

    def keep_stopped(self) -> bool:
        """A run stopped (Ctrl-C, SIGTERM) after it produced closed results: they go into the folder (commit, True)
        only when it holds no earlier results of the command; else those stay as they are and the stopped run's stay
        in the staging folder (False; the lock released, the next run names it): nothing already produced is lost."""
        writer, old = read_manifest(self.final) if self.final.is_dir() else (None, set())
        if writer == self.command and any(os.path.lexists(self.final / r) for r in old):
            self.release()
            return False
        self.commit()
        return True

    def abandon(self):
        """A run that failed or produced nothing: the staging folder goes, the previous results stay."""
        shutil.rmtree(self.staging, ignore_errors=True)
        self.release()

    def release(self):
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def final_path(self, path):
        """Where a file written under the staging folder ends up (other paths as they are)."""
        if path is None:
            return None
        p = Path(path)
        try:
            return self.final / p.relative_to(self.staging)
        except ValueError:
            return p


def _real(path) -> Path:
    """``path`` with its links resolved; a broken or looping link as far as it resolves (Path.resolve raised
    "RuntimeError: Symlink loop" on an input that links to itself: a traceback before the reader could say so)."""
    return Path(os.path.realpath(path))


def check_outputs_not_inputs(outputs: Iterable[tuple[str, object]], inputs: Iterable = ()) -> None:
    """OutputNotOurs naming the option when an output file (option, path) is a folder, one of ``inputs`` or the file
    of an earlier output (skyplot --csv x.png --png x.png: the plot replaced the table without a word)."""
    ins = {_real(p) for p in inputs if p}
    taken: dict = {}
    for option, path in outputs:
        if path is None:
            continue
        final = Path(path)
        if _real(final) in taken:
            raise OutputNotOurs(f"options {taken[_real(final)]} and {option} name the same file {final}: one would "
                                f"replace the other; give each its own file")
        taken[_real(final)] = option
        if final.is_dir():
            raise OutputNotOurs(f"option {option}: {final} is a folder; give a file name")
        if _real(final) in ins:
            raise OutputNotOurs(f"option {option}: {final} is also an input of this command and would be "
                                f"overwritten; give another file name")


def check_unnamed_output(path, option: str, first_line: str) -> None:
    """OutputNotOurs when ``path``, an output the user did not name (a default beside a named one, e.g. skyplot's
    skyline.csv), exists and is not what the command writes there (its first line is not ``first_line``): such a
    file is replaced only when its option names it."""
    p = Path(path)
    if not os.path.lexists(p):
        return
    try:
        with open(p, encoding="utf-8", errors="replace") as fh:
            head = fh.readline().rstrip("\r\n")
    except OSError:
        head = None
    if p.is_symlink() or head != first_line:
        raise OutputNotOurs(f"{p} exists and gnss-sim did not write it (the default of {option}); gnss-sim never "
                            f"replaces files it did not write unless named: give {option} FILE")


@contextmanager
def staged_files(outputs: Iterable[tuple[str, object]], inputs: Iterable = ()):
    """Named output files written under temporary paths and renamed into place when the block ends without an
    exception (removed otherwise): no half-written file under a final name.  ``outputs``: (option, path) pairs
    (None paths skipped); yields {path: temporary path} (same file name, in a staging folder beside it).
    An output that is a folder or one of ``inputs`` is refused (OutputNotOurs naming the option)."""
    outputs = [(option, path) for option, path in outputs if path is not None]
    check_outputs_not_inputs(outputs, inputs)
    temp: dict = {}
    stages: list[Path] = []
    for _option, path in outputs:
        final = Path(path)
        stage = final.parent / f".gnss_sim.partial-{os.getpid()}"
        if stage not in stages:
            final.parent.mkdir(parents=True, exist_ok=True)
            stage.mkdir(exist_ok=True)
            stages.append(stage)
        temp[path] = stage / final.name
    try:
        yield temp
        for path, tmp in temp.items():
            if tmp.exists():
                os.replace(tmp, path)
    finally:
        for stage in stages:
            shutil.rmtree(stage, ignore_errors=True)


def record_outputs(folder, command: str, files: Iterable) -> None:
    """Add ``files`` (paths under ``folder`` that ``command`` wrote in place) to its manifest there; entries of an
    earlier manifest of the same command stay while their files exist (a command that writes in place, as the
    sweep's results while its runs go, removes nothing)."""
    folder = Path(folder).resolve()
    writer, old = read_manifest(folder)
    keep = {r for r in old if os.path.lexists(folder / r)} if writer == command else set()
    for f in files:
        p = Path(f).resolve()
        if folder in p.parents and p.exists():
            keep.add(p.relative_to(folder).as_posix())
    write_manifest(folder, keep, command)
