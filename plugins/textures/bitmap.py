"""The ``a5_bitmap`` texture: a material's ``texture`` file sampled as the sample solution does (SPEC A.4)."""

from __future__ import annotations

import mitsuba as mi

from a5mi.plugins.textures.atlas_texture import AtlasTexture
from a5mi.plugins.textures.imagedata import ImageAtlas, bitmap_rgb8, load_rgb8, resolve


class A5Bitmap(AtlasTexture):
    """Image texture with the 6.837 lookup (SPEC A.4; ``texture NAME`` of A.5).

    .. list-table::
       :header-rows: 1

       * - Parameter
         - Type
         - Description
       * - ``filename``
         - string
         - An 8-bit image (the course ships 24-bit BMP; PNG and anything OpenImageIO reads work too),
           decoded with ``a5mi.platform.imageio.read_uint8``.
       * - ``bitmap``
         - ``mi.Bitmap``
         - Instead of ``filename``: the already decoded 8-bit pixels (row 0 = top), as stock ``bitmap``
           takes them. Exactly one of the two is required.

    Lookup at ``si.uv`` = (u, v), with W×H the image size and P the file's bytes, row 0 = top row::

        x = u·W, y = (1 − v)·H, ix = (int)x, iy = (int)y, a = x − ix, b = y − iy
        kd = [(1−a)(1−b)·P[ix,iy] + a(1−b)·P[ix+1,iy] + (1−a)b·P[ix,iy+1] + ab·P[ix+1,iy+1]] / 255

    Indices are clamped to the image edge. Unlike Mitsuba's stock ``bitmap`` there is no sRGB decoding,
    no wrapping and no half-texel offset (with one, renders fall to 37-44 dB against the references).

    A missing or unreadable file raises ``ValueError`` naming ``filename`` and the path.

    .. code-block:: python

        'kd': {'type': 'a5_bitmap', 'filename': 'tex/head.bmp'}
        'kd': {'type': 'a5_bitmap', 'bitmap': mi.Bitmap(pixels)}   # pixels: (H, W, 3) uint8
    """

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)
        has_file, has_bitmap = "filename" in props, "bitmap" in props
        if has_file == has_bitmap:
            raise ValueError("a5_bitmap: exactly one of the parameters 'filename' and 'bitmap' is required")
        self.filename: str | None
        if has_bitmap:
            self.filename = None
            pixels = bitmap_rgb8(props["bitmap"], "a5_bitmap: parameter 'bitmap'")
        else:
            self.filename = str(props["filename"])
            try:
                pixels = load_rgb8(resolve(self.filename))
            except ValueError as exc:
                raise ValueError(f"a5_bitmap: parameter 'filename' ({self.filename!r}): {exc}") from None
        self.height, self.width = pixels.shape[:2]
        self.atlas = ImageAtlas([pixels])
        self._mean = float(pixels.mean() / 255.0)

    def eval(self, si: mi.SurfaceInteraction3f, active: mi.Bool = True) -> mi.Color3f:
        """Output tex(si.uv) per SPEC A.4 (formula in the class docstring)."""
        return self.atlas.sample(si.uv.x, si.uv.y, 0, active)

    def resolution(self) -> mi.ScalarVector2i:
        return mi.ScalarVector2i(self.width, self.height)

    def to_string(self) -> str:
        return f"A5Bitmap[filename={self.filename!r}, size={self.width}x{self.height}]"


def register() -> None:
    """Register ``a5_bitmap`` with Mitsuba (call after selecting a JIT variant)."""
    mi.register_texture("a5_bitmap", lambda props: A5Bitmap(props))
