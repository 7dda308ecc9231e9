"""``a5mi view``'s HTTP server against hostile local clients (a5mi/view/server.py, docs/VIEW.md): a malformed or
huge ``Content-Length`` is one JSON error (400, 413) without a traceback or a thread held on the body, a silent
connection is closed after ``IDLE_SECONDS``, and a ``Host`` or ``Origin`` that is not this server is refused
(DNS rebinding: the token is not the only check)."""

from __future__ import annotations

import json
import socket
import threading

import pytest
from view_scenes import time_limit

from a5mi.render.options import RenderOptions
from a5mi.view import controls
from a5mi.view import server as server_module
from a5mi.view.server import Hub, Jobs, Server

TOKEN = "t0k3n-for-limits"


@pytest.fixture
def served(monkeypatch):  # noqa: ANN001, ANN201 - fixture
    monkeypatch.setattr(server_module, "IDLE_SECONDS", 1.0, raising=False)
    server = Server(TOKEN, Hub(), Jobs(), lambda values: controls.apply(RenderOptions(), values))
    server.start()
    try:
        yield server
    finally:
        server.stop()


def _exchange(server: Server, head: str, body: bytes = b"") -> tuple[int, bytes]:
    """Send a raw request; the status and the body of the answer (the server closes or answers in time)."""
    sock = socket.create_connection(("127.0.0.1", server.port), timeout=30)
    try:
        sock.sendall(head.encode("latin-1") + b"\r\n\r\n" + body)
        buf = b""
        while b"\r\n\r\n" not in buf:
            chunk = sock.recv(65536)
            if not chunk:
                break
            buf += chunk
        first, _, rest = buf.partition(b"\r\n\r\n")
        length = next((int(ln.split(b":")[1]) for ln in first.split(b"\r\n") if ln.lower().startswith(
            b"content-length:")), 0)
        while len(rest) < length:
            chunk = sock.recv(65536)
            if not chunk:
                break
            rest += chunk
        return int(first.split(b" ")[1]), rest
    finally:
        sock.close()


@pytest.mark.parametrize("declared, status, words", [
    ("abc", 400, "Content-Length 'abc' is not a byte count"),
    ("-5", 400, "Content-Length '-5' is not a byte count"),
    ("1e3", 400, "Content-Length '1e3' is not a byte count"),
    ("99999999999999", 413, "a request body of 99999999999999 bytes is more than 65536"),
])
def test_a_bad_content_length_is_one_json_error_and_no_traceback(served, capfd, declared: str, status: int,  # noqa: ANN001
                                                                   words: str) -> None:
    with time_limit(60):
        code, body = _exchange(served, f"POST /api/render?token={TOKEN} HTTP/1.1\r\nHost: 127.0.0.1:{served.port}"
                                       f"\r\nContent-Length: {declared}")
    assert code == status and json.loads(body) == {"error": f"a5mi view: error: {words}"}
    out, err = capfd.readouterr()
    assert "Traceback" not in err and "Exception" not in err, err


def test_a_silent_connection_is_closed_and_its_thread_ends(served) -> None:  # noqa: ANN001
    before = threading.active_count()
    with time_limit(60):
        idle = [socket.create_connection(("127.0.0.1", served.port), timeout=30) for _ in range(20)]
        half = socket.create_connection(("127.0.0.1", served.port), timeout=30)  # a body that never comes
        half.sendall(f"POST /api/render?token={TOKEN} HTTP/1.1\r\nHost: 127.0.0.1:{served.port}\r\n"
                     "Content-Length: 100\r\n\r\n{".encode())
        for s in [*idle, half]:
            assert s.recv(1 << 16) == b""  # end of stream: the server closed it (a hang fails the 30 s recv)
            s.close()
        deadline = 200
        while threading.active_count() > before and deadline:
            threading.Event().wait(0.05)
            deadline -= 1
    assert threading.active_count() <= before


@pytest.mark.parametrize("headers, status", [
    ("Host: 127.0.0.1:{port}", 200),
    ("Host: localhost:{port}", 200),
    ("Host: 127.0.0.1:{port}\r\nOrigin: http://127.0.0.1:{port}", 200),
    ("Host: evil.example:{port}", 403),
    ("Host: 127.0.0.1:{port}\r\nOrigin: http://evil.example", 403),
    ("Host: 127.0.0.1:{port}\r\nOrigin: null", 403),
    ("Host: 127.0.0.1:1", 403),
    ("X-No-Host: 1", 403),
])
def test_host_and_origin_must_be_this_server(served, headers: str, status: int) -> None:  # noqa: ANN001
    with time_limit(60):
        code, _ = _exchange(served, f"GET /api/state?token={TOKEN} HTTP/1.1\r\n"
                                    + headers.format(port=served.port) + "\r\nConnection: close")
    assert code == status


@pytest.mark.parametrize("headers, status", [
    ("Host: 127.0.0.1:{port}", 202),
    ("Host: evil.example:{port}", 403),
    ("Host: 127.0.0.1:{port}\r\nOrigin: http://evil.example", 403),
    ("X-No-Host: 1", 403),
])
@pytest.mark.parametrize("route, body", [("/api/diagnose", b'{"image": "render"}'),
                                         ("/api/region", b'{"region": [1, 5, 2, 6]}')])
def test_the_diagnose_and_region_routes_check_host_and_origin(served, headers: str, status: int, route: str,  # noqa: ANN001
                                                              body: bytes) -> None:
    with time_limit(60):
        code, _ = _exchange(served, f"POST {route}?token={TOKEN} HTTP/1.1\r\n" + headers.format(port=served.port)
                            + f"\r\nContent-Length: {len(body)}\r\nConnection: close", body)
    assert code == status
