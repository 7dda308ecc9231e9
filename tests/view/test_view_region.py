"""The page's marked region, rendered at full quality first (a5mi/view/region.py, docs/VIEW.md "Full quality
first"): the route's checks (malformed regions are one 400 line, nothing queued; a region marks a render, null
clears), the crop render's refusals as the page's one line, and the engine's loop: on a save the composite (the
image shown before with the region pasted) comes before the preview and the full image, and its region's pixels
(floats and 8-bit levels) are bit for bit the full image's same pixels, which is ``a5``'s image."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from test_view_server import TOKEN, get
from view_scenes import a5_png, scene_text, time_limit, view_loop, wait_for

from a5mi.render.options import RenderOptions
from a5mi.view import controls
from a5mi.view.region import RegionError, clamp, parse_region, paste, why_not
from a5mi.view.server import Hub, Jobs, Server

OPTS = RenderOptions(width=32, height=32, shadows=True, jitter=True, filter=True)
FLAGS = ("-size", "32", "32", "-shadows", "-jitter", "-filter")
REGION = (9, 21, 5, 14)  # X0 X1 Y0 Y1: on the glass sphere and the floor, row 0 the top


@pytest.mark.parametrize("doc, why", [
    ([1, 2, 3, 4], "give {\"region\""),
    ({"region": [1, 2, 3]}, "expected four integers"),
    ({"region": [1, 2, 3, 4], "x": 1}, "give {\"region\""),
    ({"region": [1.0, 2, 3, 4]}, "expected four integers"),
    ({"region": [True, 2, 3, 4]}, "expected four integers"),
    ({"region": "1 2 3 4"}, "expected four integers"),
    ({"region": [5, 5, 3, 4]}, "needs 0 <= X0 < X1"),
    ({"region": [1, 2, 4, 3]}, "needs 0 <= X0 < X1"),
    ({"region": [-1, 2, 3, 4]}, "needs 0 <= X0 < X1"),
    ({"region": [1, 2, 3, 1 << 40]}, "needs 0 <= X0 < X1"),
    ({"region": [40, 50, 3, 4]}, "lies outside the 32x32 image"),
])
def test_malformed_regions_are_refused_in_one_line(doc: object, why: str) -> None:
    with pytest.raises(RegionError) as exc:
        parse_region(doc, [32, 32])
    assert why in str(exc.value) and "\n" not in str(exc.value)


def test_a_region_is_clamped_to_the_image_and_null_clears() -> None:
    assert parse_region({"region": [3, 40, 30, 35]}, [32, 32]) == (3, 32, 30, 32)
    assert parse_region({"region": [3, 40, 30, 35]}) == (3, 40, 30, 35)  # no image yet: clamped when rendered
    assert parse_region({"region": None}, [32, 32]) is None
    assert clamp((3, 40, 30, 35), (32, 31)) == (3, 32, 30, 31) and clamp((3, 40, 31, 35), (32, 31)) is None
    base = np.arange(4 * 5 * 3, dtype=np.float32).reshape(4, 5, 3)
    part = np.full((2, 3, 3), -1, np.float32)
    out, what = paste(base, part, (1, 4, 2, 4), (5, 4))
    assert what == "base" and (out[2:4, 1:4] == -1).all() and out.sum() - out[2:4, 1:4].sum() == (
        base.sum() - base[2:4, 1:4].sum())
    out, what = paste(base, part, (1, 4, 2, 4), (6, 4))  # the size changed: a black image with the region
    assert what == "blank" and out.shape == (4, 6, 3) and (out[2:4, 1:4] == -1).all() and out[:2].sum() == 0


@pytest.mark.parametrize("change, why", [
    ({"integrator": "photon"}, "-integrator photon keeps state across the image"),
    ({"integrator": "ppm"}, "-integrator ppm keeps state"),
    ({"integrator": "irradiancecache"}, "-integrator irradiancecache keeps state"),
    ({"mistakes": ("upside_down",)}, "cannot make the mistake upside_down"),
    ({"mistakes": ("blur_zero_border",)}, "cannot make the mistake blur_zero_border"),
    ({"width": 8, "height": 8}, "the marked region lies outside the 8x8 image"),
])
def test_why_a_region_cannot_go_first(change: dict, why: str) -> None:
    line = why_not(dataclasses.replace(OPTS, **change), REGION)
    assert line is not None and why in line and "the whole image renders alone" in line and "\n" not in line
    assert why_not(OPTS, REGION) is None and why_not(dataclasses.replace(OPTS, integrator="path"), REGION) is None


def test_the_region_route_marks_a_render_and_refuses_malformed_regions() -> None:
    hub, jobs = Hub(), Jobs()
    server = Server(TOKEN, hub, jobs, lambda values: controls.apply(RenderOptions(), values))
    server.start()
    try:
        with time_limit(60):
            hub.update(size=[32, 32])
            for token in (None, "wrong"):
                assert get(server, "/api/region", token=token, data=b'{"region": [1, 5, 2, 6]}')[0] == 403
            for bad in (b"not json", b'{"region": [1, 5, 2]}', b'{"region": [5, 1, 2, 6]}',
                        b'{"region": [40, 50, 2, 6]}'):
                status, body, _ = get(server, "/api/region", data=bad)
                assert status == 400 and json.loads(body)["error"].startswith("a5mi view: error: "), body
            assert jobs.next(0.01) is None and "region" not in hub.state()  # nothing marked, nothing queued
            status, body, _ = get(server, "/api/region", data=b'{"region": [1, 50, 2, 6]}')
            assert status == 202 and json.loads(body) == {"region": [1, 32, 2, 6]}
            assert hub.state()["region"] == [1, 32, 2, 6] and jobs.region == (1, 32, 2, 6)
            assert jobs.render_pending() and jobs.next(0.1) == ("render", (False, None))  # once right away
            assert get(server, "/api/region", data=b'{"region": null}')[0] == 202
            assert hub.state()["region"] is None and jobs.region is None and jobs.next(0.01) is None
    finally:
        server.stop()


@pytest.fixture(scope="module")
def session(variant):  # noqa: ANN001, ANN201 - fixtures
    from a5mi.view.build import ViewSession

    return ViewSession()


def pixels(state: dict, tmp: Path) -> tuple[np.ndarray, np.ndarray]:
    """The floats and the 8-bit levels of a state's render (its value blob) and, checked equal to the levels, its
    PNG's decoded pixels."""
    from a5mi.platform.imageio import read_uint8

    w, h = state["size"]
    blob = state["values"]
    lin = np.frombuffer(blob[:w * h * 12], "<f4").reshape(h, w, 3)
    lev = np.frombuffer(blob[w * h * 12:], np.uint8).reshape(h, w, 3)
    (tmp / "shown.png").write_bytes(state["png"])
    assert np.array_equal(read_uint8(tmp / "shown.png")[..., :3], lev)
    return lin, lev


