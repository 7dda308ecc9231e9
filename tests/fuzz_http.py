"""The ``http`` mutants of ``make fuzz``: one hostile request to ``a5mi view``'s server (a5mi/view/server.py).

A request is drawn from routes x methods x tokens x bodies x headers: the page's routes and junk ones
(traversal, encoded bytes, long paths), every method and a garbage one, the right token, none, a wrong or
truncated one, a huge one, control bodies (valid, out of range, wrong types, not JSON, binary, deep), and
``Host`` / ``Origin`` / ``Content-Length`` / ``Transfer-Encoding`` of every kind. :func:`judge` holds the server to
its promises: an answer (a status line) or a clean close within the time limit, never a 5xx, nothing printed on
the terminal (no traceback), 403 unless both the token and ``Host``/``Origin`` are right, 202 only for a body
the controls accept (on ``/api/diagnose``: only for a body that asks for a diagnosis; on ``/api/region``: only for
a region :func:`a5mi.view.region.parse_region` takes), and after the server
stops no thread of it left running.
"""

from __future__ import annotations

import json
import random
import socket
import threading
import urllib.parse

TOKEN = "fuzz-token-Zq3"
ROUTES = ("/", "/index.html", "/static/view.js", "/static/look.js", "/static/view.css", "/static/../server.py",
          "/static/%2e%2e/x", "/api/values/render.bin", "/api/values/diff.bin", "/api/values/../x", "/api/diagnose",
          "/api/state", "/api/events", "/api/image/render.png", "/api/image/reference.png", "/api/image/../x",
          "/api/render", "/api/trace", "/api/trace?x=1&y=2", "/api/trace?x=-1&y=1e9", "/api/trace?x=a&y=",
          "/nowhere", "//", "/%00", "/" + "a" * 5000, "/api/state/..;/", "/\u00e9", "/api/region")
METHODS = ("GET", "POST", "HEAD", "PUT", "DELETE", "OPTIONS", "PATCH", "TRACE", "CONNECT", "G\x00T", "get", "")
CONTROLS = ({}, {"width": 8, "height": 8}, {"bounces": 2, "shadows": True}, {"indirect": 200, "bounces": 2},
            {"indirect": 4096, "bounces": 64}, {"integrator": "path", "indirect": 3}, {"spp": 0},
            {"width": 2, "filter": True}, {"width": 100000, "height": 100000}, {"width": 1.5}, {"shadows": "yes"},
            {"integrator": "bogus"}, {"fresnel": None}, {"nope": 1}, {"width": True}, {"rr_depth": -1},
            {"width": 10**30}, {"spp": 65536, "jitter": True}, {"region": [1, 5, 2, 6]}, {"region": None},
            {"region": [5, 1, 2, 6]}, {"region": [0, 10**30, 0, 1]}, {"region": [1.5, 2, 3, 4]}, {"region": "1 2 3 4"})


def _body(rng: random.Random) -> bytes:
    kind = rng.randrange(7)
    if kind == 0:
        return b""
    if kind <= 2:
        return json.dumps(rng.choice(CONTROLS)).encode()
    if kind == 3:
        return rng.choice((b"not json", b"[1, 2]", b"null", b'"s"', b"{\"width\": NaN}", b"{" * 3000 + b"}" * 3000))
    if kind == 4:
        return bytes(rng.randrange(256) for _ in range(rng.choice((1, 64, 4096))))
    if kind == 5:
        return json.dumps({"width": "x" * 70000}).encode()  # more than the 64 KiB a body may hold
    return "{\"width\": 8, \"é\": \"\u2028\"}".encode()


def request(seed: int) -> tuple[str, str, bytes, dict[str, str]]:
    """(method, target, body, headers) of the mutant ``seed``; header values may be junk, ``{port}`` is filled
    in when sent."""
    rng = random.Random(seed)
    route = rng.choice(ROUTES)
    token = rng.choice((TOKEN, TOKEN, TOKEN, None, "", TOKEN[:-1], TOKEN + "x", "x" * 9000, TOKEN.upper()))
    if token is not None:
        sep = "&" if "?" in route else "?"
        route += f"{sep}token={urllib.parse.quote(token)}" + rng.choice(("", "", "&token=wrong", "&x=%ff"))
    method = rng.choice(METHODS[:3] * 4 + METHODS)
    body = _body(rng) if method in ("POST", "PUT", "PATCH") or rng.random() < 0.1 else b""
    headers = {"Host": rng.choice(("127.0.0.1:{port}",) * 6 + ("localhost:{port}", "evil.example:{port}",
                                                             "127.0.0.1:1", "", "127.0.0.1:{port}\r\nHost: x"))}
    if rng.random() < 0.3:
        headers["Origin"] = rng.choice(("http://127.0.0.1:{port}", "http://localhost:{port}", "null",
                                        "http://evil.example", "https://127.0.0.1:{port}"))
    length = rng.random()
    if body or length < 0.2:
        headers["Content-Length"] = (str(len(body)) if length > 0.35 else
                                     rng.choice(("abc", "-1", "1e3", "99999999999999", str(len(body) + 50), "0",
                                                 " 12", "１２", "")))
    if rng.random() < 0.05:
        headers["Transfer-Encoding"] = "chunked"
    if rng.random() < 0.05:
        headers["X-Junk"] = "y" * rng.choice((10, 70000))
    return method, route, body, headers


