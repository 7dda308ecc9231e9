"""``a5mi view --binary``: the other executable runs in a fresh folder holding the scene and links to the files
it names (docs/VIEW.md), sandboxed; neither the scene's folder nor the working directory is visible as a whole,
so a classmate's file beside the scene or in the working directory cannot be read."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from view_scenes import scene_text, time_limit

from a5mi.render.options import RenderOptions

QUAD_OBJ = "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3\nf 1 3 4\n"

#: The "binary": says on stderr what it can read (the run's status line is its last stderr line) and fails.
PROBE = """#!/bin/sh
if [ -r "{scene_dir}/solution.cpp" ] || [ -r "{cwd}/notes.cpp" ] || ls "{scene_dir}" | grep -q solution; then
    echo LEAKED >&2
elif [ ! -r meshes/m.obj ] || [ ! -r scene.txt ]; then
    echo MISSING >&2
else
    echo SEALED >&2
fi
exit 1
"""


def test_the_binary_sees_the_files_the_scene_names_and_nothing_beside_them(tmp_path: Path, monkeypatch) -> None:  # noqa: ANN001
    from a5mi.difftest.runner import Binary, check_binary
    from a5mi.sandbox import bwrap as sandbox
    from a5mi.view.build import ViewSession
    from a5mi.view.engine import ViewEngine

    if sandbox.sandbox_problem():
        pytest.skip(f"--binary runs only sandboxed: {sandbox.sandbox_problem()}")
    scene_dir, cwd = tmp_path / "class", tmp_path / "ta"
    (scene_dir / "meshes").mkdir(parents=True)
    cwd.mkdir()
    (scene_dir / "meshes" / "m.obj").write_text(QUAD_OBJ)
    (scene_dir / "solution.cpp").write_text("// a classmate's work\n")
    (cwd / "notes.cpp").write_text("// the TA's notes\n")
    text = scene_text().replace("numObjects 3", "numObjects 4")
    end = text.rindex("}")
    scene = scene_dir / "s.txt"
    scene.write_text(text[:end] + "    MaterialIndex 2\n    TriangleMesh {\n        obj_file meshes/m.obj\n    }\n"
                     + text[end:])
    (tmp_path / "bin").mkdir()
    exe = tmp_path / "bin" / "probe"
    exe.write_text(PROBE.format(scene_dir=scene_dir, cwd=cwd))
    for p in (exe, exe.parent, tmp_path, scene_dir, scene_dir / "meshes", cwd):
        p.chmod(0o755)
    for p in (scene_dir / "solution.cpp", cwd / "notes.cpp", scene, scene_dir / "meshes" / "m.obj"):
        p.chmod(0o644)  # readable by the run's own user id, were it bound
    monkeypatch.chdir(cwd)
    with time_limit(300):
        engine = ViewEngine(str(scene), ViewSession(), binary=Binary(check_binary(exe)))
        frame = engine.render(RenderOptions(width=16, height=16))
    assert frame.reference_error is not None and frame.reference_error.endswith("binary failed: SEALED"), \
        frame.reference_error


def test_staged_links_link_only_existing_files_inside_the_folder(tmp_path: Path) -> None:
    from a5mi.view.binary import staged_links

    root, folder = tmp_path / "root", tmp_path / "run"
    (root / "tex").mkdir(parents=True)
    folder.mkdir()
    (root / "tex" / "a.bmp").write_bytes(b"x")
    (tmp_path / "outside.obj").write_text("v 0 0 0\n")
    named = [root / "tex" / "a.bmp", root / "missing.obj", root / ".." / "outside.obj", root / "tex"]
    files = staged_links(folder, named, (root,))
    assert files == (str((root / "tex" / "a.bmp").resolve()),)
    assert os.readlink(folder / "tex" / "a.bmp") == files[0]
    assert sorted(p.name for p in folder.rglob("*")) == ["a.bmp", "tex"]
