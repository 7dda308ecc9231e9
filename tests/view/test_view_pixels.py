"""The page's pixel values and the diagnose panel's checks (a5mi/view/pixels.py): the blob is float32 linear RGB then
the 8-bit levels, row 0 = top; an 8-bit reference's linear value is ``k / 255`` and its levels ``k``; an ``.exr``
reference's are its floats and their SPEC B.1 quantisation; a diagnosis refuses, in one line, what ``a5mi
diagnose`` refuses."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from a5mi.platform.errors import UserError
from a5mi.render.options import RenderOptions


def unpack(blob: bytes, h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    n = h * w * 3
    assert len(blob) == 5 * n
    return (np.frombuffer(blob[:4 * n], "<f4").reshape(h, w, 3), np.frombuffer(blob[4 * n:], np.uint8).reshape(h, w, 3))


def test_render_values_are_the_floats_and_the_png_levels() -> None:
    from a5mi.platform.imageio import quantize
    from a5mi.view.pixels import render_values

    img = np.array([[[0.5, 1.2, -0.1, 1.0], [0.2, 0.4, 0.6, 1.0]]], np.float32)  # alpha dropped
    lin, lev = unpack(render_values(img), 1, 2)
    assert np.array_equal(lin, img[..., :3])
    assert lev.tolist() == [[[127, 255, 0], [51, 102, 153]]] == quantize(img[..., :3]).tolist()


def test_reference_values_of_an_8bit_and_an_exr_file(tmp_path: Path) -> None:
    from a5mi.platform.imageio import quantize, read_levels, write_image
    from a5mi.view.pixels import ReferenceValues

    rng = np.random.default_rng(3)
    exr = rng.uniform(0, 1.5, (3, 4, 3)).astype(np.float32)
    write_image(tmp_path / "r.exr", exr)
    write_image(tmp_path / "r.png", exr)
    levels = read_levels(tmp_path / "r.png")
    lin, lev = unpack(ReferenceValues(str(tmp_path / "r.png")).blob(levels), 3, 4)
    assert np.array_equal(lev, levels.astype(np.uint8)) and np.array_equal(lin, (levels / 255.0).astype(np.float32))
    values = ReferenceValues(str(tmp_path / "r.exr"))
    levels = read_levels(tmp_path / "r.exr")
    blob = values.blob(levels)
    lin, lev = unpack(blob, 3, 4)
    assert np.array_equal(lin, exr) and np.array_equal(lev, quantize(exr))
    assert values.blob(levels) is blob  # encoded once per reference array


def test_the_diagnosis_refuses_what_a5mi_diagnose_refuses() -> None:
    from a5mi.view.pixels import diagnose_frame, spec_flags

    opts = RenderOptions(width=8, height=8, shadows=True)
    frame = SimpleNamespace(options=opts, preview=False, image=np.zeros((8, 8, 3), np.float32), reference_levels=None)
    cases = [(SimpleNamespace(frame=None, desc=None), "render", "nothing rendered yet"),
             (SimpleNamespace(frame=SimpleNamespace(
                 **{**vars(frame), "preview": True}), desc=object()), "render", "nothing rendered yet"),
             (SimpleNamespace(frame=SimpleNamespace(**{**vars(frame), "options": dataclasses.replace(
                 opts, integrator="path")}), desc=object()), "render", "-integrator whitted"),
             (SimpleNamespace(frame=SimpleNamespace(**{**vars(frame), "options": dataclasses.replace(
                 opts, jitter=True)}), desc=object()), "render", "-jitter -filter"),
             (SimpleNamespace(frame=frame, desc=object()), "reference", "no reference image")]
    for engine, image, why in cases:
        with pytest.raises(UserError, match=why):
            diagnose_frame(engine, image)
    assert spec_flags(dataclasses.replace(opts, jitter=True, filter=True, bounces=2)) == \
        "-size 8 8 -bounces 2 -shadows -jitter -filter"


def test_diagnosing_the_reference_names_the_mistake_it_was_made_with(tmp_path: Path, variant) -> None:  # noqa: ANN001
    """``--reference`` made by ``a5 -mistake no_shadows`` (a student's image), the page's render correct: the panel's
    diagnosis of the reference names ``no_shadows``; of the render, finds nothing (``match``)."""
    from view_scenes import a5_png, time_limit, write_scene

    from a5mi.view.build import ViewSession
    from a5mi.view.engine import ViewEngine
    from a5mi.view.pixels import diagnose_frame

    with time_limit(300):
        scene = write_scene(tmp_path / "s.txt")
        a5_png(scene, tmp_path / "student.png", "-size", "32", "32", "-shadows", "-mistake", "no_shadows")
        engine = ViewEngine(str(scene), ViewSession(), reference=str(tmp_path / "student.png"))
        try:
            engine.render(RenderOptions(width=32, height=32, shadows=True))
            of_reference = diagnose_frame(engine, "reference")
            of_render = diagnose_frame(engine, "render")
        finally:
            engine.close()
    assert of_reference["verdict"] == "diagnosis" and list(of_reference["causes"][0]["mistakes"]) == ["no_shadows"]
    assert of_reference["image"] == "reference" and of_reference["flags"] == "-size 32 32 -bounces 4 -shadows"
    assert of_render["verdict"] == "match" and of_render["mistakes"] == []
