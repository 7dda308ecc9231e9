"""The render driver: a loaded Mitsuba scene, the a5 camera and the options -> images (SPEC B.2, B.5, B.6).

:func:`render_scene` renders as ``a5soln`` does:

* render buffer ``RW x RH`` = ``3W x 3H`` with ``-jitter``, else ``W x H`` (SPEC B.5), visited in tiles of
  whole rows, bottom-up (:mod:`a5mi.render.tiles`: sample ``(i, j)``, ``j = 0`` the bottom row, through
  ``x_pix = i + jx``, ``y_pix = j + jy``, float32, glibc's seed-1 jitter stream or PCG64 for a ``seed``);
* each tile traced by :mod:`a5mi.render.render_pass`: the B.2 camera rays of
  :func:`a5mi.plugins.sensors.camera.camera_rays`, ``integrator.sample(scene, sampler, ray, None, active)`` of
  ``a5_whitted`` over the ``-spp`` passes (:mod:`a5mi.render.passes`, EXTENSIONS E.5), its AOVs read **by name**, one
  kernel per tile, compiled once and reused;
* ``-filter``: blur + 3x3 downsample (:mod:`a5mi.render.filters`) streamed tile by tile
  (:class:`a5mi.render.filters.FilterStream`): the full-size colour buffer is never held, so with ``-jitter -filter``
  memory is bounded by the tile size plus the W x H output, not by the 3W x 3H buffer;
* ``-normals``: ``|N|`` per component; ``-depth dmin dmax``: :func:`depth_gray` of ``t`` (SPEC B.6), both at the
  render buffer's resolution, unfiltered, traced with the main image's rays (``aov_mode="quadrant"``: with the
  binary's top-right-quadrant rays instead, a second pass, :func:`a5mi.render.tiles.quadrant_coords`);
* ``classes`` (:attr:`RenderOptions.classes`): the ``class`` AOV of ``a5_whitted`` per sample of the main pass
  (0 the camera ray misses, 1 opaque, 2 the SPEC B.3 ray tree touches a material with
  ``refraction_index > 0``), uint8 at the render buffer's resolution, unfiltered;
* ``crop`` (:attr:`RenderOptions.crop`, ``-crop``): one region of the saved image alone, bit for bit its pixels
  of the whole render (:mod:`a5mi.render.crop`: its samples and the blur's margin traced, then filtered);
* ``threads`` (:attr:`RenderOptions.threads`): Dr.Jit's worker threads for this render only
  (:func:`thread_count`: the process's count is restored afterwards);
* ``mistakes`` (:attr:`RenderOptions.mistakes`, docs/MISTAKES.md): the driver's own (camera, jitter, filter, the
  saved image: :func:`mistaken`, :func:`a5mi.render.filters.mistaken_postprocess`,
  :func:`a5mi.render.filters.image_mistakes`);
  the kernel's travel in the integrator's ``mistakes`` parameter.

The driver builds nothing: the caller loads the scene from its description (:func:`a5mi.render.session.build_scene`),
so data flows one way, description -> dict -> Mitsuba objects -> driver -> image.

Images in :class:`RenderResult` have row 0 = the **top** row (ready for :func:`a5mi.platform.imageio.write_image`).
This module never prints: progress goes through a callback.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from a5mi.render import crop
from a5mi.render.filters import FilterStream, image_mistakes, mistaken_postprocess, postprocess
from a5mi.render.options import CAMERA_MISTAKES, FILTER_MISTAKES, IMAGE_MISTAKES, JITTER_MISTAKES, RenderOptions
from a5mi.render.render_pass import CameraRays, PassBuffers, PassHook, Progress, TraceContext, trace_moving, trace_pass
from a5mi.render.tiles import PROGRESS_STEPS, main_tiles, quadrant_tiles, tile_rows

if TYPE_CHECKING:
    import mitsuba as mi

    from a5mi.converters.model import Camera


@dataclass
class RenderResult:
    """The saved image and the AOV images (float32 HxWx3, row 0 = top) plus statistics; ``classes``
    (uint8 RHxRW, row 0 = top) is the ``class`` AOV when :attr:`RenderOptions.classes` asked for it.

    ``timings`` (seconds): ``build`` (dict + ``mi.load_dict``, filled by the caller that built the scene),
    ``compile`` (Dr.Jit codegen + LLVM), ``execute`` (kernels), ``render`` (wall time of the tile loop, without
    the filter), ``jitter`` (offset generation, mostly overlapped with rendering), ``filter`` (blur +
    downsample, streamed per tile).
    """

    image: npt.NDArray[np.float32]
    normals: npt.NDArray[np.float32] | None
    depth: npt.NDArray[np.float32] | None
    render_size: tuple[int, int]
    camera_rays: int
    tiles: int
    timings: dict[str, float] = field(default_factory=dict)
    #: ``reflection``, ``refraction``, ``shadow`` ray totals, when the integrator reports them
    ray_counts: dict[str, int] = field(default_factory=dict)
    #: kernel launches by where the kernel came from: ``memory`` (this process's cache), ``disk``
    #: (Dr.Jit's cache folder), ``compiled`` (LLVM ran); a repeated render should be all ``memory``
    kernels: dict[str, int] = field(default_factory=dict)
    #: per-sample ray-tree class (0 miss, 1 opaque, 2 glass), when ``RenderOptions.classes`` asked for it
    classes: npt.NDArray[np.uint8] | None = None
    #: what the integrator reports of the render (its ``render_extras()``, if it has one; the irradiance
    #: cache's records, docs/EXTENSIONS.md E.23)
    extras: dict[str, Any] = field(default_factory=dict)


def depth_gray(t: npt.ArrayLike, dmin: float, dmax: float) -> npt.NDArray[np.float32]:
    """SPEC B.6: 1 if ``t <= dmin``; 0 if ``t >= dmax`` or ``dmin >= dmax``; else ``1 - (t-dmin)/(dmax-dmin)``."""
    t = np.asarray(t, dtype=np.float32)
    dmin32, dmax32 = np.float32(dmin), np.float32(dmax)
    with np.errstate(invalid="ignore", divide="ignore"):
        ramp = np.float32(1.0) - (t - dmin32) / (dmax32 - dmin32)
    return np.select(
        [t <= dmin32, (t >= dmax32) | (dmin32 >= dmax32) | np.isnan(t)], [np.float32(1), np.float32(0)], ramp
    ).astype(np.float32)


@contextmanager
def thread_count(threads: int | None) -> Iterator[None]:
    """Dr.Jit's worker-thread count (process-wide) set to ``threads`` inside the block and restored after it,
    also when the block raises; ``None`` leaves it alone."""
    if threads is None:
        yield
        return
    import drjit as dr

    before = dr.thread_count()
    dr.set_thread_count(threads)
    try:
        yield
    finally:
        dr.set_thread_count(before)


def _default_camera_rays() -> CameraRays:
    from a5mi.plugins.sensors.camera import camera_rays

    return camera_rays


def mistaken(camera: Camera, camera_rays: CameraRays, options: RenderOptions
             ) -> tuple[Camera, CameraRays, RenderOptions]:
    """``(camera, ray generator, options)`` with the docs/MISTAKES.md camera mistakes of ``options`` made
    (:data:`a5mi.render.options.CAMERA_MISTAKES`, SPEC B.2, B.5):

    * ``fov_full_angle``: ``f = 1/tan(angle)`` instead of ``1/tan(angle/2)``, i.e. the camera of angle ``2 angle``
      (needs ``angle < 90``; otherwise left as is);
    * ``camera_divides_by_w``: ``x = 2(i + jx)/W - 1`` (likewise y with H), i.e. the B.2 rays of a ``W+1 x H+1``
      buffer through the same pixel positions;
    * ``no_supersampling``: ``-jitter -filter`` ignored: one ray through each pixel of the W x H image.
    """
    made = options.of_layer(CAMERA_MISTAKES)
    if "fov_full_angle" in made and 0.0 < camera.angle < 90.0:
        camera = dataclasses.replace(camera, angle=2.0 * camera.angle)
    if "camera_divides_by_w" in made:
        base = camera_rays

        def camera_rays(center, direction, up, angle, x_pix, y_pix, width, height):  # type: ignore[no-untyped-def]
            return base(center, direction, up, angle, x_pix, y_pix, width + 1, height + 1)

    return camera, camera_rays, _sampling(options)


def _sampling(options: RenderOptions) -> RenderOptions:
    """``options`` with docs/MISTAKES.md's ``no_supersampling`` made: ``-jitter -filter`` dropped."""
    if "no_supersampling" in options.mistakes and options.jitter and options.filter:
        return dataclasses.replace(options, jitter=False, filter=False)
    return options


