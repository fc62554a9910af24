"""fetch_broadcast_nav against a local HTTP server (127.0.0.1, port chosen by the OS): success,
cache hit without a request, 404 falling through to the next template, a server failing once,
corrupt gzip, a non-RINEX answer.  No other address is contacted: every call passes its own
templates and a proxy-free opener."""
from __future__ import annotations

import datetime as dt
import gzip
import threading
import urllib.request
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import ncompress
import pytest

from gnss_sim_ros2.core.ephemeris.download import NavDownloadError, fetch_broadcast_nav, template_fields
from gnss_sim_ros2.core.time import GnssTime

NAV_TEXT = (
    b"     3.04           N: GNSS NAV DATA    M: MIXED            RINEX VERSION / TYPE\n"
    b"                                                            END OF HEADER\n"
)
NO_PROXY = urllib.request.build_opener(urllib.request.ProxyHandler({}))


class _Server:
    """Routes: path -> list of (status, body); the last entry repeats.  Counts requests per path."""

    def __init__(self):
        self.routes: dict[str, list[tuple[int, bytes]]] = {}
        self.hits: dict[str, int] = {}
        outer = self

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self):  # noqa: N802 (http.server API)
                outer.hits[self.path] = outer.hits.get(self.path, 0) + 1
                answers = outer.routes.get(self.path, [(404, b"not found")])
                status, body = answers[min(outer.hits[self.path], len(answers)) - 1]
                self.send_response(status)
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, *args):
                pass

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.base = f"http://127.0.0.1:{self.httpd.server_address[1]}"
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)
        self.thread.start()

    def close(self):
        self.httpd.shutdown()
        self.httpd.server_close()


@pytest.fixture
def server():
    s = _Server()
    yield s
    s.close()


def _fetch(server, day, tmp_path, templates, **kw):
    kw.setdefault("retries", 3)
    return fetch_broadcast_nav(day, cache_dir=tmp_path / "cache", templates=[server.base + t for t in templates],
                               backoff_s=0.0, timeout_s=5.0, opener=NO_PROXY, **kw)


def test_template_fields():
    f = template_fields(dt.date(2022, 1, 1))
    # 2022-01-01: day 001, GPS week 2190, Saturday (GPS day of week 6)
    assert f == {"yyyy": "2022", "yy": "22", "ddd": "001", "mm": "01", "dd": "01", "gpsweek": "2190", "dow": "6"}
    assert template_fields(dt.date(2024, 12, 31))["ddd"] == "366"


def test_success_then_cache_hit(server, tmp_path):
    server.routes["/2022/001/nav_2022001.rnx.gz"] = [(200, gzip.compress(NAV_TEXT))]
    tpl = ["/{yyyy}/{ddd}/nav_{yyyy}{ddd}.rnx.gz"]
    p = _fetch(server, "2022-01-01", tmp_path, tpl)
    assert p.read_bytes() == NAV_TEXT
    assert p.name == "nav_2022001.rnx"
    assert p.parent == tmp_path / "cache" / "brdc" / "2022" / "001"
    assert server.hits == {"/2022/001/nav_2022001.rnx.gz": 1}
    p2 = _fetch(server, GnssTime.from_iso("2022-01-01T13:00:00"), tmp_path, tpl)
    assert p2 == p
    assert server.hits == {"/2022/001/nav_2022001.rnx.gz": 1}  # no second request


def test_404_falls_through_then_clear_error(server, tmp_path):
    server.routes["/b/brdc0010.22n.Z"] = [(200, ncompress.compress(NAV_TEXT))]
    tpl = ["/a/{ddd}.rnx.gz", "/b/brdc{ddd}0.{yy}n.Z"]
    p = _fetch(server, dt.date(2022, 1, 1), tmp_path, tpl)
    assert p.read_bytes() == NAV_TEXT and p.name == "brdc0010.22n"
    assert server.hits == {"/a/001.rnx.gz": 1, "/b/brdc0010.22n.Z": 1}  # a 404 is not retried
    with pytest.raises(NavDownloadError) as exc:
        _fetch(server, dt.date(2022, 1, 2), tmp_path, tpl)
    msg = str(exc.value)
    assert "2022-01-02" in msg and "HTTP 404" in msg
    assert f"{server.base}/a/002.rnx.gz" in msg and f"{server.base}/b/brdc0020.22n.Z" in msg


def test_server_error_is_retried(server, tmp_path):
    server.routes["/x/001.rnx"] = [(503, b"busy"), (200, NAV_TEXT)]
    p = _fetch(server, "2022-01-01", tmp_path, ["/x/{ddd}.rnx"])
    assert p.read_bytes() == NAV_TEXT
    assert server.hits["/x/001.rnx"] == 2
    server.routes["/y/001b.rnx"] = [(500, b"down")]
    with pytest.raises(NavDownloadError, match=r"HTTP 500"):
        _fetch(server, "2022-01-01", tmp_path, ["/y/{ddd}b.rnx"], retries=2)
    assert server.hits["/y/001b.rnx"] == 2


def test_corrupt_gzip_and_wrong_content(server, tmp_path):
    good = gzip.compress(NAV_TEXT)
    server.routes["/c/001.rnx.gz"] = [(200, good[: len(good) // 2])]
    with pytest.raises(NavDownloadError, match=r"corrupt gzip data from http://127\.0\.0\.1:\d+/c/001\.rnx\.gz "
                                                r"\(date 2022-01-01\)"):
        _fetch(server, "2022-01-01", tmp_path, ["/c/{ddd}.rnx.gz"])
    server.routes["/h/001.rnx"] = [(200, b"<html>login</html>\n")]
    with pytest.raises(NavDownloadError, match="not a RINEX navigation file"):
        _fetch(server, "2022-01-01", tmp_path, ["/h/{ddd}.rnx"])
    assert not (tmp_path / "cache" / "brdc" / "2022" / "001" / "001.rnx").exists()


def test_network_error_and_bad_arguments(tmp_path):
    # a port nobody listens on: bind, read the port, close
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(NavDownloadError, match="URLError"):
        fetch_broadcast_nav("2022-01-01", cache_dir=tmp_path, templates=[f"http://127.0.0.1:{port}/{{ddd}}"],
                            retries=2, backoff_s=0.0, timeout_s=2.0, opener=NO_PROXY)
    with pytest.raises(ValueError, match="YYYY-MM-DD"):
        fetch_broadcast_nav("01/01/2022", cache_dir=tmp_path, templates=["http://127.0.0.1:1/x"])
    with pytest.raises(ValueError, match="bad URL template"):
        fetch_broadcast_nav("2022-01-01", cache_dir=tmp_path, templates=["http://127.0.0.1:1/{doy}"])
