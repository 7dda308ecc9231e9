"""The render driver: camera rays, jitter, tiles, AOV images, post-filter (SPEC B.2, B.5, B.6).

:func:`render` turns a parsed scene (``a5mi.converters.model``) into a float image the way ``a5soln`` does:

* render buffer ``RW x RH`` = ``3W x 3H`` with ``-jitter``, else ``W x H`` (SPEC B.5);
* sample ``(i, j)``, ``j = 0`` the bottom row, visited rows bottom-up; its camera ray goes through
  ``x_pix = i + jx``, ``y_pix = j + jy`` (float32) of :func:`a5mi.plugins.camera.camera_rays` (SPEC B.2);
* jitter: per sample ``r1 = rand(); r2 = rand()``, ``jy = (float)r1·2^-31 - 0.5`` first, then ``jx``, from
  glibc's seed-1 stream (:mod:`a5mi.glibc_rand`); ``seed`` selects numpy's PCG64 instead;
* ``integrator.sample(scene, sampler, ray, None, active)`` of ``a5_whitted`` gives the colour and the AOVs
  ``[nx, ny, nz, t]``, in tiles of whole rows (:func:`tile_rows`: at most ``tile_rays`` rays, about
  :data:`PROGRESS_STEPS` per render when a progress callback is given, each starting on a multiple of
  :data:`PACKET_ALIGN` samples so the image does not depend on the tile size; one kernel, compiled once and
  reused);
* ``-filter``: blur + 3x3 downsample (:mod:`a5mi.filters`) of the render buffer, streamed tile by tile
  (:class:`a5mi.filters.FilterStream`): the full-size colour buffer is never held, so with ``-jitter
  -filter`` memory is bounded by the tile size plus the W x H output, not by the 3W x 3H buffer;
* pixel coordinates are handed to Dr.Jit in 64-byte-aligned arrays: ``mi.Float(numpy)`` maps numpy memory
  without copying and the kernel's load alignment (part of its hash) follows the address, so unaligned
  arrays recompiled the render kernel at random;
* ``-normals``: ``|N|`` per component; ``-depth dmin dmax``: gray ``1`` if ``t <= dmin``, ``0`` if
  ``t >= dmax`` or ``dmin >= dmax``, else ``1 - (t - dmin)/(dmax - dmin)`` (SPEC B.6), both at the render
  buffer's resolution, unfiltered, traced with the main image's rays (``aov_mode="quadrant"``: with the
  binary's top-right-quadrant rays instead, a second pass);
* ``classes`` (:attr:`RenderOptions.classes`): the ``class`` AOV of ``a5_whitted`` per sample of the main
  pass (0 the camera ray misses, 1 opaque, 2 the SPEC B.3 ray tree touches a material with
  ``refraction_index > 0``), uint8 at the render buffer's resolution, unfiltered.

AOVs are read from the integrator **by name** (``dict(zip(integrator.aov_names(), aovs))``).

Images in :class:`RenderResult` have row 0 = the **top** row (ready for :func:`a5mi.imageio.write_image`).
This module never prints: progress goes through a callback.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from a5mi import interrupts
from a5mi.arrays import aligned_float32  # noqa: F401 - re-exported (warm scenes, trace, bench)
from a5mi.filters import FilterStream, postprocess
from a5mi.glibc_rand import glibc_stream, jitter_offsets
from a5mi.options import TILE_RAYS, RenderOptions  # noqa: F401 - re-exported
from a5mi.passes import sample_passes

Progress = Callable[[int, int], None]  # (samples done, samples total)
CameraRays = Callable[..., Any]  # a5mi.plugins.camera.camera_rays
#: docs/EXTENSIONS.md E.12: ``hook(k)`` updates the scene for pass ``k`` of ``spp`` and returns its camera
PassHook = Callable[[int], Any]


@dataclass
class RenderResult:
    """The saved image and the AOV images (float32 HxWx3, row 0 = top) plus statistics; ``classes``
    (uint8 RHxRW, row 0 = top) is the ``class`` AOV when :attr:`RenderOptions.classes` asked for it.

    ``timings`` (seconds): ``build`` (dict + ``mi.load_dict``), ``compile`` (Dr.Jit codegen + LLVM),
    ``execute`` (kernels), ``render`` (wall time of the tile loop, without the filter), ``jitter`` (offset
    generation, mostly overlapped with rendering), ``filter`` (blur + downsample, streamed per tile).
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