def _pass_buffers(options: RenderOptions, separate: bool) -> tuple[PassBuffers, PassBuffers]:
    """``(main, aov)``: the colour pass's buffers (the whole buffer, or the ``-filter`` stream; the class image)
    and the AOV images (``|N|``, ``t``), which the main pass fills too unless ``separate``."""
    rw, rh = options.render_size
    aov = PassBuffers(
        color=None,
        normal=np.empty((rh, rw, 3), np.float32) if options.normals else None,
        dist=np.empty((rh, rw), np.float32) if options.depth is not None else None,
    )
    if options.filter and not options.of_layer(FILTER_MISTAKES):
        main = PassBuffers(color=None, normal=None, dist=None, stream=FilterStream(rw, rh, options.kernel))
    else:
        main = PassBuffers(color=np.empty((rh, rw, 3), np.float32), normal=None, dist=None)
    if options.classes:
        main.classes = np.empty((rh, rw), np.uint8)
    if not separate:
        main.normal, main.dist = aov.normal, aov.dist
    return main, aov


def _flipped(a: np.ndarray | None) -> np.ndarray | None:
    """Row 0 = top (the buffers' row 0 is the bottom row ``j = 0``)."""
    return None if a is None else np.ascontiguousarray(a[::-1])


def _result(options: RenderOptions, main: PassBuffers, aov: PassBuffers, separate: bool, tiles: int,
            total: int, timings: dict[str, float], clip: bool = False) -> RenderResult:
    """The :class:`RenderResult` of the filled buffers: the colour (filtered or as traced), ``-normals``,
    ``-depth`` as three equal channels, the class image, the counts and the kernel launches of both passes. With
    ``clip`` (a dispersive render) the colour is clipped at 0 after ``-filter``: E.10's spectral weight has
    negative lobes (outside the sRGB gamut), and a pixel whose mean stays out of gamut is clipped in float images
    as quantisation clips it in 8-bit ones, so the 8-bit images are unchanged. Any other colour, a negative
    diffuseColor's included, stays linear (SPEC A.5 sets no range)."""
    if main.stream is not None:
        image = main.stream.result()
    elif options.filter and options.of_layer(FILTER_MISTAKES):   # docs/MISTAKES.md: the whole buffer, mistaken
        assert main.color is not None
        image = mistaken_postprocess(main.color, options.of_layer(FILTER_MISTAKES), options.kernel)
    else:
        assert main.color is not None
        image = postprocess(main.color, filter=False)
    if clip:
        image = np.maximum(image, np.float32(0.0))
    depth_img = None
    if aov.dist is not None and options.depth is not None:
        gray = depth_gray(aov.dist, *options.depth)
        depth_img = np.repeat(gray[:, :, None], 3, axis=2)
    flipped_image = _flipped(image)
    assert flipped_image is not None
    if options.of_layer(IMAGE_MISTAKES):   # docs/MISTAKES.md: the saved image
        flipped_image = image_mistakes(flipped_image, options.of_layer(IMAGE_MISTAKES))
    return RenderResult(
        image=flipped_image,
        normals=_flipped(aov.normal),
        depth=_flipped(depth_img),
        render_size=options.render_size,
        camera_rays=total,
        tiles=tiles,
        timings=timings,
        ray_counts=main.counts,
        kernels={k: main.kernels.get(k, 0) + (aov.kernels.get(k, 0) if separate else 0)
                 for k in ("memory", "disk", "compiled")},
        classes=_flipped(main.classes),
    )


