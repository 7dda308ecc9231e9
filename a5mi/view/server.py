"""The live page's HTTP side: routes, the token, server-sent events and the jobs handed to the engine (docs/VIEW.md).

Threads: the HTTP server (:class:`http.server.ThreadingHTTPServer`, one daemon thread per request) and the file
watcher only read the :class:`Hub` and post :class:`Jobs`; everything that touches Mitsuba runs in
:func:`run_engine` on the caller's thread (the main thread in ``a5mi view``, where signals arrive), one job at a
time. Render requests coalesce: a burst of control changes or saves renders once, with the latest options.

Security: bound to 127.0.0.1 only; every request needs ``token=T`` in its query (a random
``secrets.token_urlsafe(24)`` made per run, compared with :func:`hmac.compare_digest`), else 403, before any
route is looked at, so another local user cannot read the scene or its images. Against DNS rebinding the
``Host`` header must name this server (``127.0.0.1:PORT`` or ``localhost:PORT``) and an ``Origin``, when sent,
its origin (``http://127.0.0.1:PORT`` or ``http://localhost:PORT``), else 403. A connection silent for
:data:`IDLE_SECONDS` (a request line, headers, a body, the next keep-alive request) is closed; a request body
must declare its ``Content-Length`` as decimal digits (else 400) of at most :data:`MAX_BODY` bytes (else 413).

Routes (``?token=T`` on each): ``GET /`` the page; ``GET /static/NAME`` its script and style (package data);
``GET /api/state`` the state as JSON; ``GET /api/image/{render,reference,diff}.png`` the current frame's PNG
bytes; ``POST /api/render`` a JSON object of control values (:mod:`a5mi.view.controls`: 202, or 400 with the
one-line error); ``GET /api/trace?x=X&y=Y`` the pixel's trace (:meth:`a5mi.view.engine.ViewEngine.trace`; 400
with the error); ``GET /api/values/{render,reference}.bin`` the current frame's pixel values
(:func:`a5mi.view.pixels.values_blob`: float32 linear RGB, then the 8-bit levels); ``POST /api/diagnose`` a JSON
object ``{"image": "render" | "reference"}``: runs :func:`a5mi.view.pixels.diagnose_frame` on the engine's thread
(202; the result comes as the state's ``diagnosis``); ``POST /api/region`` ``{"region": [X0, X1, Y0, Y1]}`` or
``{"region": null}``: marks (clears) the region rendered first (:mod:`a5mi.view.region`: 202, or 400 with the
one-line error; the state's ``region``); ``GET /api/events`` the event stream: ``event: state``
(the whole state, on connect and after every change) and ``event: progress`` (``{"stage", "done", "total"}``),
each ``data:`` one JSON line, and a ``: ping`` comment every :data:`PING_SECONDS`.
"""

from __future__ import annotations

import hmac
import json
import queue
import threading
from collections.abc import Callable
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources as package_data
from typing import Any
from urllib.parse import parse_qs, urlsplit

from a5mi.platform.errors import UserError
from a5mi.view.jobs import Jobs
from a5mi.view.region import RegionError, parse_region

#: Seconds between two keep-alive comments of the event stream.
PING_SECONDS = 15.0
#: Seconds a trace request waits for the engine.
TRACE_SECONDS = 600.0
#: Seconds a connection may stay silent before the server closes it (each socket operation's limit).
IDLE_SECONDS = 20.0
#: The largest request body taken (bytes): a control object is a few hundred.
MAX_BODY = 1 << 16
#: The page's files (package data ``a5mi/view/static``) and their content types.
STATIC = {"index.html": "text/html; charset=utf-8", "view.js": "text/javascript; charset=utf-8",
          "look.js": "text/javascript; charset=utf-8", "view.css": "text/css; charset=utf-8"}
IMAGES = ("render", "reference", "diff")
#: The images whose pixel values the page reads (``/api/values/NAME.bin``, stored as ``values-NAME``).
VALUES = ("render", "reference")
#: What ``POST /api/diagnose`` may diagnose.
DIAGNOSABLE = ("render", "reference")


