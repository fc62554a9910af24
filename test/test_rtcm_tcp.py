"""RTCM3 served on TCP: RTKLIB's str2str, connecting as a TCP client, receives exactly the bytes written."""
from __future__ import annotations

import shutil
import socket
import subprocess
import time

import pytest

from gnss_sim_ros2.core.rtcm.frame import epochs_of
from gnss_sim_ros2.core.rtcm.tcp_server import RtcmTcpServer


def _stream(tmp_path) -> bytes:
    from test_rtcm_rtklib import BASE_ECEF_M, simulate_to_rtcm

    run = simulate_to_rtcm(tmp_path, BASE_ECEF_M, "GEC", 20.0, 1.0, 5, "TCPS")
    return run["rtcm"].read_bytes()


@pytest.mark.skipif(shutil.which("str2str") is None, reason="RTKLIB str2str is not installed (apt-get install rtklib)")
def test_str2str_receives_our_stream(tmp_path):
    data = _stream(tmp_path)
    epochs = epochs_of(data)
    out = tmp_path / "got.rtcm3"
    with RtcmTcpServer() as srv:
        proc = subprocess.Popen(["str2str", "-in", f"tcpcli://127.0.0.1:{srv.port}#rtcm3", "-out", f"file://{out}"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        try:
            t_end = time.monotonic() + 10
            while srv.clients == 0 and time.monotonic() < t_end:
                time.sleep(0.05)
            assert srv.clients == 1
            for e in epochs:
                srv.write(e)
                time.sleep(0.01)
            t_end = time.monotonic() + 10
            while (not out.exists() or out.stat().st_size < len(data)) and time.monotonic() < t_end:
                time.sleep(0.1)
        finally:
            proc.terminate()
            proc.wait(10)
    assert out.read_bytes() == data
    assert srv.bytes_written == len(data) and srv.dropped_bytes == 0


def test_two_clients_and_a_client_that_leaves():
    with RtcmTcpServer() as srv:
        a = socket.create_connection(("127.0.0.1", srv.port))
        b = socket.create_connection(("127.0.0.1", srv.port))
        t_end = time.monotonic() + 5
        while srv.clients < 2 and time.monotonic() < t_end:
            time.sleep(0.02)
        assert srv.write(b"\xd3\x00\x00abc") == 2
        a.settimeout(5)
        b.settimeout(5)
        assert a.recv(100) == b"\xd3\x00\x00abc" and b.recv(100) == b"\xd3\x00\x00abc"
        a.close()
        for _ in range(50):
            srv.write(b"x" * 1000)
            if srv.clients == 1:
                break
            time.sleep(0.05)
        assert srv.clients == 1
        b.close()


def test_port_in_use_is_a_clear_error():
    with RtcmTcpServer() as srv, pytest.raises(ValueError, match=f"cannot listen on 127.0.0.1:{srv.port}"):
        RtcmTcpServer(port=srv.port)
    with pytest.raises(ValueError, match="0..65535"):
        RtcmTcpServer(port=70000)
