"""Every command keeps its inputs (docs/GUARANTEES.md): no output of any command may be one of its inputs or
another of its outputs, compared by resolved path and inode (:func:`a5mi.platform.clobber.check_outputs`, the rule
``a5`` follows), refused before anything is written: one line, exit 2, every file as it was. ``a5mi convert``
replaces only the folders a conversion wrote (its ``.a5mi-convert`` marker); ``a5mi grade`` never writes its
report among the submissions."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from helpers import refused

from a5mi.cli import run_a5mi
from a5mi.platform import imageio

HEAD = ("PerspectiveCamera { center 0 0 10 direction 0 0 -1 up 0 1 0 angle 20 }\n"
        "Lights { numLights 1 DirectionalLight { direction -0.2 -0.2 -1 color 1 1 1 } }\n"
        "Background { color 0.2 0 0.6 ambientLight 0 0 0 }\n")
SCENE = HEAD + ("Materials { numMaterials 1 Material { diffuseColor 1 1 1 } }\n"
                "Group { numObjects 1 MaterialIndex 0 Sphere { center 0 0 0 radius 1 } }\n")
ANIMATION = SCENE + "Animation { frames 2 fps 2 Track { Camera center linear key 0 0 0 10 key 1 0 0 9 } }\n"
XML = """<scene version="3.0.0">
    <default name="tex" value="tex.png"/>
    <bsdf type="diffuse" id="m"><texture type="bitmap" name="reflectance"><string name="filename" value="$tex"/>
    </texture></bsdf>
    <shape type="ply"><string name="filename" value="mesh.ply"/></shape>
</scene>
"""


@pytest.fixture
def work(tmp_path: Path, monkeypatch) -> Path:
    """A folder with two images (one also as A.svg), a scene, an animated scene named like a video, an XML
    scene with its texture and mesh, and a hard link to one image."""
    for name, value in (("A.png", 0.2), ("B.png", 0.6)):
        imageio.write_image(tmp_path / name, np.full((6, 6, 3), value, np.float32))
    os.link(tmp_path / "A.png", tmp_path / "hardA.png")
    (tmp_path / "s.txt").write_text(SCENE)
    (tmp_path / "s.svg").write_text(SCENE)
    (tmp_path / "anim.gif").write_text(ANIMATION)
    (tmp_path / "S.png").write_text(XML)
    (tmp_path / "S.xml").write_text(XML)
    imageio.write_image(tmp_path / "tex.png", np.full((2, 2, 3), 0.5, np.float32))
    (tmp_path / "mesh.ply").write_bytes(b"ply\n")
    (tmp_path / "A.svg").write_bytes((tmp_path / "A.png").read_bytes())
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.mark.parametrize("argv,match", [
    (["compare", "A.png", "B.png", "--diff", "A.png"], "--diff 'A.png' is the input file 'A.png'"),
    (["compare", "A.png", "B.png", "--flip-map", "B.png"], "--flip-map 'B.png' is the input file 'B.png'"),
    (["compare", "A.png", "B.png", "--diff", "hardA.png"], "--diff 'hardA.png' is the input file 'A.png'"),
    (["compare", "A.png", "B.png", "--diff", "d.png", "--flip-map", "d.png"],
     "--diff 'd.png' and --flip-map 'd.png' are the same file"),
    (["render-xml", "S.xml", "-o", "tex.png"], "-o 'tex.png' is the input file"),
    (["render-xml", "S.png", "-o", "S.png"], "-o 'S.png' is the input file 'S.png'"),
    (["render-xml", "S.xml", "-o", "x.png", "-D", "tex=x.png"], "-o 'x.png' is the input file"),
    (["trace", "-input", "s.svg", "-size", "8", "8", "--pixel", "1", "1", "--svg", "s.svg"],
     "--svg 's.svg' is the input file 's.svg'"),
    (["trace", "-input", "s.txt", "-size", "6", "6", "--diff", "A.svg", "--svg", "A.svg"],
     "--svg 'A.svg' is the input file 'A.svg'"),
    (["animate", "anim.gif", "-o", "frames", "--video", "anim.gif", "--size", "8", "8", "-q"],
     "--video 'anim.gif' is the input file 'anim.gif'"),
])
def test_no_command_overwrites_its_inputs(work: Path, capsys, argv: list[str], match: str) -> None:
    """One line, exit 2, nothing written or changed, before anything renders."""
    if argv[:2] == ["render-xml", "S.xml"] and "-D" in argv:
        imageio.write_image(work / "x.png", np.zeros((2, 2, 3), np.float32))
    assert match in refused(capsys, work, run_a5mi, argv)


def test_animate_frames_never_overwrite_the_scene(work: Path, capsys) -> None:
    """A frame's file name that is the scene (the scene kept in the frames folder under that name)."""
    (work / "frames").mkdir()
    (work / "frames" / "frame_00001.png").write_text(ANIMATION)
    argv = ["animate", "frames/frame_00001.png", "-o", "frames", "--size", "8", "8", "-q"]
    line = refused(capsys, work, run_a5mi, argv)
    assert "is the input file 'frames/frame_00001.png'" in line


def test_convert_uses_only_empty_folders_or_its_own(work: Path, mi, capsys) -> None:
    """``q_images/`` and ``q_meshes/`` the user made (no marker) are refused, before the scene is read; an empty
    one is used; a conversion's own folders (with the marker) are replaced on the next run."""
    (work / "q.txt").write_text(SCENE.replace("Sphere { center 0 0 0 radius 1 }", "TriangleMesh { obj_file m.obj }"))
    (work / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    for folder in ("q_images", "q_meshes"):
        (work / folder).mkdir()
        (work / folder / "mine.jpg").write_bytes(b"holiday")
        line = refused(capsys, work, run_a5mi, ["convert", "q.txt", "-o", "q.xml"])
        assert line.startswith(f"a5mi convert: error: {folder}: this folder was not written by a5mi convert")
        (work / folder / "mine.jpg").unlink()  # empty: nothing to lose, used
    assert run_a5mi(["convert", "q.txt", "-o", "q.xml", "-q"]) == 0
    assert sorted(os.listdir(work / "q_meshes")) == [".a5mi-convert", "mesh_000.ply"]
    (work / "q_meshes" / "mesh_009.ply").write_bytes(b"stale")
    assert run_a5mi(["convert", "q.txt", "-o", "q.xml", "-q"]) == 0
    assert sorted(os.listdir(work / "q_meshes")) == [".a5mi-convert", "mesh_000.ply"]


@pytest.mark.parametrize("report,match", [
    ("subs", "-o 'subs' is the SUBMISSIONS folder 'subs'"),
    ("subs/report", "-o 'subs/report' is inside the SUBMISSIONS folder 'subs'"),
    ("link", "-o 'link' is the SUBMISSIONS folder 'subs'"),
])
def test_grade_never_writes_its_report_among_the_submissions(work: Path, capsys, report: str, match: str) -> None:
    (work / "subs" / "alice").mkdir(parents=True)
    imageio.write_image(work / "subs" / "alice" / "a.png", np.zeros((2, 2, 3), np.float32))
    os.symlink("subs", work / "link")
    assert match in refused(capsys, work, run_a5mi, ["grade", "subs", "-o", report])
