"""The kept image atlases (plugins/textures/imagedata.py): a texture or cube map built again from the same bytes
uses the device buffer made before, anything else gets its own; lookups are the same either way (SPEC A.4)."""

from __future__ import annotations

import numpy as np


def _images(seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, (h, w, 3), dtype=np.uint8) for h, w in ((8, 16), (4, 4), (16, 8))]


def _bytes(atlas) -> np.ndarray:
    """The atlas's texels as (pixels, 3) bytes R, G, B (the packed word's low three bytes)."""
    return np.asarray(atlas.data).astype("<u4").view(np.uint8).reshape(-1, 4)[:, :3]


def test_same_bytes_share_the_device_buffer_other_bytes_do_not(variant: str) -> None:
    from a5mi.plugins.textures import imagedata

    imgs = _images(3)
    first = imagedata.ImageAtlas([img.copy() for img in imgs])
    again = imagedata.ImageAtlas([img.copy() for img in imgs])   # equal bytes, other arrays (a rebuilt scene)
    assert again.data.index == first.data.index and again.data is not first.data
    assert again.sizes == first.sizes == [(16, 8), (4, 4), (8, 16)]
    changed = [img.copy() for img in imgs]
    changed[2][15, 7, 2] ^= 1                                    # one bit of the last image's last texel
    other = imagedata.ImageAtlas(changed)
    assert other.data.index != first.data.index
    np.testing.assert_array_equal(_bytes(other), np.concatenate([img.reshape(-1, 3) for img in changed]))
    np.testing.assert_array_equal(_bytes(again), np.concatenate([img.reshape(-1, 3) for img in imgs]))
    reordered = imagedata.ImageAtlas([imgs[1], imgs[0], imgs[2]])   # same images, other order: other atlas
    assert reordered.data.index != first.data.index and reordered.sizes[0] == (4, 4)


def test_kept_atlas_lookups_equal_a_fresh_one(variant: str) -> None:
    """A lookup through a kept atlas returns what a newly packed one returns, bit for bit."""
    import mitsuba as mi

    from a5mi.plugins.textures import imagedata

    imgs = _images(5)
    imagedata._KEPT.clear()
    fresh = imagedata.ImageAtlas(imgs)
    kept = imagedata.ImageAtlas([img.copy() for img in imgs])
    assert kept.data.index == fresh.data.index
    imagedata._KEPT.clear()
    packed_again = imagedata.ImageAtlas(imgs)
    assert packed_again.data.index != fresh.data.index
    u = mi.Float(np.linspace(0.0, 1.0, 37, dtype=np.float32))
    v = mi.Float(np.linspace(1.0, 0.0, 37, dtype=np.float32))
    for k in range(3):
        np.testing.assert_array_equal(np.asarray(kept.sample(u, v, k)), np.asarray(packed_again.sample(u, v, k)))


def test_the_kept_atlases_are_bounded(variant: str, monkeypatch) -> None:
    from a5mi.plugins.textures import imagedata

    monkeypatch.setattr(imagedata, "KEEP_ATLASES", 2)
    imagedata._KEPT.clear()
    for seed in range(4):
        imagedata.ImageAtlas(_images(seed))
    assert len(imagedata._KEPT) == 2
    monkeypatch.setattr(imagedata, "KEEP_TEXELS", 100)   # under one atlas's 320 texels: only the newest stays
    imagedata.ImageAtlas(_images(9))
    assert len(imagedata._KEPT) == 1


def test_an_rgb_bitmap_is_read_in_place(variant: str) -> None:
    """``bitmap_rgb8`` of an RGB ``mi.Bitmap`` is a view of its pixels (no copy per build); a grey one is
    widened to three channels."""
    import mitsuba as mi

    from a5mi.plugins.textures.imagedata import bitmap_rgb8

    img = _images(2)[0]
    bm = mi.Bitmap(img)
    got = bitmap_rgb8(bm)
    assert np.shares_memory(got, np.asarray(bm)) and np.array_equal(got, img)
    grey = bitmap_rgb8(mi.Bitmap(img[:, :, :1].copy()))
    assert grey.shape == img.shape and np.array_equal(grey[:, :, 2], img[:, :, 0])
