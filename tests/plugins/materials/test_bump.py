"""Bump and normal mapping (docs/EXTENSIONS.md E.7): a constant-slope height field gives the tilted normal, a
zero height field and a flat normal map give the unperturbed image bit for bit, -bump off ignores the maps."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import QUAD_OBJ

W = 24  # image size of every test render


SCENE = """PerspectiveCamera {{ center 0.3 -0.2 4 direction 0 0 -1 up 0 1 0 angle 20 }}
Lights {{ numLights 2
  DirectionalLight {{ direction -0.5 0.3 -1 color 0.8 0.8 0.8 }}
  PointLight {{ position 1 2 3 color 0.5 0.5 0.5 }} }}
Background {{ color 0.1 0.2 0.3 ambientLight 0.1 0.1 0.1 }}
Materials {{ numMaterials 2
  Material {{ diffuseColor 0.8 0.6 0.4 specularColor 0.3 0.3 0.3 {maps} }}
  Material {{ diffuseColor 0.2 0.9 0.3 }} }}
Group {{ numObjects 2
  MaterialIndex 0 TriangleMesh {{ obj_file quad.obj }}
  MaterialIndex 1 Sphere {{ center 0 1.4 0.6 radius 0.5 }} }}
"""


def _write(tmp_path: Path, maps: str, images: dict[str, np.ndarray]) -> Path:
    from a5mi.platform import imageio

    (tmp_path / "quad.obj").write_text(QUAD_OBJ)
    for name, pixels in images.items():
        imageio.write_image(tmp_path / name, pixels.astype(np.float32) / 255.0)
    scene = tmp_path / "s.txt"
    scene.write_text(SCENE.format(maps=maps))
    return scene


def _render(scene: Path, bump: bool, **kw: object) -> np.ndarray:
    """(H, W, 6): colour and the first-hit normal of each pixel (one ray per pixel centre)."""
    import mitsuba as mi

    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import build_scene

    options = RenderOptions(**{"width": W, "height": W, "bump": bump, "normals": True, "shadows": True, "bounces": 2,
                               **kw})
    desc = describe(parse_file(str(scene)), bump=bump)
    return np.asarray(mi.render(build_scene(desc, options)))


def _ramp(slope: int, size: int = 16) -> np.ndarray:
    """Grey bytes ``slope · ix``: g rises by slope/255 per texel along +x (u)."""
    row = (slope * np.arange(size)).astype(np.uint8)
    return np.repeat(np.tile(row, (size, 1))[:, :, None], 3, axis=2)


def test_constant_slope_gives_the_tilted_normal(tmp_path: Path, variant: str) -> None:
    """h = s·g with ∂g/∂u = slope·W/255 (exact for the bilinear lookup inside the image): the normal is
    normalize(P_u' × P_v') = normalize((−2 h_u, 0, 4)) at every hit whose lookup cell is not clamped."""
    s, slope, size = 0.01, 12, 16
    scene = _write(tmp_path, "bump ramp.png bumpScale 0.01", {"ramp.png": _ramp(slope, size)})
    img = _render(scene, bump=True)
    h_u = s * slope * size / 255.0
    want = np.array([-2.0 * h_u, 0.0, 4.0])
    want /= np.linalg.norm(want)
    n = img[..., 3:6]
    on_quad = np.abs(n[..., 2]) > 0.5
    # the lookup cell [ix, ix+1] is unclamped for u*size < size - 1, i.e. x < 1 - 2/size in world units
    xs = (np.arange(W) - (W - 1) / 2) / ((W - 1) / 2) * np.tan(np.radians(10)) * 4 + 0.3
    inside = on_quad & (xs[None, :] < 1 - 2.0 / size - 0.05) & (xs[None, :] > -0.95)
    assert inside.sum() > 100
    assert np.allclose(n[inside], want, atol=2e-6), np.abs(n[inside] - want).max()
    # the tilt shows in the colour too: the same scene without -bump differs on the quad
    plain = _render(scene, bump=False)
    assert np.abs(plain[inside][:, :3] - img[inside][:, :3]).max() > 1e-3
    assert np.allclose(plain[inside][:, 3:6], [0.0, 0.0, 1.0], atol=1e-7)


def test_zero_height_field_is_the_unperturbed_image(tmp_path: Path, variant: str) -> None:
    """A black height field (g = 0 everywhere, any bumpScale): with -bump the image equals the plain render
    bit for bit (colour and normals), and equals the render of the scene without the bump keyword."""
    zero = np.zeros((8, 8, 3), dtype=np.uint8)
    scene = _write(tmp_path, "bump zero.png bumpScale 3", {"zero.png": zero})
    bumped = _render(scene, bump=True)
    plain = _render(scene, bump=False)
    assert np.array_equal(bumped, plain)
    (tmp_path / "bare").mkdir()
    assert np.array_equal(_render(_write(tmp_path / "bare", "", {}), bump=True), plain)


def test_flat_normal_map_is_the_unperturbed_image(tmp_path: Path, variant: str) -> None:
    """A normal map of (128, 128, 255) = (0.5, 0.5, 1) decodes to t = (0, 0, 1) exactly: the image is the plain
    render bit for bit; a tilted map (255, 128, 255) turns the normal towards +T = +x."""
    flat = np.zeros((8, 8, 3), dtype=np.uint8)
    flat[...] = (128, 128, 255)
    scene = _write(tmp_path, "normalMap flat.png", {"flat.png": flat})
    assert np.array_equal(_render(scene, bump=True), _render(scene, bump=False))
    tilt = flat.copy()
    tilt[..., 0] = 255
    scene = _write(tmp_path, "normalMap tilt.png", {"tilt.png": tilt})
    n = _render(scene, bump=True)[..., 3:6]
    on_quad = n[..., 2] > 0.5
    assert np.allclose(n[on_quad], np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0), atol=2e-6)


def test_bump_keywords_and_errors(tmp_path: Path) -> None:
    """-bump off: the bump file is not even read (a5soln ignores it); -bump on: a missing file is an error at
    its name; the sibenik fallback STEM-bump.EXT beside the texture is used with a warning."""
    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.converters.errors import SceneError

    scene = _write(tmp_path, "bump missing.png bumpScale -0.5", {})
    model = parse_file(str(scene))
    assert model.materials[0].bump_scale == -0.5
    assert describe(model).materials[0].bump is None
    with pytest.raises(SceneError) as exc:
        describe(model, bump=True)
    line = scene.read_text().splitlines()[6]
    assert f"s.txt:7:{line.index('missing.png') + 1}:" in str(exc.value)
    assert "bump file 'missing.png' not found" in str(exc.value)
    (tmp_path / "tex").mkdir()
    from a5mi.platform import imageio

    imageio.write_image(tmp_path / "tex" / "kd.png", np.ones((4, 4, 3), dtype=np.float32))
    imageio.write_image(tmp_path / "tex" / "kamen-bump.png", np.zeros((4, 4, 3), dtype=np.float32))
    scene.write_text(SCENE.format(maps="texture tex/kd.png bump bump/kamen.png"))
    desc = describe(parse_file(str(scene)), bump=True)
    assert desc.materials[0].bump is not None and desc.materials[0].bump.path.name == "kamen-bump.png"
    assert any("using 'tex/kamen-bump.png' beside the texture" in w for _, w in desc.warnings)
    scene.write_text(SCENE.format(maps="normalMap"))
    with pytest.raises(SceneError):
        parse_file(str(scene))


def test_stock_mapping_wraps_the_bsdf(tmp_path: Path, variant: str) -> None:
    """--stock: the BSDF of a bumped material is Mitsuba's bumpmap (scale = bumpScale) around a normalmap."""
    import mitsuba as mi

    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.converters.to_mitsuba import to_dict
    from a5mi.render.options import RenderOptions

    flat = np.full((8, 8, 3), 128, dtype=np.uint8)
    scene = _write(tmp_path, "bump ramp.png normalMap flat.png bumpScale 0.02",
                   {"ramp.png": _ramp(10), "flat.png": flat})
    desc = describe(parse_file(str(scene)), bump=True)
    d = to_dict(desc, RenderOptions(width=8, height=8, bump=True), stock=True)
    mesh = next(v for k, v in d.items() if k.startswith("mesh"))
    text = str(mesh.bsdf())
    assert "BumpMap" in text and "NormalMap" in text, text[:300]
    assert mi.load_dict(d) is not None


