"""The page's PNG encodings: the bytes of the file ``a5 -output X.png`` writes, made without writing that file.

:func:`a5mi.platform.imageio.write_image` is the writer of the files a user keeps: it checks the target, writes a
temporary
beside it, fsyncs it, decodes it again and compares the pixels, then renames it over the target. The page needs
only the bytes, so :func:`png_bytes` runs the same encoder on the same pixels with the same settings (OpenImageIO's
PNG writer, 8-bit levels ``clamp(int(255 c), 0, 255)`` of SPEC B.1 by :func:`a5mi.platform.imageio.quantize` for a float
image, a ``uint8`` image as it is, zlib level :data:`a5mi.platform.imageio.PNG_COMPRESSION`) into one scratch file of
the
view's own folder, reads it back as bytes and removes it: no fsync, no decode, no rename. That the bytes equal
``a5``'s file is tested (tests/view/test_view_engine.py).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from a5mi.platform.errors import ImageWriteError

#: The scratch file's name in the view's folder (one encoding at a time: the engine's thread makes them all).
SCRATCH_NAME = "frame.png"


def png_bytes(img: np.ndarray, folder: str | os.PathLike[str]) -> bytes:
    """The bytes of ``img`` (H x W, or H x W x 1, 3 or 4; float, or ``uint8`` levels) as the PNG file
    :func:`a5mi.platform.imageio.write_image` writes (module docstring); ``folder``: where the scratch file goes.
    Raises :class:`~a5mi.platform.errors.ImageWriteError` when the encoder fails."""
    import OpenImageIO as oiio

    from a5mi.platform.imageio import PNG_COMPRESSION, native_stderr, quantize

    a = np.asarray(img)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[2] not in (1, 3, 4) or a.shape[0] == 0 or a.shape[1] == 0:
        raise ValueError(f"expected an HxW, HxWx1, HxWx3 or HxWx4 image, got shape {a.shape}")
    pixels = np.ascontiguousarray(a if a.dtype == np.uint8 else quantize(a))
    h, w, c = pixels.shape
    path = Path(folder) / SCRATCH_NAME
    out = oiio.ImageOutput.create(str(path))
    if out is None:
        raise ImageWriteError(f"cannot create a PNG writer: {oiio.geterror()}")
    spec = oiio.ImageSpec(w, h, c, oiio.UINT8)
    spec.attribute("png:compressionLevel", PNG_COMPRESSION)
    with native_stderr() as printed:
        ok = out.open(str(path), spec) and out.write_image(pixels)
        err = out.geterror() if not ok else ""
        ok = out.close() and ok
    if not ok:
        raise ImageWriteError(f"the page's PNG: {err or out.geterror() or (printed or ['unknown error'])[0]}")
    data = path.read_bytes()
    path.unlink()  # (a file truncated and written again would be flushed early by ext4's auto_da_alloc)
    return data


__all__ = ["SCRATCH_NAME", "png_bytes"]
