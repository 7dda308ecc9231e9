"""8-bit image loading and the course's texture lookup ``tex(u, v)`` (SPEC A.4), shared by a5_bitmap and
a5_cubemap.

The lookup is the sample solution's, for material textures and cube-map faces alike::

    x = u·W,  y = (1 − v)·H          (row 0 = the top row of the image)
    ix = (int)x, iy = (int)y,  a = x − ix,  b = y − iy
    c = (1−a)(1−b)·P[ix, iy] + a(1−b)·P[ix+1, iy] + (1−a)b·P[ix, iy+1] + ab·P[ix+1, iy+1]
    result = c / 255

with every pixel index clamped to the image, no wrapping, no half-texel offset and no gamma: the bytes of
the file are used as they are. ``(int)`` truncates toward zero, as the C cast does.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import drjit as dr
import mitsuba as mi
import numpy as np


def load_rgb8(path: str | Path) -> np.ndarray:
    """Read an image file as an (H, W, 3) ``uint8`` array, row 0 = the top row of the picture.

    Parameter ``path``: any format OpenImageIO reads (the course uses 24-bit BMP and PNG). Grey images are
    replicated to three channels, a fourth (alpha) channel is dropped, and a file stored with more than
    8 bits per channel is converted to 8 bits by OpenImageIO.

    Raises ``ValueError`` naming the path when the file is missing, unreadable or not an image.
    """
    import OpenImageIO as oiio  # heavy import, only when a texture is loaded

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"image file not found: {path}")
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise ValueError(f"cannot read image {path}: {oiio.geterror() or 'unknown format'}")
    try:
        spec = inp.spec()
        pixels = inp.read_image(0, 0, 0, spec.nchannels, "uint8")
        reason = inp.geterror() if pixels is None else ""  # e.g. a truncated file
    finally:
        inp.close()
    if pixels is None or spec.width <= 0 or spec.height <= 0:
        raise ValueError(f"cannot read image {path}: {reason or oiio.geterror() or 'no pixel data'}")
    pixels = np.asarray(pixels, dtype=np.uint8).reshape(spec.height, spec.width, spec.nchannels)
    if spec.nchannels in (1, 2):
        pixels = np.repeat(pixels[:, :, :1], 3, axis=2)
    return np.ascontiguousarray(pixels[:, :, :3])


class ImageAtlas:
    """One or more 8-bit RGB images in a single device buffer, sampled with the A.4 ``tex(u, v)``.

    Parameter ``images``: (H, W, 3) ``uint8`` arrays, row 0 = top (as :func:`load_rgb8` returns them).

    Pixel bytes are stored as float32 0..255; offsets, widths and heights are opaque arrays, so the
    compiled lookup is the same for every texture and every scene.
    """

    def __init__(self, images: Sequence[np.ndarray]) -> None:
        if not images:
            raise ValueError("ImageAtlas needs at least one image")
        offsets, widths, heights, chunks = [], [], [], []
        offset = 0
        for img in images:
            img = np.asarray(img)
            if img.ndim != 3 or img.shape[2] != 3 or img.shape[0] < 1 or img.shape[1] < 1:
                raise ValueError(f"expected an (H, W, 3) image, got shape {img.shape}")
            h, w = img.shape[:2]
            offsets.append(offset)
            widths.append(w)
            heights.append(h)
            chunks.append(img.astype(np.float32).ravel())
            offset += w * h
        self.sizes: list[tuple[int, int]] = list(zip(widths, heights, strict=True))
        self.data = mi.Float(np.concatenate(chunks))  # 3 floats per pixel, 0..255
        self.offsets = mi.UInt32(offsets)  # first pixel of each image
        self.widths = mi.Int32(widths)
        self.heights = mi.Int32(heights)
        dr.make_opaque(self.data, self.offsets, self.widths, self.heights)

    def sample(self, u: mi.Float, v: mi.Float, image: mi.UInt32 | int = 0, active: mi.Bool | bool = True) -> mi.Color3f:
        """Output tex(u, v) of image number ``image`` (a per-lane index), as in the module docstring."""
        idx = mi.UInt32(image)
        off = dr.gather(mi.UInt32, self.offsets, idx, active)
        w = dr.gather(mi.Int32, self.widths, idx, active)
        h = dr.gather(mi.Int32, self.heights, idx, active)
        x = u * mi.Float(w)
        y = (1.0 - v) * mi.Float(h)
        ix = mi.Int32(x)  # truncation toward zero, like (int)x
        iy = mi.Int32(y)
        a = x - mi.Float(ix)
        b = y - mi.Float(iy)
        x0 = mi.UInt32(dr.clip(ix, 0, w - 1))
        x1 = mi.UInt32(dr.clip(ix + 1, 0, w - 1))
        y0 = mi.UInt32(dr.clip(iy, 0, h - 1))
        y1 = mi.UInt32(dr.clip(iy + 1, 0, h - 1))
        wu = mi.UInt32(w)

        def px(xi: mi.UInt32, yi: mi.UInt32) -> mi.Color3f:
            return dr.gather(mi.Color3f, self.data, off + yi * wu + xi, active)

        c = (1.0 - a) * (1.0 - b) * px(x0, y0)
        c += a * (1.0 - b) * px(x1, y0)
        c += (1.0 - a) * b * px(x0, y1)
        c += a * b * px(x1, y1)
        return dr.select(active, c / 255.0, 0.0)
