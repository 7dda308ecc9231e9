"""Hostile inputs through the real commands: each ends with a correct render or
one line, exit 2 and nothing written; outputs never destroy inputs; ``a5mi convert`` writes only its set."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import files_under, one_error_line, refused

from a5mi import cli
from a5mi.cli.app import Console, load_scene
from a5mi.platform import imageio
from a5mi.render import session
from a5mi.render.options import RenderOptions

HEAD = ("PerspectiveCamera { center 0 0 10 direction 0 0 -1 up 0 1 0 angle 20 }\n"
        "Lights { numLights 1 DirectionalLight { direction -0.2 -0.2 -1 color 1 1 1 } }\n"
        "Background { color 0.2 0 0.6 ambientLight 0 0 0 }\n")


def _scene(material: str, objects: str = "Sphere { center 0 0 0 radius 1 }", n: int = 1) -> str:
    return HEAD + (f"Materials {{ numMaterials 1 Material {{ {material} }} }}\n"
                   f"Group {{ numObjects {n} MaterialIndex 0 {objects} }}\n")


# ------------------------------------------------------------------------------- colours
def _render(tmp_path: Path, text: str, mi, size: int = 12) -> np.ndarray:
    (tmp_path / "s.txt").write_text(text.replace("color 0.2 0 0.6", "color 0 0 0"))  # black: only shading
    desc = load_scene(str(tmp_path / "s.txt"), Console("a5", quiet=True))
    return session.render(desc, RenderOptions(width=size, height=size)).image


@pytest.mark.parametrize("color", ["1.5 1.5 1.5", "2 0 0", "1.0000001 0 0", "-0.5 3 0"])
def test_colours_outside_unit_range_render_linearly(tmp_path: Path, mi, color: str) -> None:
    """any finite diffuseColor renders (SPEC A.5 sets no range), and Lambert shading is linear in it:
    the image of colour c is c times the image of white (unquantised renderer output)."""
    c = np.array([float(x) for x in color.split()], np.float32)
    white = _render(tmp_path, _scene("diffuseColor 1 1 1"), mi)
    img = _render(tmp_path, _scene(f"diffuseColor {color}"), mi)
    np.testing.assert_allclose(img, white * c, rtol=1e-6, atol=1e-7)
    assert white.max() > 0.5


def test_every_colour_field_accepts_any_finite_value(tmp_path: Path, mi, capsys) -> None:
    """specular, marble, light, background and ambient colours far outside [0, 1], through the CLI."""
    text = (HEAD.replace("color 1 1 1", "color 4 -2 9").replace("ambientLight 0 0 0", "ambientLight 2 -1 7")
            .replace("color 0.2 0 0.6", "color -3 5 1e30")
            + "Materials { numMaterials 2 Material { diffuseColor 1e30 -1e30 2 specularColor 5 -5 0.5 }\n"
              " Material { Noise { color 9 -9 1 color -2 2 40 octaves 2 frequency 1 amplitude 1 } "
              "diffuseColor 1 1 1 } }\n"
              "Group { numObjects 2 MaterialIndex 0 Sphere { center -1 0 0 radius 1 } MaterialIndex 1 "
              "Sphere { center 1 0 0 radius 1 } }\n")
    (tmp_path / "s.txt").write_text(text)
    out = tmp_path / "o.png"
    assert cli.run(["-input", str(tmp_path / "s.txt"), "-output", str(out), "-size", "16", "16",
                    "-bounces", "2", "-q"]) == 0
    assert capsys.readouterr().err == ""
    assert imageio.read_uint8(out).shape == (16, 16, 3)


def test_huge_colours_give_no_numpy_warnings(tmp_path: Path) -> None:
    """a successful render with colours near FLT_MAX prints nothing (no RuntimeWarning) in a fresh
    interpreter, with -jitter -filter (the blur sums them)."""
    (tmp_path / "s.txt").write_text(_scene("diffuseColor 3e38 3e38 3e38 specularColor 3e38 0 0"))
    p = subprocess.run([sys.executable, "-W", "default", "-m", "a5mi", "-input", "s.txt", "-output", "o.png",
                        "-size", "9", "9", "-jitter", "-filter", "-normals", "n.png", "-depth", "9", "11", "d.png"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and p.stderr == "", p.stderr


# ------------------------------------------------------------------------------- positioned errors
@pytest.mark.parametrize("camera,match", [
    ("direction 1e-40 1e-40 -1e-40 up 0 1 0", "do not define a basis in float32"),
    ("direction 0 0 -1 up 0 1e-30 -1", "do not define a basis in float32"),
    ("direction 1e20 0 -1e20 up 0 1 0", "do not define a basis in float32"),
    ("direction 0 0 -1 up 1e20 1e20 0", "do not define a basis in float32"),
])
def test_camera_degenerate_in_float32(tmp_path: Path, capsys, camera: str, match: str) -> None:
    text = _scene("diffuseColor 1 1 1").replace("direction 0 0 -1 up 0 1 0", camera)
    (tmp_path / "s.txt").write_text(text)
    assert cli.run(["-input", str(tmp_path / "s.txt"), "-output", str(tmp_path / "o.png")]) == 2
    line = one_error_line(capsys)
    assert line.startswith(f"{tmp_path / 's.txt'}:1:") and match in line
    assert not (tmp_path / "o.png").exists()


@pytest.mark.parametrize("name,match", [
    ("a" * 300 + ".obj", "File name too long"),
    ("f.obj", "is a FIFO, not a file"),
    ("dev.obj", "is a device, not a file"),
])
def test_mesh_names_that_cannot_be_files(tmp_path: Path, capsys, name: str, match: str) -> None:
    """A name longer than the filesystem allows, a FIFO, a device: each said as such, and nothing hangs."""
    os.mkfifo(tmp_path / "f.obj")
    os.symlink("/dev/zero", tmp_path / "dev.obj")
    (tmp_path / "s.txt").write_text(_scene("diffuseColor 1 1 1", f"TriangleMesh {{ obj_file {name} }}"))
    assert cli.run(["-input", str(tmp_path / "s.txt"), "-output", str(tmp_path / "o.png")]) == 2
    line = one_error_line(capsys)
    assert line.startswith(f"{tmp_path / 's.txt'}:5:") and match in line and len(line) < 400


#: ``python -c AS_NOBODY ARGV``: ``a5 ARGV`` as ``nobody`` (uid and gid 65534), wherever this interpreter, its
#: packages and the project live (a clone in a 0700 folder, a Python under /root). The process starts as root: a
#: first, silent run with the output in a missing folder loads every module ``a5`` needs up to its output checks
#: (it must end with status 2); then it drops to ``nobody`` and runs ``a5 ARGV``.
AS_NOBODY = f"""\
import os, sys
sys.path[:0] = {sys.path!r}
from a5mi import cli
from a5mi.entry import a5
argv = sys.argv[1:]
out = argv.index("-output") + 1
stderr = os.dup(2)
os.dup2(os.open(os.devnull, os.O_WRONLY), 2)
status = cli.run([*argv[:out], "no-such-folder/" + argv[out], *argv[out + 1:]])
sys.stderr.flush()
os.dup2(stderr, 2)
assert status == 2, f"the loading run ended with status {{status}}"
os.setgroups([])
os.setresgid(65534, 65534, 65534)
os.setresuid(65534, 65534, 65534)
sys.argv = ["a5", *argv]
a5()
"""


def test_output_of_another_user_in_a_sticky_folder_is_refused_before_rendering(tmp_path: Path) -> None:
    """as a user who may not replace the file (sticky folder, owned by someone else), the output is
    refused before the render, and the file is untouched. Runs the command as ``nobody`` (needs root)."""
    if os.geteuid() != 0:
        pytest.skip("needs root to run as another user")
    box = tmp_path / "sticky"
    box.mkdir()
    os.chmod(box, 0o1777)
    (box / "s.txt").write_text(_scene("diffuseColor 1 1 1"))
    (box / "o.png").write_bytes(b"root's file")
    p = subprocess.run([sys.executable, "-c", AS_NOBODY, "-input", "s.txt", "-output", "o.png", "-size", "8", "8"],
                       cwd=box, capture_output=True, text=True, timeout=120,
                       env={**os.environ, "HOME": str(box), "A5MI_CACHE_DIR": str(box)})
    assert p.returncode == 2, p.stderr
    assert p.stderr.strip() == "a5: error: o.png: cannot replace it: it belongs to another user in the sticky " \
                               "folder '.'"
    assert (box / "o.png").read_bytes() == b"root's file"


# ------------------------------------------------------------------------------- outputs vs inputs
def _textured(tmp_path: Path) -> Path:
    (tmp_path / "tex").mkdir()
    imageio.write_image(tmp_path / "tex" / "head.bmp", np.full((4, 4, 3), 0.5, np.float32))
    (tmp_path / "s.txt").write_text(_scene("diffuseColor 1 1 1 texture tex/head.bmp",
                                           "Triangle { vertex0 -1 -1 0 vertex1 1 -1 0 vertex2 0 1 0 }"))
    return tmp_path / "s.txt"


@pytest.mark.parametrize("argv,match", [
    (["-output", "o.png", "-normals", "tex/head.bmp"], "-normals 'tex/head.bmp' is the input file"),
    (["-output", "tex/head.bmp"], "-output 'tex/head.bmp' is the input file"),
    (["-output", "real/o.png", "-normals", "link/o.png"], "-output 'real/o.png' and -normals 'link/o.png' are "
                                                           "the same file"),
    (["-output", "o.png", "-depth", "1", "2", "hard.png"], "-output 'o.png' and -depth 'hard.png' are the same"),
    (["-output", "scene.png"], "-output 'scene.png' is the input file 'scene.png'"),
])
def test_outputs_never_overwrite_inputs_or_each_other(tmp_path: Path, capsys, monkeypatch, argv, match) -> None:
    """compared by resolved path and inode, before anything is rendered; nothing changes on disk."""
    scene = _textured(tmp_path)
    (tmp_path / "real").mkdir()
    os.symlink("real", tmp_path / "link")
    imageio.write_image(tmp_path / "o.png", np.zeros((2, 2, 3), np.float32))
    os.link(tmp_path / "o.png", tmp_path / "hard.png")
    shutil.copy(scene, tmp_path / "scene.png")
    monkeypatch.chdir(tmp_path)
    inp = "scene.png" if "scene.png" in argv else "s.txt"
    # -q: the texture has no uv here (warned)
    assert match in refused(capsys, tmp_path, cli.run, ["-input", inp, *argv, "-size", "8", "8", "-q"])


# ------------------------------------------------------------------------------- items 4, 6: convert
BUNNY = _scene("diffuseColor 1 1 1", "TriangleMesh { obj_file m.obj }")
OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


@pytest.fixture
def convert_dir(tmp_path: Path) -> Path:
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "s.txt").write_text(BUNNY)
    (tmp_path / "in" / "m.obj").write_text(OBJ)
    (tmp_path / "out").mkdir()
    return tmp_path


def test_convert_never_writes_through_symlinks_and_replaces_the_set(convert_dir: Path, mi, capsys) -> None:
    """symlinks in the meshes folder or at the envmap are replaced, not followed; stale PLYs of an
    earlier conversion go (its folder carries the conversion's marker); a second conversion leaves exactly the
    files of a fresh one."""
    out = convert_dir / "out"
    victim = convert_dir / "victim.ply"
    victim.write_bytes(b"precious")
    assert cli.run_a5mi(["convert", str(convert_dir / "in" / "s.txt"), "-o", str(out / "o.xml"), "-q"]) == 0
    first = files_under(out)
    assert sorted(first) == ["o.xml", "o_meshes", "o_meshes/.a5mi-convert", "o_meshes/mesh_000.ply"]
    os.unlink(out / "o_meshes" / "mesh_000.ply")
    os.symlink(victim, out / "o_meshes" / "mesh_000.ply")
    (out / "o_meshes" / "mesh_007.ply").write_bytes(b"stale")
    os.symlink(victim, out / "o_envmap.exr")
    assert cli.run_a5mi(["convert", str(convert_dir / "in" / "s.txt"), "-o", str(out / "o.xml"), "-q"]) == 0
    assert victim.read_bytes() == b"precious"
    assert not (out / "o_meshes" / "mesh_000.ply").is_symlink()
    assert files_under(out) == first
    capsys.readouterr()


@pytest.mark.parametrize("case,match", [
    ("meshes_is_a_file", "o_meshes: exists and is a regular file, not a folder"),
    ("xml_is_a_folder", "o.xml: exists and is a folder, not a regular file"),
    ("meshes_hold_an_input", "the meshes folder"),
])
def test_convert_refuses_before_writing(convert_dir: Path, capsys, case: str, match: str) -> None:
    """a file where the meshes folder goes, a folder where the XML goes, or an input inside the
    meshes folder: one line, exit 2, nothing written or removed."""
    out = convert_dir / "out"
    scene = convert_dir / "in" / "s.txt"
    if case == "meshes_is_a_file":
        (out / "o_meshes").write_bytes(b"mine")
    elif case == "xml_is_a_folder":
        (out / "o.xml").mkdir()
    else:
        (out / "o_meshes").mkdir()
        (out / "o_meshes" / ".a5mi-convert").write_text("")  # a conversion's folder, then used as an input
        shutil.copy(convert_dir / "in" / "m.obj", out / "o_meshes" / "m.obj")
        shutil.copy(scene, out / "o_meshes" / "s.txt")
        scene = out / "o_meshes" / "s.txt"
    assert match in refused(capsys, convert_dir, cli.run_a5mi, ["convert", str(scene), "-o", str(out / "o.xml")])


def test_convert_into_a_read_only_folder_leaves_nothing(convert_dir: Path, capsys, monkeypatch) -> None:
    """a folder the user may not write: refused before the scene is read (as root, whom permissions
    do not stop, the check is exercised through os.access)."""
    out = convert_dir / "out"
    os.chmod(out, 0o555)
    monkeypatch.setattr(os, "access", lambda path, mode, **kw: not str(path).endswith("out"))
    assert cli.run_a5mi(["convert", str(convert_dir / "in" / "s.txt"), "-o", str(out / "o.xml")]) == 2
    line = one_error_line(capsys)
    assert "output folder" in line and line.endswith("is not writable")
    assert list(out.iterdir()) == []


# ------------------------------------------------------------------------------- render-xml: one line, checked first
@pytest.fixture
def textured_xml(tmp_path: Path) -> Path:
    """A converted scene with an OBJ mesh (a PLY) and a texture (a5 plugins), rendered 8x8."""
    imageio.write_image(tmp_path / "t.png", np.full((4, 4, 3), 0.5, np.float32))
    (tmp_path / "m.obj").write_text("v -1 -1 0\nv 1 -1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n")
    (tmp_path / "s.txt").write_text(_scene("diffuseColor 1 1 1 texture t.png", "TriangleMesh { obj_file m.obj }"))
    assert cli.run_a5mi(["convert", str(tmp_path / "s.txt"), "-o", str(tmp_path / "s.xml"), "-size", "8",
                         "8"]) == 0
    return tmp_path / "s.xml"


@pytest.mark.parametrize("remove,match", [
    ("s_images", r"s.xml:\d+:\d+: error: file 's_images/texture_000_t.png' not found"),
    ("s_meshes", r"s.xml:\d+:\d+: error: file 's_meshes/mesh_000.ply' not found"),
])
def test_render_xml_checks_the_files_it_names_first(textured_xml: Path, capsys, monkeypatch, remove: str,
                                                    match: str) -> None:
    """A missing texture or PLY: one line at the XML position, before Mitsuba is asked (no std::bad_alloc,
    no traceback of the plugin)."""
    shutil.rmtree(textured_xml.parent / remove)
    monkeypatch.chdir(textured_xml.parent / "s_meshes" if remove == "s_images" else textured_xml.parent)
    capsys.readouterr()
    assert cli.run_a5mi(["render-xml", str(textured_xml), "-o", str(textured_xml.parent / "o.png")]) == 2
    line = one_error_line(capsys)
    assert re.search(match, line), line
    assert not (textured_xml.parent / "o.png").exists()


def test_render_xml_plugin_errors_are_one_positioned_line(textured_xml: Path, capsys) -> None:
    """angle nan: the plugin's exception, at the sensor's position, no flattened traceback."""
    bad = textured_xml.parent / "nan.xml"
    bad.write_text(re.sub(r'name="angle" value="[^"]*"', 'name="angle" value="nan"', textured_xml.read_text()))
    capsys.readouterr()
    assert cli.run_a5mi(["render-xml", str(bad), "-o", str(bad.parent / "o.png")]) == 2
    line = one_error_line(capsys)
    assert re.fullmatch(rf"{re.escape(str(bad))}:\d+:\d+: error: failed to instantiate sensor plugin of type "
                        r'"a5_camera": ValueError: a5_camera: camera angle .*got nan', line), line
    assert "Traceback" not in line and "File " not in line


def test_render_xml_names_an_unused_define(textured_xml: Path, capsys) -> None:
    """Mitsuba's two-line "Found unused parameters:" error keeps the parameter it names in its one line."""
    capsys.readouterr()
    assert cli.run_a5mi(["render-xml", str(textured_xml), "-o", str(textured_xml.parent / "o.png"), "-D",
                         "nosuch=1"]) == 2
    line = one_error_line(capsys)
    assert line.endswith("Found unused parameters: $nosuch=1"), line
    assert not (textured_xml.parent / "o.png").exists()


def test_render_xml_refuses_a_film_beyond_memory(textured_xml: Path, capsys) -> None:
    capsys.readouterr()
    assert cli.run_a5mi(["render-xml", str(textured_xml), "-o", str(textured_xml.parent / "o.png"), "-D",
                         "width=100000", "-D", "height=100000"]) == 2
    line = one_error_line(capsys)
    assert "a 100000x100000 film at 1 samples per pixel needs about" in line and "is available" in line


def test_render_xml_image_bomb_is_refused_by_its_header(textured_xml: Path, capsys, monkeypatch) -> None:
    """A stock or a5 bitmap whose header promises more pixels than memory holds: refused before decoding."""
    from hostile import png_bomb

    (textured_xml.parent / "s_images" / "texture_000_t.png").write_bytes(png_bomb(30000))
    monkeypatch.setenv("A5MI_MEMORY_LIMIT", str(4 << 30))
    capsys.readouterr()
    assert cli.run_a5mi(["render-xml", str(textured_xml), "-o", str(textured_xml.parent / "o.png")]) == 2
    assert "30000x30000 pixels need about" in one_error_line(capsys)


@pytest.mark.parametrize("obj", ["Sphere { center 0 0 0 radius 1e-40 }", "Sphere { center 0 0 0 radius 3e38 }",
                                 "Transform { UniformScale 1e30 Sphere { center 0 0 0 radius 1 } }"])
def test_mitsuba_warnings_never_reach_stdout(tmp_path: Path, obj: str) -> None:
    """Mitsuba's ``WARN [Sphere] 'to_world' transform shouldn't contain non-uniform scaling!`` (a float32
    round-off of a uniform scale) is not printed: stdout stays empty and stderr has only a5mi's own lines."""
    (tmp_path / "s.txt").write_text(_scene("diffuseColor 1 0 0", obj))
    p = subprocess.run([sys.executable, "-m", "a5mi", "-input", "s.txt", "-output", "o.png", "-size", "8", "8"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and p.stdout == "", p.stdout
    assert "WARN" not in p.stderr and "non-uniform" not in p.stderr, p.stderr


# ------------------------------------------------------------------------------- special files never block
def _a5mi_process(cwd: Path, argv: list[str]) -> subprocess.CompletedProcess[str]:
    """``a5mi ARGV`` in a child process with a time limit (a blocking open must fail the test, not hang it)."""
    py = "import sys; from a5mi.entry import a5mi; sys.argv = ['a5mi'] + sys.argv[1:]; a5mi()"
    try:
        return subprocess.run([sys.executable, "-c", py, *argv], cwd=cwd, capture_output=True, text=True,
                              timeout=60, env={**os.environ, "A5MI_CACHE_DIR": str(cwd)})
    except subprocess.TimeoutExpired:
        pytest.fail(f"a5mi {' '.join(argv)} blocked for 60 s")


XML_MESH = """<scene version="3.0.0">
    <shape type="ply"><string name="filename" value="{mesh}"/></shape>
</scene>
"""


@pytest.mark.parametrize("argv,match", [
    (["compare", "a.png", "a.png", "--noise", "fifo"], "--noise: cannot read 'fifo': not a regular file (FIFO)"),
    (["render", "--jobs", "fifo"], "cannot read the jobs file 'fifo': not a regular file (FIFO)"),
    (["render", "--jobs", "/dev/zero"], "cannot read the jobs file '/dev/zero': not a regular file (character"),
    (["render-xml", "fifo.xml", "-o", "o.png"], "fifo.xml:2:23: error: 'fifo' is not a regular file (FIFO)"),
    (["render-xml", "zero.xml", "-o", "o.png"],
     "zero.xml:2:23: error: '/dev/zero' is not a regular file (character device)"),
])
def test_special_files_are_refused_not_waited_on(tmp_path: Path, argv: list[str], match: str) -> None:
    """As ``a5 -input``: inputs are read only if they are regular files (:func:`a5mi.platform.paths.read_regular`);
    a FIFO or a device named as the noise band, the jobs file or an XML scene's mesh is one line, exit 2."""
    os.mkfifo(tmp_path / "fifo")
    imageio.write_image(tmp_path / "a.png", np.zeros((2, 2, 3), np.float32))
    (tmp_path / "fifo.xml").write_text(XML_MESH.format(mesh="fifo"))
    (tmp_path / "zero.xml").write_text(XML_MESH.format(mesh="/dev/zero"))
    p = _a5mi_process(tmp_path, argv)
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and match in lines[0], p.stderr
    assert not (tmp_path / "o.png").exists()


# ------------------------------------------------------------------------------- unwritable outputs: exit 2
def _no_render(monkeypatch) -> None:
    def render(*a, **k):  # the checks come before the render
        raise AssertionError("rendered before the output was checked")

    monkeypatch.setattr(session, "render", render)


@pytest.mark.parametrize("case,match", [
    ("loop", "loop.png: Too many levels of symbolic links"),
    ("name300", "the file name is too long (300 bytes"),
    ("name240", "the file name is too long (240 bytes"),  # fits NAME_MAX, its temporary does not
    ("path_max", "the path is too long (the limit is"),
])
def test_unwritable_output_names_are_one_line_before_rendering(tmp_path: Path, monkeypatch, capsys, case: str,
                                                               match: str) -> None:
    (tmp_path / "s.txt").write_text(_scene("diffuseColor 1 1 1"))
    monkeypatch.chdir(tmp_path)
    os.symlink("loop2.png", "loop.png")
    os.symlink("loop.png", "loop2.png")
    out = {"loop": "loop.png", "name300": "a" * 296 + ".png", "name240": "b" * 236 + ".png",
           "path_max": "/".join(["c" * 200] * 21) + "/o.png"}[case]
    _no_render(monkeypatch)
    line = refused(capsys, tmp_path, cli.run, ["-input", "s.txt", "-output", out, "-size", "8", "8"])
    assert line.startswith("a5: error: ") and match in line and len(line) < 300, line


def test_immutable_output_is_refused_before_rendering(tmp_path: Path, monkeypatch, capsys) -> None:
    """``chattr +i`` (or ``+a``): the file cannot be replaced, which ``os.replace`` would find only after the
    render; refused before it, the file untouched."""
    if shutil.which("chattr") is None:
        pytest.skip("needs chattr")
    (tmp_path / "s.txt").write_text(_scene("diffuseColor 1 1 1"))
    (tmp_path / "o.png").write_bytes(b"kept")
    for flag in ("+i", "+a"):
        if subprocess.run(["chattr", flag, str(tmp_path / "o.png")], capture_output=True).returncode != 0:
            pytest.skip("this filesystem or user cannot set chattr flags")
        try:
            monkeypatch.chdir(tmp_path)
            _no_render(monkeypatch)
            assert cli.run(["-input", "s.txt", "-output", "o.png", "-size", "8", "8"]) == 2
            assert one_error_line(capsys) == \
                "a5: error: o.png: cannot replace it: the file is immutable or append-only (chattr)"
        finally:
            subprocess.run(["chattr", flag.replace("+", "-"), str(tmp_path / "o.png")], check=True)
        assert (tmp_path / "o.png").read_bytes() == b"kept"


@pytest.mark.parametrize("argv,match", [
    (["-o", "file"], "a5mi grade: error: -o 'file': exists and is not a folder"),
    (["-o", "r", "--timeout", "-1"], "a5mi grade: error: --timeout expects a number more than 0"),
    (["-o", "r", "--timeout", "0"], "a5mi grade: error: --timeout expects a number more than 0"),
    (["-o", "r", "--scheduler", "tcp://127.0.0.1:1", "--insecure-scheduler"],
     "a5mi grade: error: --scheduler tcp://127.0.0.1:1: cannot connect: Connection refused"),
])
def test_grade_mistakes_fail_fast_and_leave_nothing(tmp_path: Path, monkeypatch, capsys, argv, match) -> None:
    """An existing file as the report folder, a timeout that is not positive, a scheduler nothing listens on
    (refused by the grade command's own connection check, before Dask's client and its 30 s timeout: no
    ``distributed.Client`` and no cluster is ever made): one line, exit 2, no report folder left behind."""
    import distributed

    def no_dask(*args: object, **kw: object) -> None:
        raise AssertionError("a Dask client or cluster was started")

    monkeypatch.setattr(distributed, "Client", no_dask)
    monkeypatch.setattr(distributed, "LocalCluster", no_dask)
    (tmp_path / "subs" / "alice").mkdir(parents=True)
    (tmp_path / "file").write_text("mine")
    monkeypatch.chdir(tmp_path)
    assert refused(capsys, tmp_path, cli.run_a5mi, ["grade", "subs", *argv]).startswith(match)


# ------------------------------------------------------------------- float32 limits that would give NaN pixels
def test_refraction_index_whose_square_overflows_float32_is_refused(tmp_path: Path, capsys) -> None:
    """refractionIndex 1e20: leaving the sphere, Snell's (n/nt)²(1 - c²) is inf x 0 = NaN (10 NaN pixels saved
    as black before); refused at its position. 1.8e19 still renders, every pixel finite."""
    scene = tmp_path / "s.txt"
    scene.write_text(_scene("diffuseColor 0.5 0.5 0.5 specularColor 0.5 0.5 0.5 refractionIndex 1e20"))
    capsys.readouterr()
    assert cli.run(["-input", str(scene), "-output", str(tmp_path / "o.exr"), "-size", "50", "50"]) == 2
    line = one_error_line(capsys)
    assert re.fullmatch(rf"{re.escape(str(scene))}:4:\d+: error: refractionIndex 1e\+20 is too large: .*", line), line
    assert not (tmp_path / "o.exr").exists()
    scene.write_text(_scene("diffuseColor 0.5 0.5 0.5 specularColor 0.5 0.5 0.5 refractionIndex 1.8e19"))
    assert cli.run(["-input", str(scene), "-output", str(tmp_path / "o.exr"), "-size", "50", "50"]) == 0
    assert np.isfinite(imageio.read_image(tmp_path / "o.exr")).all()


def test_camera_angle_whose_ray_length_overflows_float32_is_refused(tmp_path: Path, capsys) -> None:
    """angle 5e-18: 1/tan(angle/2) squared overflows float32, every ray direction is inf/NaN (a5soln draws white,
    a5mi drew the background); refused. 1e-17 renders the centre's colour everywhere, as a5soln does."""
    scene = tmp_path / "s.txt"
    text = _scene("diffuseColor 0.5 0.5 0.5")
    scene.write_text(text.replace("angle 20", "angle 5e-18"))
    capsys.readouterr()
    assert cli.run(["-input", str(scene), "-output", str(tmp_path / "o.png"), "-size", "8", "8"]) == 2
    assert "camera angle 5e-18 is too small" in one_error_line(capsys)
    scene.write_text(text.replace("angle 20", "angle 1e-17"))
    assert cli.run(["-input", str(scene), "-output", str(tmp_path / "o.png"), "-size", "8", "8"]) == 0
    img = imageio.read_uint8(tmp_path / "o.png")
    assert (img == img[4, 4]).all() and not (img[4, 4] == [51, 0, 153]).all()


def test_depth_bounds_beyond_float32_are_refused(tmp_path: Path, capsys) -> None:
    scene = tmp_path / "s.txt"
    scene.write_text(_scene("diffuseColor 0.5 0.5 0.5"))
    capsys.readouterr()
    assert cli.run(["-input", str(scene), "-output", str(tmp_path / "o.png"), "-size", "8", "8",
                    "-depth", "1e39", "1e40", str(tmp_path / "d.png")]) == 2
    assert one_error_line(capsys) == ("a5: error: -depth expects depths within float32 (|d| <= 3.4e38, the sample "
                                      "solution's precision), found '1e39'")
    assert not (tmp_path / "o.png").exists() and not (tmp_path / "d.png").exists()


def test_near_singular_transforms_render_without_numpy_warnings(tmp_path: Path, capsys, recwarn) -> None:
    """A sphere under ``Scale 1e-15`` and a plane under ``Scale 1e-20 1 1``: the binary's float32 inverse has
    determinant 0 (inf/NaN entries, as in a5soln); the render completes with no RuntimeWarning (before: two
    numpy warnings on stderr, four lines)."""
    scene = tmp_path / "s.txt"
    scene.write_text(HEAD + "Materials { numMaterials 1 Material { diffuseColor 0.5 0.5 0.5 } }\n"
                     "Group { numObjects 2 MaterialIndex 0 Transform { Scale 1e-15 1e-15 1e-15 Sphere { center 0 0 0 "
                     "radius 1 } } Transform { Scale 1e-20 1 1 Plane { normal 0 1 0 offset -1 } } }\n")
    assert cli.run(["-input", str(scene), "-output", str(tmp_path / "o.png"), "-size", "8", "8"]) == 0
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)], [str(w.message) for w in recwarn]
    assert capsys.readouterr().err == ""
