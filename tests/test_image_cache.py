"""SPEC A.4 images are decoded once per process: the converter's file check keeps the pixels
(``to_mitsuba.decoded_image``), ``a5mi.variant.activate`` hands that cache to the plugins
(``imagedata.set_pixel_source``), and the packed ``ImageAtlas`` returns exactly the file's bytes / 255."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from a5mi import imageio
from a5mi.converters.errors import FileLoc
from a5mi.converters.to_mitsuba import check_image, decoded_image


def _png(path: Path, pixels: np.ndarray) -> Path:
    """Write 8-bit ``pixels`` (H, W, C) exactly (value / 255 quantises back to the same byte)."""
    imageio.write_image(path, (pixels.astype(np.float32) + 0.5) / 255.0)
    return path


def test_a4_check_image_keeps_the_decoded_pixels_until_the_file_changes(tmp_path: Path) -> None:
    px = np.arange(2 * 3 * 3, dtype=np.uint8).reshape(2, 3, 3) * 7
    p = _png(tmp_path / "t.png", px)
    assert decoded_image(p) is None  # never checked
    check_image(p, FileLoc("s.txt", 1, 1), "texture")
    cached = decoded_image(p)
    assert cached is not None and cached.dtype == np.uint8 and not cached.flags.writeable
    np.testing.assert_array_equal(cached, px)
    _png(p, px[::-1])  # new content: new mtime -> the cache no longer answers for it
    os.utime(p, ns=(1, 1))
    assert decoded_image(p) is None


def test_a4_load_rgb8_takes_the_pixel_source_and_reads_the_file_otherwise(variant: str, tmp_path: Path,
                                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    from a5mi.plugins import imagedata

    grey = np.array([[[10], [20]], [[30], [40]]], dtype=np.uint8)  # 1 channel: replicated to RGB
    p = _png(tmp_path / "g.png", grey)
    monkeypatch.setattr(imagedata, "_PIXEL_SOURCE", None)
    from_file = imagedata.load_rgb8(p)
    np.testing.assert_array_equal(from_file, np.repeat(grey, 3, axis=2))

    def no_decoding(path: Path) -> np.ndarray:
        raise AssertionError(f"{path} decoded again")

    monkeypatch.setattr(imagedata, "_read_uint8", no_decoding)
    imagedata.set_pixel_source(lambda path: grey if Path(path) == p else None)
    np.testing.assert_array_equal(imagedata.load_rgb8(p), from_file)


def test_a4_activate_wires_the_converter_cache(variant: str) -> None:
    from a5mi.plugins import imagedata
    from a5mi.variant import activate

    activate()
    assert imagedata._PIXEL_SOURCE is decoded_image


def test_a4_packed_atlas_returns_the_bytes_over_255_at_texel_corners(variant: str) -> None:
    """tex(u, v) at u = i/W, v = 1 - j/H is pixel (i, j) exactly (a = b = 0): every byte value 0..255 and
    both images of the atlas (the packed UInt32 texels unpack to the file's bytes)."""
    import mitsuba as mi

    from a5mi.plugins.imagedata import ImageAtlas

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
