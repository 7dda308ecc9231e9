"""8-bit image loading and the course's texture lookup ``tex(u, v)`` (SPEC A.4), shared by a5_bitmap and
a5_cubemap.

The lookup is the sample solution's, for material textures and cube-map faces alike::

    x = u·W,  y = (1 − v)·H          (row 0 = the top row of the image)
    ix = (int)x, iy = (int)y,  a = x − ix,  b = y − iy
    c = (1−a)(1−b)·P[ix, iy] + a(1−b)·P[ix+1, iy] + (1−a)b·P[ix, iy+1] + ab·P[ix+1, iy+1]
    result = c / 255

with every pixel index clamped to the image, no wrapping, no half-texel offset and no gamma: the bytes of
the file are used as they are. ``(int)`` truncates toward zero, as the C cast does.

Decoding: :func:`load_rgb8` reads a file with the project's one OpenImageIO reader
(:func:`a5mi.platform.imageio.read_uint8`; the XML path, where plugins get file names); on the ``mi.load_dict`` path
the converter hands over the pixels it decoded once, as ``mi.Bitmap`` parameters, and :func:`bitmap_rgb8`
takes them without reading the file again.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NamedTuple

import drjit as dr
import mitsuba as mi
import numpy as np

from a5mi.platform import imageio
from a5mi.platform.errors import ImageReadError


def rgb8(pixels: np.ndarray, what: str = "image") -> np.ndarray:
    """(H, W, C) ``uint8`` pixels as OpenImageIO reads them -> (H, W, 3) ``uint8``: grey images (1 or 2
    channels) are replicated to three channels, a fourth (alpha) channel is dropped. Raises ``ValueError``
    for any other shape or type."""
    if pixels.ndim != 3 or pixels.dtype != np.uint8 or pixels.shape[2] < 1 or 0 in pixels.shape[:2]:
        raise ValueError(f"cannot use {what}: expected (H, W, C) uint8 pixels, got {pixels.dtype} {pixels.shape}")
    if pixels.shape[2] in (1, 2):
        pixels = np.repeat(pixels[:, :, :1], 3, axis=2)
    return np.ascontiguousarray(pixels[:, :, :3])


def resolve(filename: str) -> Path:
    """The file or folder a plugin's ``filename`` names: as Mitsuba's own plugins do, through the file resolver
    (``mi.file_resolver()``: during ``mi.load_file`` the XML's folder comes first, so a converted scene's
    relative names work wherever its folder lies); a name the resolver does not find stays as given."""
    path = Path(filename)
    if path.is_absolute():
        return path
    found = Path(str(mi.file_resolver().resolve(str(path))))
    return found if found.exists() else path


def load_rgb8(path: str | Path) -> np.ndarray:
    """Read an image file as an (H, W, 3) ``uint8`` array, row 0 = the top row of the picture (:func:`rgb8`).

    Parameter ``path``: any format OpenImageIO reads (the course uses 24-bit BMP and PNG); a file stored with
    more than 8 bits per channel is converted to 8 bits by OpenImageIO.

    Raises ``ValueError`` naming the path when the file is missing, unreadable or not an image.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"image file not found: {path}")
    try:
        pixels = imageio.read_uint8(path)
    except ImageReadError as exc:
        raise ValueError(f"cannot read image {path}: {exc.reason}") from None
    return rgb8(pixels, f"image {path}")


def bitmap_rgb8(bitmap: Any, what: str = "bitmap") -> np.ndarray:
    """An 8-bit ``mi.Bitmap`` (the converter's decoded pixels) as (H, W, 3) ``uint8`` (:func:`rgb8`); raises
    ``ValueError`` for anything else (another object, float pixels). An RGB bitmap's pixels are not copied: the
    array is a view of the bitmap's memory (and keeps the bitmap alive), which :class:`ImageAtlas` reads and
    copies into its own buffer."""
    if not isinstance(bitmap, mi.Bitmap):
        raise ValueError(f"{what}: expected an mi.Bitmap, got {type(bitmap).__name__}")
    pixels = np.asarray(bitmap)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    return rgb8(pixels, what)