def render_scene(
    mi_scene: mi.Scene,
    camera: Camera,
    options: RenderOptions,
    *,
    integrator: mi.SamplingIntegrator | None = None,
    camera_rays: CameraRays | None = None,
    progress: Progress | None = None,
    pass_hook: PassHook | None = None,
) -> RenderResult:
    """Render a loaded Mitsuba scene with the a5 camera ``camera`` (``center``, ``direction``, ``up``,
    ``angle`` in degrees; E.3 ``aperture``, ``focus_distance``) as the module docstring says. ``integrator``
    defaults to ``mi_scene.integrator()``; ``camera_rays`` to :func:`a5mi.plugins.sensors.camera.camera_rays`. With
    ``options.classes`` the integrator must list the ``class`` AOV (``a5_whitted`` ``aovs`` including
    ``class``). ``progress(done, total)`` is called after each tile (and the render split into about
    :data:`a5mi.render.tiles.PROGRESS_STEPS` tiles for it). ``pass_hook`` (motion blur, docs/EXTENSIONS.md E.12):
    called before each of the ``spp`` passes, which then run one after the other over the whole image
    (:func:`a5mi.render.render_pass.trace_moving`); its camera replaces ``camera``.

    Needs an active JIT variant with the a5mi plugins registered (:func:`a5mi.runtime.variant.activate`).
    """
    with thread_count(options.threads):
        integrator = integrator if integrator is not None else mi_scene.integrator()
        camera_rays = camera_rays if camera_rays is not None else _default_camera_rays()
        camera, camera_rays, options = mistaken(camera, camera_rays, options)
        if options.crop is not None:
            if pass_hook is not None:
                raise ValueError("a crop render takes no pass hook (motion blur renders the whole image)")
            return _render_crop(mi_scene, camera, options, integrator, camera_rays, progress)
        rw, rh = options.render_size
        # progress steps only for a caller that shows them: each extra tile re-traces the integrator (~50 ms)
        rows = tile_rows(rw, rh, options.tile_rays, steps=PROGRESS_STEPS if progress is not None else 1)
        separate = (options.normals or options.depth is not None) and options.aov_mode == "quadrant"
        total = rw * rh * (2 if separate else 1)
        main, aov = _pass_buffers(options, separate)
        timings: dict[str, float] = {"compile": 0.0, "execute": 0.0, "jitter": 0.0, "filter": 0.0}

        t_start = time.perf_counter()
        ctx = TraceContext(mi_scene, camera, integrator, camera_rays, (rw, rh), timings, progress, total,
                           options.spp, options.seed or 0)
        if pass_hook is None:
            done = trace_pass(ctx, main_tiles(rw, rows, options.seed, options.jitter, timings,
                                                 options.of_layer(JITTER_MISTAKES)), main, 0)
        else:
            trace_moving(ctx, lambda: main_tiles(rw, rows, options.seed, options.jitter, timings,
                                                 options.of_layer(JITTER_MISTAKES)), main, pass_hook)
            done = total * ctx.spp
        if separate:
            trace_pass(ctx, quadrant_tiles(rw, rh, rows), aov, done)
        timings["render"] = time.perf_counter() - t_start - timings["filter"]  # the streamed filter: its own stage
    result = _result(options, main, aov, separate, len(rows), total, timings, clip=_dispersive(integrator))
    extras = getattr(integrator, "render_extras", None)
    result.extras = extras() if callable(extras) else {}
    return result


