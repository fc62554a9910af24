"""rtkrcv as a subprocess fed and read through local TCP streams.

The wrapper opens five TCP servers on 127.0.0.1 (ports chosen by the OS):
rover, base and navigation RTCM3 in (rtkrcv input streams 1, 2 and 3; the
third carries broadcast ephemerides where the rover and base streams have
none), solution (llh or enu) and NMEA out; rtkrcv connects to
them as a TCP client (stream type ``tcpcli``, rtkrcv.c ``rcvopts``).  Bytes
given to :meth:`RtkrcvProcess.feed_rover` / :meth:`feed_base` go to rtkrcv as
they come (whole RTCM frames: rtkrcv decodes and synchronises rover and base
by epoch time itself, ``pos2-maxage``); solution lines and NMEA sentences
come back through callbacks on reader threads.

Clock: RTCM3 MSM carry the time of week only; RTKLIB resolves the week (and
the day of GLONASS) from the computer clock (rtcm3.c ``adjweek``: the epoch
is put within half a week of it), so rtkrcv must run with its clock at the
simulated time.  With ``clock_start_utc`` the wrapper preloads libfaketime
into rtkrcv (``LD_PRELOAD`` of its multi-threaded library, ``FAKETIME=@START``,
as the ``faketime -m -f`` wrapper does; Debian package ``faketime``), whose
clock then runs on from the simulation start; the monotonic clock
(timeouts, cycles) is left real (``FAKETIME_DONT_FAKE_MONOTONIC=1``).
Without it rtkrcv keeps the real clock (a simulation of the current week).

rtkrcv is the wrapper's direct child, in a process group of its own, and
gets SIGTERM when the wrapper's process dies (Linux ``PR_SET_PDEATHSIG``):
it never outlives the node, even one killed with SIGKILL.

rtkrcv runs with ``-s`` (start at once), ``-p PORT`` (its telnet console on a
free local port; no terminal needed) and ``-o FILE`` in a work folder of its
own (it reads and writes ``rtkrcv.nav`` there).  :meth:`stop` sends SIGTERM
(rtkrcv.c ``sigshut``: the server stops and the process exits), then SIGKILL
after ``stop_timeout_s``.
"""
from __future__ import annotations

import datetime as _dt
import os
import shutil
import signal
import socket
import subprocess
import tempfile
import threading
import time
import weakref
from collections.abc import Callable
from pathlib import Path

from .config import FORMAT_OPTIONS, default_options, merge_options, read_conf, write_conf
from .solution import RtkSolution, parse_enu_line, parse_llh_line

#: most bytes kept per input while rtkrcv has not connected yet (older data is dropped first)
PENDING_LIMIT_BYTES = 1 << 20


class RtkrcvNotFound(ValueError):
    """The rtkrcv executable is not installed (or not where the parameter says)."""


#: where distributions install libfaketime's multi-threaded library (Debian: package libfaketime)
FAKETIME_LIBRARY_GLOBS = ("/usr/lib/*/faketime/libfaketimeMT.so.1", "/usr/lib/faketime/libfaketimeMT.so.1",
                          "/usr/local/lib/faketime/libfaketimeMT.so.1", "/usr/lib64/faketime/libfaketimeMT.so.1")


def find_faketime() -> str:
    """libfaketime's multi-threaded library (rtkrcv runs threads)."""
    import glob

    for pattern in FAKETIME_LIBRARY_GLOBS:
        hits = sorted(glob.glob(pattern))
        if hits:
            return hits[0]
    raise RtkrcvNotFound("libfaketime not found (" + ", ".join(FAKETIME_LIBRARY_GLOBS) + "): rtkrcv needs its "
                         "clock at the simulated time (RTCM3 carries the time of week only; RTKLIB takes the week "
                         "from the computer clock); install it, e.g. 'apt-get install faketime' (parameter "
                         "rtkrcv_clock=system keeps the real clock)")


def _die_with_parent():
    """preexec: SIGTERM to the child when its parent dies (prctl PR_SET_PDEATHSIG = 1), in the child."""
    if _PRCTL is not None:
        _PRCTL(1, signal.SIGTERM)


def _load_prctl():
    try:
        import ctypes

        return ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None


#: resolved once in the parent: the child only calls it between fork and exec
_PRCTL = _load_prctl()


def find_rtkrcv(path: str = "") -> str:
    """The rtkrcv executable: ``path`` if given, else the one on PATH."""
    exe = shutil.which(path or "rtkrcv")
    if exe is None:
        where = f"'{path}'" if path else "on PATH"
        raise RtkrcvNotFound(f"rtkrcv not found {where} (parameter rtkrcv_path): install RTKLIB's rtkrcv, e.g. "
                             f"'apt-get install rtklib' on Debian/Ubuntu")
    return exe


class _Server:
    """One listening socket on 127.0.0.1 accepting rtkrcv's connection."""

    def __init__(self, name: str):
        self.name = name
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(1)
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self.conn: socket.socket | None = None
        self.lock = threading.Lock()

    def accept(self) -> socket.socket | None:
        try:
            conn, _ = self.sock.accept()
        except (TimeoutError, OSError):
            return None
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        with self.lock:
            if self.conn is not None:
                self.conn.close()
            self.conn = conn
        return conn

    def close(self) -> None:
        with self.lock:
            if self.conn is not None:
                self.conn.close()
                self.conn = None
        self.sock.close()


