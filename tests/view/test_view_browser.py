"""``a5mi view`` in a real headless Chromium (Debian's ``/usr/bin/chromium``, driven by Playwright) against the
real command: the page's image is ``a5``'s PNG (the bytes and the decoded pixels), a saved edit updates it
without a reload, a scene error shows its positioned line and keeps the last good image, a control re-renders,
a clicked pixel's ray tree sums to the pixel and hovering a node marks its hit point, nothing is fetched from
outside 127.0.0.1, no console error; a closed tab leaves the server running and Ctrl-C ends it with 130.
Requests without the token, or with a wrong one, get 403.

``A5MI_VIEW_SCREENSHOTS=DIR`` also saves the page's screenshots there (docs/view.png is made so).
"""

from __future__ import annotations

import os
import selectors
import signal
import subprocess
import sys
import urllib.error
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from view_scenes import a5_png, time_limit, write_scene

CHROMIUM = "/usr/bin/chromium"
pytestmark = pytest.mark.skipif(not os.access(CHROMIUM, os.X_OK),
                                reason=f"{CHROMIUM} is missing (make setup's tools step installs it with apt)")
BROWSER_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking"]
FLAGS = ["-size", "48", "48", "-shadows"]


def start_view(*argv: str, cwd: Path) -> tuple[subprocess.Popen[str], str]:
    """``a5mi view ARGV`` as its own process; its URL from the first line of stdout."""
    proc = subprocess.Popen([str(Path(sys.executable).with_name("a5mi")), "view", *argv], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ)
    if not sel.select(timeout=120):
        proc.kill()
        pytest.fail("a5mi view printed no URL within 120 s")
    line = proc.stdout.readline()
    assert line.startswith("a5mi view: http://127.0.0.1:"), (line, proc.stderr.read() if proc.poll() else "")
    return proc, line.split(": ", 1)[1].strip()


def stop_view(proc: subprocess.Popen[str]) -> tuple[int, str]:
    proc.send_signal(signal.SIGINT)
    try:
        _, err = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise
    return proc.returncode, err


def status_of(url: str) -> int:
    try:
        with urllib.request.urlopen(url, timeout=10) as r:
            return r.status
    except urllib.error.HTTPError as e:
        return e.code


def test_requests_without_the_token_or_with_a_wrong_one_get_403(tmp_path: Path) -> None:
    with time_limit(180):
        proc, url = start_view(str(write_scene(tmp_path / "s.txt")), *FLAGS, cwd=tmp_path)
        try:
            base, token = url.split("/?token=")
            assert status_of(url) == 200
            for path in ("/", "/api/state", "/static/view.js", "/api/image/render.png"):
                assert status_of(base + path) == 403
                assert status_of(f"{base}{path}?token=x{token}") == 403
                assert status_of(f"{base}{path}?token={token[:-1]}") == 403
        finally:
            code, err = stop_view(proc)
        assert code == 130 and err.rstrip().endswith("a5mi view: error: interrupted (SIGINT)"), err


@contextmanager
def browser_page(url: str, height: int = 1000) -> Iterator[tuple[Any, list[str], list[str]]]:
    """A tab of headless Chromium on ``url`` (1400 x ``height``), with the page's errors (uncaught and console) and
    every URL it requested, filled in as it runs."""
    from playwright.sync_api import sync_playwright

    errors: list[str] = []
    requests: list[str] = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=BROWSER_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": height})
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("request", lambda r: requests.append(r.url))
            page.goto(url)
            yield page, errors, requests
        finally:
            browser.close()


def page_pixels(page, selector: str) -> np.ndarray:  # noqa: ANN001 - a Playwright page
    """The decoded pixels of the page's image ``selector`` (drawn on a canvas), (H, W, 3) uint8."""
    data = page.evaluate("""(sel) => { const img = document.querySelector(sel);
        const c = document.createElement('canvas'); c.width = img.naturalWidth; c.height = img.naturalHeight;
        const g = c.getContext('2d'); g.drawImage(img, 0, 0);
        return [c.width, c.height, Array.from(g.getImageData(0, 0, c.width, c.height).data)]; }""", selector)
    w, h, rgba = data
    return np.array(rgba, np.uint8).reshape(h, w, 4)[..., :3]


def check_image(page, tmp_path: Path, scene: Path, frame: int, *flags: str) -> None:  # noqa: ANN001
    """The page shows frame ``frame``, whose PNG bytes and decoded pixels are ``a5``'s for ``flags``."""
    from a5mi.platform.imageio import read_uint8

    page.wait_for_selector(f"#render[data-frame='{frame}']", timeout=120_000)
    want = a5_png(scene, tmp_path / f"a5-{frame}.png", *flags)
    src = page.get_attribute("#render", "src")
    got = page.request.get(page.url.split("/?")[0] + src).body()
    assert got == want
    assert np.array_equal(page_pixels(page, "#render"), read_uint8(tmp_path / f"a5-{frame}.png")[..., :3])