def _render_crop(mi_scene: mi.Scene, camera: Camera, options: RenderOptions, integrator: mi.SamplingIntegrator,
                 camera_rays: CameraRays, progress: Progress | None) -> RenderResult:
    """:func:`render_scene` of ``options.crop`` alone (:mod:`a5mi.render.crop`): its samples traced, its colour
    filtered from them, its AOVs cut to its own samples (with ``aov_mode="quadrant"`` a second pass over its
    own samples); the images are the region's, row 0 = top."""
    plan = crop.plan(options)
    rw, rh = options.render_size
    separate = (options.normals or options.depth is not None) and options.aov_mode == "quadrant"
    own_samples = crop.aligned_samples(rw, rh, plan.aov) if separate else plan.samples[:0]
    timings: dict[str, float] = {"compile": 0.0, "execute": 0.0, "jitter": 0.0, "filter": 0.0}
    total = len(plan.samples) + len(own_samples)
    ctx = TraceContext(mi_scene, camera, integrator, camera_rays, (rw, rh), timings, progress, total,
                       options.spp, options.seed or 0)
    traced = crop.region_buffers(options, plan.trace, aovs=not separate)
    aov = crop.region_buffers(options, plan.aov, color=False)
    t_start = time.perf_counter()
    launches, done = crop.trace_region(ctx, crop.launches(options, plan.samples), plan.trace, traced)
    if separate:
        launches += crop.trace_region(ctx, crop.quadrant_launches(options, own_samples), plan.aov, aov, done)[0]
        traced.kernels = {k: traced.kernels.get(k, 0) + aov.kernels.get(k, 0) for k in {*traced.kernels, *aov.kernels}}
    else:
        aov.normal, aov.dist = crop.own(traced.normal, plan), crop.own(traced.dist, plan)
    timings["render"] = time.perf_counter() - t_start
    assert traced.color is not None
    t0 = time.perf_counter()
    color = (crop.filter_region(traced.color, plan, (rw, rh), options.kernel) if options.filter
             else traced.color)
    timings["filter"] = time.perf_counter() - t0
    main = PassBuffers(color=color, normal=None, dist=None, classes=crop.own(traced.classes, plan),
                       counts=traced.counts, kernels=traced.kernels)
    result = _result(dataclasses.replace(options, filter=False), main, aov, False, launches, total, timings,
                     clip=_dispersive(integrator))
    extras = getattr(integrator, "render_extras", None)
    result.extras = extras() if callable(extras) else {}
    return result


