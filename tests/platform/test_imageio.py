"""Quantisation, formats, orientation and atomic writes (SPEC B.1)."""

from __future__ import annotations

import os

import numpy as np
import pytest

from a5mi.platform import imageio
from a5mi.platform.errors import ImageReadError, ImageWriteError

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process


def test_b1_quantize_truncates() -> None:
    q = imageio.quantize([0.5, 1.2, -0.1, 1.0, 0.0, 254.9 / 255, float("nan"), float("inf")])
    assert q.tolist() == [127, 255, 0, 255, 0, 254, 0, 0]   # inf: beyond int32, 0 (tests/platform/)


@pytest.mark.parametrize("ext", imageio.EXTENSIONS)
def test_b1_formats_round_trip(tmp_path, ext) -> None:
    img = np.random.default_rng(3).random((5, 7, 3)).astype(np.float32) * 1.2 - 0.1
    path = tmp_path / f"img{ext}"
    imageio.write_image(path, img)
    back = imageio.read_image(path)
    assert back.shape == (5, 7, 3)
    if ext == ".exr":
        np.testing.assert_array_equal(back, img)
    else:
        np.testing.assert_array_equal(np.round(back * 255).astype(np.uint8), imageio.quantize(img))
    assert not [p for p in os.listdir(tmp_path) if p != path.name]  # no temporary left behind


def test_b1_row0_is_top_of_file(tmp_path) -> None:
    img = np.zeros((2, 1, 3), np.float32)
    img[0] = 1.0  # top row white
    imageio.write_image(tmp_path / "t.png", img)
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(str(tmp_path / "t.png"))
    assert buf.getpixel(0, 0)[0] == 1.0 and buf.getpixel(0, 1)[0] == 0.0


def test_b1_new_file_mode_follows_umask(tmp_path) -> None:
    imageio.write_image(tmp_path / "m.png", np.zeros((1, 1, 3)))
    umask = os.umask(0)
    os.umask(umask)
    assert (tmp_path / "m.png").stat().st_mode & 0o777 == 0o666 & ~umask


def test_b1_rejected_image_keeps_old_file(tmp_path) -> None:
    path = tmp_path / "keep.png"
    path.write_bytes(b"old contents")
    with pytest.raises(ValueError):
        imageio.write_image(path, np.zeros((2, 2, 7)))  # bad channel count, raised before any write
    assert path.read_bytes() == b"old contents"
    assert sorted(os.listdir(tmp_path)) == ["keep.png"]


def test_b1_oiio_failure_keeps_old_file(tmp_path, monkeypatch) -> None:
    """OpenImageIO reporting an error mid-write becomes ImageWriteError; nothing is replaced."""
    import OpenImageIO as oiio

    path = tmp_path / "keep.tga"
    path.write_bytes(b"old")

    class FailingOutput:
        def open(self, *a):
            return True

        def write_image(self, *a):
            return False

        def geterror(self):
            return "simulated failure"

        def close(self):
            return True

    monkeypatch.setattr(oiio.ImageOutput, "create", staticmethod(lambda name: FailingOutput()))
    with pytest.raises(ImageWriteError, match="simulated failure"):
        imageio.write_image(path, np.ones((2, 2, 3)))
    assert path.read_bytes() == b"old"
    assert sorted(os.listdir(tmp_path)) == ["keep.tga"]


@pytest.mark.parametrize(
    "name,match",
    [("out.jpg2", "unknown image extension '.jpg2'"), ("out", "out: no image extension"),
     ("missing/out.png", "does not exist")],
)
def test_b1_check_output_path(tmp_path, name, match) -> None:
    with pytest.raises(ImageWriteError, match=match):
        imageio.check_output_path(tmp_path / name)


def test_b1_unwritable_folder(tmp_path) -> None:
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        if os.access(ro, os.W_OK):
            pytest.skip("running as a user that ignores permissions")
        with pytest.raises(ImageWriteError, match="not writable"):
            imageio.check_output_path(ro / "x.png")
    finally:
        ro.chmod(0o755)


def test_read_image_errors(tmp_path) -> None:
    with pytest.raises(ImageReadError, match="no such image"):
        imageio.read_image(tmp_path / "nope.png")
    (tmp_path / "bad.png").write_bytes(b"\x89PNG\r\n\x1a\nnot really")
    with pytest.raises(ImageReadError):
        imageio.read_image(tmp_path / "bad.png")


@pytest.mark.parametrize("channels", [2, 4])
def test_a4_alpha_channel_never_scales_the_stored_colour(tmp_path, channels: int) -> None:
    """SPEC A.4 uses the file's bytes as they are: a PNG with alpha 128 (stored unassociated, as image editors
    write it) reads back with its colour bytes, not multiplied by alpha (OpenImageIO's default would darken
    them by 0.5)."""
    import OpenImageIO as oiio

    rng = np.random.default_rng(4)
    pixels = rng.integers(0, 256, (5, 7, channels), dtype=np.uint8)
    pixels[..., -1] = 128
    path = tmp_path / "a.png"
    spec = oiio.ImageSpec(7, 5, channels, oiio.UINT8)
    spec.attribute("oiio:UnassociatedAlpha", 1)
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec)
    out.write_image(pixels)
    out.close()
    assert np.array_equal(imageio.read_uint8(path), pixels)
