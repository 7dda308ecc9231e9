"""The live page's kept Mitsuba objects (a5mi/view/build.py) and its preview: after every kind of edit (a number of
the integrator, a material, the OBJ file, a sphere) the frame is ``a5``'s PNG byte for byte, what did not change is
reused and no render kernel is compiled again; an edited mesh file reloads through the loop; with ``-jitter
-filter`` the loop publishes the one-ray preview (``a5``'s image without those flags) and then the full image."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from view_scenes import a5_png, scene_text, time_limit, view_loop, wait_for

from a5mi.render.options import RenderOptions

OPTS = RenderOptions(width=32, height=32, shadows=True)
FLAGS = ("-size", "32", "32", "-shadows")
FACES = ("left", "right", "up", "down", "front", "back")
#: two triangles; the fourth vertex lies inside the mesh's bounding box, so moving it there keeps the box (a box
#: that grows compiles again: the stock directional light bakes the scene's bounding sphere into the kernel)
OBJ = "v -1.5 -1 -2\nv 0 -1 -2.5\nv -0.8 0.6 -2.2\nv -0.7 -0.2 -2.3\nf 1 2 3\nf 1 4 3\n"


@pytest.fixture(scope="module")
def session(variant):  # noqa: ANN001, ANN201 - fixtures
    from a5mi.view.build import ViewSession

    return ViewSession()


def mesh_scene(folder: Path) -> Path:
    """The tests' scene with a triangle mesh (material 2) and a cube map of six 4x4 faces."""
    from a5mi.platform.imageio import write_image

    (folder / "sky").mkdir()
    for k, face in enumerate(FACES):
        write_image(folder / "sky" / f"{face}.png", np.full((4, 4, 3), (k + 1) / 8.0))
    (folder / "m.obj").write_text(OBJ)
    text = scene_text().replace("    ambientLight 0.2 0.2 0.2", "    ambientLight 0.2 0.2 0.2\n    cubeMap sky")
    text = text.replace("numObjects 3", "numObjects 4")
    end = text.rindex("}")
    text = text[:end] + "    MaterialIndex 2\n    TriangleMesh {\n        obj_file m.obj\n    }\n" + text[end:]
    scene = folder / "s.txt"
    scene.write_text(text)
    return scene


def edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))


def test_freeze_keys_equal_contents_and_nothing_else() -> None:
    from a5mi.view.build import Pending, freeze

    keep: list = []
    a = {"type": "a5_point", "color": [0.5, 0.5, 0.5], "m": np.eye(4), "n": 1}
    assert freeze(a, keep) == freeze({**a, "m": np.eye(4)}, keep) and keep == []
    assert freeze({"x": 0.0}, keep) != freeze({"x": -0.0}, keep)  # a sign can flip a direction
    assert freeze({"x": 1}, keep) != freeze({"x": True}, keep) != freeze({"x": 1.0}, keep)
    assert freeze({"m": np.eye(4)}, keep) != freeze({"m": np.eye(4, dtype=np.float32)}, keep)
    assert freeze({"a": 1, "b": 2}, keep) != freeze({"b": 2, "a": 1}, keep)  # load_dict's order is kept
    p = Pending(("image", 7), lambda resolve: None)
    assert freeze({"bitmap": p}, keep) == ("dict", (("bitmap", ("pending", ("image", 7))),))
    obj = object()
    assert freeze({"o": obj}, keep) != freeze({"o": object()}, keep) and obj in keep  # unknown: by identity


def test_every_edit_renders_as_a5_reusing_what_did_not_change(tmp_path: Path, session) -> None:  # noqa: ANN001
    from a5mi.view.engine import ViewEngine

    with time_limit(300):
        scene = mesh_scene(tmp_path)
        engine = ViewEngine(str(scene), session)
        engine.load()
        frame = engine.render(OPTS)
        assert frame.render_png == a5_png(scene, tmp_path / "a5-0.png", *FLAGS)
        steps = [  # (the edit, which file, the cube map kept, the Mitsuba scene kept)
            ("ambient", scene, "ambientLight 0.2 0.2 0.2", "ambientLight 0.25 0.2 0.2", True),
            ("mesh material", scene, "diffuseColor 0.8 0.8 0.8", "diffuseColor 0.3 0.8 0.5", False),
            ("OBJ file", tmp_path / "m.obj", "v -0.7 -0.2 -2.3", "v -0.5 -0.1 -2.4", False),
            ("sphere", scene, "center -0.5 -0.6 0.2", "center -0.4 -0.6 0.2", True),
            ("point light", scene, "position -1 1 0", "position -1 1.2 0", False),
        ]
        cube_keys = [k for k in session._objects if k[:2] == ("entry", "background")]
        assert len(cube_keys) == 1
        cube = session._objects[cube_keys[0]]  # (holding nothing else: a dropped object must be freed)
        for k, (what, path, old, new, scene_kept) in enumerate(steps, 1):
            kept_before, made_before = session.scenes_kept, session.made
            edit(path, old, new)
            engine.load()
            frame = engine.render(OPTS)
            assert frame.kernels["compiled"] == 0, (what, frame.kernels)  # IDs reused: the cached kernel
            assert session._objects[cube_keys[0]] is cube, what  # the cube map is not made again
            assert (session.scenes_kept - kept_before == 1) == scene_kept, what
            if what == "ambient":
                assert session.made == made_before  # nothing but the integrator
            if what in ("mesh material", "OBJ file"):
                assert session.made - made_before == (2 if what == "mesh material" else 1), what  # BSDF + mesh
            assert frame.render_png == a5_png(scene, tmp_path / f"a5-{k}.png", *FLAGS), what