def test_a_save_publishes_the_region_first_bit_identical_to_the_full_image(tmp_path: Path, session) -> None:  # noqa: ANN001
    from a5mi.view.engine import ViewEngine

    x0, x1, y0, y1 = REGION
    with time_limit(300):
        scene = tmp_path / "s.txt"
        scene.write_text(scene_text())

        def drive(jobs, states) -> None:  # noqa: ANN001
            first = wait_for(states, lambda s: s.get("frame") and not s["busy"], "first frame")
            jobs.mark(REGION)  # once right after marking: the region, then the unchanged whole image again
            marked = wait_for(states, lambda s: (s.get("frame") or 0) > first["frame"] and not s["busy"], "marked")
            new = [s for s in states if (s.get("frame") or 0) > first["frame"]]
            assert [s["composite"] is not None for s in new] == [True, False], new
            assert new[0]["composite"]["region"] == list(REGION) and new[0]["composite"]["base"] == "previous"
            assert marked["png"] == first["png"] and marked["seconds"]["render"] == first["seconds"]["render"]  # not
            # rendered again: the last full frame, published anew
            assert np.array_equal(pixels(new[0], tmp_path)[0], pixels(first, tmp_path)[0])  # the region's pixels
            # were already these
            scene.write_text(scene_text().replace("ambientLight 0.2 0.2 0.2", "ambientLight 0.4 0.2 0.2"))  # a save
            final = wait_for(states, lambda s: (s.get("frame") or 0) > marked["frame"] and not s["busy"], "saved")
            new = [s for s in states if (s.get("frame") or 0) > marked["frame"]]
            kinds = [("composite" if s["composite"] and not s["preview"] else "preview" if s["preview"] else
                      "final") for s in new]
            assert kinds == ["composite", "preview", "final"], kinds
            comp, preview = new[0], new[1]
            assert comp["composite"]["base"] == "previous" and comp["busy"] and comp["seconds"]["region"] > 0
            assert preview["composite"]["base"] == "preview"  # the preview carries the region too
            lin, lev = pixels(final, tmp_path)
            assert final["png"] == a5_png(scene, tmp_path / "a5.png", *FLAGS)
            for shown, base in ((comp, pixels(marked, tmp_path)), (preview, None)):
                got_lin, got_lev = pixels(shown, tmp_path)
                assert np.array_equal(got_lin[y0:y1, x0:x1], lin[y0:y1, x0:x1])  # bit for bit, floats
                assert np.array_equal(got_lev[y0:y1, x0:x1], lev[y0:y1, x0:x1])
                if base is not None:  # elsewhere the image shown before
                    outside = np.ones(lin.shape[:2], bool)
                    outside[y0:y1, x0:x1] = False
                    assert np.array_equal(got_lin[outside], base[0][outside])
            before = pixels(marked, tmp_path)[1][y0:y1, x0:x1]
            assert (before != lev[y0:y1, x0:x1]).any(axis=2).all()  # the save changed every pixel of the region

        view_loop(ViewEngine(str(scene), session), OPTS, drive, preview_after=0.0)


