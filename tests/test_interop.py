"""Mitsuba interop (docs/MITSUBA.md): a converted scene rendered by a plain Mitsuba script or by
``a5mi render-xml`` gives the a5 image; the documented Python example runs."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import QUAD_OBJ

from a5mi.cli import run, run_a5mi
from a5mi.imageio import read_levels

ROOT = Path(__file__).resolve().parent.parent

PLAIN_SCRIPT = """
import sys
import mitsuba as mi
import numpy as np
mi.set_variant("llvm_ad_rgb")
from a5mi.plugins import register_all
register_all()
image = mi.render(mi.load_file(sys.argv[1]))
assert image.shape[2] == 3, image.shape            # RGB only: a5_whitted's AOVs are opt-in
mi.Bitmap(image).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, srgb_gamma=False).write(sys.argv[2])
"""


@pytest.fixture(scope="module")
def scene10(tmp_path_factory: pytest.TempPathFactory, scenes_dir: Path) -> tuple[Path, Path]:
    """scene10 at 40x40 with shadows: the a5 render and the converted XML."""
    out = tmp_path_factory.mktemp("interop")
    flags = ["-size", "40", "40", "-shadows", "-bounces", "3"]
    assert run(["-input", str(scenes_dir / "scene10_sphere.txt"), "-output", str(out / "a5.png"), *flags]) == 0
    assert run_a5mi(["convert", str(scenes_dir / "scene10_sphere.txt"), "-o", str(out / "s.xml"), *flags]) == 0
    return out / "a5.png", out / "s.xml"


def test_plain_mitsuba_script_on_the_converted_xml_writes_the_a5_image(scene10, tmp_path: Path) -> None:
    a5_png, xml = scene10
    subprocess.run([sys.executable, "-c", PLAIN_SCRIPT, str(xml), str(tmp_path / "plain.png")], check=True,
                   timeout=300)
    diff = np.abs(read_levels(tmp_path / "plain.png") - read_levels(a5_png))
    assert diff.max() <= 1.0  # Mitsuba's 8-bit conversion rounds where a5 truncates: at most one level


def test_render_xml_is_the_a5_render(scene10, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a5_png, xml = scene10
    assert run_a5mi(["render-xml", str(xml), "-o", str(tmp_path / "x.png")]) == 0
    assert np.array_equal(read_levels(tmp_path / "x.png"), read_levels(a5_png))
    assert run_a5mi(["render-xml", str(xml), "-o", str(tmp_path / "y.png"), "-D", "oops"]) == 2
    assert "a5mi render-xml: error: -D expects NAME=VALUE" in capsys.readouterr().err
    bad = tmp_path / "bad.xml"
    bad.write_text("<scene version='3.0.0'><shape type='nosuchplugin'/></scene>")
    assert run_a5mi(["render-xml", str(bad), "-o", str(tmp_path / "z.png")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f'{bad}:1:25: error: failed to instantiate shape plugin of type "nosuchplugin": Plugin '
                   '"nosuchplugin" not found!'] and not (tmp_path / "z.png").exists()


def test_documented_python_example_runs(tmp_path: Path) -> None:
    """The example of docs/MITSUBA.md (also in README), run as written: a mixed a5 + stock scene."""
    text = (ROOT / "docs" / "MITSUBA.md").read_text()
    code = re.search(r"```python\n(.*?)```", text, re.S)
    assert code is not None
    assert code.group(1) in (ROOT / "README.md").read_text()  # README shows the same code
    subprocess.run([sys.executable, "-c", code.group(1)], cwd=tmp_path, check=True, timeout=300)
    img = read_levels(tmp_path / "mixed.png")
    assert img.shape == (96, 96, 3) and img.std() > 10  # a picture, not a constant


@pytest.mark.parametrize("umask", [0o022, 0o077])
def test_converted_xml_and_diff_images_honour_the_umask(scene10, tmp_path: Path, umask: int) -> None:
    """Issue 18: the XML and compare's --diff were written 0600 whatever the umask (mkstemp's mode)."""
    import os

    a5_png, _ = scene10
    old = os.umask(umask)
    try:
        assert run_a5mi(["compare", str(a5_png), str(a5_png), "--diff", str(tmp_path / "d.png")]) == 0
        xml = tmp_path / "s.xml"
        assert run_a5mi(["convert", str(ROOT / "scenes" / "demo.txt"), "-o", str(xml)]) == 0
    finally:
        os.umask(old)
    for path in (tmp_path / "d.png", xml):
        assert path.stat().st_mode & 0o777 == 0o666 & ~umask, path


def test_convert_writes_render_flags_as_mitsuba_defaults(tmp_path: Path, scenes_dir: Path) -> None:
    """Issue 18: size, bounces and --spp become <default> parameters (mitsuba -Dspp=256 scene.xml)."""
    import mitsuba as mi

    xml = tmp_path / "s.xml"
    assert run_a5mi(["convert", str(scenes_dir / "scene10_sphere.txt"), "-o", str(xml), "--stock", "--size", "30",
                     "20", "--bounces", "2", "--spp", "16", "-q"]) == 0
    text = xml.read_text()
    for name, value in (("spp", "16"), ("width", "30"), ("height", "20"), ("max_depth", "4")):
        assert f'<default name="{name}" value="{value}" />' in text, name  # path: max_depth = bounces + 2
    scene = mi.load_file(str(xml), width=12, height=8, spp=9)  # the stratified sampler wants a square
    assert tuple(scene.sensors()[0].film().size()) == (12, 8)
    assert scene.sensors()[0].sampler().sample_count() == 9


TEXTURED_SCENE = """PerspectiveCamera { center 0.3 0.2 4 direction -0.1 -0.05 -1 up 0 1 0 angle 45 }
Lights { numLights 1 DirectionalLight { direction -0.3 -0.5 -1 color 0.9 0.9 0.9 } }
Background { color 0 0 0 ambientLight 0.2 0.2 0.2 cubeMap maps/sky }
Materials { numMaterials 2
  PhongMaterial { diffuseColor 1 1 1 texture maps/wood/char.bmp }
  PhongMaterial { diffuseColor 0.1 0.1 0.1 specularColor 0.8 0.8 0.8 }
}
Group { numObjects 2
  MaterialIndex 0 TriangleMesh { obj_file meshes/quad.obj }
  MaterialIndex 1 Sphere { center 0.9 0.6 0.5 radius 0.35 }
}
"""


def test_converted_folder_can_be_moved(tmp_path: Path, scenes_dir: Path) -> None:
    """Issue 18: textures, cube-map faces and meshes are written beside the XML and named relative to it, so
    the folder renders the same after a move, with the scene's own files gone; the picture is the a5 render."""
    import shutil
    import xml.etree.ElementTree as ET

    src = tmp_path / "in"
    (src / "maps" / "wood").mkdir(parents=True)
    (src / "meshes").mkdir()
    shutil.copy(scenes_dir / "tex" / "char.bmp", src / "maps" / "wood" / "char.bmp")
    shutil.copytree(scenes_dir / "tex" / "church", src / "maps" / "sky")
    (src / "meshes" / "quad.obj").write_text(QUAD_OBJ)
    (src / "s.txt").write_text(TEXTURED_SCENE)
    flags = ["-size", "24", "24", "-shadows"]
    assert run(["-input", str(src / "s.txt"), "-output", str(tmp_path / "a5.png"), *flags]) == 0
    out = tmp_path / "out dir"
    out.mkdir()
    xml = out / "my scene.xml"
    assert run_a5mi(["convert", str(src / "s.txt"), "-o", str(xml), *flags]) == 0
    names = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    assert names == ["my scene.xml", "my scene_images/.a5mi-convert",
                     "my scene_images/cubemap/back.png", "my scene_images/cubemap/down.png",
                     "my scene_images/cubemap/front.png", "my scene_images/cubemap/left.png",
                     "my scene_images/cubemap/right.png", "my scene_images/cubemap/up.png",
                     "my scene_images/texture_000_char.png", "my scene_meshes/.a5mi-convert",
                     "my scene_meshes/mesh_000.ply"]
    files = [e.get("value") for e in ET.parse(xml).getroot().iter("string") if e.get("name") == "filename"]
    assert files and all(not Path(f).is_absolute() and str(tmp_path) not in f for f in files), files
    assert run_a5mi(["render-xml", str(xml), "-o", str(tmp_path / "before.png")]) == 0
    assert run_a5mi(["convert", str(src / "s.txt"), "-o", str(out / "stock.xml"), "--stock", *flags]) == 0
    assert run_a5mi(["render-xml", str(out / "stock.xml"), "-o", str(tmp_path / "stock_before.png")]) == 0

    moved = tmp_path / "elsewhere" / "moved here"
    moved.parent.mkdir()
    shutil.move(out, moved)
    shutil.rmtree(src)  # nothing may still point at the scene's own files
    assert run_a5mi(["render-xml", str(moved / "my scene.xml"), "-o", str(tmp_path / "after.png")]) == 0
    after = read_levels(tmp_path / "after.png")
    np.testing.assert_array_equal(after, read_levels(tmp_path / "before.png"))
    np.testing.assert_array_equal(after, read_levels(tmp_path / "a5.png"))  # texture and sky really loaded
    assert after.std() > 10
    assert run_a5mi(["render-xml", str(moved / "stock.xml"), "-o", str(tmp_path / "stock_after.png")]) == 0
    np.testing.assert_array_equal(read_levels(tmp_path / "stock_after.png"),
                                  read_levels(tmp_path / "stock_before.png"))  # the stock bitmap and envmap too
