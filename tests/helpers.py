"""Helpers shared by the test folders (importable from any of them: tests/ is on ``sys.path`` through its
conftest): the project's folders, and a5 scene text rendered in-process."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

#: tests/
TESTS = Path(__file__).resolve().parent
#: the project root
ROOT = TESTS.parent
#: the project's own scenes (scenes/)
SCENES = ROOT / "scenes"


def write_image(path: Path, pixels: np.ndarray) -> Path:
    """Write an (H, W, C) uint8 array with OpenImageIO (row 0 = top)."""
    import OpenImageIO as oiio

    h, w, c = pixels.shape
    out = oiio.ImageOutput.create(str(path))
    assert out is not None, oiio.geterror()
    assert out.open(str(path), oiio.ImageSpec(w, h, c, "uint8"))
    assert out.write_image(np.ascontiguousarray(pixels))
    out.close()
    return path


def read_bmp24(path: Path) -> np.ndarray:
    """Independent 24-bit BMP reader: bottom-up rows padded to 4 bytes, BGR -> (H, W, 3) RGB, top row first."""
    raw = path.read_bytes()
    assert raw[:2] == b"BM"
    (offset,) = struct.unpack_from("<I", raw, 10)
    width, height, _, bpp = struct.unpack_from("<iiHH", raw, 18)
    assert bpp == 24
    stride = (width * 3 + 3) & ~3
    rows = [np.frombuffer(raw, np.uint8, width * 3, offset + r * stride).reshape(width, 3) for r in range(abs(height))]
    img = np.stack(rows)[:, :, ::-1]
    return img[::-1] if height > 0 else img
