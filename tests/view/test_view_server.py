"""``a5mi view``'s server without a browser and without rendering: the token (403 without it or with a wrong
one), the routes, the server-sent events' format, the control checks, the job queue and the file watcher."""

from __future__ import annotations

import json
import socket
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest
from view_scenes import time_limit

from a5mi.render.options import RenderOptions
from a5mi.view import controls
from a5mi.view.server import Hub, Jobs, Server, finite, sse
from a5mi.view.watcher import Watcher

TOKEN = "t0k3n-for-tests"


@pytest.fixture
def served():  # noqa: ANN201 - fixture
    hub, jobs = Hub(), Jobs()
    server = Server(TOKEN, hub, jobs, lambda values: controls.apply(RenderOptions(), values))
    server.start()
    try:
        yield server, hub, jobs
    finally:
        server.stop()


def get(server: Server, path: str, token: str | None = TOKEN, data: bytes | None = None) -> tuple[int, bytes, str]:
    sep = "&" if "?" in path else "?"
    url = f"http://127.0.0.1:{server.port}{path}" + (f"{sep}token={token}" if token is not None else "")
    req = urllib.request.Request(url, data=data, headers={"Content-Type": "application/json"} if data else {})
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status, r.read(), r.headers.get("Content-Type", "")
    except urllib.error.HTTPError as e:
        return e.code, e.read(), e.headers.get("Content-Type", "")


def test_sse_event_format_and_strict_json() -> None:
    assert sse("state", {"a": 1, "b": [1.5, None]}) == b'event: state\ndata: {"a":1,"b":[1.5,null]}\n\n'
    assert sse("progress", {"psnr": float("inf")}) == b'event: progress\ndata: {"psnr":null}\n\n'
    import numpy as np

    assert finite({"x": (np.float32(0.5), float("nan")), 1: np.array([1, 2])}) == {"x": [0.5, None], "1": [1, 2]}


def test_every_request_needs_the_token(served) -> None:  # noqa: ANN001
    server, hub, _ = served
    with time_limit(60):
        for path in ("/", "/static/view.js", "/api/state", "/api/events", "/api/image/render.png", "/nowhere"):
            assert get(server, path, token=None)[0] == 403, path
            assert get(server, path, token="wrong")[0] == 403, path
            assert get(server, path, token=TOKEN[:-1])[0] == 403, path
        assert get(server, "/api/render", token="wrong", data=b"{}")[0] == 403
        assert server.httpd.server_address[0] == "127.0.0.1"


def test_routes(served) -> None:  # noqa: ANN001
    server, hub, jobs = served
    with time_limit(60):
        status, body, ctype = get(server, "/")
        assert status == 200 and ctype.startswith("text/html") and TOKEN.encode() in body
        assert b"{{TOKEN}}" not in body and b"http" not in body.replace(b"http-equiv", b"")  # no CDN: all local
        for name, kind in (("view.js", "text/javascript"), ("view.css", "text/css")):
            status, body, ctype = get(server, f"/static/{name}")
            assert status == 200 and ctype.startswith(kind) and len(body) > 500
        assert get(server, "/static/../server.py")[0] == 404
        assert get(server, "/api/image/render.png")[0] == 404  # nothing rendered yet
        hub.update({"render": b"\x89PNG fake"}, frame=1)
        status, body, ctype = get(server, "/api/image/render.png")
        assert (status, body, ctype) == (200, b"\x89PNG fake", "image/png")
        status, body, _ = get(server, "/api/state")
        assert status == 200 and json.loads(body)["frame"] == 1
        assert get(server, "/api/elsewhere")[0] == 404


def test_render_requests_are_checked_and_coalesce(served) -> None:  # noqa: ANN001
    server, _, jobs = served
    with time_limit(60):
        assert get(server, "/api/render", data=b'{"bounces": 2}')[0] == 202
        assert get(server, "/api/render", data=b'{"integrator": "path", "rr_depth": 2, "indirect": 0}')[0] == 202
        assert get(server, "/api/render", data=b'{"bounces": 3, "shadows": true}')[0] == 202
        for bad, why in ((b'{"bounces": 99}', "outside 0..64"), (b'{"shadows": 1}', "true or false"),
                         (b'{"colour": 1}', "unknown control"), (b'{"fresnel": "x"}', "expected one of"),
                         (b'{"filter": true, "width": 2}', "too small"), (b"not json", "not JSON")):
            status, body, _ = get(server, "/api/render", data=bad)
            assert status == 400 and why in json.loads(body)["error"], body
            assert json.loads(body)["error"].startswith("a5mi view: error: ")
        kind, (reload, options) = jobs.next(0.1)
        assert kind == "render" and not reload and (options.bounces, options.shadows) == (3, True)
        assert jobs.next(0.01) is None


