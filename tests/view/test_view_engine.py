"""``a5mi view``'s engine and loop in this process (no browser): the frame's PNG is ``a5``'s file byte for byte,
the reference comparison is ``compare``'s, a clicked pixel's tree sums to the pixel and its hit point projects
onto it, a scene error is one positioned line and keeps the last good image, a save re-renders."""

from __future__ import annotations

import dataclasses
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from view_scenes import a5_png, beside_loop, scene_text, time_limit, write_scene

from a5mi.render.options import RenderOptions

OPTS = RenderOptions(width=40, height=40, shadows=True)


@pytest.fixture(scope="module")
def session(variant):  # noqa: ANN001, ANN201 - fixtures
    from a5mi.view.build import ViewSession

    return ViewSession()


def test_frame_png_is_a5s_file_and_the_reference_comparison_is_compares(tmp_path: Path, session) -> None:  # noqa: ANN001
    from a5mi import compare
    from a5mi.platform.imageio import read_levels
    from a5mi.view.engine import ViewEngine

    with time_limit(120):
        scene = write_scene(tmp_path / "s.txt")
        ref_scene = write_scene(tmp_path / "r.txt", "0.1 1 0.1")
        ref = tmp_path / "ref.png"
        a5_png(ref_scene, ref, "-size", "40", "40", "-shadows")
        engine = ViewEngine(str(scene), session, reference=str(ref))
        frame = engine.render(OPTS)
        assert frame.render_png == a5_png(scene, tmp_path / "a5.png", "-size", "40", "40", "-shadows")
        want = compare.compare_arrays(read_levels(tmp_path / "a5.png"), read_levels(ref))
        assert frame.metrics is not None and frame.metrics["psnr"] == pytest.approx(want.psnr)
        assert frame.metrics["share_over"] == want.share_over and frame.metrics["verdict"] == "wrong"
        assert frame.diff_png is not None and frame.reference_png is not None
        # -jitter -filter through the same session: still a5's bytes
        jf = dataclasses.replace(OPTS, jitter=True, filter=True)
        assert engine.render(jf).render_png == a5_png(scene, tmp_path / "jf.png", "-size", "40", "40", "-shadows",
                                                       "-jitter", "-filter")


@pytest.mark.parametrize("flags", [{}, {"jitter": True, "filter": True}])
def test_trace_sums_to_the_pixel_and_projects_the_camera_hit_onto_it(tmp_path: Path, session, flags) -> None:  # noqa: ANN001
    from a5mi.platform.imageio import quantize
    from a5mi.view.engine import ViewEngine

    with time_limit(120):
        engine = ViewEngine(str(write_scene(tmp_path / "s.txt")), session,
                            reference=None)
        frame = engine.render(dataclasses.replace(OPTS, **flags))
        for x, y in ((20, 22), (8, 30), (35, 5)):
            doc = engine.trace(x, y)
            pixel = tuple(int(v) for v in quantize(frame.image[y, x])[:3])
            assert tuple(doc["image_byte"]) == pixel and tuple(doc["value_byte"]) == pixel
            if not flags:
                total = np.array(doc["samples"][0]["sum"], np.float32)
                assert np.array_equal(total, frame.image[y, x, :3])
                assert doc["marks"][0] == pytest.approx([x, y], abs=1e-3)  # the camera ray's hit is this pixel
            assert len(doc["lines"]) >= 3 and doc["diff"] is None