@dataclass
class Band:
    """Rows ``j0 .. j1-1`` of a render buffer as :func:`render_band` traced them: the colour (unfiltered,
    row 0 = render row ``j0``, bottom-up), ``|N|`` and ``t`` when asked for, the ray counts and kernel launches."""

    j0: int
    j1: int
    color: npt.NDArray[np.float32]
    normal: npt.NDArray[np.float32] | None = None
    dist: npt.NDArray[np.float32] | None = None
    counts: dict[str, int] = field(default_factory=dict)
    kernels: dict[str, int] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)
    clip: bool = False   # a dispersive render's image is clipped at 0 (:func:`_result`)


def _dispersive(integrator: Any) -> bool:
    """Whether ``integrator`` renders E.10's dispersion (its spectral weight has negative lobes)."""
    return bool(getattr(integrator, "dispersion", False))


def render_band(mi_scene: mi.Scene, camera: Camera, options: RenderOptions, band: tuple[int, int], *,
                integrator: mi.SamplingIntegrator | None = None) -> Band:
    """Render-buffer rows ``band = (j0, j1)`` of :func:`render_scene`'s main pass, each sample exactly as the
    whole render traces it: the same pixel position (the ``-jitter`` offsets of rows ``0 .. j0-1`` are drawn
    and dropped, so the stream is where it would be), the same E.5 keys (absolute sample index), tiles
    starting on :data:`a5mi.render.tiles.PACKET_ALIGN` samples when ``j0 · RW`` does. The ``-filter`` step is the
    caller's (:func:`assemble`); ``aov_mode="quadrant"`` AOVs and motion blur are not rendered here."""
    j0, j1 = band
    with thread_count(options.threads):
        integrator = integrator if integrator is not None else mi_scene.integrator()
        camera, camera_rays, options = mistaken(camera, _default_camera_rays(), options)
        rw, rh = options.render_size
        rows = [(j0 + a, j0 + b) for a, b in tile_rows(rw, j1 - j0, options.tile_rays, steps=1)]
        skipped = [(0, j0)] if j0 > 0 and options.jitter else []
        timings: dict[str, float] = {"compile": 0.0, "execute": 0.0, "jitter": 0.0, "filter": 0.0}
        buf = PassBuffers(color=np.empty((j1 - j0, rw, 3), np.float32),
                          normal=np.empty((j1 - j0, rw, 3), np.float32) if options.normals else None,
                          dist=np.empty((j1 - j0, rw), np.float32) if options.depth is not None else None, row0=j0)
        tiles = main_tiles(rw, skipped + rows, options.seed, options.jitter, timings, options.of_layer(JITTER_MISTAKES))
        if skipped:
            next(tiles)
        t0 = time.perf_counter()
        ctx = TraceContext(mi_scene, camera, integrator, camera_rays, (rw, rh), timings, None,
                           rw * (j1 - j0), options.spp, options.seed or 0)
        trace_pass(ctx, tiles, buf, 0)
        timings["render"] = time.perf_counter() - t0
    assert buf.color is not None
    return Band(j0, j1, buf.color, buf.normal, buf.dist, buf.counts, buf.kernels, timings,
                _dispersive(integrator))