def test_traces_go_first_and_errors_come_back_as_400(served) -> None:  # noqa: ANN001
    server, _, jobs = served
    with time_limit(60):
        import threading

        from a5mi.trace.core import TraceError

        jobs.render(RenderOptions(), reload=True)
        queued = jobs.trace(1, 2)
        assert jobs.next(0.1)[0] == "trace" and jobs.next(0.1)[0] == "render"  # the trace first
        queued.cancel()

        def engine() -> None:
            kind, (x, y, fut) = jobs.next(5)
            assert kind == "trace"
            fut.set_exception(TraceError(f"pixel ({x}, {y}) is outside the 4x4 image"))

        t = threading.Thread(target=engine)
        t.start()
        status, body, _ = get(server, "/api/trace?x=9&y=1")
        t.join(5)
        assert status == 400 and json.loads(body)["error"] == "a5mi view: error: pixel (9, 1) is outside the 4x4 image"
        assert get(server, "/api/trace?x=a")[0] == 400


def test_event_stream_and_a_closed_tab(served) -> None:  # noqa: ANN001
    server, hub, _ = served
    with time_limit(60):
        hub.update(frame=3)
        sock = socket.create_connection(("127.0.0.1", server.port), timeout=10)
        sock.sendall(f"GET /api/events?token={TOKEN} HTTP/1.1\r\nHost: 127.0.0.1:{server.port}\r\n\r\n".encode())
        buf = b""
        while b"\n\n" not in buf.partition(b"\r\n\r\n")[2]:  # the headers, then the first event
            buf += sock.recv(4096)
        head, _, rest = buf.partition(b"\r\n\r\n")
        assert b"200" in head.split(b"\r\n")[0] and b"text/event-stream" in head
        assert rest.startswith(b"event: state\ndata: {") and b'"frame":3' in rest
        hub.progress("render", 5, 10)
        while b"event: progress" not in rest:
            rest += sock.recv(4096)
        assert b'event: progress\ndata: {"stage":"render","done":5,"total":10}\n\n' in rest
        sock.close()  # the tab is closed: the server goes on
        hub.update(frame=4)
        time.sleep(0.1)
        assert json.loads(get(server, "/api/state")[1])["frame"] == 4


def test_watcher_sees_edits_new_files_and_uses_the_baseline(tmp_path: Path) -> None:
    with time_limit(30):
        seen: list[int] = []
        w = Watcher(lambda: seen.append(1))
        scene, mesh = tmp_path / "s.txt", tmp_path / "m.obj"
        scene.write_text("a")
        w.watch([scene, mesh])
        assert not w.poll()
        scene.write_text("ab")  # size changes
        assert w.poll() and not w.poll()
        mesh.write_text("v 0 0 0\n")  # a missing file appears
        assert w.poll()
        before = {scene: (0, 0, 0)}  # a snapshot from before the read: the file has changed since
        w.watch([scene, mesh], before)
        assert w.poll() and len(seen) == 3


def test_command_line_errors_are_one_line_before_anything_serves(tmp_path: Path, capsys) -> None:
    """A port in use, an unreadable --reference, both --reference and --binary: exit 2, one line."""
    from a5mi import cli

    scene = tmp_path / "s.txt"
    scene.write_text("")
    (tmp_path / "not.png").write_text("not an image")
    with time_limit(60), socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        for argv, message in (
                (["--port", str(port)], f"a5mi view: error: cannot listen on 127.0.0.1:{port}: "),
                (["--reference", str(tmp_path / "not.png")], "a5mi view: error: "),
                (["--reference", "a.png", "--binary", "b"], "give --reference IMG or --binary PATH, not both")):
            assert cli.run_a5mi(["view", str(scene), *argv]) == 2
            err = capsys.readouterr().err.strip()
            assert len(err.splitlines()) == 1 and message in err, err


