"""RTCM3 served on a TCP port for outside tools (RTKLIB str2str/rtkrcv ``tcpcli``, NTRIP casters'
source side, u-center ...): every client that connects receives the bytes written from then on,
as RTKLIB's ``tcpsvr`` output stream does.

``RtcmTcpServer(port).write(data)`` never blocks the caller: each client has
a bounded queue drained by its own thread; a client too slow to keep up
loses its oldest data (counted in ``dropped_bytes``), a client that closes
is forgotten.  The write side can be an :class:`~.writer.RtcmWriter` sink.
"""
from __future__ import annotations

import collections
import socket
import threading

#: bytes queued per client before the oldest are dropped
CLIENT_QUEUE_BYTES = 1 << 20


class _Client:
    def __init__(self, conn: socket.socket, addr):
        self.conn = conn
        self.addr = addr
        self.chunks: collections.deque[bytes] = collections.deque()
        self.size = 0
        self.cond = threading.Condition()
        self.closed = False
        self.dropped = 0


class RtcmTcpServer:
    """Broadcast bytes to every connected TCP client (module docstring).

    ``port`` 0 lets the OS choose (``self.port`` tells which); ``host``
    "127.0.0.1" serves this machine only, "0.0.0.0" every interface.
    """

    def __init__(self, port: int = 0, host: str = "127.0.0.1"):
        if not 0 <= int(port) <= 65535:
            raise ValueError(f"RTCM TCP port {port!r}: must be 0..65535 (parameter rtcm_tcp_port)")
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self.sock.bind((host, int(port)))
        except OSError as exc:
            self.sock.close()
            raise ValueError(f"RTCM TCP server: cannot listen on {host}:{port} ({exc.strerror}) "
                             f"(parameter rtcm_tcp_port)") from None
        self.sock.listen(8)
        self.sock.settimeout(0.2)
        self.host, self.port = self.sock.getsockname()[:2]
        self._clients: list[_Client] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self.bytes_written = 0
        self.dropped_bytes = 0
        self._accept_thread = threading.Thread(target=self._accept, name=f"rtcm-tcp-{self.port}", daemon=True)
        self._accept_thread.start()

    @property
    def clients(self) -> int:
        with self._lock:
            return len(self._clients)

    def _accept(self) -> None:
        while not self._stop.is_set():
            try:
                conn, addr = self.sock.accept()
            except (TimeoutError, OSError):
                continue
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            c = _Client(conn, addr)
            with self._lock:
                self._clients.append(c)
            threading.Thread(target=self._send_loop, args=(c,), name=f"rtcm-tcp-{addr}", daemon=True).start()

    def _send_loop(self, c: _Client) -> None:
        while True:
            with c.cond:
                while not c.chunks and not c.closed:
                    c.cond.wait(0.5)
                if c.closed and not c.chunks:
                    break
                data = b"".join(c.chunks)
                c.chunks.clear()
                c.size = 0
            try:
                c.conn.sendall(data)
            except OSError:
                break
        c.conn.close()
        with self._lock:
            if c in self._clients:
                self._clients.remove(c)

    def write(self, data: bytes) -> int:
        """Queue ``data`` for every connected client; returns the number of clients."""
        data = bytes(data)
        self.bytes_written += len(data)
        with self._lock:
            clients = list(self._clients)
        for c in clients:
            with c.cond:
                c.chunks.append(data)
                c.size += len(data)
                while c.size > CLIENT_QUEUE_BYTES and len(c.chunks) > 1:
                    old = c.chunks.popleft()
                    c.size -= len(old)
                    c.dropped += len(old)
                    self.dropped_bytes += len(old)
                c.cond.notify()
        return len(clients)

    def flush(self) -> None:
        """Nothing to do: the client threads send as soon as data is queued (RtcmWriter sink protocol)."""

    def close(self) -> None:
        """Stop accepting, send what is queued, close every client."""
        self._stop.set()
        self._accept_thread.join(2.0)
        self.sock.close()
        with self._lock:
            clients = list(self._clients)
        for c in clients:
            with c.cond:
                c.closed = True
                c.cond.notify()

    def __enter__(self) -> RtcmTcpServer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
