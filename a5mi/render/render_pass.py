"""One pass over the render buffer: trace its tiles and fill the pass's buffers (SPEC B.2, B.5, B.6).

A pass visits the :class:`a5mi.render.tiles.Tile` sequence it is given; per tile, one step each:

1. :func:`camera_rays_of`: the SPEC B.2 camera rays through the tile's ``x_pix``, ``y_pix`` (float32);
2. :func:`a5mi.render.passes.sample_passes`: ``integrator.sample`` over the ``-spp`` passes (EXTENSIONS E.5), the mean
   colour and the AOVs of pass 0;
3. :func:`named_aovs`: the AOVs read **by name** (``dict(zip(integrator.aov_names(), aovs))``), every one the
   buffers need present;
4. :func:`evaluate`: one ``dr.eval`` of everything the pass keeps (one kernel per tile);
5. :meth:`PassBuffers.store`: the colour rows (stored, or pushed through the streamed ``-filter``), ``|N|`` per
   component, ``t``, the ``class`` AOV;
6. :meth:`PassBuffers.add_counts`: the ``-v`` ray totals (``n_reflection``, ``n_refraction``, ``n_shadow``);
7. :func:`account_kernels`: the tile's launches from Dr.Jit's kernel history (by cache source) and their
   compile and execution times;
8. the progress callback ``progress(samples done, samples total)``.

:func:`trace_moving` runs the passes of a moving scene one after the other over the whole buffer (E.12).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from a5mi.platform import interrupts
from a5mi.platform.arrays import aligned_float32
from a5mi.platform.loading import load_dict
from a5mi.render.filters import FilterStream
from a5mi.render.passes import sample_passes
from a5mi.render.tiles import Tile

if TYPE_CHECKING:
    import mitsuba as mi

    from a5mi.converters.model import Camera

Progress = Callable[[int, int], None]  # (samples done, samples total)
#: :func:`a5mi.plugins.sensors.camera.camera_rays`: ``(center, direction, up, angle, x_pix, y_pix, width, height)``
CameraRays = Callable[..., "mi.Ray3f"]
#: docs/EXTENSIONS.md E.12: ``hook(k)`` updates the scene for pass ``k`` of ``spp`` and returns its camera
PassHook = Callable[[int], "Camera"]

#: ``-v`` ray kinds, read from the ``n_<kind>`` AOVs of ``a5_whitted`` (its ``counts`` AOV group)
COUNT_NAMES = ("reflection", "refraction", "shadow")
#: the AOVs behind ``-normals`` and ``-depth`` (SPEC B.6)
GEOMETRY_AOVS = ("nx", "ny", "nz", "t")


@dataclass
class PassBuffers:
    """Buffers and counters of one pass over the ``RW x RH`` render buffer (row 0 = bottom). The pass computes
    the colour when ``color`` (the full render buffer) or ``stream`` (blur + downsample as it goes) is set;
    ``normal``, ``dist``, ``classes``: the AOV buffers it fills (None: not asked for)."""

    color: np.ndarray | None
    normal: np.ndarray | None
    dist: np.ndarray | None
    stream: FilterStream | None = None
    classes: np.ndarray | None = None
    counts: dict[str, int] = field(default_factory=dict)
    kernels: dict[str, int] = field(default_factory=dict)  # launches by source: memory / disk / compiled
    row0: int = 0   #: render-buffer row of the buffers' row 0 (a band of rows, a5mi.render.bands)

    @property
    def trace_color(self) -> bool:
        return self.color is not None or self.stream is not None

    @property
    def aov_names(self) -> tuple[str, ...]:
        """Names of the integrator AOVs this pass stores (``a5_whitted`` channel names)."""
        return (("nx", "ny", "nz") if self.normal is not None else ()) + (
            ("t",) if self.dist is not None else ()) + (("class",) if self.classes is not None else ())

    def eval_targets(self, rgb: Any, named: dict[str, Any]) -> tuple[list[Any], list[Any]]:
        """``(outputs, counts)``: the arrays this pass reads back, and the ray counts it sums (colour passes
        only, those the integrator reports)."""
        counted = [named[f"n_{k}"] for k in COUNT_NAMES if f"n_{k}" in named] if self.trace_color else []
        want_geometry = self.normal is not None or self.dist is not None
        outputs = ([rgb] if self.trace_color else []) + [named[k] for k in GEOMETRY_AOVS
                                                         if k in named and want_geometry]
        if self.classes is not None:
            outputs.append(named["class"])
        return outputs, counted

    def store(self, tile: Tile, rw: int, rgb: Any, named: dict[str, Any], timings: dict[str, float]) -> None:
        """Write the evaluated tile into the buffers: colour rows (the streamed filter's time added to
        ``timings["filter"]``), ``|N|`` per component (SPEC B.6), ``t``, the class as uint8."""
        j0, j1 = tile.j0 - self.row0, tile.j1 - self.row0
        if self.trace_color:
            rows = np.asarray(rgb).T.reshape(j1 - j0, rw, 3)
            if self.stream is not None:
                t0 = time.perf_counter()
                self.stream.push(rows)
                timings["filter"] = timings.get("filter", 0.0) + time.perf_counter() - t0
            else:
                assert self.color is not None
                self.color[j0:j1] = rows
        if self.normal is not None:
            nrm = np.stack([np.asarray(named[k]) for k in ("nx", "ny", "nz")], axis=-1)
            self.normal[j0:j1] = np.abs(nrm).reshape(j1 - j0, rw, 3)
        if self.dist is not None:
            self.dist[j0:j1] = np.asarray(named["t"]).reshape(j1 - j0, rw)
        if self.classes is not None:
            self.classes[j0:j1] = np.asarray(named["class"]).reshape(j1 - j0, rw).astype(np.uint8)

    def add_counts(self, counted: list[Any]) -> None:
        """Add a tile's per-lane ray counts (evaluated, float) to the totals, in :data:`COUNT_NAMES` order."""
        for name, a in zip(COUNT_NAMES, counted, strict=False):
            self.counts[name] = self.counts.get(name, 0) + int(np.rint(np.asarray(a, np.float64)).sum())