def depth_gray(t: npt.ArrayLike, dmin: float, dmax: float) -> npt.NDArray[np.float32]:
    """SPEC B.6: 1 if ``t <= dmin``; 0 if ``t >= dmax`` or ``dmin >= dmax``; else ``1 - (t-dmin)/(dmax-dmin)``."""
    t = np.asarray(t, dtype=np.float32)
    dmin32, dmax32 = np.float32(dmin), np.float32(dmax)
    with np.errstate(invalid="ignore", divide="ignore"):
        ramp = np.float32(1.0) - (t - dmin32) / (dmax32 - dmin32)
    return np.select(
        [t <= dmin32, (t >= dmax32) | (dmin32 >= dmax32) | np.isnan(t)], [np.float32(1), np.float32(0)], ramp
    ).astype(np.float32)


# --------------------------------------------------------------------------------------------------------
# Jitter offsets, tile by tile
# --------------------------------------------------------------------------------------------------------


def jitter_stream(seed: int | None, total: int | None = None) -> Callable[[int], tuple[np.ndarray, np.ndarray]]:
    """A function ``next(n) -> (jx, jy)`` giving the offsets of the next ``n`` samples (SPEC B.5 order).

    ``seed=None``: glibc ``rand()`` from seed 1 (r1 -> jy first, r2 -> jx), its fixed prefix read from the
    disk cache of :func:`a5mi.glibc_rand.glibc_stream`; else numpy's PCG64 with that seed, also drawn in
    (jy, jx) pairs so a sample's offsets do not depend on the tile size. ``total``: the number of samples
    that will be drawn, if known (small renders skip the disk cache).
    """
    if seed is None:
        rng = glibc_stream(need=None if total is None else 2 * total)

        def glibc_next(n: int) -> tuple[np.ndarray, np.ndarray]:
            pairs = rng.next(2 * n).reshape(n, 2)
            return jitter_offsets(pairs[:, 1]), jitter_offsets(pairs[:, 0])

        return glibc_next
    gen = np.random.default_rng(seed)

    def numpy_next(n: int) -> tuple[np.ndarray, np.ndarray]:
        pairs = gen.random((n, 2), dtype=np.float32) - np.float32(0.5)
        return np.ascontiguousarray(pairs[:, 1]), np.ascontiguousarray(pairs[:, 0])

    return numpy_next


#: Tiles start on a sample index that is a multiple of this (every SIMD packet width of Dr.Jit's LLVM backend
#: divides it: 4, 8, 16). Some sample's result depends, in the last bits, on which samples share its SIMD packet
#: (seen on scene10 at 30x30 -jitter, 8-wide AVX2: one pixel off by 2.8e-5 whenever a tile started off an
#: 8-sample boundary, none when it started on one). Narrowed down: it stays without the cube mesh, the glass,
#: the cube map or -bounces (0), and goes with -shadows off, so it is a shadow test (Mitsuba's ray queries in
#: plugins/octree_rule.occluded) flipping for one grazing sample whose light term is 2.8e-5; which query
#: depends on its packet was not isolated. Aligned tiles keep every packet as in a one-launch render.
PACKET_ALIGN = 64
#: With a progress callback, a render of many samples is split into about this many tiles (points where the
#: progress bar learns the render's rate); without one it is one tile up to ``tile_rays`` ...
PROGRESS_STEPS = 4
#: ... of at least this many samples each: every launch re-traces the integrator in Python (about 50-90 ms
#: for the course scenes on the shared 2-core machine), so finer tiles would cost more than they show; the
#: bar moves between tiles on the measured rate (a5mi.cli.app.ProgressBar).
MIN_TILE_RAYS = 1 << 18