def test_scene_error_keeps_the_last_good_image_and_a_save_re_renders(tmp_path: Path, session) -> None:  # noqa: ANN001
    from a5mi.view.engine import ViewEngine
    from a5mi.view.live import run_engine
    from a5mi.view.server import Hub, Jobs
    from a5mi.view.watcher import Watcher

    with time_limit(120):
        scene = write_scene(tmp_path / "s.txt")
        engine = ViewEngine(str(scene), session)
        hub, jobs, stop = Hub(), Jobs(), threading.Event()
        watcher = Watcher(lambda: jobs.render(reload=True), interval=0.05)
        watcher.start()
        done = threading.Event()

        def wait_version(v: int) -> dict:
            t0 = time.monotonic()
            while hub.state().get("version", 0) < v:
                assert time.monotonic() - t0 < 60, hub.state()
                time.sleep(0.02)
            return hub.state()

        def drive() -> None:
            first = wait_version(1)
            assert first["error"] is None and hub.image("render") is not None
            good = hub.image("render")
            scene.write_text(scene.read_text().replace("numObjects 3", "numObjects 3\n    Sphere {\n  radius"))
            bad = wait_version(2)
            assert bad["error"].startswith(f"{scene}:") and ": error: " in bad["error"], bad["error"]
            assert "\n" not in bad["error"] and hub.image("render") == good and bad["frame"] == first["frame"]
            write_scene(scene, "0.9 0.9 0.1")
            fixed = wait_version(3)
            assert fixed["error"] is None and fixed["frame"] == first["frame"] + 1
            assert hub.image("render") == a5_png(scene, tmp_path / "a5.png", "-size", "40", "40", "-shadows")
            done.set()

        # the loop renders on this (the main) thread, as in a5mi view; the checks run beside it
        try:
            beside_loop(drive, stop, lambda: run_engine(engine, hub, jobs, watcher, OPTS, stop=stop))
        finally:
            watcher.stop()
        assert done.is_set()


def test_page_png_is_write_images_file_without_its_checks(tmp_path: Path, monkeypatch) -> None:  # noqa: ANN001
    """``png_bytes`` gives the bytes ``write_image`` (``a5``'s writer) puts in a PNG file, for float images (out of
    range, NaN, 1, 3 and 4 channels, opaque: write_image refuses what PNG's alpha would change) and ``uint8``
    levels, without fsync or decoding anything back."""
    import os

    from a5mi.platform import imageio
    from a5mi.view.png import png_bytes

    rng = np.random.default_rng(7)
    floats = rng.uniform(-0.2, 1.3, (37, 53, 3)).astype(np.float32)
    floats[3, 4] = np.nan
    images = [floats, floats[..., :1], floats[..., 0], np.concatenate([floats, np.ones_like(floats[..., :1])], axis=2),
              rng.integers(0, 256, (20, 30, 3), dtype=np.uint8)]
    want = []
    for k, img in enumerate(images):
        imageio.write_image(tmp_path / f"{k}.png", img)
        want.append((tmp_path / f"{k}.png").read_bytes())

    def refused(*args, **kw) -> None:  # noqa: ANN002, ANN003
        raise AssertionError("the page's PNG is not verified on disk")

    monkeypatch.setattr(os, "fsync", refused)
    monkeypatch.setattr(imageio, "_decode", refused)
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    assert [png_bytes(img, scratch) for img in images] == want


def test_binary_argv_is_the_spec_flags() -> None:
    from a5mi.view.binary import binary_argv

    opts = RenderOptions(width=30, height=20, bounces=2, shadows=True, jitter=True, filter=True, refraction=False,
                         phong=True)
    assert binary_argv(opts) == ["-size", "30", "20", "-bounces", "2", "-shadows", "-jitter", "-filter",
                                 "-refraction_off"]