def test_an_edited_mesh_file_reloads_and_the_page_shows_a5s_image(tmp_path: Path, session) -> None:  # noqa: ANN001
    from a5mi.view.engine import ViewEngine

    with time_limit(300):
        scene = mesh_scene(tmp_path)

        def drive(jobs, states) -> None:  # noqa: ANN001
            first = wait_for(states, lambda s: s.get("frame") and not s["busy"], "first frame")
            edit(tmp_path / "m.obj", "v -0.8 0.6 -2.2", "v -0.8 0.9 -2.2")
            after = wait_for(states, lambda s: (s.get("frame") or 0) > first["frame"] and not s["busy"], "reload")
            assert after["error"] is None and after["changes"] == first["changes"] + 1
            assert after["png"] == a5_png(scene, tmp_path / "a5.png", *FLAGS) != first["png"]

        view_loop(ViewEngine(str(scene), session), OPTS, drive)


def test_jitter_filter_shows_a_labelled_preview_then_a5s_full_image_then_its_comparison(
        tmp_path: Path, session) -> None:  # noqa: ANN001
    """Three updates per save when the last full image was slow (here: any time, ``preview_after=0``): the preview
    (the last comparison kept), the full image (compared next), the comparison of that image."""
    from a5mi.view.engine import ViewEngine, preview_options

    jf = dataclasses.replace(OPTS, jitter=True, filter=True)
    assert preview_options(OPTS) is None and preview_options(dataclasses.replace(jf, integrator="path")) is None
    assert preview_options(jf) == OPTS
    with time_limit(300):
        scene = mesh_scene(tmp_path)

        def drive(jobs, states) -> None:  # noqa: ANN001
            first = wait_for(states, lambda s: s.get("frame") and not s["busy"], "first frame")
            edit(scene, "ambientLight 0.2 0.2 0.2", "ambientLight 0.3 0.2 0.2")
            final = wait_for(states, lambda s: (s.get("frame") or 0) > first["frame"] and not s["busy"], "final")
            preview, image, compared = [s for s in states if (s.get("frame") or 0) > first["frame"]]
            assert preview["preview"] and preview["busy"] and preview["frame"] == final["frame"] - 1
            assert preview["compared"] == first["frame"] == first["compared"]  # the last comparison stays
            assert preview["png"] == a5_png(scene, tmp_path / "pv.png", *FLAGS)  # no -jitter -filter
            assert image["comparing"] and not image["preview"] and image["frame"] == final["frame"]
            assert image["compared"] == first["frame"]
            assert compared is final and final["compared"] == final["frame"] and not final["comparing"]
            assert not final["preview"] and final["error"] is None and final["metrics"]["verdict"] == "wrong"
            assert final["png"] == image["png"] == a5_png(scene, tmp_path / "jf.png", *FLAGS, "-jitter", "-filter")

        ref = tmp_path / "ref.png"
        a5_png(scene, ref, *FLAGS)  # without -jitter -filter: not the same image
        view_loop(ViewEngine(str(scene), session, reference=str(ref)), jf, drive, preview_after=0.0)


@pytest.mark.parametrize("loop", [{"preview_after": float("inf")}, {"preview": False}])
def test_a_fast_full_image_or_no_preview_skips_the_preview(tmp_path: Path, session, loop) -> None:  # noqa: ANN001
    """The first render shows its preview (no full render timed yet) unless ``--no-preview``; a save after a full
    image faster than ``preview_after`` (here: any) goes straight to the full image, ``a5``'s bytes."""
    from a5mi.view.engine import ViewEngine

    jf = dataclasses.replace(OPTS, jitter=True, filter=True)
    with time_limit(300):
        scene = mesh_scene(tmp_path)

        def drive(jobs, states) -> None:  # noqa: ANN001
            first = wait_for(states, lambda s: s.get("frame") and not s["busy"], "first frame")
            assert any(s.get("preview") for s in states) == loop.get("preview", True)
            edit(scene, "ambientLight 0.2 0.2 0.2", "ambientLight 0.3 0.2 0.2")
            final = wait_for(states, lambda s: (s.get("frame") or 0) > first["frame"] and not s["busy"], "final")
            assert [s for s in states if (s.get("frame") or 0) > first["frame"]] == [final]  # no preview
            assert not final["preview"] and final["error"] is None and final["frame"] == first["frame"] + 1
            assert final["png"] == a5_png(scene, tmp_path / "jf.png", *FLAGS, "-jitter", "-filter")

        view_loop(ViewEngine(str(scene), session), jf, drive, **loop)


def test_a_mistake_leaves_no_trace_in_the_next_options_integrator(tmp_path: Path, session) -> None:  # noqa: ANN001
    """A render with ``-mistake no_shadows`` and then one without, in the same session (the page's diagnosis renders
    the correct image after a ``-mistake`` frame): each is ``a5``'s image for its own flags (a template that kept
    the first options' ``mistakes`` parameter made the second render without shadows too)."""
    from a5mi.view.engine import ViewEngine

    with time_limit(240):
        scene = tmp_path / "s.txt"
        scene.write_text(scene_text())
        engine = ViewEngine(str(scene), session)
        try:
            wrong = engine.render(dataclasses.replace(OPTS, mistakes=("no_shadows",)))
            right = engine.render(OPTS)
        finally:
            engine.close()
        assert wrong.render_png == a5_png(scene, tmp_path / "m.png", *FLAGS, "-mistake", "no_shadows")
        assert right.render_png == a5_png(scene, tmp_path / "a5.png", *FLAGS) != wrong.render_png