def test_the_page_in_headless_chromium(tmp_path: Path) -> None:
    shots = os.environ.get("A5MI_VIEW_SCREENSHOTS")
    with time_limit(420):
        scene = write_scene(tmp_path / "s.txt")
        ref = tmp_path / "ref.png"
        a5_png(write_scene(tmp_path / "r.txt", "1 0.5 0.1"), ref, *FLAGS)
        proc, url = start_view(str(scene), *FLAGS, "--reference", str(ref), cwd=tmp_path)
        try:
            with browser_page(url) as (page, errors, requests):
                check_image(page, tmp_path, scene, 1, *FLAGS)
                page.wait_for_selector("#diff[data-frame='1']", timeout=60_000)
                assert page.inner_text("#verdict") == "wrong"
                assert "PSNR" in page.inner_text("#metrics")

                # a saved edit re-renders without a reload
                write_scene(scene, "0.1 0.9 0.9")
                check_image(page, tmp_path, scene, 2, *FLAGS)
                # a scene error: its positioned line; the last good image stays
                scene.write_text(scene.read_text().replace("radius 0.4", "radius oops"))
                page.wait_for_selector("#error:not([hidden])", timeout=60_000)
                line = page.inner_text("#error")
                assert line.startswith(f"{scene}:") and ": error: " in line and "\n" not in line.strip(), line
                assert page.get_attribute("#render", "data-frame") == "2"
                if shots:
                    page.screenshot(path=str(Path(shots) / "view-error.png"))
                write_scene(scene, "0.1 0.9 0.9")
                page.wait_for_selector("#error", state="hidden", timeout=60_000)
                check_image(page, tmp_path, scene, 3, *FLAGS)

                # a control re-renders with that flag
                page.locator("#controls input[name=bounces]").fill("1")
                page.locator("#controls input[name=bounces]").dispatch_event("change")
                check_image(page, tmp_path, scene, 4, *FLAGS, "-bounces", "1")

                # click a pixel: the tree's sum is the pixel; hovering a node marks its hit point
                pixels = page_pixels(page, "#render")
                box = page.locator("#render").bounding_box()
                x, y = 20, 30  # on the glass sphere
                scale = box["width"] / 48
                page.mouse.click(box["x"] + (x + 0.5) * scale, box["y"] + (y + 0.5) * scale)
                page.wait_for_selector("#trace-sum", timeout=120_000)
                want = ",".join(str(int(v)) for v in pixels[y, x])
                assert page.get_attribute("#trace-sum", "data-byte") == want
                assert page.get_attribute("#trace-sum", "data-pixel") == want
                assert page.get_attribute("#trace-check", "class") == "ok"
                assert page.locator(".node").count() >= 2
                page.locator(".node").first.hover()
                marked = page.evaluate("""() => { const c = document.getElementById('overlay');
                    const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
                    let n = 0; for (let i = 3; i < d.length; i += 4) n += d[i] > 0; return n; }""")
                assert marked > 20
                assert "trace --diff" in page.inner_text("#trace")
                if shots:
                    page.screenshot(path=str(Path(shots) / "view.png"))

                # -jitter -filter: a preview announced to the page and labelled while it is the image shown, then
                # a5's full image, the label gone. (A full image that arrives before the preview's PNG has loaded
                # replaces it unseen: then no load event of the preview, but its announcement.) -jitter first, to its
                # full image: the two boxes' requests would otherwise make one job or two, as the page's timing falls.
                # Every kind set is kept: an observer called once for several sets sees only the last value, so each
                # record's old value is kept (the value before it) and the kinds set are those after the first.
                page.evaluate("""() => { window.shown = []; window.before = [];
                    const img = document.getElementById('render');
                    new MutationObserver((records) => { for (const r of records) window.before.push(r.oldValue); })
                        .observe(img, {attributes: true, attributeOldValue: true,
                                       attributeFilter: ['data-pending-kind']});
                    img.addEventListener('load', () => window.shown.push([img.dataset.kind,
                        !document.getElementById('preview-badge').hidden])); }""")
                rendered = ("() => window.shown.length && window.shown.at(-1)[0] === 'final'"
                            " && document.getElementById('status').textContent.startsWith('rendered')"
                            " && !document.getElementById('status').textContent.endsWith('...')")
                page.locator("#controls input[name=jitter]").check()
                page.wait_for_function(rendered, timeout=120_000)
                page.evaluate("() => { window.shown = []; window.before = []; }")
                page.locator("#controls input[name=filter]").check()
                page.wait_for_function(rendered, timeout=120_000)
                shown, announced = page.evaluate("""() => [window.shown, [...window.before.slice(1),
                    document.getElementById('render').dataset.pendingKind]]""")
                assert "preview" in announced and announced[-1] == "final", announced
                assert all(badge == (kind == "preview") for kind, badge in shown), shown
                assert shown[-1] == ["final", False], shown
                frame = int(page.get_attribute("#render", "data-frame"))
                check_image(page, tmp_path, scene, frame, *FLAGS, "-bounces", "1", "-jitter", "-filter")
                page.close()  # a closed tab: the server goes on
                assert status_of(url) == 200
        finally:
            code, err = stop_view(proc)
        assert errors == []
        assert all(u.startswith("http://127.0.0.1:") for u in requests), requests  # no CDN: works offline
        assert code == 130, err
