"""The page's marked region, rendered at full quality first (docs/VIEW.md "Full quality first").

A region is ``(X0, X1, Y0, Y1)``: the saved image's pixels ``X0 <= x < X1``, ``Y0 <= y < Y1``, row 0 the top, in
``-crop``'s order and pixels (docs/USAGE.md "Crop renders"). The page posts it as ``{"region": [X0, X1, Y0, Y1]}``
(``{"region": null}`` clears it; :func:`parse_region`). On every render the engine
(:func:`a5mi.view.live.run_engine`) first renders the region alone with the page's flags through the crop render
(:mod:`a5mi.render.crop`: bit for bit the same pixels of the whole image, ``-jitter -filter`` included) and
publishes a composite: the image shown before with the region's pixels pasted at ``[Y0:Y1, X0:X1]``
(:func:`paste`); then the preview, where the page shows one, with the region pasted on it too, and the whole image
as before. Where the crop render
refuses the flags (:func:`a5mi.render.crop.refusal`: ``-integrator photon``, ``ppm``, ``irradiancecache``, a
mistake that reads the whole image) :func:`why_not` says so in one line and the whole image renders alone.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import numpy as np

from a5mi.platform.errors import UsageError
from a5mi.render import crop
from a5mi.render.filters import output_size
from a5mi.render.options import RenderOptions

Region = tuple[int, int, int, int]
#: Coordinates beyond this are refused as malformed (no saved image is wider: ``-jitter`` alone saves 3W x 3H).
MAX_COORD = 1 << 20


class RegionError(UsageError):
    """A region the page sent that is not one (one line)."""


def saved_size(options: RenderOptions) -> tuple[int, int]:
    """``(W, H)`` of the image a render with ``options`` saves (SPEC B.5's table)."""
    return output_size(options.width, options.height, jitter=options.jitter, filter=options.filter)


def clamp(region: Region, size: tuple[int, int] | list[int]) -> Region | None:
    """``region`` clamped to a ``W x H`` image (``min(X, W)``, ``min(Y, H)``); None when nothing of it is left."""
    x0, x1, y0, y1 = region
    w, h = size
    x0, x1, y0, y1 = min(x0, w), min(x1, w), min(y0, h), min(y1, h)
    return (x0, x1, y0, y1) if x0 < x1 and y0 < y1 else None


def parse_region(doc: Any, size: list[int] | None = None) -> Region | None:
    """The region of the page's ``{"region": [X0, X1, Y0, Y1]}`` (None for ``{"region": null}``), clamped to the
    image shown (``size`` ``[W, H]``, when there is one); :class:`RegionError` for anything else: not that object,
    not four integers, ``X0 >= X1`` or ``Y0 >= Y1``, a negative or huge coordinate, a region outside the image."""
    if not isinstance(doc, dict) or set(doc) != {"region"}:
        raise RegionError('give {"region": [X0, X1, Y0, Y1]} (image pixels, row 0 the top, X1 and Y1 exclusive) '
                          'or {"region": null}')
    value = doc["region"]
    if value is None:
        return None
    if not (isinstance(value, list) and len(value) == 4
            and all(isinstance(v, int) and not isinstance(v, bool) for v in value)):
        raise RegionError(f"region: expected four integers X0 X1 Y0 Y1, found {value!r:.60}")
    x0, x1, y0, y1 = value
    if not (0 <= x0 < x1 <= MAX_COORD and 0 <= y0 < y1 <= MAX_COORD):
        raise RegionError(f"region {x0} {x1} {y0} {y1}: needs 0 <= X0 < X1 and 0 <= Y0 < Y1 (X1, Y1 exclusive, "
                          f"at most {MAX_COORD})")
    region = (x0, x1, y0, y1)
    if size is not None:
        clamped = clamp(region, size)
        if clamped is None:
            raise RegionError(f"region {x0} {x1} {y0} {y1} lies outside the {size[0]}x{size[1]} image")
        region = clamped
    return region


def why_not(options: RenderOptions, region: Region) -> str | None:
    """None when ``region`` of a render with ``options`` can go first, else the page's one line saying why not:
    the crop render's refusal (:func:`a5mi.render.crop.refusal`), or a region outside the saved image (its size
    changed since the region was marked)."""
    w, h = saved_size(options)
    if clamp(region, (w, h)) is None:
        return f"the marked region lies outside the {w}x{h} image: the whole image renders alone"
    why = crop.refusal(dataclasses.replace(options, crop=clamp(region, (w, h))))
    return None if why is None else f"the marked region cannot go first ({why}): the whole image renders alone"


def render_region(engine: Any, options: RenderOptions, region: Region) -> tuple[np.ndarray, float]:
    """The saved pixels of ``region`` (clamped to the saved image; :func:`why_not` must be None) rendered with
    ``options`` by the engine's warm session as ``a5 ... -crop X0 X1 Y0 Y1`` renders them (row 0 the top), and
    the seconds it took."""
    t0 = time.perf_counter()
    if engine.desc is None or options.bump != engine.bump:  # as ViewEngine.render: described with the bump maps
        engine.load(options.bump)
    region = clamp(region, saved_size(options)) or region
    result = engine.session.render(engine.desc, dataclasses.replace(options, crop=region))
    return result.image, time.perf_counter() - t0


def paste(base: np.ndarray | None, part: np.ndarray, region: Region, size: tuple[int, int]) -> tuple[np.ndarray, str]:
    """``(composite, what)``: a copy of ``base`` with ``part`` at ``[Y0:Y1, X0:X1]`` (``what`` ``"base"``), or,
    where ``base`` is None or not of the saved ``size`` ``(W, H)`` with ``part``'s channels, a black image with it
    (``"blank"``)."""
    x0, x1, y0, y1 = clamp(region, size) or region
    w, h = size
    if base is not None and base.shape == (h, w, part.shape[2]):
        out, what = base.copy(), "base"
    else:
        out, what = np.zeros((h, w, part.shape[2]), part.dtype), "blank"
    out[y0:y1, x0:x1] = part
    return out, what


__all__ = ["MAX_COORD", "Region", "RegionError", "clamp", "parse_region", "paste", "render_region", "saved_size",
           "why_not"]