def assemble(options: RenderOptions, bands: list[Band], timings: dict[str, float] | None = None) -> RenderResult:
    """The :class:`RenderResult` of bands covering the render buffer (any order, no overlap): colour rows in
    bottom-up order into the buffer or the streamed ``-filter`` (the same float32 operations as
    :func:`render_scene`, so the image is bit for bit its image), AOVs, summed counts and launches."""
    options = _sampling(options)
    rw, rh = options.render_size
    main, aov = _pass_buffers(options, separate=False)
    ordered = sorted(bands, key=lambda b: b.j0)
    if [b.j0 for b in ordered] != [0, *(b.j1 for b in ordered[:-1])] or ordered[-1].j1 != rh:
        raise ValueError(f"bands {[(b.j0, b.j1) for b in ordered]} do not cover rows 0..{rh}")
    timings = {"compile": 0.0, "execute": 0.0, "jitter": 0.0, "filter": 0.0, **(timings or {})}
    for b in ordered:
        if main.stream is not None:
            t0 = time.perf_counter()
            main.stream.push(b.color)
            timings["filter"] += time.perf_counter() - t0
        else:
            assert main.color is not None
            main.color[b.j0:b.j1] = b.color
        if aov.normal is not None and b.normal is not None:
            aov.normal[b.j0:b.j1] = b.normal
        if aov.dist is not None and b.dist is not None:
            aov.dist[b.j0:b.j1] = b.dist
        for k, v in b.counts.items():
            main.counts[k] = main.counts.get(k, 0) + v
        for k, v in b.kernels.items():
            main.kernels[k] = main.kernels.get(k, 0) + v
        for k in ("compile", "execute", "jitter"):
            timings[k] += b.timings.get(k, 0.0)
    return _result(options, main, aov, False, len(ordered), rw * rh, timings,
                   clip=any(b.clip for b in ordered))