@dataclass(frozen=True)
class TraceContext:
    """What every pass of one render shares: the loaded scene, the a5 camera (``center``, ``direction``,
    ``up``, ``angle``), the integrator, the SPEC B.2 ray generator, the render buffer size ``(RW, RH)``, the
    timings being filled, the progress callback and the total number of samples."""

    scene: mi.Scene
    camera: Camera
    integrator: mi.SamplingIntegrator
    camera_rays: CameraRays
    size: tuple[int, int]
    timings: dict[str, float]
    progress: Progress | None
    total: int
    spp: int = 1    #: docs/EXTENSIONS.md E.5: passes per pixel (a5mi/render/passes.py)
    seed: int = 0   #: seed of the stochastic samples
    only_pass: int | None = None  #: E.12: trace only this pass of ``spp`` (not averaged)


def camera_rays_of(ctx: TraceContext, tile: Tile) -> mi.Ray3f:
    """SPEC B.2 rays of ``ctx.camera`` through the tile's ``x_pix``, ``y_pix``, handed to Dr.Jit in 64-byte
    aligned arrays (``mi.Float(numpy)`` maps numpy memory without copying, and the kernel's load alignment,
    part of its hash, follows the address: unaligned arrays recompiled the render kernel at random)."""
    import mitsuba as mi

    camera = ctx.camera
    rw, rh = ctx.size
    return ctx.camera_rays(camera.center, camera.direction, camera.up, camera.angle,
                           mi.Float(aligned_float32(tile.x_pix)), mi.Float(aligned_float32(tile.y_pix)), rw, rh)


def named_aovs(integrator: mi.SamplingIntegrator, aovs: list[Any], wanted: Iterable[str]) -> dict[str, Any]:
    """The integrator's AOVs by name; raises ``RuntimeError`` when one of ``wanted`` is not among them (the
    ``a5_whitted`` ``aovs`` parameter did not ask for it)."""
    named = dict(zip(integrator.aov_names(), aovs, strict=True))
    missing = [k for k in wanted if k not in named]
    if missing:
        raise RuntimeError(f"integrator has no AOV {', '.join(missing)} (a5_whitted 'aovs' parameter)")
    return named