def _stock_normal(bsdf_dict: dict, uv: tuple[float, float]) -> np.ndarray:
    """The shading normal a stock adapter uses at ``uv`` on the quad (dp_du = (2,0,0), dp_dv = (0,2,0), N = z),
    read off a white Lambert inside it: π f(wo) = N'·wo for three directions wo in front."""
    import drjit as dr
    import mitsuba as mi

    bsdf = mi.load_dict(bsdf_dict)
    si = dr.zeros(mi.SurfaceInteraction3f, 1)
    si.n = mi.Normal3f(0, 0, 1)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    si.uv = mi.Point2f(*uv)
    si.dp_du, si.dp_dv, si.wi = mi.Vector3f(2, 0, 0), mi.Vector3f(0, 2, 0), mi.Vector3f(0, 0, 1)

    def f(x: float, y: float, z: float) -> float:
        return float(bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(x, y, z))[0][0]) * np.pi

    r = float(np.sqrt(0.5))
    c = f(0.0, 0.0, 1.0)
    return np.array([f(r, 0.0, r) / r - c, f(0.0, r, r) / r - c, c])


def test_stock_bumpmap_has_the_same_law(variant: str) -> None:
    """Mitsuba's bumpmap on the stock bitmap (converters/materials.py: raw, bilinear, v flipped to A.4's rows)
    tilts a constant-slope ramp in u and in v exactly as a5mi does (the half-texel offset does not change a
    constant gradient); the stock texture shows A.4's top row at v near 1."""
    import drjit as dr
    import mitsuba as mi

    from a5mi.converters.files import Image
    from a5mi.converters.materials import stock_bitmap

    size, slope, s = 16, 12, 0.01
    lambert = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}}
    h = s * slope * size / 255.0
    ramp_u = _ramp(slope, size)
    ramp_rows = np.ascontiguousarray(ramp_u.transpose(1, 0, 2))  # g rises down the image: ∂g/∂v < 0 in A.4
    for pixels, want in ((ramp_u, (-2.0 * h, 0.0, 4.0)), (ramp_rows, (0.0, 2.0 * h, 4.0))):
        tex = stock_bitmap(Image(Path("ramp.png"), pixels), lambda img: {"bitmap": mi.Bitmap(img.pixels.copy())})
        tex["to_uv"] = mi.ScalarTransform4f(tex["to_uv"].tolist())
        got = _stock_normal({"type": "bumpmap", "scale": s, "bsdf": lambert, "height": tex}, (0.37, 0.41))
        assert np.allclose(got, np.array(want) / np.linalg.norm(want), atol=1e-5), got
    top = np.zeros((16, 16, 3), dtype=np.uint8)
    top[:8] = 255
    tex = stock_bitmap(Image(Path("top.png"), top), lambda img: {"bitmap": mi.Bitmap(img.pixels.copy())})
    tex["to_uv"] = mi.ScalarTransform4f(tex["to_uv"].tolist())
    si = dr.zeros(mi.SurfaceInteraction3f, 1)
    si.uv = mi.Point2f(0.5, 0.9)
    assert np.allclose(np.asarray(mi.load_dict(tex).eval(si)), 1.0)


