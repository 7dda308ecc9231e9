"""SPEC A.4 / A.6 input files are read once: ``describe`` reads every OBJ mesh and decodes every image (texture,
cube-map face) exactly once, and nothing after it (``to_dict``, ``mi.load_dict``, the render) opens a file
again: the plugins take the decoded pixels as ``mi.Bitmap`` parameters. The plugins still read files when
given ``filename`` (the XML path), through the same reader, with the same pixels; and the packed
``ImageAtlas`` returns exactly the file's bytes / 255."""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from a5mi import data_dir
from a5mi.converters import obj as objfile
from a5mi.converters.a5_parser import parse_file
from a5mi.converters.describe import CubeMapBackground, MeshShape, describe
from a5mi.converters.files import Image
from a5mi.platform import imageio
from a5mi.render.options import RenderOptions

CUBE_FACES = ("left", "right", "up", "down", "front", "back")


def _png(path: Path, pixels: np.ndarray) -> Path:
    """Write 8-bit ``pixels`` (H, W, C) exactly (value / 255 quantises back to the same byte)."""
    imageio.write_image(path, (pixels.astype(np.float32) + 0.5) / 255.0)
    return path


@pytest.fixture
def reads(monkeypatch: pytest.MonkeyPatch) -> dict[str, Counter]:
    """Counts of ``a5mi.platform.imageio.read_uint8`` (the one image reader) and ``converters.obj.load_obj`` calls,
    per resolved path."""
    counts: dict[str, Counter] = {"image": Counter(), "obj": Counter()}
    read_uint8, load_obj = imageio.read_uint8, objfile.load_obj

    def counted_read(path: Any) -> np.ndarray:
        counts["image"][Path(path).resolve()] += 1
        return read_uint8(path)

    def counted_load(path: Any, loc: Any = None) -> objfile.ObjMesh:
        counts["obj"][Path(path).resolve()] += 1
        return load_obj(path, loc)

    monkeypatch.setattr(imageio, "read_uint8", counted_read)
    monkeypatch.setattr(objfile, "load_obj", counted_load)
    return counts


def _filenames(value: Any) -> list[str]:
    """Every ``filename`` parameter anywhere in a scene dict."""
    if isinstance(value, dict):
        own = [str(v) for k, v in value.items() if k == "filename"]
        return own + [f for v in value.values() for f in _filenames(v)]
    return []


SCENES = ["scene08_c", "scene11_cube", "scene10_sphere", "sibenik"]


@pytest.mark.course_data
@pytest.mark.parametrize("name", SCENES)
def test_a4_a6_each_file_is_read_once_from_describe_to_render(variant: str, reads: dict[str, Counter],
                                                            name: str) -> None:
    """scene08: textures on uv meshes; scene11: a cube map and OBJ files; scene10: a cube map, marble, a
    plane; sibenik: 15 OBJ files, several textures and a cube-map link file. Each file once, then nothing."""
    import mitsuba as mi

    from a5mi.converters.to_mitsuba import to_dict
    from a5mi.render.driver import render_scene

    root = data_dir()
    path = root / "extras" / "sibenik" / "s.txt" if name == "sibenik" else root / "scenes" / f"{name}.txt"
    model = parse_file(path)
    desc = describe(model)
    objs = {s.obj_file for s in desc.shapes if isinstance(s, MeshShape) and s.obj_file is not None}
    images = {m.kd.path for m in desc.materials if isinstance(m.kd, Image)}
    if isinstance(desc.background, CubeMapBackground):
        images |= {f.path for f in desc.background.faces}
    names = {p.primitive.obj_file for p in model.objects if hasattr(p.primitive, "obj_file")}
    assert len(objs) == len(names) > 0  # every OBJ the scene names, resolved
    assert dict(reads["obj"]) == dict.fromkeys(objs, 1)
    assert dict(reads["image"]) == dict.fromkeys(images, 1) and images

    options = RenderOptions(6, 4, shadows=True)
    for stock in (False, True):
        scene_dict = to_dict(desc, options, stock=stock)
        assert _filenames(scene_dict) == []  # no plugin, stock or a5, is handed a file to open
        scene = mi.load_dict(scene_dict)
        if not stock:
            image = render_scene(scene, desc.camera, options).image
            assert image.shape == (4, 6, 3) and np.isfinite(image).all()
        else:
            mi.render(scene, spp=1)
    assert dict(reads["obj"]) == dict.fromkeys(objs, 1)  # still once each
    assert dict(reads["image"]) == dict.fromkeys(images, 1)


def test_a4_described_pixels_are_the_files_bytes_and_read_only(scenes_dir: Path) -> None:
    desc = describe(parse_file(scenes_dir / "scene08_c.txt"))
    textures = [m.kd for m in desc.materials if isinstance(m.kd, Image)]
    assert textures
    for img in textures:
        assert img.pixels.dtype == np.uint8 and img.pixels.ndim == 3 and not img.pixels.flags.writeable
        np.testing.assert_array_equal(img.pixels, imageio.read_uint8(img.path))
        assert img.size == (img.pixels.shape[1], img.pixels.shape[0])