def evaluate(outputs: list[Any], counted: list[Any]) -> None:
    """One kernel for everything the pass reads back: a reduction of an unevaluated count would trace the
    scene again. Waits for it to finish."""
    import drjit as dr

    dr.eval(*outputs, *counted)
    dr.sync_thread()


@contextmanager
def kernel_history() -> Iterator[None]:
    """Record Dr.Jit's kernel launches while the pass runs (:func:`account_kernels` drains the record)."""
    import drjit as dr

    with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
        dr.kernel_history_clear()
        yield


def account_kernels(kernels: dict[str, int], timings: dict[str, float]) -> None:
    """Drain the kernel history: count the JIT launches (not memsets, host functions, aggregates) by where the
    kernel came from (``memory``: this process's cache, ``disk``: Dr.Jit's cache folder, ``compiled``: LLVM
    ran), and add every entry's execution time to ``timings["execute"]`` and its codegen + backend time to
    ``timings["compile"]`` (seconds)."""
    import drjit as dr

    for entry in dr.kernel_history():
        if entry.get("type") == dr.KernelType.JIT:
            kind = "disk" if entry.get("cache_disk") else "memory" if entry.get("cache_hit") else "compiled"
            kernels[kind] = kernels.get(kind, 0) + 1
        timings["execute"] += entry.get("execution_time", 0.0) / 1000.0
        timings["compile"] += (entry.get("codegen_time", 0.0) + entry.get("backend_time", 0.0)) / 1000.0


def trace_pass(ctx: TraceContext, tiles: Iterable[Tile], buffers: PassBuffers, done: int) -> int:
    """Trace every tile of ``tiles`` (module docstring, steps 1-8) and fill ``buffers``; ``done`` samples were
    traced before; returns the updated ``done``."""
    rw = ctx.size[0]
    sampler = load_dict({"type": "independent", "sample_count": 1})
    with kernel_history():
        for tile in tiles:
            # one tile is one step: a signal waits for its end (a5mi.platform.interrupts), then stops the render
            with interrupts.deferred():
                n = (tile.j1 - tile.j0) * rw
                ray = camera_rays_of(ctx, tile)
                rgb, aovs = sample_passes(ctx.scene, ctx.integrator, sampler, ray, ctx.camera, tile.j0 * rw, n,
                                          ctx.spp, ctx.seed, only=ctx.only_pass)
                named = named_aovs(ctx.integrator, aovs, buffers.aov_names)
                outputs, counted = buffers.eval_targets(rgb, named)
                evaluate(outputs, counted)
                buffers.store(tile, rw, rgb, named, ctx.timings)
                buffers.add_counts(counted)
                account_kernels(buffers.kernels, ctx.timings)
                done += n
                if ctx.progress is not None:
                    ctx.progress(done, ctx.total)
    return done


def trace_moving(ctx: TraceContext, tiles: Callable[[], Iterable[Tile]], main: PassBuffers, hook: PassHook) -> None:
    """docs/EXTENSIONS.md E.12: pass ``k`` of ``spp`` traces every tile of the scene as ``hook(k)`` left it,
    with the camera it returns; the colours are summed in pass order and scaled by ``1/spp`` in float32 (the
    operations of :func:`a5mi.render.passes.sample_passes`, so a scene that does not move renders bit for bit as
    without the hook); AOVs and classes come from pass 0."""
    rw, rh = ctx.size
    total: np.ndarray | None = None
    done = 0
    for k in range(ctx.spp):
        camera = hook(k)
        buf = PassBuffers(color=np.empty((rh, rw, 3), np.float32), normal=main.normal if k == 0 else None,
                          dist=main.dist if k == 0 else None, classes=main.classes if k == 0 else None,
                          counts=main.counts, kernels=main.kernels)
        done = trace_pass(dataclasses.replace(ctx, camera=camera, only_pass=k, total=ctx.total * ctx.spp),
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
