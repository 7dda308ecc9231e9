"""What the page's tools for looking closely read: each image's pixel values, and the diagnosis panel (docs/VIEW.md).

:func:`values_blob` packs an image's values for the page's readout, exposure and A/B flip: ``W·H·3`` float32 linear
RGB (little-endian, row 0 = top) followed by ``W·H·3`` 8-bit levels. For the render the linear values are the
saved image's floats (the values ``a5 -output X.exr`` writes) and the levels SPEC B.1's ``clamp(int(255 c), 0,
255)`` (the PNG's bytes); for a reference made of 8-bit levels ``k`` the linear value is ``k / 255``; for an
``.exr`` reference its float values, and its levels their SPEC B.1 quantisation.

:func:`diagnose_frame` is ``a5mi diagnose`` of the current frame (:func:`a5mi.diagnose.rank.diagnose`,
docs/MISTAKES.md "How the diagnosis works") through the page's warm session: the render (its 8-bit levels, made
with the frame's flags, ``-mistake`` included) or the reference image (the course's, or ``--binary``'s render)
against a5mi's correct render of the scene with the frame's SPEC B flags and no ``-mistake``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from a5mi.platform.errors import UserError


def values_blob(linear: np.ndarray, levels: np.ndarray) -> bytes:
    """``linear`` (H, W, >=3) as float32 little-endian, then ``levels`` (H, W, >=3) as uint8 (module docstring)."""
    lin = np.ascontiguousarray(np.asarray(linear)[..., :3], dtype="<f4")
    lev = np.ascontiguousarray(np.asarray(levels)[..., :3], dtype=np.uint8)
    if lin.shape != lev.shape:
        raise ValueError(f"values {lin.shape} and levels {lev.shape} differ in shape")
    return lin.tobytes() + lev.tobytes()


def render_values(image: np.ndarray) -> bytes:
    """The render's blob: its floats and their SPEC B.1 levels (``quantize``: the PNG's bytes)."""
    from a5mi.platform.imageio import quantize

    return values_blob(image, quantize(np.asarray(image)[..., :3]))


def is_float_image(path: str | None) -> bool:
    """Whether ``path`` names a float image (``.exr``: linear, unquantised)."""
    from a5mi.platform.imageio import FLOAT_FORMATS

    return path is not None and Path(path).suffix.lower() in FLOAT_FORMATS


class ReferenceValues:
    """The reference's blob, encoded once per reference array (the float file read once, when it is ``.exr``)."""

    def __init__(self, path: str | None) -> None:
        self.path = path
        self._float: np.ndarray | None = None
        self._last: tuple[int, bytes] | None = None

    def blob(self, levels: np.ndarray) -> bytes:
        """The blob of the reference whose 8-bit-scale levels (``read_levels`` or ``--binary``'s image) are
        ``levels``."""
        if self._last is not None and self._last[0] == id(levels):
            return self._last[1]
        if is_float_image(self.path):
            from a5mi.platform.imageio import quantize, read_image

            if self._float is None:
                img = read_image(str(self.path))
                self._float = np.repeat(img[..., :1], 3, axis=2) if img.shape[2] < 3 else img[..., :3]
            data = values_blob(self._float, quantize(self._float))
        else:
            data = values_blob(np.asarray(levels, np.float32) / np.float32(255.0), np.clip(levels, 0, 255))
        self._last = (id(levels), data)
        return data


def diagnose_frame(engine: Any, image: str, progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """The diagnosis of the current frame's ``image`` (``render`` or ``reference``) as JSON-ready data
    (:meth:`a5mi.diagnose.rank.Diagnosis.to_dict` plus ``image``, ``flags`` and ``mistakes``: the ``-mistake``
    names the frame was rendered with). Raises :class:`UserError` where there is nothing to diagnose or the flags
    are not the sample solution's (``-integrator whitted``; ``-jitter`` only with ``-filter``)."""
    from a5mi.diagnose.rank import diagnose
    from a5mi.platform.imageio import quantize

    frame = engine.frame
    if frame is None or engine.desc is None or frame.preview:
        raise UserError("nothing rendered yet: the diagnosis waits for the full image")
    opts = frame.options
    if opts.integrator != "whitted":
        raise UserError("the diagnosis follows the sample solution's renderer: set -integrator whitted")
    if opts.jitter and not opts.filter:
        raise UserError("-jitter without -filter saves the 3W x 3H buffer: diagnose it with -jitter -filter")
    if image == "render":
        pixels = quantize(np.asarray(frame.image)[..., :3])
    else:
        if frame.reference_levels is None:
            raise UserError("there is no reference image to diagnose")
        pixels = np.clip(np.trunc(frame.reference_levels), 0, 255).astype(np.uint8)
    clean = dataclasses.replace(opts, mistakes=())
    result = diagnose(pixels, engine.desc, clean, session=engine.session, progress=progress)
    doc = result.to_dict()
    doc.update(image=image, mistakes=list(opts.mistakes), flags=spec_flags(opts))
    return doc


def spec_flags(options: Any) -> str:
    """The SPEC B.1 flags of ``options`` as ``a5`` takes them (the diagnosis's reference is rendered with them)."""
    flags = [f"-size {options.width} {options.height}", f"-bounces {options.bounces}"]
    flags += [f for f, on in (("-shadows", options.shadows), ("-jitter", options.jitter),
                              ("-filter", options.filter)) if on]
    return " ".join(flags)


__all__ = ["ReferenceValues", "diagnose_frame", "is_float_image", "render_values", "spec_flags", "values_blob"]
