"""The Mitsuba side of the image textures (SPEC A.4 lookups, docs/EXTENSIONS.md E.19): a base class. Importable
only once a JIT variant is set (it subclasses ``mi.Texture``); :mod:`.imagedata` itself needs no variant."""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

from a5mi.plugins.textures.imagedata import ImageAtlas


class AtlasTexture(mi.Texture):
    """The Mitsuba side shared by the image textures (``a5_bitmap``, ``a5_btf``): their pixels are one
    :class:`ImageAtlas` in ``self.atlas``, exposed as the non-differentiable parameter ``data`` and kept opaque
    (a changed image is a new buffer, never a new kernel). A subclass defines ``eval`` (the RGB lookup) and sets
    ``self._mean`` (the mean of all its bytes / 255); ``eval_3`` is ``eval`` and ``eval_1`` its channel mean."""

    atlas: ImageAtlas
    _mean: float

    def eval_3(self, si: mi.SurfaceInteraction3f, active: mi.Bool = True) -> mi.Color3f:
        return self.eval(si, active)

    def eval_1(self, si: mi.SurfaceInteraction3f, active: mi.Bool = True) -> mi.Float:
        """Channel mean of the lookup."""
        return dr.mean(self.eval(si, active))

    def mean(self) -> float:
        """Mean of all bytes / 255."""
        return self._mean

    def is_spatially_varying(self) -> bool:
        return True

    def traverse(self, cb: mi.TraversalCallback) -> None:
        cb.put("data", self.atlas.data, mi.ParamFlags.NonDifferentiable)

    def parameters_changed(self, keys: list[str]) -> None:
        dr.make_opaque(self.atlas.data)