def send(port: int, method: str, target: str, body: bytes, headers: dict[str, str], timeout: float) -> tuple[
        int | None, str]:
    """Send the raw request; (status or None for a clean close without an answer, a problem or '')."""
    head = f"{method} {target} HTTP/1.1\r\n" + "".join(f"{k}: {v.format(port=port)}\r\n" for k, v in
                                                       headers.items()) + "Connection: close\r\n\r\n"
    sock = socket.create_connection(("127.0.0.1", port), timeout=timeout)
    try:
        try:
            sock.sendall(head.encode("utf-8", "surrogateescape") + body)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the server answered and closed before reading it all (413, 400)
        buf = b""
        while b"\r\n" not in buf:
            try:
                chunk = sock.recv(65536)
            except ConnectionResetError:
                break
            except TimeoutError:
                return None, f"hang: no answer within {timeout:g} s"
            if not chunk:
                break
            buf += chunk
        if not buf:
            return None, ""
        parts = buf.split(b"\r\n", 1)[0].split(b" ")
        if len(parts) < 2 or not parts[1].isdigit():
            return None, f"bad status line: {buf[:80]!r}"
        return int(parts[1]), ""
    finally:
        sock.close()


def _diagnose_request(body: bytes) -> bool:
    """Whether ``body`` asks ``POST /api/diagnose`` for a diagnosis: empty, or a JSON object whose ``image`` is
    absent, ``render`` or ``reference``."""
    try:
        doc = json.loads(body or b"{}")
    except (json.JSONDecodeError, UnicodeDecodeError):
        return False
    return isinstance(doc, dict) and doc.get("image", "render") in ("render", "reference")


def _region_request(body: bytes) -> bool:
    """Whether ``body`` is a region ``POST /api/region`` takes (:func:`a5mi.view.region.parse_region`)."""
    from a5mi.view.region import RegionError, parse_region

    try:
        parse_region(json.loads(body or b"{}"))
    except (json.JSONDecodeError, UnicodeDecodeError, RegionError):
        return False
    return True


def judge(seed: int, timeout: float = 30.0) -> tuple[list[str], str, str]:
    """Run the mutant ``seed`` against a fresh server (no engine: jobs are queued, not rendered); (argv-like
    description, stderr printed, problem or '')."""
    import contextlib
    import io

    from a5mi.render.options import RenderOptions
    from a5mi.view import controls
    from a5mi.view.server import Hub, Jobs, Server

    method, target, body, headers = request(seed)
    accepted: list[object] = []

    def apply(values: object) -> RenderOptions:
        options = controls.apply(RenderOptions(), values)
        accepted.append(values)
        return options

    err = io.StringIO()
    before = {t.ident for t in threading.enumerate()}
    stop = threading.Event()

    def engine(jobs: Jobs) -> None:  # the engine's answer before any frame (a5mi/view/engine.py ``trace``)
        from a5mi.platform.errors import UserError

        while not stop.is_set():
            job = jobs.next(0.05)
            if job is not None and job[0] == "trace":
                job[1][2].set_exception(UserError("nothing rendered yet"))

    with contextlib.redirect_stderr(err):
        hub, jobs = Hub(), Jobs()
        server = Server(TOKEN, hub, jobs, apply)
        server.start()
        worker = threading.Thread(target=engine, args=(jobs,), name="fuzz-engine", daemon=True)
        worker.start()
        try:
            if target.startswith("/api/events") and method == "GET":
                hub.close()  # the stream ends at once: the mutant is about the request, not a long poll
            status, problem = send(server.port, method, target, body, headers, timeout)
        finally:
            server.stop()
            stop.set()
            worker.join()
    desc = ["http", method, target[:120], f"body {len(body)} B", json.dumps(headers)[:200]]
    if problem:
        return desc, err.getvalue(), problem
    printed = err.getvalue()
    if printed.strip():
        return desc, printed, f"printed on the terminal: {printed.strip().splitlines()[-1][:200]}"
    if status is not None and status >= 500 and status != 501:
        return desc, printed, f"status {status}"
    # the first of repeated headers counts (http.server's ``headers.get``), as a browser sends one
    host = headers.get("Host", "").format(port=server.port).split("\r\n")[0]
    origin = headers.get("Origin", "").format(port=server.port).split("\r\n")[0]
    given = (urllib.parse.parse_qs(urllib.parse.urlsplit(target).query).get("token") or [""])[0]
    good = (given == TOKEN and
            host in (f"127.0.0.1:{server.port}", f"localhost:{server.port}") and
            origin in ("", f"http://127.0.0.1:{server.port}", f"http://localhost:{server.port}"))
    if status == 200 and not good and method in ("GET", "HEAD", "POST"):
        return desc, printed, "answered 200 without the token, Host and Origin"
    if status == 202 and urllib.parse.urlsplit(target).path == "/api/diagnose":
        if not _diagnose_request(body):
            return desc, printed, "202 for a body that asks for no diagnosis"
    elif status == 202 and urllib.parse.urlsplit(target).path == "/api/region":
        if not _region_request(body):
            return desc, printed, "202 for a body that is no region"
    elif status == 202 and not accepted:
        return desc, printed, "202 for a body the controls did not accept"
    for t in threading.enumerate():
        if t.ident not in before and t.is_alive() and t.name.startswith("a5mi-view"):
            t.join(timeout)
            if t.is_alive():
                return desc, printed, f"thread {t.name} left running"
    return desc, printed, ""
