"""The marked region in a real headless Chromium against the real ``a5mi view`` (docs/VIEW.md "Full quality
first"): at 2x zoom and panned, a shift+drag marks the image pixels under its two ends and every pixel between
(not a pan, not a traced click), drawn on the view; a save then announces the region's composite, labelled, before
the whole image, which is ``a5``'s; a region the render cannot put first is one line on the page; the clear
button removes the region."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from test_view_browser import CHROMIUM, browser_page, check_image, start_view, stop_view
from test_view_look import geometry
from view_scenes import scene_text, time_limit, write_scene

pytestmark = pytest.mark.skipif(not os.access(CHROMIUM, os.X_OK),
                                reason=f"{CHROMIUM} is missing (make setup's tools step installs it with apt)")
FLAGS = ["-size", "48", "48", "-shadows", "-jitter", "-filter"]
STATE = "fetch('/api/state' + location.search).then(r => r.json())"
IDLE = ("() => { const s = document.getElementById('status').textContent;"
        " return s.startsWith('rendered') && !s.endsWith('...'); }")


def marked_screen_pixels(page) -> int:  # noqa: ANN001 - a Playwright page
    """How many pixels of the render view's mark canvas are the region's yellow (#fd6)."""
    return page.evaluate("""() => { const c = document.getElementById('overlay');
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data; let n = 0;
        for (let i = 0; i < d.length; i += 4) n += d[i] === 255 && d[i + 1] === 221 && d[i + 2] === 102;
        return n; }""")


def test_shift_drag_marks_a_region_whose_composite_comes_before_the_whole_image(tmp_path: Path) -> None:
    with time_limit(420):
        scene = write_scene(tmp_path / "s.txt")
        proc, url = start_view(str(scene), *FLAGS, "--no-preview", cwd=tmp_path)  # (the preview: test_view_region)
        try:
            with browser_page(url) as (page, errors, requests):
                page.wait_for_selector("#render[data-frame]", timeout=120_000)
                page.wait_for_function(IDLE, timeout=120_000)
                assert not page.locator("#region-clear").is_visible()

                # 2x about the centre, then panned by a plain drag: the mapping has an offset
                page.select_option("#zoom", "2")
                box = page.locator("#view-render").bounding_box()
                page.mouse.move(box["x"] + 100, box["y"] + 100)
                page.mouse.down()
                page.mouse.move(box["x"] + 140, box["y"] + 125, steps=4)
                page.mouse.up()
                tx, ty, k = geometry(page)
                assert k == 16 and (tx, ty) == (-192 + 40, -192 + 25), (tx, ty, k)
                # without a reference the values table hides its rows, keeping their room: no view moves on hover
                assert page.locator("#view-render").bounding_box() == box
                lo_x, lo_y = int(np.ceil(-tx / k)), int(np.ceil(-ty / k))  # the first whole pixels in view
                a, b = (lo_x + 17, lo_y + 18), (lo_x + 2, lo_y + 3)  # dragged up and to the left
                screen = [(box["x"] + tx + (p[0] + 0.5) * k, box["y"] + ty + (p[1] + 0.5) * k) for p in (a, b)]
                last = int(page.get_attribute("#render", "data-frame"))
                page.evaluate("""() => { window.announced = []; window.badges = [];
                    const img = document.getElementById('render');
                    new MutationObserver(() => window.announced.push([img.dataset.pendingKind,
                        Number(img.dataset.pending)])).observe(img, {attributes: true,
                                                                     attributeFilter: ['data-pending']});
                    img.addEventListener('load', () => window.badges.push([img.dataset.kind,
                        !document.getElementById('region-badge').hidden,
                        document.getElementById('region-badge').textContent])); }""")
                page.keyboard.down("Shift")
                page.mouse.move(*screen[0])
                page.mouse.down()
                page.mouse.move((screen[0][0] + screen[1][0]) / 2, (screen[0][1] + screen[1][1]) / 2, steps=4)
                page.mouse.move(*screen[1], steps=4)
                page.mouse.up()
                page.keyboard.up("Shift")
                region = [b[0], a[0] + 1, b[1], a[1] + 1]  # X0 X1 Y0 Y1, X1 and Y1 exclusive
                page.wait_for_selector("#region-clear", state="visible", timeout=60_000)  # the server's state has it
                assert page.evaluate(STATE)["region"] == region
                assert geometry(page) == (tx, ty, k)  # a shift+drag does not pan
                assert page.locator("#trace-sum").count() == 0  # nor trace
                assert marked_screen_pixels(page) > 300  # the dashed outline around 16 x 16 pixels at 16 px each
                assert page.locator("#view-render").bounding_box() == box  # the page did not move under the cursor
                assert page.inner_text("#region-info") == f"x {b[0]}..{a[0]}, y {b[1]}..{a[1]}"

                # marking renders the region once; then a save: the region's composite before the whole image
                page.wait_for_function(f"() => window.announced.some(([k, f]) => k === 'final' && f > {last})"
                                       f" && ({IDLE})()", timeout=120_000)
                marked = page.evaluate("window.announced.filter(([k]) => k === 'final').at(-1)[1]")
                scene.write_text(scene_text().replace("ambientLight 0.2 0.2 0.2", "ambientLight 0.4 0.2 0.2"))
                page.wait_for_function(f"() => window.announced.some(([k, f]) => k === 'final' && f > {marked})"
                                       f" && ({IDLE})()", timeout=120_000)
                announced = page.evaluate("window.announced")
                kinds = [kind for kind, frame in announced if frame > last]
                assert kinds == ["region", "final", "region", "final"], announced
                badges = page.evaluate("window.badges")
                for kind, shown, text in badges:  # labelled while it is the image shown
                    assert shown == (kind == "region"), badges
                    assert not shown or text.startswith(f"REGION x {b[0]}..{a[0]}, y {b[1]}..{a[1]} at full "
                                                        "quality, pasted on the previous image"), text
                frame = announced[-1][1]  # the whole image's (announced, maybe not loaded yet)
                check_image(page, tmp_path, scene, frame, *FLAGS)

                # a -size that leaves the region outside the image: one line says so, the image renders as before
                page.locator("#controls input[name=width]").fill("8")
                page.locator("#controls input[name=width]").dispatch_event("change")
                page.wait_for_selector("#region-note:not([hidden])", timeout=120_000)
                note = page.inner_text("#region-note")
                assert note == "the marked region lies outside the 8x48 image: the whole image renders alone", note
                page.wait_for_function(f"() => document.getElementById('render').dataset.frame > {frame}"
                                       f" && ({IDLE})()", timeout=120_000)
                assert page.get_attribute("#render", "data-kind") == "final" and page.is_hidden("#region-badge")

                # cleared: no region in the state, none drawn, the button hidden
                page.locator("#region-clear").click()
                page.wait_for_function("() => state.region === null || state.region === undefined", timeout=60_000)
                assert page.evaluate(STATE)["region"] is None
                page.wait_for_selector("#region-clear", state="hidden", timeout=60_000)  # (its room kept)
                assert marked_screen_pixels(page) == 0
        finally:
            code, err = stop_view(proc)
        assert errors == []
        assert all(u.startswith("http://127.0.0.1:") for u in requests), requests
        assert code == 130, err
