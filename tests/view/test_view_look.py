"""The page's tools for looking closely, in a real headless Chromium against the real ``a5mi view`` (docs/VIEW.md
"Look closely"): at 16x every screen pixel of the three locked views shows the image pixel the zoom maps it to
(nearest neighbour) and the pixel under the cursor is that one; the wheel zooms about the cursor; a drag pans the
three together; the values shown are the images' (the render's floats are ``a5 -output X.exr``'s, its 8-bit levels
the PNG's, the ``.exr`` reference's its floats and their SPEC B.1 levels); exposure redraws the ``.exr`` and the render
as ``quantize(c·2^EV)``; the A/B flip shows the reference in the render's place and back; the clicked pixel's mark
changes the screen around the pixel; the diagnose panel names the mistake a ``-mistake`` render was made with."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from test_view_browser import CHROMIUM, browser_page, start_view, stop_view
from view_scenes import a5_png, time_limit, write_scene

pytestmark = pytest.mark.skipif(not os.access(CHROMIUM, os.X_OK),
                                reason=f"{CHROMIUM} is missing (make setup's tools step installs it with apt)")
SIZE = 48  # the page's fit scale is floor(384 / 48) = 8 screen pixels per image pixel at 1x
FLAGS = ["-size", str(SIZE), str(SIZE), "-shadows"]
MISTAKE = ["-mistake", "no_shadows"]


def shot(page, view: str, path: Path) -> np.ndarray:  # noqa: ANN001 - a Playwright page
    """The screen pixels of ``#view-NAME`` as (H, W, 3) uint8."""
    from a5mi.platform.imageio import read_uint8

    box = page.locator(f"#view-{view}").bounding_box()
    page.screenshot(path=str(path), clip=box)
    return read_uint8(path)[..., :3]


def geometry(page) -> tuple[float, float, float]:  # noqa: ANN001
    """``(tx, ty, k)``: screen = (tx, ty) + k · image pixel, k = zoom x the fit scale."""
    d = page.evaluate("() => ({...document.getElementById('view-render').dataset})")
    return float(d["tx"]), float(d["ty"]), float(d["zoom"]) * float(d["base"])


