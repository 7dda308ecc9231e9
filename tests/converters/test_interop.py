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
from helpers import ROOT

from a5mi.cli import run, run_a5mi
from a5mi.platform.imageio import read_levels

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
    """the XML and compare's --diff were written 0600 whatever the umask (mkstemp's mode)."""
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
    """size, bounces and --spp become <default> parameters (mitsuba -Dspp=256 scene.xml)."""
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
    """textures, cube-map faces and meshes are written beside the XML and named relative to it, so
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


# ------------------------------------------------------------------ E.3 lens and -spp in the converted XML
def _xml_render(xml: Path, spp: int) -> np.ndarray:
    """``mi.render`` of a converted XML (the README's Python route) as the a5 levels: ``int(c·255)`` (B.1)."""
    import mitsuba as mi

    image = np.asarray(mi.render(mi.load_file(str(xml)), spp=spp, seed=0))[..., :3]
    return np.floor(np.clip(image, 0.0, 1.0) * 255.0)


def _a5(scene: Path, out: Path, flags: list[str]) -> np.ndarray:
    assert run(["-input", str(scene), "-output", str(out), *flags]) == 0
    return read_levels(out).astype(np.float64)


def _rmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)))


def _psnr(a: np.ndarray, b: np.ndarray) -> float:
    return float(20.0 * np.log10(255.0 / _rmse(a, b)))


def test_converted_xml_renders_the_thin_lens(variant: str, tmp_path: Path) -> None:
    """docs/EXTENSIONS.md E.3 in the a5_camera sensor: ``a5mi convert`` (no --stock) of scenes/dof.txt rendered
    by mi.render at 16 spp against ``a5 -spp 16``. The noise floor is two a5 renders of different seeds (the
    same estimator twice); the XML (its lens samples from Mitsuba's stratified sampler, not E.5's strata)
    must come within 3 dB of it, and far above the pinhole image (which the XML rendered before). Measured at
    48x48: a5 seed 0 vs 1 36.3 dB, XML vs a5 36.2 dB, pinhole vs a5 25.7 dB."""
    scene = ROOT / "scenes" / "dof.txt"
    flags = ["-size", "48", "48", "-shadows"]
    a5 = _a5(scene, tmp_path / "a5.png", [*flags, "-spp", "16", "-seed", "0"])
    a5_other = _a5(scene, tmp_path / "a5b.png", [*flags, "-spp", "16", "-seed", "1"])

    assert run_a5mi(["convert", str(scene), "-o", str(tmp_path / "dof.xml"), *flags, "--spp", "16"]) == 0
    assert 'name="aperture"' in (tmp_path / "dof.xml").read_text()
    xml = _xml_render(tmp_path / "dof.xml", 16)
    floor, got = _psnr(a5, a5_other), _psnr(xml, a5)
    text = scene.read_text().replace("aperture 0.35", "aperture 0")
    (tmp_path / "pinhole.txt").write_text(text)
    pinhole = _a5(tmp_path / "pinhole.txt", tmp_path / "pin.png", flags)
    assert got >= floor - 3.0, (got, floor)
    assert got > _psnr(pinhole, a5) + 5.0, (got, _psnr(pinhole, a5))


def test_converted_xml_at_many_spp_keeps_the_pixel_centres(variant: str, tmp_path: Path) -> None:
    """scenes/soft_shadows.txt: the XML at 256 spp (mi.render) against ``a5 -spp 64`` (which samples the
    lights only, every pass through the pixel centre, E.5). If the two estimate the same image, the RMSE is
    the noise alone: ``sqrt(σ₆₄² + σ₁²/256)``, with ``σ₆₄`` from two a5 renders of different seeds
    (``RMSE/√2``) and ``σ₁``, the noise of one sample of the XML's estimator, from two XML renders of 1 spp
    (``RMSE/√2``, an upper bound: 256 samples of it are independent). Allowed: 1.5 times that (the RMSE over
    2304 pixels scatters by a few percent). Measured at 48x48: σ₆₄ = 0.16, σ₁ = 2.14 levels, bound 0.31,
    RMSE 0.27 levels; with the sampler's positions spread over the pixel (antialiased edges, as before
    ``pixel_centres``) 6.5 levels."""
    scene = ROOT / "scenes" / "soft_shadows.txt"
    flags = ["-size", "48", "48", "-shadows"]
    a5 = _a5(scene, tmp_path / "a.png", [*flags, "-spp", "64", "-seed", "0"])
    a5_other = _a5(scene, tmp_path / "b.png", [*flags, "-spp", "64", "-seed", "1"])
    assert run_a5mi(["convert", str(scene), "-o", str(tmp_path / "s.xml"), *flags, "--spp", "256"]) == 0
    import mitsuba as mi

    loaded = mi.load_file(str(tmp_path / "s.xml"))
    one = [np.clip(np.asarray(mi.render(loaded, spp=1, seed=s))[..., :3], 0, 1) * 255.0 for s in (1, 2)]
    sigma_64 = _rmse(a5, a5_other) / np.sqrt(2.0)
    sigma_1 = _rmse(*one) / np.sqrt(2.0)
    bound = 1.5 * np.sqrt(sigma_64**2 + sigma_1**2 / 256.0)
    got = _rmse(_xml_render(tmp_path / "s.xml", 256), a5)
    assert got <= bound, (got, bound, sigma_64, sigma_1)