def test_a_region_the_crop_render_refuses_is_one_line_and_the_image_renders_as_before(
        tmp_path: Path, session) -> None:  # noqa: ANN001
    from a5mi.view.engine import ViewEngine

    with time_limit(300):
        scene = tmp_path / "s.txt"
        scene.write_text(scene_text())

        def drive(jobs, states) -> None:  # noqa: ANN001
            first = wait_for(states, lambda s: s.get("frame") and not s["busy"], "first frame")
            jobs.mark(REGION)
            final = wait_for(states, lambda s: (s.get("frame") or 0) > first["frame"] and not s["busy"], "marked")
            assert all(s.get("composite") is None for s in states)
            assert "cannot make the mistake upside_down" in final["region_note"] and final["error"] is None
            assert final["png"] == a5_png(scene, tmp_path / "a5.png", *FLAGS, "-mistake", "upside_down")

        view_loop(ViewEngine(str(scene), session), dataclasses.replace(OPTS, mistakes=("upside_down",)), drive,
             preview=False)


def test_the_region_render_reuses_the_warm_scene(tmp_path: Path, session) -> None:  # noqa: ANN001
    """The crop render goes through the page's warm session (no Mitsuba object made again); its pixels are the
    full frame's, clamped to the image; a ``-bump`` change describes the scene again first, as the full render
    does."""
    from a5mi.view.engine import ViewEngine
    from a5mi.view.region import render_region

    x0, x1, y0, y1 = REGION
    with time_limit(240):
        scene = tmp_path / "s.txt"
        scene.write_text(scene_text())
        engine = ViewEngine(str(scene), session)
        try:
            full = engine.render(OPTS)
            made = session.made
            part, seconds = render_region(engine, OPTS, REGION)
            assert session.made == made and seconds > 0
            assert np.array_equal(part, full.image[y0:y1, x0:x1])
            part, _ = render_region(engine, OPTS, (x0, 99, y0, 99))  # clamped to the 32 x 32 image
            assert np.array_equal(part, full.image[y0:, x0:])
            bumped = dataclasses.replace(OPTS, bump=True)
            part, _ = render_region(engine, bumped, REGION)
            assert engine.bump and np.array_equal(part, engine.render(bumped).image[y0:y1, x0:x1])
        finally:
            engine.close()