def tile_rows(rw: int, rh: int, tile_rays: int, *, align: int | None = None,
              steps: int | None = None) -> list[tuple[int, int]]:
    """Row ranges ``[j0, j1)`` (bottom-up) of the ``rw x rh`` render buffer, one per kernel launch.

    Rows per tile: ``max(1, target // rw)`` with ``target = min(tile_rays, max(MIN_TILE_RAYS, ceil(rw·rh /
    steps)))`` (``steps`` = :data:`PROGRESS_STEPS`), rounded down to a multiple of ``m = align / gcd(rw,
    align)`` (``align`` = :data:`PACKET_ALIGN`) and at least ``m``, then evened out (the same number of tiles,
    ``ceil(rh / count)`` rows rounded up to ``m``); a buffer that fits in one tile is one tile. Every tile
    starts on a sample index that is a multiple of ``align``: each sample then shares its SIMD packet with the
    same neighbours whatever the tile size, and the image is bit-identical for any ``tile_rays`` (a tile may
    exceed ``tile_rays`` by up to ``m`` rows when the width is odd).
    """
    align = PACKET_ALIGN if align is None else align
    steps = PROGRESS_STEPS if steps is None else steps
    target = min(tile_rays, max(MIN_TILE_RAYS, math.ceil(rw * rh / max(1, steps))))
    m = align // math.gcd(rw, align)
    rows = max(1, target // rw)
    if rows >= rh:
        return [(0, rh)]  # one launch: nothing to align
    rows = max(m, rows - rows % m)
    count = math.ceil(rh / rows)
    rows = math.ceil(math.ceil(rh / count) / m) * m  # the same number of tiles, evened out (still <= rows)
    return [(j0, min(rh, j0 + rows)) for j0 in range(0, rh, rows)]


def _pixel_coords(
    rw: int, j0: int, j1: int, jitter: tuple[np.ndarray, np.ndarray] | None
) -> tuple[np.ndarray, np.ndarray]:
    """float32 ``x_pix = i + jx``, ``y_pix = j + jy`` for rows ``j0..j1-1``, row-major (i fastest)."""
    i = np.tile(np.arange(rw, dtype=np.float32), j1 - j0)
    j = np.repeat(np.arange(j0, j1, dtype=np.float32), rw)
    if jitter is None:
        return i, j
    jx, jy = jitter
    return i + jx, j + jy


def _tiles_with_jitter(
    rw: int, tiles: list[tuple[int, int]], seed: int | None, enabled: bool, timings: dict[str, float]
) -> Iterator[tuple[int, int, tuple[np.ndarray, np.ndarray] | None]]:
    """Yield tiles with their offsets; the next tile's offsets are computed in a worker thread while the
    current tile renders (numpy's BLAS and Dr.Jit's kernels both release the GIL)."""
    if not enabled:
        for j0, j1 in tiles:
            yield j0, j1, None
        return
    draw = jitter_stream(seed, total=rw * sum(j1 - j0 for j0, j1 in tiles))

    def timed(n: int) -> tuple[np.ndarray, np.ndarray]:
        t0 = time.perf_counter()
        out = draw(n)
        timings["jitter"] = timings.get("jitter", 0.0) + time.perf_counter() - t0
        return out

    with ThreadPoolExecutor(max_workers=1) as pool:
        pending: Future[tuple[np.ndarray, np.ndarray]] = pool.submit(timed, (tiles[0][1] - tiles[0][0]) * rw)
        for k, (j0, j1) in enumerate(tiles):
            current = pending.result()
            if k + 1 < len(tiles):
                nj0, nj1 = tiles[k + 1]
                pending = pool.submit(timed, (nj1 - nj0) * rw)
            yield j0, j1, current


# --------------------------------------------------------------------------------------------------------
# Rendering
# --------------------------------------------------------------------------------------------------------


def _default_camera_rays() -> CameraRays:
    from a5mi.plugins.camera import camera_rays

    return camera_rays


def quadrant_coords(rw: int, rh: int, j0: int, j1: int) -> tuple[np.ndarray, np.ndarray]:
    """``x_pix``, ``y_pix`` of the sample solution's AOV rays (SPEC B.6 compatibility, ``aov_mode="quadrant"``).

    Pixel (X, Y) uses the camera-plane point ``p = ((X+0.5-W/2)/max(W,H) + 0.5, (Y+0.5-H/2)/max(W,H) + 0.5)``
    in [0, 1] directly as B.2's ``(x, y)`` in [-1, 1] (only the top-right quadrant, magnified 2x). Expressed as
    pixel coordinates of :func:`camera_rays`: ``x_pix = (p_x + 1)(W-1)/2`` (likewise y), in float64 then
    rounded to float32, so the rays agree with the binary's to float precision, not bit for bit.
    """
    m = float(max(rw, rh))
    xs = (np.arange(rw) + 0.5 - rw / 2) / m + 0.5
    ys = (np.arange(j0, j1) + 0.5 - rh / 2) / m + 0.5
    x_pix = ((xs + 1.0) * (rw - 1) / 2.0).astype(np.float32)
    y_pix = ((ys + 1.0) * (rh - 1) / 2.0).astype(np.float32)
    return np.tile(x_pix, j1 - j0), np.repeat(y_pix, rw)


@dataclass
class _Pass:
    """Buffers and counters of one tile loop over the render buffer. ``trace_color``: the pass computes the
    colour, stored in ``color`` (full render buffer) or pushed to ``stream`` (blur + downsample as it goes);
    ``normal``, ``dist``, ``classes``: the AOV buffers the pass fills (None: not asked for)."""

    color: np.ndarray | None
    normal: np.ndarray | None
    dist: np.ndarray | None
    stream: FilterStream | None = None
    classes: np.ndarray | None = None
    counts: dict[str, int] = field(default_factory=dict)
    kernels: dict[str, int] = field(default_factory=dict)  # launches by source: memory / disk / compiled

    @property
    def trace_color(self) -> bool:
        return self.color is not None or self.stream is not None

    @property
    def aov_names(self) -> tuple[str, ...]:
        """Names of the integrator AOVs this pass stores (``a5_whitted`` channel names)."""
        return (("nx", "ny", "nz") if self.normal is not None else ()) + (
            ("t",) if self.dist is not None else ()) + (("class",) if self.classes is not None else ())


@dataclass(frozen=True)
class _TraceContext:
    """What every tile loop of one render shares: the loaded scene, the a5 camera (``center``,
    ``direction``, ``up``, ``angle``), the integrator, the SPEC B.2 ray generator, the render buffer size
    ``(RW, RH)``, the timings being filled, the progress callback and the total number of samples."""

    scene: Any
    camera: Any
    integrator: Any
    camera_rays: CameraRays
    size: tuple[int, int]
    timings: dict[str, float]
    progress: Progress | None
    total: int
    spp: int = 1    #: docs/EXTENSIONS.md E.5: passes per pixel (a5mi/passes.py)
    seed: int = 0   #: seed of the stochastic samples
    only_pass: int | None = None  #: E.12: trace only this pass of ``spp`` (not averaged)


_COUNT_NAMES = ("reflection", "refraction", "shadow")


def _trace_pass(
    ctx: _TraceContext, tiles: Iterator[tuple[int, int, np.ndarray, np.ndarray]], buffers: _Pass, done: int
) -> int:
    """Trace every tile ``(j0, j1, x_pix, y_pix)`` (SPEC B.2 rays through ``x_pix``, ``y_pix``) and fill
    ``buffers``; ``done`` samples were traced before; returns the updated ``done``."""
    import drjit as dr
    import mitsuba as mi

    camera, integrator, timings = ctx.camera, ctx.integrator, ctx.timings
    rw, rh = ctx.size
    sampler = mi.load_dict({"type": "independent", "sample_count": 1})
    want_aov = buffers.normal is not None or buffers.dist is not None
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
        dr.kernel_history_clear()
        for j0, j1, x_pix, y_pix in tiles:
            # one tile is one step: a signal waits for its end (a5mi.interrupts), then stops the render
            with interrupts.deferred():
                n = (j1 - j0) * rw
                ray = ctx.camera_rays(
                    camera.center, camera.direction, camera.up, camera.angle,
                    mi.Float(aligned_float32(x_pix)), mi.Float(aligned_float32(y_pix)), rw, rh,
                )  # fmt: skip
                rgb, aovs = sample_passes(ctx.scene, integrator, sampler, ray, camera, j0 * rw, n, ctx.spp, ctx.seed,
                                          only=ctx.only_pass)
                named = dict(zip(integrator.aov_names(), aovs, strict=True))
                missing = [k for k in buffers.aov_names if k not in named]
                if missing:
                    raise RuntimeError(f"integrator has no AOV {', '.join(missing)} (a5_whitted 'aovs' parameter)")
                counted = [named[f"n_{k}"] for k in _COUNT_NAMES if f"n_{k}" in named] if buffers.trace_color else []
                outputs = ([rgb] if buffers.trace_color else []) + [named[k] for k in ("nx", "ny", "nz", "t")
                                                                     if k in named and want_aov]
                if buffers.classes is not None:
                    outputs.append(named["class"])
                # one kernel for everything: a reduction of an unevaluated count would trace the scene again
                dr.eval(*outputs, *counted)
                dr.sync_thread()
                if buffers.trace_color:
                    rows = np.asarray(rgb).T.reshape(j1 - j0, rw, 3)
                    if buffers.stream is not None:
                        t0 = time.perf_counter()
                        buffers.stream.push(rows)
                        timings["filter"] = timings.get("filter", 0.0) + time.perf_counter() - t0
                    else:
                        assert buffers.color is not None
                        buffers.color[j0:j1] = rows
                if buffers.normal is not None:
                    nrm = np.stack([np.asarray(named[k]) for k in ("nx", "ny", "nz")], axis=-1)
                    buffers.normal[j0:j1] = np.abs(nrm).reshape(j1 - j0, rw, 3)
                if buffers.dist is not None:
                    buffers.dist[j0:j1] = np.asarray(named["t"]).reshape(j1 - j0, rw)
                if buffers.classes is not None:
                    buffers.classes[j0:j1] = np.asarray(named["class"]).reshape(j1 - j0, rw).astype(np.uint8)
                for name, a in zip(_COUNT_NAMES, counted, strict=False):
                    buffers.counts[name] = buffers.counts.get(name, 0) + int(np.rint(np.asarray(a, np.float64)).sum())
                for entry in dr.kernel_history():
                    if entry.get("type") == dr.KernelType.JIT:  # not memsets, host functions, aggregates
                        kind = "disk" if entry.get("cache_disk") else "memory" if entry.get("cache_hit") else "compiled"
                        buffers.kernels[kind] = buffers.kernels.get(kind, 0) + 1
                    timings["execute"] += entry.get("execution_time", 0.0) / 1000.0
                    timings["compile"] += (entry.get("codegen_time", 0.0) + entry.get("backend_time", 0.0)) / 1000.0
                done += n
                if ctx.progress is not None:
                    ctx.progress(done, ctx.total)
    return done


def _trace_moving(ctx: _TraceContext, tiles: Callable[[], Iterator[tuple[int, int, np.ndarray, np.ndarray]]],
                  main: _Pass, hook: PassHook) -> None:
    """docs/EXTENSIONS.md E.12: pass ``k`` of ``spp`` traces every tile of the scene as ``hook(k)`` left it,
    with the camera it returns; the colours are summed in pass order and scaled by ``1/spp`` in float32 (the
    operations of :func:`a5mi.passes.sample_passes`, so a scene that does not move renders bit for bit as
    without the hook); AOVs and classes come from pass 0."""
    import dataclasses

    rw, rh = ctx.size
    total: np.ndarray | None = None
    done = 0
    for k in range(ctx.spp):
        camera = hook(k)
        buf = _Pass(color=np.empty((rh, rw, 3), np.float32), normal=main.normal if k == 0 else None,
                    dist=main.dist if k == 0 else None, classes=main.classes if k == 0 else None,
                    counts=main.counts, kernels=main.kernels)
        done = _trace_pass(dataclasses.replace(ctx, camera=camera, only_pass=k, total=ctx.total * ctx.spp),
                           tiles(), buf, done)
        total = buf.color if total is None else total + buf.color
    assert total is not None
    if ctx.spp > 1:
        total = total * np.float32(1.0 / ctx.spp)
    if main.stream is not None:
        main.stream.push(total)
    else:
        assert main.color is not None
        main.color[...] = total


def render_scene(
    mi_scene: Any,
    camera: Any,
    options: RenderOptions,
    *,
    integrator: Any = None,
    camera_rays: CameraRays | None = None,
    progress: Progress | None = None,
    pass_hook: PassHook | None = None,
) -> RenderResult:
    """Render a loaded Mitsuba scene with the a5 camera ``camera`` (``center``, ``direction``, ``up``,
    ``angle`` in degrees). ``integrator`` defaults to ``mi_scene.integrator()``; ``camera_rays`` to
    :func:`a5mi.plugins.camera.camera_rays`. With ``aov_mode="quadrant"`` the AOV images come from a second
    pass with the sample solution's own AOV rays (:func:`quadrant_coords`). With ``options.classes`` the
    integrator must list the ``class`` AOV (``a5_whitted`` ``aovs`` including ``class``); it is read from the
    main pass into :attr:`RenderResult.classes`. ``pass_hook`` (motion blur, docs/EXTENSIONS.md E.12): called
    before each of the ``spp`` passes, which then run one after the other over the whole image
    (:func:`_trace_moving`); its camera replaces ``camera``."""
    import drjit as dr

    if options.threads is not None:
        dr.set_thread_count(options.threads)
    integrator = integrator if integrator is not None else mi_scene.integrator()
    camera_rays = camera_rays if camera_rays is not None else _default_camera_rays()
    rw, rh = options.render_size
    # progress steps only for a caller that shows them: each extra tile re-traces the integrator (~50 ms)
    tiles = tile_rows(rw, rh, options.tile_rays, steps=PROGRESS_STEPS if progress is not None else 1)
    want_aov = options.normals or options.depth is not None
    separate = want_aov and options.aov_mode == "quadrant"
    total = rw * rh * (2 if separate else 1)

    aov = _Pass(
        color=None,
        normal=np.empty((rh, rw, 3), np.float32) if options.normals else None,
        dist=np.empty((rh, rw), np.float32) if options.depth is not None else None,
    )
    if options.filter:
        main = _Pass(color=None, normal=None, dist=None, stream=FilterStream(rw, rh, options.kernel))
    else:
        main = _Pass(color=np.empty((rh, rw, 3), np.float32), normal=None, dist=None)
    if options.classes:
        main.classes = np.empty((rh, rw), np.uint8)
    if not separate:
        main.normal, main.dist = aov.normal, aov.dist
    timings: dict[str, float] = {"compile": 0.0, "execute": 0.0, "jitter": 0.0, "filter": 0.0}

    def main_tiles() -> Iterator[tuple[int, int, np.ndarray, np.ndarray]]:
        for j0, j1, jit in _tiles_with_jitter(rw, tiles, options.seed, options.jitter, timings):
            yield (j0, j1, *_pixel_coords(rw, j0, j1, jit))

    def quadrant_tiles() -> Iterator[tuple[int, int, np.ndarray, np.ndarray]]:
        for j0, j1 in tiles:
            yield (j0, j1, *quadrant_coords(rw, rh, j0, j1))

    t_start = time.perf_counter()
    ctx = _TraceContext(mi_scene, camera, integrator, camera_rays, (rw, rh), timings, progress, total,
                        options.spp, options.seed or 0)
    if pass_hook is None:
        done = _trace_pass(ctx, main_tiles(), main, 0)
    else:
        _trace_moving(ctx, main_tiles, main, pass_hook)
        done = total * ctx.spp
    if separate:
        _trace_pass(ctx, quadrant_tiles(), aov, done)
    timings["render"] = time.perf_counter() - t_start - timings["filter"]  # the streamed filter is its own stage

    if main.stream is not None:
        image = main.stream.result()
    else:
        assert main.color is not None
        image = postprocess(main.color, filter=False)
    depth_img = None
    if aov.dist is not None and options.depth is not None:
        gray = depth_gray(aov.dist, *options.depth)
        depth_img = np.ascontiguousarray(np.repeat(gray[:, :, None], 3, axis=2)[::-1])
    return RenderResult(
        image=np.ascontiguousarray(image[::-1]),
        normals=None if aov.normal is None else np.ascontiguousarray(aov.normal[::-1]),
        depth=depth_img,
        render_size=(rw, rh),
        camera_rays=total,
        tiles=len(tiles),
        timings=timings,
        ray_counts=main.counts,
        kernels={k: main.kernels.get(k, 0) + (aov.kernels.get(k, 0) if separate else 0)
                 for k in ("memory", "disk", "compiled")},
        classes=None if main.classes is None else np.ascontiguousarray(main.classes[::-1]),
    )


def build_scene(desc: Any, options: RenderOptions) -> Any:
    """``mi.load_dict(to_dict(desc, options))``: the Mitsuba scene with ``a5_whitted`` of a scene description
    (:func:`a5mi.converters.describe.describe`); no file is read here."""
    import mitsuba as mi

    from a5mi.converters.to_mitsuba import to_dict

    scene_dict = to_dict(desc, options)
    with interrupts.deferred():  # plugin constructors run inside Mitsuba's C++ loader
        return mi.load_dict(scene_dict)


def describe_if_needed(desc_or_model: Any, *, bump: bool = False) -> Any:
    """A scene description: ``desc_or_model`` itself, or :func:`~a5mi.converters.describe.describe` of a parsed
    scene (``a5mi.converters.a5_parser.parse_file``; ``bump``: with its bump and normal maps, EXTENSIONS E.7)."""
    from a5mi.converters.describe import SceneDescription, describe

    return desc_or_model if isinstance(desc_or_model, SceneDescription) else describe(desc_or_model, bump=bump)


def render(desc_or_model: Any, options: RenderOptions, *, progress: Progress | None = None) -> RenderResult:
    """Render a scene description (or a parsed scene, described here) as ``a5soln`` would (SPEC B.2, B.5).

    Needs an active JIT variant with the a5mi plugins registered (:func:`a5mi.variant.activate`).
    """
    t0 = time.perf_counter()
    desc = describe_if_needed(desc_or_model, bump=options.bump)
    mi_scene = build_scene(desc, options)
    t_build = time.perf_counter() - t0
    result = render_scene(mi_scene, desc.camera, options, progress=progress)
    result.timings["build"] = t_build
    return result