def sse(event: str, data: Any) -> bytes:
    """One server-sent event: ``event: NAME``, ``data: JSON`` (one line), blank line."""
    return f"event: {event}\ndata: {json.dumps(finite(data), allow_nan=False, separators=(',', ':'))}\n\n".encode()


def static_file(name: str) -> bytes:
    """A file of the page from the package data."""
    return package_data.files("a5mi.view").joinpath("static", name).read_bytes()


class Hub:
    """What the page reads: the state (a JSON-ready dict), the current images, and the event subscribers."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._state: dict[str, Any] = {"version": 0, "busy": True, "error": None}
        self._images: dict[str, bytes | Callable[[], bytes]] = {}
        self._subs: list[queue.Queue[bytes | None]] = []
        self.closed = False

    def state(self) -> dict[str, Any]:
        with self._lock:
            return dict(self._state)

    def image(self, name: str) -> bytes | None:
        """The bytes stored as ``name``; one stored as a function (made only when asked for: the pixel values)
        is called here, on the asking thread, once."""
        with self._lock:
            data = self._images.get(name)
        if callable(data):
            made = data()
            with self._lock:
                if self._images.get(name) is data:
                    self._images[name] = made
            return made
        return data

    def update(self, images: dict[str, bytes | Callable[[], bytes] | None] | None = None, **state: Any) -> None:
        """Change the state (and images: None removes one; a function is called when the image is first asked
        for) and send the whole state to every subscriber."""
        with self._lock:
            self._state.update(state)
            for name, data in (images or {}).items():
                if data is None:
                    self._images.pop(name, None)
                else:
                    self._images[name] = data
            doc = dict(self._state)
        self._send(sse("state", doc))

    def progress(self, stage: str, done: int, total: int, **extra: Any) -> None:
        """A ``progress`` event: the stage, ``done`` of ``total``, and what the engine adds (``rays``, ``eta``,
        ``estimate``: the work estimate's bound so far, the seconds left, its summary)."""
        self._send(sse("progress", {"stage": stage, "done": done, "total": total, **extra}))

    def _send(self, event: bytes | None) -> None:
        with self._lock:
            subs = list(self._subs)
        for q in subs:
            q.put(event)

    def subscribe(self) -> queue.Queue[bytes | None]:
        q: queue.Queue[bytes | None] = queue.Queue()
        with self._lock:
            self._subs.append(q)
        return q

    def unsubscribe(self, q: queue.Queue[bytes | None]) -> None:
        with self._lock:
            if q in self._subs:
                self._subs.remove(q)

    def close(self) -> None:
        """End every event stream (the server is stopping)."""
        self.closed = True
        self._send(None)


def make_handler(token: str, hub: Hub, jobs: Jobs, apply_controls: Callable[[Any], Any]) -> type:
    """The request handler class of one server (module docstring)."""

    class Handler(BaseHTTPRequestHandler):
        server_version = "a5mi-view"
        protocol_version = "HTTP/1.1"
        default_request_version = "HTTP/1.1"  # a malformed request line still gets a status line, not HTTP/0.9

        def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - the base class's name
            pass  # no access log on the terminal: the page is the output

        def _reply(self, status: int, body: bytes, ctype: str = "application/json", cache: bool = False) -> None:
            self.send_response(status)
            self.send_header("Content-Type", ctype)
            self.send_header("Content-Length", str(len(body)))
            self.send_header("Cache-Control", "max-age=3600" if cache else "no-store")
            self.send_header("X-Content-Type-Options", "nosniff")
            self.end_headers()
            if self.command != "HEAD":
                self.wfile.write(body)

        def _json(self, status: int, doc: Any) -> None:
            self._reply(status, json.dumps(finite(doc), allow_nan=False).encode())

        timeout = IDLE_SECONDS  # StreamRequestHandler: the socket's timeout, so no silent peer holds a thread

        def _same_origin(self) -> bool:
            port = self.server.server_address[1]
            hosts = (f"127.0.0.1:{port}", f"localhost:{port}")
            origin = self.headers.get("Origin")
            return self.headers.get("Host", "") in hosts and (origin is None or origin in
                                                               tuple(f"http://{h}" for h in hosts))

        def _authorised(self) -> tuple[str, dict[str, list[str]]] | None:
            if not self._same_origin():
                self._reply(403, b"forbidden: Host or Origin is not this server (127.0.0.1 or localhost)\n",
                            "text/plain")
                return None
            url = urlsplit(self.path)
            query = parse_qs(url.query)
            given = (query.get("token") or [""])[0]
            if not hmac.compare_digest(given.encode(), token.encode()):
                self._reply(403, b"forbidden: this page needs the token printed by a5mi view\n", "text/plain")
                return None
            return url.path, query

        def do_GET(self) -> None:  # noqa: N802 - http.server's name
            auth = self._authorised()
            if auth is None:
                return
            path, query = auth
            if path in ("/", "/index.html"):
                page = static_file("index.html").replace(b"{{TOKEN}}", token.encode())
                self._reply(200, page, STATIC["index.html"])
            elif path.startswith("/static/") and path[len("/static/"):] in STATIC:
                name = path[len("/static/"):]
                self._reply(200, static_file(name), STATIC[name])
            elif path == "/api/state":
                self._json(200, hub.state())
            elif path.startswith("/api/image/") and path[len("/api/image/"):].removesuffix(".png") in IMAGES:
                data = hub.image(path[len("/api/image/"):].removesuffix(".png"))
                if data is None:
                    self._json(404, {"error": "no such image yet"})
                else:
                    self._reply(200, data, "image/png")
            elif path.startswith("/api/values/") and path[len("/api/values/"):].removesuffix(".bin") in VALUES:
                try:  # made here (Hub.image): the reference's .exr is read on the first request
                    data = hub.image("values-" + path[len("/api/values/"):].removesuffix(".bin"))
                except Exception as exc:  # noqa: BLE001 - an unreadable reference: one JSON line, the server goes on
                    self._json(500, {"error": f"a5mi view: error: {(str(exc).splitlines() or [''])[0]}"})
                    return
                if data is None:
                    self._json(404, {"error": "no such image yet"})
                else:
                    self._reply(200, data, "application/octet-stream")
            elif path == "/api/trace":
                self._trace(query)
            elif path == "/api/events":
                self._events()
            else:
                self._json(404, {"error": f"no route {path[:80]}"})

        def do_HEAD(self) -> None:  # noqa: N802
            self.do_GET()

        def do_POST(self) -> None:  # noqa: N802
            auth = self._authorised()
            if auth is None:
                return
            path, _ = auth
            declared = (self.headers.get("Content-Length") or "0").strip()
            if not declared.isascii() or not declared.isdigit():
                self.close_connection = True
                self._json(400, {"error": f"a5mi view: error: Content-Length '{declared[:20]}' is not a byte count"})
                return
            if int(declared) > MAX_BODY:
                self.close_connection = True  # the body is not read: the connection cannot be reused
                self._json(413, {"error": f"a5mi view: error: a request body of {int(declared)} bytes is more "
                                          f"than {MAX_BODY}"})
                return
            body = self.rfile.read(int(declared))
            if path == "/api/diagnose":
                self._diagnose(body)
                return
            if path == "/api/region":
                self._region(body)
                return
            if path != "/api/render":
                self._json(404, {"error": f"no route {path[:80]}"})
                return
            try:
                options = apply_controls(json.loads(body or b"{}"))
            except json.JSONDecodeError:
                self._json(400, {"error": "a5mi view: error: the request is not JSON"})
                return
            except (UserError, ValueError) as exc:  # ControlError; a RenderOptions check
                self._json(400, {"error": f"a5mi view: error: {exc}"})
                return
            jobs.render(options)
            self._json(202, {"queued": True})

        def _diagnose(self, body: bytes) -> None:
            try:
                doc = json.loads(body or b"{}")
            except json.JSONDecodeError:
                doc = None
            image = doc.get("image", "render") if isinstance(doc, dict) else None
            if image not in DIAGNOSABLE:
                self._json(400, {"error": "a5mi view: error: give {\"image\": \"render\"} or {\"image\": "
                                          "\"reference\"}"})
                return
            hub.update(diagnosis={"status": "queued", "image": image})
            jobs.diagnose(image)
            self._json(202, {"queued": True})

        def _region(self, body: bytes) -> None:
            try:
                region = parse_region(json.loads(body or b"{}"), hub.state().get("size"))
            except json.JSONDecodeError:
                self._json(400, {"error": "a5mi view: error: the request is not JSON"})
                return
            except RegionError as exc:
                self._json(400, {"error": f"a5mi view: error: {exc}"})
                return
            hub.update(region=None if region is None else list(region))
            jobs.mark(region)
            self._json(202, {"region": region})

        def _trace(self, query: dict[str, list[str]]) -> None:
            try:
                x, y = int(query["x"][0]), int(query["y"][0])
            except (KeyError, ValueError):
                self._json(400, {"error": "a5mi view: error: give integer x and y"})
                return
            try:
                doc = jobs.trace(x, y).result(timeout=TRACE_SECONDS)
            except (UserError, ValueError) as exc:  # TraceError; a SceneError
                self._json(400, {"error": str(exc) if ": error: " in str(exc) else f"a5mi view: error: {exc}"})
                return
            except Exception as exc:  # noqa: BLE001 - reported on the page, the server goes on
                self._json(500, {"error": f"a5mi view: internal error: {type(exc).__name__}: {exc}"})
                return
            self._reply(200, json.dumps(finite(doc), allow_nan=False).encode())

        def _events(self) -> None:
            q = hub.subscribe()
            try:
                self.send_response(200)
                self.send_header("Content-Type", "text/event-stream")
                self.send_header("Cache-Control", "no-store")
                self.send_header("Connection", "close")
                self.end_headers()
                self.close_connection = True
                self.wfile.write(sse("state", hub.state()))
                self.wfile.flush()
                while not hub.closed:
                    try:
                        event = q.get(timeout=PING_SECONDS)
                    except queue.Empty:
                        event = b": ping\n\n"
                    if event is None:
                        break
                    self.wfile.write(event)
                    self.wfile.flush()
            except (BrokenPipeError, ConnectionResetError, OSError):
                pass  # the tab was closed: the server goes on
            finally:
                hub.unsubscribe(q)

    return Handler


def finite(x: Any) -> Any:
    """``x`` as strict JSON values: numpy scalars and arrays as Python ones, a float that is not finite (a miss's
    ``t``, an infinite PSNR) as None, tuples as lists."""
    import math

    import numpy as np

    if isinstance(x, dict):
        return {str(k): finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [finite(v) for v in x]
    if isinstance(x, np.ndarray):
        return finite(x.tolist())
    if isinstance(x, (np.floating, np.integer, np.bool_)):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


class Server:
    """The HTTP server on 127.0.0.1 (``port`` 0: a free one) in a daemon thread."""

    def __init__(self, token: str, hub: Hub, jobs: Jobs, apply_controls: Callable[[Any], Any],
                 port: int = 0) -> None:
        self.httpd = ThreadingHTTPServer(("127.0.0.1", port), make_handler(token, hub, jobs, apply_controls))
        self.httpd.daemon_threads = True
        self.hub = hub
        self.token = token
        self._thread = threading.Thread(target=self.httpd.serve_forever, kwargs={"poll_interval": 0.2},
                                        name="a5mi-view-http", daemon=True)

    @property
    def port(self) -> int:
        return int(self.httpd.server_address[1])

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}/?token={self.token}"

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self.hub.close()
        self.httpd.shutdown()
        self.httpd.server_close()


__all__ = ["DIAGNOSABLE", "IMAGES", "PING_SECONDS", "STATIC", "VALUES", "Hub", "Jobs", "Server", "finite",
           "make_handler", "sse", "static_file"]