MIRROR = """PerspectiveCamera { center 0 0 5 direction 0 0 -1 up 0 1 0 angle 8 }
Background { color 0 0 0 }
Materials { numMaterials 2
  Material { diffuseColor 0 0 0 specularColor 1 1 1 normalMap tilt.png }
  Material { diffuseColor 0 1 0 } }
Group { numObjects 2
  MaterialIndex 0 TriangleMesh { obj_file quad.obj }
  MaterialIndex 1 Sphere { center 3 0 0 radius 0.8 } }
"""


def test_mirror_rays_leave_about_the_perturbed_normal(tmp_path: Path, variant: str) -> None:
    """A mirror quad facing the camera with a normal map tilted 45° towards +x: with -bump the mirror ray of
    d = −z is reflect(d, N') = +x and sees the green sphere there (no lights: ambient 1, SPEC A.1, so its colour
    is exactly (0, 1, 0)); without -bump it goes back to the black background."""
    from a5mi.platform import imageio

    (tmp_path / "quad.obj").write_text(QUAD_OBJ)
    tilt = np.full((8, 8, 3), 128, dtype=np.uint8)
    tilt[..., 0] = 255
    tilt[..., 2] = 255
    imageio.write_image(tmp_path / "tilt.png", tilt.astype(np.float32) / 255.0)
    scene = tmp_path / "m.txt"
    scene.write_text(MIRROR)
    bumped, plain = _render(scene, bump=True, shadows=False), _render(scene, bump=False, shadows=False)
    centre = slice(W // 2 - 2, W // 2 + 2)
    assert np.allclose(bumped[centre, centre, :3], [0.0, 1.0, 0.0], atol=1e-6)
    assert np.allclose(plain[centre, centre, :3], 0.0)