def test_a_reload_decodes_only_the_images_that_changed(tmp_path: Path, monkeypatch) -> None:  # noqa: ANN001
    """The six cube-map faces are decoded once; a save of the scene text reuses them, a changed face is read
    again (and only it)."""
    from a5mi.converters import files
    from a5mi.platform.imageio import write_image
    from a5mi.view.engine import ViewEngine

    (tmp_path / "sky").mkdir()
    faces = ("left", "right", "up", "down", "front", "back")
    for k, face in enumerate(faces):
        write_image(tmp_path / "sky" / f"{face}.png", np.full((4, 4, 3), k / 8.0))
    scene = tmp_path / "s.txt"
    scene.write_text(write_scene(tmp_path / "plain.txt").read_text().replace(
        "    ambientLight 0.2 0.2 0.2", "    ambientLight 0.2 0.2 0.2\n    cubeMap sky"))
    reads: list[str] = []
    real = files.imageio.read_uint8
    monkeypatch.setattr(files.imageio, "read_uint8", lambda p: (reads.append(Path(p).name), real(p))[1])
    from types import SimpleNamespace

    engine = ViewEngine(str(scene), session=SimpleNamespace(forget=lambda desc: None))
    time.sleep(0.05)
    engine.load()
    assert sorted(reads) == sorted(f"{f}.png" for f in faces)
    first = engine.desc.background.faces
    reads.clear()
    scene.write_text(scene.read_text().replace("0.2 0.1 0.6", "0.3 0.1 0.6"))
    engine.load()
    assert reads == [] and engine.desc.background.faces[0] is first[0]
    write_image(tmp_path / "sky" / "up.png", np.full((4, 4, 3), 0.9))
    engine.load()
    up = next(f for f in engine.desc.background.faces if f.path.name == "up.png")
    assert reads == ["up.png"] and int(up.pixels[0, 0, 0]) == int(np.float32(0.9) * np.float32(255))


#: a mesh with a quad (its first triangle kept, with a warning at the OBJ line) and a second triangle
QUAD_OBJ = "v -1.5 -1 -2\nv 0 -1 -2.5\nv -0.8 0.6 -2.2\nv -0.7 -0.2 -2.3\nf 1 2 3 4\nf 1 4 3\n"