def test_a4_a5_bitmap_from_pixels_equals_from_file_and_reads_nothing(variant: str, tmp_path: Path,
                                                                     reads: dict[str, Counter]) -> None:
    import drjit as dr
    import mitsuba as mi

    from a5mi.converters.files import read_image
    from a5mi.converters.to_mitsuba import bitmap

    rng = np.random.default_rng(3)
    p = _png(tmp_path / "t.png", rng.integers(0, 256, (5, 7, 3), dtype=np.uint8))
    img = read_image(p, None, "texture")  # type: ignore[arg-type]
    assert reads["image"][p.resolve()] == 1
    uv = rng.random((2, 500)).astype(np.float32)
    si = dr.zeros(mi.SurfaceInteraction3f, 500)
    si.uv = mi.Point2f(uv)
    pairs = [({"type": "a5_bitmap", "bitmap": bitmap(img)}, {"type": "a5_bitmap", "filename": str(p)}),
             ({"type": "bitmap", "bitmap": bitmap(img), "raw": True, "filter_type": "bilinear", "wrap_mode": "clamp"},
              {"type": "bitmap", "filename": str(p), "raw": True, "filter_type": "bilinear", "wrap_mode": "clamp"})]
    for from_pixels, from_file in pairs:
        before = reads["image"][p.resolve()]
        a = np.array(mi.load_dict(from_pixels).eval(si))
        assert reads["image"][p.resolve()] == before  # the bitmap parameter opens no file
        b = np.array(mi.load_dict(from_file).eval(si))
        np.testing.assert_array_equal(a, b)
    assert reads["image"][p.resolve()] == 2  # read_image, then a5_bitmap's filename (stock reads natively)


def test_a4_load_rgb8_reads_the_file_through_imageio(variant: str, tmp_path: Path,
                                                    reads: dict[str, Counter]) -> None:
    from a5mi.plugins.textures import imagedata

    grey = np.array([[[10], [20]], [[30], [40]]], dtype=np.uint8)  # 1 channel: replicated to RGB
    p = _png(tmp_path / "g.png", grey)
    np.testing.assert_array_equal(imagedata.load_rgb8(p), np.repeat(grey, 3, axis=2))
    assert reads["image"][p.resolve()] == 1
    with pytest.raises(ValueError, match="image file not found"):
        imagedata.load_rgb8(tmp_path / "missing.png")
    (tmp_path / "bad.png").write_bytes(b"not a png at all")
    with pytest.raises(ValueError, match="cannot read image"):
        imagedata.load_rgb8(tmp_path / "bad.png")


def test_a4_cubemap_takes_six_bitmaps_or_a_folder(variant: str, tmp_path: Path) -> None:
    import mitsuba as mi

    rng = np.random.default_rng(5)
    faces = {f: rng.integers(0, 256, (4, 4, 3), dtype=np.uint8) for f in CUBE_FACES}
    for f, px in faces.items():
        _png(tmp_path / f"{f}.png", px)
    bitmaps = {f: mi.Bitmap(px) for f, px in faces.items()}
    from_bitmaps = mi.load_dict({"type": "a5_cubemap", **bitmaps})
    from_folder = mi.load_dict({"type": "a5_cubemap", "filename": str(tmp_path)})
    np.testing.assert_array_equal(np.asarray(from_bitmaps.atlas.data), np.asarray(from_folder.atlas.data))
    with pytest.raises(Exception, match="not both"):
        mi.load_dict({"type": "a5_cubemap", "filename": str(tmp_path), **bitmaps})
    with pytest.raises(Exception, match=r"faces \['back'\] are missing"):
        mi.load_dict({"type": "a5_cubemap", **{f: b for f, b in bitmaps.items() if f != "back"}})
    with pytest.raises(Exception, match="exactly one of the parameters"):
        mi.load_dict({"type": "a5_bitmap"})


def test_a4_packed_atlas_returns_the_bytes_over_255_at_texel_corners(variant: str) -> None:
    """tex(u, v) at u = i/W, v = 1 - j/H is pixel (i, j) exactly (a = b = 0): every byte value 0..255 and
    both images of the atlas (the packed UInt32 texels unpack to the file's bytes)."""
    import mitsuba as mi

    from a5mi.plugins.textures.imagedata import ImageAtlas

    rng = np.random.default_rng(7)  # sizes are powers of 2: u, v and u·W, (1 - v)·H exact
    imgs = [rng.integers(0, 256, (16, 16, 3), dtype=np.uint8), rng.integers(0, 256, (8, 4, 3), dtype=np.uint8)]
    imgs[0].reshape(-1)[:256] = np.arange(256, dtype=np.uint8)
    atlas = ImageAtlas(imgs)
    for k, img in enumerate(imgs):
        h, w = img.shape[:2]
        jj, ii = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
        u = mi.Float((ii.ravel() / w).astype(np.float32))
        v = mi.Float((1.0 - jj.ravel() / h).astype(np.float32))
        got = np.asarray(atlas.sample(u, v, k)).T.reshape(h, w, 3)  # Color3f -> (3, N)
        # the bytes, divided by 255 as the lookup divides (Dr.Jit's float32 division)
        want = np.asarray(mi.Float(img.astype(np.float32).ravel()) / 255.0).reshape(h, w, 3)
        np.testing.assert_array_equal(got, want)
