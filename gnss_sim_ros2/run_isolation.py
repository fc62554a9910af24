"""What keeps one ``gnss-sim run`` out of another's way (ROS-free).

- :class:`OutputFolder`: one run per ``--out`` folder (an advisory lock,
  ``fcntl.flock``, released by the kernel when the process dies, even by
  SIGKILL); the run writes into a staging folder beside it
  (``.<name>.partial-<pid>``) that replaces the folder only when the run has
  produced something, so a run that fails to start leaves the previous
  results untouched.
- :func:`choose_domain_id`: a ROS domain of the run's own (``ROS_DOMAIN_ID``),
  one no other gnss-sim run on this machine holds and not the user's own
  domain, so two runs, or a run and the user's other ROS work, never exchange
  messages (DDS discovery is per domain).
- :func:`die_with_parent`: a child node process gets SIGTERM when its parent
  dies (Linux ``prctl(PR_SET_PDEATHSIG)``), so a killed run leaves no orphans.
"""
from __future__ import annotations

import fcntl
import os
import shutil
import signal
import tempfile
from pathlib import Path

#: ROS 2 domain ids that are safe on Linux with the default ports (ROS 2 docs, "The ROS_DOMAIN_ID")
DOMAIN_IDS = range(1, 102)


class OutputBusy(RuntimeError):
    pass


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


class OutputFolder:
    """The ``--out`` folder of one run: locked, staged, moved into place at the end."""

    def __init__(self, final: Path):
        self.final = Path(final).resolve()
        self.lock_path = self.final.parent / f".{self.final.name}.lock"
        self.staging = self.final.parent / f".{self.final.name}.partial-{os.getpid()}"
        self._fd = None

    def acquire(self) -> Path:
        """Lock the folder and create the staging folder (returned); OutputBusy when another run has it."""
        self.final.parent.mkdir(parents=True, exist_ok=True)
        fd = _lock(self.lock_path)
        if fd is None:
            raise OutputBusy(f"output folder {self.final} is in use by another gnss-sim run (pid "
                             f"{_holder(self.lock_path)}); give another --out")
        self._fd = fd
        stale = sorted(p for p in self.final.parent.glob(f".{self.final.name}.partial-*") if p != self.staging)
        self.stale = stale             # outputs of killed runs, kept for their owner
        if self.staging.exists():
            shutil.rmtree(self.staging)
        self.staging.mkdir()
        return self.staging

    def commit(self):
        """Replace the folder by the staging folder (the previous results go)."""
        old = None
        if self.final.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{self.final.name}.old-", dir=self.final.parent))
            os.replace(self.final, old / "out")
        os.replace(self.staging, self.final)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
        self.release()

    def abandon(self):
        """A run that produced nothing: the staging folder goes, the previous results stay."""
        shutil.rmtree(self.staging, ignore_errors=True)
        self.release()

    def release(self):
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


def choose_domain_id(avoid=()) -> tuple[int, int]:
    """(domain id, lock fd) of a ROS domain no other gnss-sim run on this machine holds; ``avoid``: ids
    never to take (the user's own ROS_DOMAIN_ID).  The lock lives as long as the fd (the process)."""
    folder = Path(tempfile.gettempdir()) / "gnss_sim_domains"
    folder.mkdir(exist_ok=True)
    start = os.getpid() % len(DOMAIN_IDS)
    ids = list(DOMAIN_IDS)[start:] + list(DOMAIN_IDS)[:start]
    for domain in ids:
        if domain in avoid:
            continue
        fd = _lock(folder / f"{domain}.lock")
        if fd is not None:
            return domain, fd
    raise OutputBusy(f"every ROS domain id {DOMAIN_IDS.start}..{DOMAIN_IDS.stop - 1} is held by another "
                     f"gnss-sim run on this machine")


def die_with_parent():
    """``preexec_fn`` of a child process: SIGTERM when the parent dies (Linux), SIGINT restored."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    try:
        import ctypes

        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        pr_set_pdeathsig = 1
        libc.prctl(pr_set_pdeathsig, signal.SIGTERM)
    except OSError:  # not Linux: the parent's close() still stops its children
        pass