def expected_screen(image: np.ndarray, shape: tuple[int, ...], tx: float, ty: float, k: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """What a view of ``shape`` shows of ``image`` under nearest-neighbour zoom, and the mask of the screen pixels
    whose centre is at least one screen pixel inside its image pixel (away from the pixel edges)."""
    sy, sx = np.mgrid[0:shape[0], 0:shape[1]] + 0.5
    ix, iy = (sx - tx) / k, (sy - ty) / k
    inner = ((ix - np.floor(ix)) * k > 1) & ((np.ceil(ix) - ix) * k > 1) & ((iy - np.floor(iy)) * k > 1) & (
        (np.ceil(iy) - iy) * k > 1)
    xi, yi = np.clip(np.floor(ix).astype(int), 0, SIZE - 1), np.clip(np.floor(iy).astype(int), 0, SIZE - 1)
    return image[yi, xi], inner


def hover(page, view: str, sx: float, sy: float) -> dict:  # noqa: ANN001
    """Move the mouse to the view point ``(sx, sy)``; the values table's pixel and rows."""
    box = page.locator(f"#view-{view}").bounding_box()
    page.mouse.move(box["x"] + sx, box["y"] + sy)
    return page.evaluate("""() => { const t = document.getElementById('values'); const row = (id) => {
        const r = document.getElementById('values-' + id); return [r.dataset.linear, r.dataset.byte]; };
        return {x: Number(t.dataset.x), y: Number(t.dataset.y), render: row('render'),
                reference: row('reference'), diff: row('diff')}; }""")


def floats(text: str) -> np.ndarray:
    return np.array([float(v) for v in text.split(",")])


def test_zoom_values_exposure_flip_mark_and_diagnose(tmp_path: Path) -> None:
    from a5mi.platform.imageio import quantize, read_image, read_uint8

    with time_limit(420):
        scene = write_scene(tmp_path / "s.txt")
        a5_png(scene, tmp_path / "m.png", *FLAGS, *MISTAKE)
        ours = read_uint8(tmp_path / "m.png")[..., :3]
        a5_png(scene, tmp_path / "m.exr", *FLAGS, *MISTAKE)
        ours_f = read_image(tmp_path / "m.exr")[..., :3]
        ref = tmp_path / "ref.exr"
        a5_png(write_scene(tmp_path / "r.txt", "1 0.5 0.1"), ref, *FLAGS)
        ref_f = read_image(ref)[..., :3]
        ref_b = quantize(ref_f)
        proc, url = start_view(str(scene), *FLAGS, *MISTAKE, "--reference", str(ref), cwd=tmp_path)
        try:
            with browser_page(url, height=1100) as (page, errors, requests):
                page.wait_for_selector("#diff[data-frame='1']", timeout=120_000)
                page.wait_for_function("() => values.render && values.reference", timeout=60_000)

                # at 1x the views show the PNG's pixels; the values under the cursor are the images'
                tx, ty, k = geometry(page)
                assert (tx, ty, k) == (0, 0, 8)
                got = hover(page, "render", (20 + 0.5) * k, (30 + 0.5) * k)
                assert (got["x"], got["y"]) == (20, 30)
                for x, y in ((20, 30), (5, 3), (40, 44)):
                    got = hover(page, "reference", (x + 0.5) * k, (y + 0.5) * k)
                    assert (got["x"], got["y"]) == (x, y)
                    assert np.array_equal(floats(got["render"][0]), ours_f[y, x].astype(np.float64))
                    assert np.array_equal(floats(got["render"][1]), ours[y, x])
                    assert np.array_equal(floats(got["reference"][0]), ref_f[y, x].astype(np.float64))
                    assert np.array_equal(floats(got["reference"][1]), ref_b[y, x])
                    assert np.array_equal(floats(got["diff"][0]), ours_f[y, x].astype(np.float64)
                                          - ref_f[y, x].astype(np.float64))
                    assert np.array_equal(floats(got["diff"][1]), ours[y, x].astype(int) - ref_b[y, x])

                # 16x, the three views locked: every screen pixel is its image pixel (nearest neighbour)
                page.select_option("#zoom", "16")
                tx, ty, k = geometry(page)
                assert k == 16 * 8 and tx < 0 and ty < 0  # about the view's centre
                screen = shot(page, "render", tmp_path / "z16.png")
                want, inner = expected_screen(ours, screen.shape, tx, ty, k)
                assert inner.sum() > 0.9 * inner.size and len(np.unique(want[inner], axis=0)) >= 2
                assert np.array_equal(screen[inner], want[inner])
                screen = shot(page, "reference", tmp_path / "z16r.png")
                want, inner = expected_screen(ref_b, screen.shape, tx, ty, k)  # the .exr's SPEC B.1 levels
                assert np.array_equal(screen[inner], want[inner])
                sx, sy = 200.0, 150.0
                got = hover(page, "render", sx, sy)
                x, y = int((sx - tx) // k), int((sy - ty) // k)
                assert (got["x"], got["y"]) == (x, y)
                assert np.array_equal(screen_at(page, "render", sx, sy, tmp_path), ours[y, x])
                assert np.array_equal(floats(got["render"][1]), ours[y, x])

                # a drag pans the three views together
                box = page.locator("#view-diff").bounding_box()
                page.mouse.move(box["x"] + 200, box["y"] + 200)
                page.mouse.down()
                page.mouse.move(box["x"] + 260, box["y"] + 240, steps=4)
                page.mouse.up()
                assert geometry(page)[:2] == (tx + 60, ty + 40)
                transforms = page.evaluate("""() => ['render', 'reference', 'diff'].map((n) =>
                    document.querySelector('#view-' + n + ' .stack').style.transform)""")
                assert len(set(transforms)) == 1 and "scale(16)" in transforms[0], transforms
                assert page.locator("#trace-sum").count() == 0  # a drag is not a click
                page.select_option("#zoom", "1")
                assert geometry(page) == (0, 0, 8)
                # the wheel zooms in at the cursor: the image pixel under it stays there
                under = hover(page, "render", 101.0, 203.0)
                page.mouse.wheel(0, -100)
                page.wait_for_function("() => document.getElementById('view-render').dataset.zoom === '2'")
                hover(page, "render", 5.0, 5.0)
                again = hover(page, "render", 101.0, 203.0)
                assert (again["x"], again["y"]) == (under["x"], under["y"]) == (101 // 8, 203 // 8)
                assert geometry(page)[2] == 16
                page.select_option("#zoom", "1")

                # exposure: the .exr reference is shown as quantize(c * 2^EV)
                before = shot(page, "reference", tmp_path / "ev0.png")
                page.fill("#exposure", "-1")
                page.dispatch_event("#exposure", "input")
                after = shot(page, "reference", tmp_path / "ev-1.png")
                want, inner = expected_screen(quantize(ref_f * np.float32(0.5)), after.shape, 0, 0, 8)
                assert np.array_equal(after[inner], want[inner])
                assert not np.array_equal(before, after)
                exposed = shot(page, "render", tmp_path / "ev-1-render.png")  # the render's floats too
                want, inner = expected_screen(quantize(ours_f * np.float32(0.5)), exposed.shape, 0, 0, 8)
                assert np.array_equal(exposed[inner], want[inner])
                page.fill("#exposure", "0")
                page.dispatch_event("#exposure", "input")

                # A/B flip: the reference in the render's place, and back
                want_ref, inner = expected_screen(ref_b, after.shape, 0, 0, 8)
                want_ours, _ = expected_screen(ours, after.shape, 0, 0, 8)
                page.click("#flip")
                flipped = shot(page, "render", tmp_path / "flip.png")
                assert np.array_equal(flipped[inner], want_ref[inner])
                assert page.inner_text("#render-title").startswith("reference")
                page.click("#flip")
                back = shot(page, "render", tmp_path / "back.png")
                assert np.array_equal(back[inner], want_ours[inner])

                # the clicked pixel's mark changes the screen around the pixel, beyond the pixel itself
                x, y = 20, 30
                box = page.locator("#view-render").bounding_box()
                page.mouse.click(box["x"] + (x + 0.5) * 8, box["y"] + (y + 0.5) * 8)
                page.wait_for_selector("#trace-sum", timeout=120_000)
                page.mouse.move(box["x"] - 20, box["y"] - 20)  # away: no hover mark
                marked = shot(page, "render", tmp_path / "mark.png")
                changed = np.any(marked != back, axis=2)
                near = np.zeros_like(changed)
                near[y * 8 - 24:y * 8 + 32, x * 8 - 24:x * 8 + 32] = True
                assert not changed[~near].any()  # the mark only, no other change
                near[y * 8:y * 8 + 8, x * 8:x * 8 + 8] = False  # outside the pixel itself
                assert changed[near].sum() >= 100, changed[near].sum()

                # the diagnose panel names the mistake the render was made with
                page.select_option("#diagnose-image", "render")
                page.click("#diagnose")
                page.wait_for_selector("#diagnosis-verdict", timeout=240_000)
                assert page.get_attribute("#diagnosis-verdict", "data-verdict") == "diagnosis"
                assert page.locator("#diagnosis-causes li").first.get_attribute("data-mistakes") == "no_shadows"
                assert "explains" in page.inner_text("#diagnosis") and "where: x" in page.inner_text("#diagnosis")
                # an unexplained image lists its closest causes as the command prints them, each with its
                # likelihood ratio where it has one (the first may explain a negative share: a noise mistake)
                page.evaluate("""() => showDiagnosis({status: 'done', image: 'render', frame: -1, flags: '-size 8 8',
                    mistakes: [], psnr: 30, verdict: 'unexplained', remaining: 0.001,
                    causes: [{mistakes: ['no_blur'], explained: -0.013, likelihood: 2.7314},
                             {mistakes: ['downsample_one_sample'], explained: 0.02, likelihood: null}]}, -1)""")
                assert page.inner_text("#diagnosis-verdict").endswith(
                    "(closest: no_blur (explains -1.3%, likelihood ratio +2.731 nats per value); "
                    "downsample_one_sample (explains 2.0%))"), page.inner_text("#diagnosis-verdict")
                # a pair listed by the paired score gives its z beside it, as the command prints it
                page.evaluate("""() => showDiagnosis({status: 'done', image: 'render', frame: -1, flags: '-size 8 8',
                    mistakes: [], psnr: 30, verdict: 'diagnosis', remaining: 0.001,
                    causes: [{mistakes: ['normal_faces_viewer', 'downsample_one_sample'], explained: 0.994,
                              scale: 'blocks', catalogue: [], evidence: null, partner: 'downsample_one_sample',
                              partner_z: 11.4253}]}, -1)""")
                assert page.locator("#diagnosis-causes li").first.inner_text() == (
                    "normal_faces_viewer + downsample_one_sample: explains 99.4% of the difference (in 4x4 block "
                    "means); the paired score prefers it to normal_faces_viewer alone, z = 11.4")
        finally:
            code, err = stop_view(proc)
        assert errors == []
        assert all(u.startswith("http://127.0.0.1:") for u in requests), requests
        assert code == 130, err


def screen_at(page, view: str, sx: float, sy: float, tmp_path: Path) -> np.ndarray:  # noqa: ANN001
    """The screen pixel at the view point ``(sx, sy)``."""
    return shot(page, view, tmp_path / "at.png")[int(sy), int(sx)]
