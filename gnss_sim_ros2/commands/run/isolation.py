"""What keeps one ``gnss-sim run`` out of another's way (ROS-free).

- :class:`OutputFolder` (``core/output_folder.py``, the rule of every command's
  outputs): one run per ``--out`` folder (an advisory lock); the run writes
  into a staging folder beside it (``.<name>.partial-<pid>``) whose files are
  moved into the folder only when the run has produced something, so a run
  that fails to start leaves the previous results untouched; a folder holding
  files gnss-sim did not write is refused, nothing but the run's own previous
  files (its manifest) is ever replaced or deleted.
- :func:`choose_domain_id`: a ROS domain of the run's own (``ROS_DOMAIN_ID``),
  one no other gnss-sim run on this machine holds and not the user's own
  domain, so two runs, or a run and the user's other ROS work, never exchange
  messages (DDS discovery is per domain).
- :func:`die_with_parent`: a child node process gets SIGTERM when its parent
  dies (Linux ``prctl(PR_SET_PDEATHSIG)``), so a killed run leaves no orphans.
"""
from __future__ import annotations

import os
import signal
import tempfile
from pathlib import Path

from gnss_sim_ros2.core.output_folder import OutputBusy, OutputFolder, OutputNotOurs, _lock

__all__ = ["OutputBusy", "OutputFolder", "OutputNotOurs", "choose_domain_id", "die_with_parent"]

#: ROS 2 domain ids that are safe on Linux with the default ports (ROS 2 docs, "The ROS_DOMAIN_ID")
DOMAIN_IDS = range(1, 102)


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