def test_a_reload_reads_a_mesh_again_only_when_its_file_changed(tmp_path: Path, monkeypatch) -> None:  # noqa: ANN001
    """OBJ meshes and their octree reach masks are kept across descriptions (``describe(meshes=...)``) while the
    file's identity stays: a second description reads no OBJ and computes no masks, and gives the same mesh and
    warnings as a fresh one; an edited OBJ is read again; a file written just before its read is not kept."""
    import os
    from types import SimpleNamespace

    from a5mi.converters import describe as describe_module
    from a5mi.converters import files
    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.view.engine import ViewEngine

    text = scene_text().replace("numObjects 3", "numObjects 4")
    end = text.rindex("}")
    scene = tmp_path / "s.txt"
    body = "    MaterialIndex 2\n    TriangleMesh {\n        obj_file m.obj\n    }\n"
    scene.write_text(text[:end] + body + text[end:])
    mesh = tmp_path / "m.obj"

    def write_obj(body: str, age_s: float) -> None:
        mesh.write_text(body)
        then = time.time_ns() - int(age_s * 1e9)
        os.utime(mesh, ns=(then, then))

    write_obj(QUAD_OBJ, 10.0)
    reads: list[str] = []
    masks: list[int] = []
    real_load, real_reach = files.objfile.load_obj, describe_module.octree.reach_masks
    monkeypatch.setattr(files.objfile, "load_obj",
                        lambda p, loc=None: (reads.append(Path(p).name), real_load(p, loc))[1])
    monkeypatch.setattr(describe_module.octree, "reach_masks",
                        lambda v, f, **kw: (masks.append(len(f)), real_reach(v, f, **kw))[1])

    def positions(desc) -> np.ndarray:  # noqa: ANN001
        (shape,) = [s for s in desc.shapes if getattr(s, "obj_file", None)]
        return shape.mesh.positions

    kept: dict = {}
    first = describe(parse_file(str(scene)), meshes=kept)
    assert reads == ["m.obj"] and masks == [2] and list(kept) == [mesh.resolve()]
    assert any("m.obj:5:" in str(loc) for loc, _ in first.warnings)  # the quad's warning
    scene.write_text(scene.read_text().replace("0.2 0.1 0.6", "0.3 0.1 0.6"))
    again = describe(parse_file(str(scene)), meshes=kept)
    assert reads == ["m.obj"] and masks == [2]  # nothing read or computed again
    fresh = describe(parse_file(str(scene)))
    assert [str(w) for w in again.warnings] == [str(w) for w in fresh.warnings] == [str(w) for w in first.warnings]
    assert np.array_equal(positions(again), positions(fresh))
    (sa,), (sf,) = ([s for s in d.shapes if getattr(s, "obj_file", None)] for d in (again, fresh))
    (s1,) = [s for s in first.shapes if getattr(s, "obj_file", None)]
    assert sa.mesh is s1.mesh  # the same placement: its world-space data kept too
    for field in ("positions", "faces", "normals", "texcoords", "octree", "triangles"):
        a, b = getattr(sa.mesh, field), getattr(sf.mesh, field)
        assert (a is None and b is None) or np.array_equal(a, b), field
    text = scene.read_text()
    scene.write_text(text.replace("    TriangleMesh {\n        obj_file m.obj\n    }\n",
                                  "    Transform {\n        Translate 0 0.1 0\n        TriangleMesh {\n"
                                  "            obj_file m.obj\n        }\n    }\n"))
    reads.clear()
    masks.clear()
    moved = describe(parse_file(str(scene)), meshes=kept)
    assert reads == [] and masks == []  # placed anew, not read again
    assert np.array_equal(positions(moved), positions(describe(parse_file(str(scene)))))
    assert np.allclose(positions(moved), positions(fresh) + [0, 0.1, 0])
    scene.write_text(text)
    reads.clear()
    masks.clear()
    write_obj(QUAD_OBJ.replace("v -0.7 -0.2 -2.3", "v -0.5 -0.1 -2.4"), 5.0)  # edited: read again
    edited = describe(parse_file(str(scene)), meshes=kept)
    assert reads == ["m.obj"] and masks == [2]
    assert np.array_equal(positions(edited), positions(describe(parse_file(str(scene)))))
    assert not np.array_equal(positions(edited), positions(fresh))
    reads.clear()
    write_obj(QUAD_OBJ, 0.0)  # just written: read, not kept
    describe(parse_file(str(scene)), meshes=kept)
    describe(parse_file(str(scene)), meshes=kept)
    assert reads == ["m.obj", "m.obj"] and kept == {}
    # the view's loads pass their own cache; a scene that no longer names the mesh lets it go
    write_obj(QUAD_OBJ, 10.0)
    reads.clear()
    engine = ViewEngine(str(scene), session=SimpleNamespace(forget=lambda desc: None))
    engine.load()
    engine.load()
    assert reads == ["m.obj"] and list(engine._meshes) == [mesh.resolve()]
    write_scene(scene)
    engine.load()
    assert engine._meshes == {}