class RtkrcvProcess:
    """One rtkrcv run (module docstring).

    ``options``: rtkrcv options to run with (stream and output format keys are
    replaced by the wrapper's); ``user_conf``: a user's rtkrcv .conf whose
    options are kept instead of the generated ones (only the owned keys
    change, listed in ``replaced_options``).  ``on_solution(RtkSolution)``,
    ``on_nmea(str)``: called from reader threads (``solution_format`` "enu": baselines,
    :class:`~.solution.RtkBaseline`, for the moving baseline).
    """

    def __init__(self, options: dict | None = None, user_conf: str | Path | None = None, rtkrcv_path: str = "",
                 workdir: str | Path | None = None, on_solution: Callable[[RtkSolution], None] | None = None,
                 on_nmea: Callable[[str], None] | None = None, stop_timeout_s: float = 5.0,
                 clock_start_utc: _dt.datetime | None = None, solution_format: str = "llh"):
        if solution_format not in ("llh", "enu"):
            raise ValueError(f"rtkrcv solution format {solution_format!r}: llh (position) or enu (baseline)")
        self.solution_format = solution_format
        self.exe = find_rtkrcv(rtkrcv_path)
        self.clock_start_utc = clock_start_utc
        self.faketime_library = find_faketime() if clock_start_utc is not None else None
        self.user_options = read_conf(user_conf) if user_conf else None
        self.base_options = dict(options) if options is not None else (
            None if user_conf else default_options())
        self.on_solution = on_solution
        self.on_nmea = on_nmea
        self.stop_timeout_s = float(stop_timeout_s)
        self._own_workdir = workdir is None
        self.workdir = Path(workdir) if workdir else None
        self.proc: subprocess.Popen | None = None
        self.replaced_options: list[str] = []
        self.conf_path: Path | None = None
        self.solutions = 0
        self.last_error = ""
        self._servers: dict[str, _Server] = {}
        self._pending: dict[str, bytearray] = {}
        self._threads: list[threading.Thread] = []
        self._stop = threading.Event()
        self._log = None

    # ----------------------------------------------------------------------------------------
    @property
    def running(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def start(self) -> None:
        """Open the streams, write the options file and start rtkrcv (no-op when running)."""
        if self.running:
            return
        self._stop.clear()
        if self.workdir is None or self._own_workdir:
            self.workdir = Path(tempfile.mkdtemp(prefix="gnss_sim_rtkrcv_"))
        self.workdir.mkdir(parents=True, exist_ok=True)
        self._servers = {n: _Server(n) for n in ("rover", "base", "nav", "solution", "nmea")}
        self._pending = {"rover": bytearray(), "base": bytearray(), "nav": bytearray()}
        owned = {"inpstr1-type": "tcpcli", "inpstr1-path": f"127.0.0.1:{self._servers['rover'].port}",
                 "inpstr1-format": "rtcm3",
                 "inpstr2-type": "tcpcli", "inpstr2-path": f"127.0.0.1:{self._servers['base'].port}",
                 "inpstr2-format": "rtcm3", "inpstr2-nmeareq": "off",
                 "inpstr3-type": "tcpcli", "inpstr3-path": f"127.0.0.1:{self._servers['nav'].port}",
                 "inpstr3-format": "rtcm3",
                 "outstr1-type": "tcpcli", "outstr1-path": f"127.0.0.1:{self._servers['solution'].port}",
                 "outstr1-format": self.solution_format,
                 "outstr2-type": "tcpcli", "outstr2-path": f"127.0.0.1:{self._servers['nmea'].port}",
                 "outstr2-format": "nmea",
                 "logstr1-type": "off", "logstr1-path": "", "logstr2-type": "off", "logstr2-path": "",
                 "logstr3-type": "off", "logstr3-path": "", **FORMAT_OPTIONS,
                 "out-solformat": self.solution_format}
        options, self.replaced_options = merge_options(self.user_options, owned, self.base_options)
        self.conf_path = write_conf(self.workdir / "gnss_sim_rtkrcv.conf", options)
        console = _free_port()
        self._log = open(self.workdir / "rtkrcv.log", "wb")
        cmd = [self.exe, "-s", "-p", str(console), "-w", "", "-o", str(self.conf_path)]
        env = None
        if self.faketime_library is not None:
            preload = " ".join(x for x in (self.faketime_library, os.environ.get("LD_PRELOAD", "")) if x)
            env = {**os.environ, "LD_PRELOAD": preload, "FAKETIME_DONT_FAKE_MONOTONIC": "1",
                   "FAKETIME": "@" + self.clock_start_utc.strftime("%Y-%m-%d %H:%M:%S")}
        self.proc = subprocess.Popen(cmd, cwd=self.workdir, stdin=subprocess.DEVNULL, stdout=self._log,
                                     stderr=subprocess.STDOUT, start_new_session=True, env=env,
                                     preexec_fn=_die_with_parent)
        self._finalizer = weakref.finalize(self, _signal_group, self.proc.pid, signal.SIGTERM)
        for name in ("rover", "base", "nav"):
            self._spawn(self._accept_input, name)
        self._spawn(self._read_output, "solution")
        self._spawn(self._read_output, "nmea")

    def _spawn(self, fn, name: str) -> None:
        th = threading.Thread(target=fn, args=(name,), name=f"rtkrcv-{name}", daemon=True)
        th.start()
        self._threads.append(th)

    def _accept_input(self, name: str) -> None:
        srv = self._servers[name]
        while not self._stop.is_set():
            if srv.conn is None and srv.accept() is not None:
                self._send(name, b"")          # flush what came before the connection
            time.sleep(0.05)

    def _read_output(self, name: str) -> None:
        srv = self._servers[name]
        buf = b""
        while not self._stop.is_set():
            conn = srv.conn or srv.accept()
            if conn is None:
                continue
            conn.settimeout(0.2)
            try:
                data = conn.recv(65536)
            except TimeoutError:
                continue
            except OSError:
                data = b""
            if not data:
                with srv.lock:
                    srv.conn = None
                conn.close()
                continue
            buf += data
            *lines, buf = buf.split(b"\n")
            for raw in lines:
                self._line(name, raw.decode("ascii", "replace").strip())

    def _line(self, name: str, line: str) -> None:
        if not line:
            return
        if name == "nmea":
            if self.on_nmea is not None:
                self.on_nmea(line)
            return
        try:
            sol = parse_llh_line(line) if self.solution_format == "llh" else parse_enu_line(line)
        except ValueError as exc:
            self.last_error = str(exc)
            return
        if sol is not None:
            self.solutions += 1
            if self.on_solution is not None:
                self.on_solution(sol)

    def _send(self, name: str, data: bytes) -> None:
        srv = self._servers.get(name)
        if srv is None:
            raise ValueError(f"rtkrcv input {name!r} is not open: start() first")
        with srv.lock:
            pend = self._pending[name]
            pend += data
            if len(pend) > PENDING_LIMIT_BYTES:
                del pend[:len(pend) - PENDING_LIMIT_BYTES]
            if srv.conn is None or not pend:
                return
            try:
                srv.conn.sendall(bytes(pend))
                pend.clear()
            except OSError:
                srv.conn.close()
                srv.conn = None

    def feed_rover(self, data: bytes) -> None:
        """RTCM3 bytes of the rover (whole frames)."""
        self._send("rover", bytes(data))

    def feed_base(self, data: bytes) -> None:
        """RTCM3 bytes of the base station (whole frames)."""
        self._send("base", bytes(data))

    def feed_nav(self, data: bytes) -> None:
        """RTCM3 ephemeris messages (input stream 3), for streams that carry none."""
        self._send("nav", bytes(data))

    def connected(self) -> dict[str, bool]:
        """Which streams rtkrcv has connected to."""
        return {n: s.conn is not None for n, s in self._servers.items()}

    def wait_connected(self, timeout_s: float = 10.0) -> bool:
        t_end = time.monotonic() + timeout_s
        while time.monotonic() < t_end:
            if self._servers and all(self.connected().values()):
                return True
            if not self.running:
                return False
            time.sleep(0.05)
        return False

    def log_text(self) -> str:
        p = self.workdir / "rtkrcv.log" if self.workdir else None
        return p.read_text(errors="replace") if p and p.is_file() else ""

    def stop(self) -> int | None:
        """Stop rtkrcv (SIGTERM, SIGKILL after stop_timeout_s) and close the streams; its exit code."""
        rc = None
        if self.proc is not None:
            # the process group of our own child (start_new_session)
            pgid = self.proc.pid
            self._finalizer.detach()
            _signal_group(pgid, signal.SIGTERM)
            try:
                self.proc.wait(self.stop_timeout_s)
            except subprocess.TimeoutExpired:
                _signal_group(pgid, signal.SIGKILL)
                self.proc.wait(self.stop_timeout_s)
            _wait_group_gone(pgid, self.stop_timeout_s)
            rc = self.proc.returncode
            self.proc = None
        self._stop.set()
        for th in self._threads:
            th.join(2.0)
        self._threads = []
        for s in self._servers.values():
            s.close()
        self._servers = {}
        if self._log is not None:
            self._log.close()
            self._log = None
        if self._own_workdir and self.workdir is not None:
            shutil.rmtree(self.workdir, ignore_errors=True)
            self.workdir = None
        return rc

    def __enter__(self) -> RtkrcvProcess:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()


def _signal_group(pgid: int, sig: int) -> None:
    try:
        os.killpg(pgid, sig)
    except ProcessLookupError:
        pass


def _wait_group_gone(pgid: int, timeout_s: float) -> None:
    """Wait until no process of the group is left (SIGKILL after ``timeout_s``)."""
    t_end = time.monotonic() + timeout_s
    while time.monotonic() < t_end:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return
        time.sleep(0.05)
    _signal_group(pgid, signal.SIGKILL)


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]