class ImageAtlas:
    """One or more 8-bit RGB images in a single device buffer, sampled with the A.4 ``tex(u, v)``.

    Parameter ``images``: (H, W, 3) ``uint8`` arrays, row 0 = top (as :func:`load_rgb8` returns them).

    Each pixel is one ``UInt32`` ``R + 256 G + 65536 B`` (its bytes R, G, B, 0: a copy of the file's bytes,
    4 bytes per pixel instead of 12 for float RGB, and one gather per texel); the lookup unpacks the bytes
    to floats 0..255, exactly the values the bytes hold. Offsets, widths and heights are opaque arrays, so
    the compiled lookup is the same for every texture and every scene. An atlas of the same bytes as one made
    before shares its device arrays (:data:`_KEPT`).
    """

    def __init__(self, images: Sequence[np.ndarray]) -> None:
        if not images:
            raise ValueError("ImageAtlas needs at least one image")
        arrays = [np.asarray(img) for img in images]
        for img in arrays:
            if img.ndim != 3 or img.shape[2] != 3 or img.shape[0] < 1 or img.shape[1] < 1:
                raise ValueError(f"expected an (H, W, 3) image, got shape {img.shape}")
        self.sizes: list[tuple[int, int]] = [(img.shape[1], img.shape[0]) for img in arrays]
        packed = _packed(arrays)
        # fresh array objects on the shared variables: an assignment to one atlas's array (a parameter update)
        # replaces that object's variable only, and Dr.Jit copies a shared variable before any scatter into it
        self.data = mi.UInt32(packed.data)  # R + 256 G + 65536 B
        self.offsets = mi.UInt32(packed.offsets)  # first pixel of each image
        self.widths = mi.Int32(packed.widths)
        self.heights = mi.Int32(packed.heights)
        dr.make_opaque(self.data, self.offsets, self.widths, self.heights)

    def sample(self, u: mi.Float, v: mi.Float, image: mi.UInt32 | int = 0, active: mi.Bool | bool = True) -> mi.Color3f:
        """Output tex(u, v) of image number ``image`` (a per-lane index), as in the module docstring: the
        bilinear blend (1−a)(1−b)·P00 + a(1−b)·P10 + (1−a)b·P01 + ab·P11 of the :meth:`texels`, over 255."""
        (p00, p10, p01, p11), a, b, _, _ = self.texels(u, v, image, active)
        c = (1.0 - a) * (1.0 - b) * p00
        c += a * (1.0 - b) * p10
        c += (1.0 - a) * b * p01
        c += a * b * p11
        return dr.select(active, c / 255.0, 0.0)

    def texels(self, u: mi.Float, v: mi.Float, image: mi.UInt32 | int = 0, active: mi.Bool | bool = True
               ) -> tuple[tuple[mi.Color3f, mi.Color3f, mi.Color3f, mi.Color3f], mi.Float, mi.Float, mi.Int32,
                          mi.Int32]:
        """The four texels of the :meth:`sample` lookup at (u, v) as bytes 0..255, ``(P00, P10, P01, P11)``
        (``P10`` = ``P[ix+1, iy]``, ...), the weights ``a``, ``b`` and the image size ``(W, H)``: the pieces
        of the module docstring's formula, for lookups that need more than the blend (docs/EXTENSIONS.md E.7:
        the height gradient, normal maps decoded per texel)."""
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
            p = dr.gather(mi.UInt32, self.data, off + yi * wu + xi, active)
            return mi.Color3f(mi.Float(p & 0xFF), mi.Float((p >> 8) & 0xFF), mi.Float(p >> 16))

        return (px(x0, y0), px(x1, y0), px(x0, y1), px(x1, y1)), a, b, w, h


class _Packed(NamedTuple):
    """The device arrays of an :class:`ImageAtlas` and the host words they were made from (``host``: every image's
    pixels as bytes R, G, B, 0, one image after the other; pixel ``k`` of the atlas = ``host[k, :3]``)."""

    variant: str                         # the Mitsuba variant of the device arrays
    sizes: tuple[tuple[int, int], ...]   # (W, H) of each image
    host: np.ndarray                     # (pixels, 4) uint8
    data: mi.UInt32
    offsets: mi.UInt32
    widths: mi.Int32
    heights: mi.Int32

    def holds(self, images: Sequence[np.ndarray]) -> bool:
        """Whether the atlas was made from exactly these images (sizes, then every byte) in the active variant."""
        if self.variant != mi.variant() or self.sizes != tuple((img.shape[1], img.shape[0]) for img in images):
            return False
        start = 0
        for img in images:
            n = img.shape[0] * img.shape[1]
            if not np.array_equal(self.host[start:start + n, :3], img.reshape(-1, 3)):
                return False
            start += n
        return True


#: The atlases made last, most recent first: a scene built again (``a5mi view``'s saves, ``a5mi serve``'s
#: requests) finds the cube map or texture it uploaded before, compared byte for byte, instead of packing and
#: uploading it again (0.1-0.3 s for the six 1024 x 1024 faces of a cube map). At most :data:`KEEP_ATLASES`
#: atlases and :data:`KEEP_TEXELS` texels are kept (4 bytes each on the host, the words compared, and the device's).
_KEPT: list[_Packed] = []
_KEPT_LOCK = threading.Lock()
KEEP_ATLASES = 8
KEEP_TEXELS = 1 << 24


def _packed(images: Sequence[np.ndarray]) -> _Packed:
    """The packed atlas of ``images`` ((H, W, 3) uint8 each): a kept one made from the same bytes, else a new one
    (kept, the oldest dropped past the limits)."""
    with _KEPT_LOCK:   # scenes may be built in several threads (a Dask worker's tasks)
        for k, kept in enumerate(_KEPT):
            if kept.holds(images):
                _KEPT.insert(0, _KEPT.pop(k))
                return kept
    sizes = tuple((img.shape[1], img.shape[0]) for img in images)
    counts = [w * h for w, h in sizes]
    offsets = [sum(counts[:k]) for k in range(len(counts))]
    total = sum(counts)
    # Bytes R, G, B, 0 per pixel in a 64-byte-aligned buffer: Dr.Jit maps numpy memory without a copy
    # and the pointer's alignment is part of the kernel's hash (a5mi/render/driver.py, aligned_float32).
    raw = np.zeros(4 * total + 64, dtype=np.uint8)
    start0 = (-raw.ctypes.data) % 64
    host = raw[start0 : start0 + 4 * total].reshape(total, 4)
    for start, img in zip(offsets, images, strict=True):
        host[start : start + img.shape[0] * img.shape[1], :3] = img.reshape(-1, 3)
    words = host.view("<u4").reshape(-1)
    data = mi.UInt32(words if words.dtype == np.uint32 else words.astype(np.uint32))
    out = _Packed(str(mi.variant()), sizes, host, data, mi.UInt32(offsets), mi.Int32([w for w, _ in sizes]),
                  mi.Int32([h for _, h in sizes]))
    dr.make_opaque(out.data, out.offsets, out.widths, out.heights)
    with _KEPT_LOCK:
        _KEPT.insert(0, out)
        while len(_KEPT) > KEEP_ATLASES or (len(_KEPT) > 1 and sum(len(p.host) for p in _KEPT) > KEEP_TEXELS):
            _KEPT.pop()
    return out
