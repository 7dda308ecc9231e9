"""The renders of one ``a5mi diagnose`` (docs/MISTAKES.md "How the diagnosis works", steps 1-4): the reference and
the mutants through one warm :class:`~a5mi.render.session.RenderSession`, at full size or small, counted.

With ``-jitter -filter`` a full-size render keeps its supersampled buffer, and the filter and saved-image mistakes
are made from it (:func:`a5mi.render.filters.mistaken_postprocess`, :func:`a5mi.render.filters.image_mistakes`):
the reference and every blur, downsample or saved-image mistake of one render cost one render.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from a5mi.diagnose.measure import Image, as_levels
from a5mi.render.filters import image_mistakes, mistaken_postprocess, postprocess
from a5mi.render.options import FILTER_MISTAKES, IMAGE_MISTAKES, RenderOptions

if TYPE_CHECKING:
    from a5mi.converters.describe import SceneDescription
    from a5mi.render.session import RenderSession

#: Full-size renders kept for the saved-image and filter mistakes made from them.
KEPT = 8


class Renders:
    """The renders of one diagnosis through one warm session, counted and timed."""

    def __init__(self, session: RenderSession, desc: SceneDescription, options: RenderOptions) -> None:
        self.session, self.desc, self.options = session, desc, options
        self.counts = {"small": 0, "full": 0}
        #: (render mistakes, seed) -> the render buffer (row 0 = top) with -jitter -filter, else the image
        self.kept: dict[tuple[tuple[str, ...], int], np.ndarray] = {}

    def full(self, mistakes: tuple[str, ...] = (), seed: int | None = None) -> Image:
        """The image at full size with ``mistakes``; the filter and saved-image mistakes from the render they
        modify (the last :data:`KEPT` renders are kept: a pair with a saved-image or filter mistake costs no
        render once its other mistake has been rendered)."""
        opts = self.options
        seed = seed if seed is not None else opts.seed
        post = tuple(m for m in mistakes if m in FILTER_MISTAKES)
        saved = tuple(m for m in mistakes if m in IMAGE_MISTAKES)
        render = tuple(sorted(m for m in mistakes if m not in post and m not in saved))
        sampling = opts.jitter and opts.filter and "no_supersampling" not in render
        key = (render, seed)
        raw = self.kept.pop(key, None)
        if raw is None:   # the render buffer with -jitter -filter, else the image as rendered
            raw = self._render(dataclasses.replace(opts, filter=opts.filter and not sampling, seed=seed,
                                                   mistakes=render), "full")
        self.kept[key] = raw
        while len(self.kept) > KEPT:
            self.kept.pop(next(iter(self.kept)))
        img = raw
        if sampling:
            flipped = raw[::-1]
            img = (mistaken_postprocess(flipped, post, opts.kernel) if post
                   else postprocess(flipped, filter=True, kernel=opts.kernel))[::-1]
        if saved:
            img = image_mistakes(img, saved)
        return as_levels(img)

    def small(self, mistakes: tuple[str, ...], size: tuple[int, int]) -> Image:
        """The image at ``size`` without supersampling, unquantised (stage 3)."""
        opts = dataclasses.replace(self.options, width=size[0], height=size[1], jitter=False, filter=False,
                                   mistakes=mistakes)
        return np.asarray(self._render(opts, "small")[..., :3], np.float64)

    def _render(self, options: RenderOptions, kind: str) -> np.ndarray:
        self.counts[kind] += 1
        return self.session.render(self.desc, options).image
