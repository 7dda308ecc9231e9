"""Crop renders: one rectangle of the saved image, bit for bit those pixels of the whole render (docs/USAGE.md
"Crop renders"; the render of SPEC B.2, B.5, B.6 restricted to the samples the rectangle is made of).

The region (``-crop X0 X1 Y0 Y1``, pbrt-v4's ``--pixelbounds x0,x1,y0,y1``): the saved image's pixels
``X0 <= x < X1``, ``Y0 <= y < Y1``, row 0 the **top** row as in the image file, in the saved image's own
pixels (``W x H`` with ``-jitter -filter``, ``3W x 3H`` with ``-jitter`` alone, ``W/3 x H/3`` with ``-filter``
alone); the image written is the region alone, ``(X1-X0) x (Y1-Y0)``, as pbrt-v4 writes its crop. In the
render buffer (``RW x RH``, row ``j = 0`` at the bottom), with ``k = 3`` under ``-filter`` and 1 without,
and the region's rows counted from the bottom ``y0 = OH - Y1``, ``y1 = OH - Y0`` (``OH`` the saved height):

* the region's own samples (:attr:`CropPlan.aov`): ``k X0 <= i < k X1``, ``k y0 <= j < k y1``; the ``-normals``,
  ``-depth`` and class images, unfiltered at the render buffer's resolution, are these samples (with SPEC B.6's
  ``-normals_mode quadrant`` traced again in a second pass with the sample solution's AOV rays,
  :func:`quadrant_launches`);
* the traced samples (:attr:`CropPlan.trace`): with ``-filter`` the region's samples grown by the blur's reach,
  2 samples on each side (SPEC B.5's 5-tap kernel), clipped to the buffer: ``max(0, 3X0-2) <= i < min(RW,
  3X1+2)``, likewise ``j``; the blur then reads them exactly as the whole render's clamped taps do
  (:func:`filter_region`: the y taps over rows ``clamp(j-2 .. j+2, 0, RH-1)``, then the x taps, then the 3x3
  downsample, the float32 operations of :class:`a5mi.render.filters.FilterStream` in the same order);
* each sample ``(i, j)`` is traced as the whole render traces it: its index ``s = j RW + i`` gives its
  ``-jitter`` offsets (the stream's values ``2s, 2s+1``, drawn in order and the ones between the region's rows
  dropped), its E.5 keys (:class:`a5mi.plugins.sampling.SamplePass` ``pixels``), and its SIMD packet: the
  traced indices are whole blocks of :data:`ALIGN` consecutive samples starting on multiples of it, so each
  sample shares its packet with the neighbours it has in the whole render (:data:`a5mi.render.tiles.
  PACKET_ALIGN` says why that matters to the last bit).

The work is the traced samples: ``(k w + 4)(k h + 4)`` for a ``w x h`` region under ``-filter`` (``w h`` without),
plus at most ``2 (ALIGN - 1)`` per row for the block alignment, against ``RW RH`` for the whole image.

Pure numpy besides the trace (:func:`trace_region`, through :mod:`a5mi.render.render_pass`). Only the integrators
whose samples carry all their state crop (``whitted``, ``path``: :func:`refusal`).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from a5mi.platform import interrupts
from a5mi.platform.loading import load_dict
from a5mi.render.filters import _blur_axis, downsample3, kernel_taps, output_size
from a5mi.render.options import FILTER_MISTAKES, JITTER_MISTAKES, RenderOptions
from a5mi.render.passes import sample_passes
from a5mi.render.render_pass import (
    PassBuffers,
    TraceContext,
    account_kernels,
    camera_rays_of,
    evaluate,
    kernel_history,
    named_aovs,
)
from a5mi.render.tiles import Tile, jitter_stream, mistaken_offsets, quadrant_axes

#: Traced samples come in blocks of this many consecutive indices, each starting on a multiple of it: the
#: widest SIMD packet of Dr.Jit's LLVM backend (16 lanes with AVX-512; 8 with AVX2, 4 with SSE or NEON). A
#: precaution: with blocks of 1 sample, 21 regions of scene10 at 30x30 ``-jitter -shadows`` starting at every
#: column mod 8 were bit-identical too on the 8-wide machine this was written on (the packet dependence of
#: a5mi.render.tiles.PACKET_ALIGN did not show); the blocks cost at most 2 (ALIGN - 1) samples a row.
ALIGN = 16
#: docs/MISTAKES.md mistakes that read pixels outside the region (the whole image turned, the whole buffer filtered
#: the mistaken way): refused with ``-crop``
NONLOCAL_MISTAKES: tuple[str, ...] = ("upside_down", "mirrored", *FILTER_MISTAKES)
#: samples of the jitter stream drawn and dropped at once when skipping to the region (bounded memory)
_SKIP_CHUNK = 1 << 22


class Rect(NamedTuple):
    """Half-open ``i0 <= i < i1``, ``j0 <= j < j1``, row ``j = 0`` at the bottom."""

    i0: int
    i1: int
    j0: int
    j1: int

    @property
    def width(self) -> int:
        return self.i1 - self.i0

    @property
    def height(self) -> int:
        return self.j1 - self.j0


@dataclass(frozen=True)
class CropPlan:
    """Where a crop's samples lie (module docstring): ``out`` the region in the saved image (bottom-up),
    ``aov`` its own render-buffer samples, ``trace`` those traced for its colour, ``samples`` their indices in
    whole :data:`ALIGN` blocks (ascending), ``k`` the downsample factor (3 under ``-filter``, else 1)."""

    out: Rect
    aov: Rect
    trace: Rect
    samples: np.ndarray
    k: int


def refusal(options: RenderOptions) -> str | None:
    """None when ``options.crop`` can be rendered, else why not (one line naming the flags): the region must lie
    in the saved image (``0 <= X0 < X1 <= OW``, ``0 <= Y0 < Y1 <= OH``); only ``-integrator whitted`` and
    ``path`` (the others keep state across the image: photon maps per pass, final-gather streams and
    irradiance records in the order of the image's points), and no :data:`NONLOCAL_MISTAKES`."""
    if options.crop is None:
        return None
    x0, x1, y0, y1 = options.crop
    ow, oh = output_size(options.width, options.height, jitter=options.jitter, filter=options.filter)
    if not (0 <= x0 < x1 <= ow and 0 <= y0 < y1 <= oh):
        return (f"-crop {x0} {x1} {y0} {y1} is not a region of the {ow}x{oh} image: it needs 0 <= X0 < X1 <= {ow} "
                f"and 0 <= Y0 < Y1 <= {oh} (X1, Y1 exclusive, row 0 the top)")
    if options.integrator not in ("whitted", "path"):
        return (f"-crop renders -integrator whitted or path; -integrator {options.integrator} keeps state across "
                "the image")
    nonlocal_ = [m for m in options.mistakes if m in NONLOCAL_MISTAKES]
    if nonlocal_:
        return f"-crop cannot make the mistake {nonlocal_[0]}: it reads pixels outside the region"
    return None


def aligned_samples(rw: int, rh: int, rect: Rect, align: int = ALIGN) -> np.ndarray:
    """The indices ``j rw + i`` of every sample of ``rect``, completed to whole blocks of ``align`` consecutive
    indices starting on multiples of ``align`` (within ``[0, rw rh)``), ascending, int64."""
    rows = np.arange(rect.j0, rect.j1, dtype=np.int64) * rw
    first = (rows + rect.i0) // align
    count = (rows + rect.i1 - 1) // align + 1 - first
    offsets = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
    blocks = np.unique(np.repeat(first, count) + offsets)
    samples = (blocks[:, None] * align + np.arange(align)).ravel()
    return samples[samples < rw * rh]


def plan(options: RenderOptions) -> CropPlan:
    """The :class:`CropPlan` of ``options.crop`` (module docstring); ``ValueError`` with :func:`refusal`'s
    line when it cannot be rendered."""
    why = refusal(options)
    if why is not None or options.crop is None:
        raise ValueError(why or "no -crop region")
    x0, x1, top0, top1 = options.crop
    rw, rh = options.render_size
    oh = output_size(options.width, options.height, jitter=options.jitter, filter=options.filter)[1]
    out = Rect(x0, x1, oh - top1, oh - top0)
    k = 3 if options.filter else 1
    aov = Rect(k * out.i0, k * out.i1, k * out.j0, k * out.j1)
    m = 2 if options.filter else 0      # SPEC B.5: the blur's 5 taps reach 2 samples each way
    trace = Rect(max(0, aov.i0 - m), min(rw, aov.i1 + m), max(0, aov.j0 - m), min(rh, aov.j1 + m))
    return CropPlan(out, aov, trace, aligned_samples(rw, rh, trace), k)


def filter_region(block: np.ndarray, plan: CropPlan, size: tuple[int, int], kernel: str) -> np.ndarray:
    """SPEC B.5's blur + 3x3 downsample of the region from its traced samples ``block`` (``plan.trace``'s
    colours, bottom-up, ``h x w x 3``) in the ``size = (RW, RH)`` buffer: output pixel ``(x, y)`` is
    ``Σ_dx Σ_dy blur[3y+dy, 3x+dx] / 9`` with ``blur`` the y taps over rows ``clamp(r-2 .. r+2, 0, RH-1)``
    then the x taps over columns ``clamp(c-2 .. c+2, 0, RW-1)``, in float32 in the whole render's order."""
    rw, rh = size
    t, a = plan.trace, plan.aov
    taps = kernel_taps(kernel)
    rows = np.clip(np.arange(a.j0 - 2, a.j1 + 2), 0, rh - 1) - t.j0
    tmp = _blur_axis(block[rows], taps, 0, a.height)
    cols = np.clip(np.arange(a.i0 - 2, a.i1 + 2), 0, rw - 1) - t.i0
    return downsample3(_blur_axis(tmp[:, cols], taps, 1, a.width))


def region_offsets(samples: np.ndarray, seed: int | None, chunk: int) -> Iterator[tuple[np.ndarray, Any]]:
    """``(indices, (jx, jy))`` per launch of at most ``chunk`` traced samples: SPEC B.5's offsets of those
    samples, the stream's values before and between them drawn in order and dropped."""
    draw = jitter_stream(seed, total=int(samples[-1]) + 1)
    pos = 0
    for a in range(0, len(samples), chunk):
        idx = samples[a:a + chunk]
        lo, hi = int(idx[0]), int(idx[-1]) + 1
        while pos < lo:
            step = min(_SKIP_CHUNK, lo - pos)
            draw(step)
            pos += step
        jx, jy = draw(hi - lo)
        pos = hi
        yield idx, (jx[idx - lo], jy[idx - lo])


def launches(options: RenderOptions, samples: np.ndarray) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """``(indices, x_pix, y_pix)`` per kernel launch of at most ``options.tile_rays`` of ``samples``: float32
    ``x_pix = i + jx``, ``y_pix = j + jy`` (SPEC B.2, B.5; the offsets 0 without ``-jitter`` or with
    docs/MISTAKES.md's ``no_jitter``)."""
    rw = options.render_size[0]
    chunk = max(ALIGN, options.tile_rays // ALIGN * ALIGN)
    mistakes = options.of_layer(JITTER_MISTAKES)
    if options.jitter and "no_jitter" not in mistakes:
        pieces: Iterator[tuple[np.ndarray, Any]] = region_offsets(samples, options.seed, chunk)
    else:
        pieces = ((samples[a:a + chunk], None) for a in range(0, len(samples), chunk))
    for idx, offsets in pieces:
        i = (idx % rw).astype(np.float32)
        j = (idx // rw).astype(np.float32)
        if offsets is None:
            yield idx, i, j
        else:
            jx, jy = mistaken_offsets(offsets, mistakes)
            yield idx, i + jx, j + jy


def quadrant_launches(options: RenderOptions, samples: np.ndarray
                      ) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """As :func:`launches` with the sample solution's AOV rays (SPEC B.6 ``-normals_mode quadrant``,
    :func:`a5mi.render.tiles.quadrant_coords`) of each sample."""
    rw, rh = options.render_size
    chunk = max(ALIGN, options.tile_rays // ALIGN * ALIGN)
    x_of, y_of = quadrant_axes(rw, rh)
    for a in range(0, len(samples), chunk):
        idx = samples[a:a + chunk]
        yield idx, x_of[idx % rw], y_of[idx // rw]


def trace_region(ctx: TraceContext, launched: Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]], rect: Rect,
                 buffers: PassBuffers, done: int = 0) -> tuple[int, int]:
    """Trace the ``launched`` samples (:func:`launches`, :func:`quadrant_launches`; module docstring) and fill
    ``buffers``, each ``rect``-sized, bottom-up: ``color``, ``normal``, ``dist``, ``classes`` (those set), the
    ray counts (of a colour pass) and kernel launches; ``done`` samples were traced before. Returns ``(launches,
    done)``. Drawing the offsets (the skipped part of the stream included) and the pixel coordinates is timed as
    ``ctx.timings["jitter"]``."""
    rw = ctx.size[0]
    t = rect
    count = 0
    sampler = _sampler()
    with kernel_history():
        while True:
            t0 = time.perf_counter()
            item = next(launched, None)     # the jitter draw and the pixel coordinates: timings["jitter"]
            ctx.timings["jitter"] = ctx.timings.get("jitter", 0.0) + time.perf_counter() - t0
            if item is None:
                break
            idx, x_pix, y_pix = item
            with interrupts.deferred():
                n = len(idx)
                j, i = idx // rw, idx % rw
                ray = camera_rays_of(ctx, Tile(int(j[0]), int(j[-1]) + 1, x_pix, y_pix))
                rgb, aovs = sample_passes(ctx.scene, ctx.integrator, sampler, ray, ctx.camera, int(idx[0]), n,
                                          ctx.spp, ctx.seed, pixels=idx)
                named = named_aovs(ctx.integrator, aovs, buffers.aov_names)
                outputs, counted = buffers.eval_targets(rgb, named)
                evaluate(outputs, counted)
                keep = (i >= t.i0) & (i < t.i1) & (j >= t.j0) & (j < t.j1)
                at = (j[keep] - t.j0, i[keep] - t.i0)
                if buffers.color is not None:
                    buffers.color[at] = np.asarray(rgb).T[keep]
                if buffers.normal is not None:
                    nrm = np.stack([np.asarray(named[c]) for c in ("nx", "ny", "nz")], axis=-1)
                    buffers.normal[at] = np.abs(nrm)[keep]
                if buffers.dist is not None:
                    buffers.dist[at] = np.asarray(named["t"])[keep]
                if buffers.classes is not None:
                    buffers.classes[at] = np.asarray(named["class"])[keep].astype(np.uint8)
                buffers.add_counts(counted)
                account_kernels(buffers.kernels, ctx.timings)
                count += 1
                done += n
                if ctx.progress is not None:
                    ctx.progress(done, ctx.total)
    return count, done


def _sampler() -> Any:
    """A one-sample ``independent`` sampler: the integrator takes one; the camera rays are the driver's (SPEC B.2)."""
    return load_dict({"type": "independent", "sample_count": 1})


def region_buffers(options: RenderOptions, rect: Rect, *, color: bool = True, aovs: bool = True) -> PassBuffers:
    """Empty ``rect``-sized buffers for :func:`trace_region`: the colour and the class image (``color``), the
    ``-normals`` / ``-depth`` AOVs ``options`` asks for (``aovs``)."""
    h, w = rect.height, rect.width
    return PassBuffers(color=np.empty((h, w, 3), np.float32) if color else None,
                       normal=np.empty((h, w, 3), np.float32) if aovs and options.normals else None,
                       dist=np.empty((h, w), np.float32) if aovs and options.depth is not None else None,
                       classes=np.empty((h, w), np.uint8) if color and options.classes else None)


def own(a: np.ndarray | None, plan: CropPlan) -> np.ndarray | None:
    """The region's own samples (``plan.aov``) of a ``plan.trace``-sized buffer."""
    if a is None:
        return None
    t, r = plan.trace, plan.aov
    return np.ascontiguousarray(a[r.j0 - t.j0:r.j1 - t.j0, r.i0 - t.i0:r.i1 - t.i0])


def traced_samples(options: RenderOptions) -> int:
    """The render-buffer samples a render of ``options`` traces: those of its crop's plan, or ``RW · RH``
    (without a crop, or with one :func:`refusal` refuses); what the work estimate counts."""
    rw, rh = options.render_size
    if options.crop is None or refusal(options) is not None:
        return rw * rh
    return len(plan(options).samples)


__all__ = ["ALIGN", "NONLOCAL_MISTAKES", "CropPlan", "Rect", "aligned_samples", "filter_region", "launches",
           "own", "plan", "quadrant_launches", "refusal", "region_buffers", "region_offsets", "trace_region",
           "traced_samples"]