def test_binary_reference_runs_sandboxed_and_trace_diff_names_a_term(tmp_path: Path, session) -> None:  # noqa: ANN001
    """``--binary``: another a5 (here a5 with ``-fresnel schlick``, a Python script of this venv, allowed to read
    its interpreter and a5mi's sources) renders the same scene and flags in the sandbox; the glass differs, so
    the verdict is not ``match``, and a glass pixel's ``trace --diff`` names terms of the tree."""
    import sys

    from a5mi import PROJECT_ROOT
    from a5mi.difftest.runner import Binary, check_binary
    from a5mi.sandbox import bwrap as sandbox
    from a5mi.view.engine import ViewEngine

    if sandbox.sandbox_problem():
        pytest.skip(f"--binary runs only sandboxed: {sandbox.sandbox_problem()}")
    with time_limit(300):
        (tmp_path / "bin").mkdir(mode=0o755)
        exe = tmp_path / "bin" / "a5schlick"
        exe.write_text(f"#!{sys.executable}\nimport sys\nfrom a5mi.cli import run\n"
                       "sys.exit(run(sys.argv[1:] + ['-fresnel', 'schlick']))\n")
        for p in (exe, exe.parent, tmp_path):  # the run's own user id reaches it
            p.chmod(0o755)
        binary = Binary(check_binary(exe), (sys.prefix, sys.base_prefix, str(PROJECT_ROOT)))
        scene = write_scene(tmp_path / "s.txt")
        engine = ViewEngine(str(scene), session, binary=binary)
        frame = engine.render(OPTS)
        assert frame.reference_error is None and frame.metrics is not None, frame.reference_error
        assert frame.metrics["psnr"] is not None and frame.metrics["verdict"] != "match"
        x0, y0, x1, y1 = frame.metrics["bbox"]
        doc = engine.trace((x0 + x1) // 2, (y0 + y1) // 2)
        assert doc["diff"] is not None and doc["diff"]["off_by"] >= 0
        again = engine.render(OPTS)  # same scene and flags: the binary's image is reused, not run again
        assert again.seconds["reference"] < 0.5 and again.reference_png == frame.reference_png


def test_an_integrator_without_a_ray_tree_says_so(tmp_path: Path, session) -> None:  # noqa: ANN001
    """``-integrator path`` renders on the page; a click answers that it records no ray tree (one line, a user
    error), instead of failing inside the record mode."""
    from a5mi.trace.core import TraceError
    from a5mi.view.engine import ViewEngine

    with time_limit(300):
        engine = ViewEngine(str(write_scene(tmp_path / "s.txt")), session)
        frame = engine.render(RenderOptions(width=12, height=12, integrator="path", seed=1))
        assert frame.size == (12, 12)
        with pytest.raises(TraceError, match="-integrator path records no ray tree"):
            engine.trace(5, 5)


def test_an_exr_reference_beyond_one_shows_clamped_not_wrapped(tmp_path: Path, session) -> None:  # noqa: ANN001
    """An ``.exr`` reference's values beyond 1 (levels beyond 255) show as 255 on the page, below 0 as 0 (a cast to
    uint8 alone wraps 300 to 44)."""
    from a5mi.platform.imageio import read_uint8, write_image
    from a5mi.view.engine import ViewEngine

    with time_limit(120):
        scene = write_scene(tmp_path / "s.txt")
        ref = np.zeros((40, 40, 3), np.float32)
        ref[:, :20] = (2.0, 1.5, -0.5)
        ref[:, 20:] = (0.25, 0.5, 0.75)
        write_image(tmp_path / "ref.exr", ref)
        engine = ViewEngine(str(scene), session, reference=str(tmp_path / "ref.exr"))
        frame = engine.render(OPTS)
        (tmp_path / "shown.png").write_bytes(frame.reference_png)
        shown = read_uint8(tmp_path / "shown.png")[..., :3]
        assert (shown[:, :20] == (255, 255, 0)).all() and (shown[:, 20:] == (63, 127, 191)).all()


def test_the_scratch_folder_goes_with_close_or_with_the_engine(tmp_path: Path) -> None:
    """The PNG encodings' scratch folder is removed by ``close()``, and also when an engine nobody closed is
    collected (tests and embedding callers dropped engines and left ``/tmp/a5mi-view-*`` folders behind)."""
    import gc
    import os
    from types import SimpleNamespace

    from a5mi.view.engine import ViewEngine

    scene = str(write_scene(tmp_path / "s.txt"))
    closed = ViewEngine(scene, session=SimpleNamespace(forget=lambda desc: None))
    assert os.path.isdir(closed._scratch)
    closed.close()
    assert not os.path.exists(closed._scratch)
    closed.close()  # a second close is harmless
    dropped = ViewEngine(scene, session=SimpleNamespace(forget=lambda desc: None))
    folder = dropped._scratch
    assert os.path.isdir(folder)
    del dropped
    gc.collect()
    assert not os.path.exists(folder)