def test_preview_rule_and_no_preview_flag(tmp_path: Path, monkeypatch, capsys) -> None:  # noqa: ANN001
    """The preview comes first when there is no full render yet with these options, or the last took longer than
    PREVIEW_AFTER_SECONDS; ``--no-preview`` reaches the loop as ``preview=False`` (the default: True)."""
    from a5mi import cli
    from a5mi.commands import view as view_cli
    from a5mi.view import build, live
    from a5mi.view.live import PREVIEW_AFTER_SECONDS, wants_preview

    a, b = RenderOptions(jitter=True), RenderOptions(jitter=True, filter=True)
    assert wants_preview(None, a) and wants_preview((b, 0.01), a)
    assert not wants_preview((a, PREVIEW_AFTER_SECONDS), a) and wants_preview((a, PREVIEW_AFTER_SECONDS + 0.01), a)
    assert not wants_preview((a, 2.0), a, after=3.0) and wants_preview((a, 0.1), a, after=0.0)
    (flag,) = [f for f in view_cli.FLAGS if "--no-preview" in f.names]
    assert f"over {PREVIEW_AFTER_SECONDS} s" in flag.help
    seen: list[dict] = []
    monkeypatch.setattr(view_cli, "activate_variant", lambda variant: None)
    monkeypatch.setattr(build, "ViewSession", lambda *args: object())  # no Mitsuba: the loop is not run
    monkeypatch.setattr(live, "run_engine", lambda *args, **kw: seen.append(kw))
    scene = tmp_path / "s.txt"
    scene.write_text("")
    with time_limit(60):
        for argv in ([], ["--no-preview"]):
            assert cli.run_a5mi(["view", str(scene), "-jitter", *argv]) == 0
    assert [kw["preview"] for kw in seen] == [True, False]
    assert capsys.readouterr().out.count("a5mi view: http://127.0.0.1:") == 2


def test_values_and_diagnose_routes_need_the_token_and_queue_one_diagnosis(served) -> None:  # noqa: ANN001
    server, hub, jobs = served
    with time_limit(60):
        for path in ("/api/values/render.bin", "/static/look.js"):
            assert get(server, path, token=None)[0] == 403 and get(server, path, token="wrong")[0] == 403
        assert get(server, "/api/diagnose", token="wrong", data=b'{"image": "render"}')[0] == 403
        assert get(server, "/api/diagnose", token=None, data=b'{"image": "render"}')[0] == 403
        assert jobs.next(0.01) is None  # nothing was queued by a refused request
        status, body, ctype = get(server, "/static/look.js")
        assert status == 200 and ctype.startswith("text/javascript") and b"function setupLook" in body
        assert get(server, "/api/values/render.bin")[0] == 404  # nothing rendered yet
        assert get(server, "/api/values/diff.bin")[0] == 404
        made: list[int] = []
        hub.update({"values-render": lambda: made.append(1) or b"\x00\x01"})  # made when first asked for, once
        assert made == []
        assert get(server, "/api/values/render.bin")[:2] == (200, b"\x00\x01")
        assert get(server, "/api/values/render.bin")[:2] == (200, b"\x00\x01") and made == [1]
        hub.update({"values-reference": lambda: 1 / 0})  # an error while making it: one JSON line, 500
        status, body, _ = get(server, "/api/values/reference.bin")
        assert status == 500 and json.loads(body)["error"].startswith("a5mi view: error: "), body
        for bad in (b'{"image": "diff"}', b"[1]", b"not json"):
            status, body, _ = get(server, "/api/diagnose", data=bad)
            assert status == 400 and json.loads(body)["error"].startswith("a5mi view: error: "), body
        assert get(server, "/api/diagnose", data=b'{"image": "render"}')[0] == 202
        assert get(server, "/api/diagnose", data=b'{"image": "reference"}')[0] == 202  # replaces the first
        assert hub.state()["diagnosis"] == {"status": "queued", "image": "reference"}
        assert jobs.next(0.1) == ("diagnose", "reference")
        assert jobs.next(0.01) is None

