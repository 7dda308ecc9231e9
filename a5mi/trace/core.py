"""``a5mi trace``: the ray trees behind one output pixel, checked against the real render (SPEC B.2, B.3, B.5).

Pixel ``(x, y)`` counts from the top-left of the **pixel grid**: the ``-size`` grid ``W x H``, except with
``-filter`` alone, whose saved image is ``W/3 x H/3`` (SPEC B.5). Its samples in the render buffer
(``RW x RH``, row ``j = 0`` at the bottom, :mod:`a5mi.render.driver`):

* neither flag: the one sample ``(x, H-1-y)``;
* ``-jitter`` and/or ``-filter``: the 3x3 block ``(3x+dx, 3(GH-1-y)+dy)``, sub-sample ``K = 3·(2-dy) + dx``
  (row-major from the block's top-left); with ``-jitter`` each ray goes through ``i + jx, j + jy`` with the
  sample's glibc offsets (stream position ``j·RW + i``, :func:`a5mi.render.tiles.jitter_stream`);
* ``-filter``: the output pixel is ``Σ w_s · c_s`` over the samples ``s`` the blur + 3x3 downsample reads,
  ``w_s = (1/9) Σ_block Σ_{a,b} K[a] K[b]`` over the taps whose clamped position is ``s`` (:func:`filter_weights`).

Every needed sample is traced in one record-mode launch of ``a5_whitted`` (the render kernel with the
recorder of plugins/kernel/record.py), and the same scene is rendered by
:func:`a5mi.render.driver.render_scene`;
:class:`PixelTrace` carries both so the report can show that the trees' sums are the image's pixels.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from a5mi.platform.errors import UsageError
from a5mi.render.options import RenderOptions
from a5mi.spec import JITTER_FACTOR
from a5mi.trace.tree import RayTree, build_trees

#: Most nodes recorded per camera ray (a full tree of 9 bounces); deeper trees are reported as cut.
MAX_NODES = 1023
#: Most floats of record buffers per launch (128 MiB); more samples are traced in several launches.
RECORD_FLOATS = 1 << 25


class TraceError(UsageError):
    """A pixel outside the image, ``--sample`` without ``-jitter``, a student image of another size."""


def pixel_grid(options: RenderOptions) -> tuple[int, int]:
    """Size of the image ``-pixel`` addresses: the saved image, or the ``-size`` grid with ``-jitter`` alone."""
    if options.filter and not options.jitter:
        return options.width // JITTER_FACTOR, options.height // JITTER_FACTOR
    return options.width, options.height


def to_top_left(options: RenderOptions, x: int, y: int, origin: str) -> tuple[int, int]:
    """``(x, y)`` from the top-left; ``origin="bottom-left"`` (the binary's ``j``) flips y. Checks the range."""
    gw, gh = pixel_grid(options)
    yt = gh - 1 - y if origin == "bottom-left" else y
    if not (0 <= x < gw and 0 <= yt < gh):
        raise TraceError(f"-pixel {x} {y} ({origin}) is outside the {gw}x{gh} image")
    return x, yt


def block_samples(options: RenderOptions, x: int, y: int) -> list[tuple[int, int]]:
    """Render-buffer samples ``(i, j)`` (j from the bottom) of pixel ``(x, y)`` (top-left), in sub-sample order K."""
    if not (options.jitter or options.filter):
        return [(x, options.height - 1 - y)]
    gh = pixel_grid(options)[1]
    jb = JITTER_FACTOR * (gh - 1 - y)
    return [(JITTER_FACTOR * x + dx, jb + dy) for dy in (2, 1, 0) for dx in range(3)]


def filter_weights(options: RenderOptions, x: int, y: int) -> dict[tuple[int, int], float]:
    """SPEC B.5 weights of the render-buffer samples feeding output pixel ``(x, y)`` (top-left) under ``-filter``:
    blur (y pass then x pass, taps clamped to each axis) then the 3x3 box downsample (/9)."""
    from a5mi.render.filters import kernel_taps

    taps = kernel_taps(options.kernel).astype(np.float64)
    rw, rh = options.render_size
    out: dict[tuple[int, int], float] = {}
    for i, j in block_samples(options, x, y):
        for a in range(5):
            jj = min(max(j + a - 2, 0), rh - 1)
            for b in range(5):
                ii = min(max(i + b - 2, 0), rw - 1)
                out[(ii, jj)] = out.get((ii, jj), 0.0) + taps[a] * taps[b] / 9.0
    return out


@dataclass
class PixelTrace:
    """What ``a5mi trace`` found for one pixel. ``samples``: render-buffer ``(i, j)`` of the trees, ``x_pix,
    y_pix`` the coordinates their camera rays went through; ``trees[k]`` the ray tree of ``samples[k]``;
    ``rendered[k]``: the real render's value of that sample (float32); ``weights``: filter weights per sample
    (empty without ``-filter``); ``value`` the output pixel the trees give, ``image_value`` / ``image_byte``
    the real saved image's pixel (float, 8-bit)."""

    x: int
    y: int
    grid: tuple[int, int]
    options: RenderOptions
    samples: list[tuple[int, int]]
    x_pix: list[float]
    y_pix: list[float]
    trees: list[RayTree]
    rendered: list[tuple[float, float, float]]
    block: list[int]
    weights: dict[tuple[int, int], float] = field(default_factory=dict)
    value: tuple[float, float, float] = (0.0, 0.0, 0.0)
    image_value: tuple[float, float, float] = (0.0, 0.0, 0.0)
    image_byte: tuple[int, int, int] = (0, 0, 0)

    @property
    def max_error(self) -> float:
        """Largest |tree sum - rendered sample| over the traced samples (float32 sums: 0 when they agree)."""
        return max(float(np.max(np.abs(t.contribution_sum() - np.array(r, np.float32))))
                   for t, r in zip(self.trees, self.rendered, strict=True))

    @property
    def value_error(self) -> float:
        """|value the trees give - the saved image's pixel| (with ``-filter``: the float64 weighted sum against
        the filter's float32 arithmetic, so about 1e-7 rather than 0)."""
        return float(np.max(np.abs(np.array(self.value) - np.array(self.image_value))))

    @property
    def value_byte(self) -> tuple[int, int, int]:
        from a5mi.platform.imageio import quantize

        return tuple(int(v) for v in quantize(np.array(self.value, np.float32))[..., :3].ravel())  # type: ignore


class Tracer:
    """A loaded scene and its integrator for tracing pixels and rendering the reference image once."""

    def __init__(self, desc: Any, options: RenderOptions) -> None:
        from a5mi.render.session import build_scene

        self.desc = desc
        self.options = dataclasses.replace(options, normals=False, depth=None, classes=False, count_rays=False)
        self.scene = build_scene(desc, self.options)
        self.integrator = self.scene.integrator()
        self._raw: np.ndarray | None = None
        self._image: np.ndarray | None = None

    # ----------------------------------------------------------------------------- the real render
    def image(self) -> np.ndarray:
        """The saved image the options give (float32, row 0 = top), rendered once by the driver."""
        from a5mi.render import driver

        if self._image is None:
            self._image = driver.render_scene(self.scene, self.desc.camera, self.options).image
            if not self.options.filter:
                self._raw = self._image
        return self._image

    def raw(self) -> np.ndarray:
        """The render buffer (RW x RH, row 0 = top) before any filter, rendered once by the driver."""
        from a5mi.render import driver

        if self._raw is None:
            if not self.options.filter:
                return self.image()
            self._raw = driver.render_scene(self.scene, self.desc.camera,
                                            dataclasses.replace(self.options, filter=False)).image
        return self._raw

    # ----------------------------------------------------------------------------- record mode
    def coords(self, samples: list[tuple[int, int]]) -> tuple[np.ndarray, np.ndarray]:
        """float32 ``x_pix, y_pix`` of render-buffer samples: as :mod:`a5mi.render.driver` (``i + jx``, ``j + jy``)."""
        i = np.array([s[0] for s in samples], np.float32)
        j = np.array([s[1] for s in samples], np.float32)
        if not self.options.jitter:
            return i, j
        from a5mi.render.tiles import jitter_stream

        rw = self.options.render_size[0]
        pos = np.array([s[1] * rw + s[0] for s in samples], np.int64)
        jx, jy = jitter_stream(self.options.seed, total=int(pos.max()) + 1)(int(pos.max()) + 1)
        return i + jx[pos], j + jy[pos]

    def trees(self, samples: list[tuple[int, int]]) -> tuple[list[RayTree], np.ndarray, np.ndarray]:
        """The ray trees of render-buffer samples, from record-mode launches of the render kernel (as many
        samples per launch as keep the record buffers under :data:`RECORD_FLOATS` floats)."""
        from a5mi.plugins.kernel.record import LIGHT_STRIDE, NODE_STRIDE

        xs, ys = self.coords(samples)
        max_nodes = min(2 ** (self.options.bounces + 1) - 1, MAX_NODES)
        per_lane = max_nodes * (NODE_STRIDE + max(1, len(self.desc.lights)) * LIGHT_STRIDE)
        chunk = max(1, RECORD_FLOATS // per_lane)
        trees: list[RayTree] = []
        for k in range(0, len(samples), chunk):
            trees += self._record(xs[k:k + chunk], ys[k:k + chunk], max_nodes)
        return trees, xs, ys

    def _record(self, xs: np.ndarray, ys: np.ndarray, max_nodes: int) -> list[RayTree]:
        import drjit as dr
        import mitsuba as mi

        from a5mi.platform.arrays import aligned_float32
        from a5mi.plugins.kernel.record import TreeRecorder
        from a5mi.plugins.sensors.camera import camera_rays

        rw, rh = self.options.render_size
        cam = self.desc.camera
        ray = camera_rays(cam.center, cam.direction, cam.up, cam.angle, mi.Float(aligned_float32(xs)),
                          mi.Float(aligned_float32(ys)), rw, rh)
        rec = TreeRecorder(len(xs), max_nodes, len(self.desc.lights))
        color = self.integrator.trace(self.scene, ray, mi.Bool(True), record=rec)[0]
        dr.eval(color)
        nodes, lights, counts = rec.read()
        colors = np.asarray(color).T.reshape(len(xs), 3)
        return build_trees(nodes, lights, counts, colors, self.desc, self.scene, self.integrator)

    def pixels(self, pixels: list[tuple[int, int]]) -> list[PixelTrace]:
        """:class:`PixelTrace` of each pixel ``(x, y)`` (top-left of :func:`pixel_grid`), traced in one launch."""
        opts = self.options
        gw, gh = pixel_grid(opts)
        for x, y in pixels:
            if not (0 <= x < gw and 0 <= y < gh):
                raise TraceError(f"pixel ({x}, {y}) is outside the {gw}x{gh} image")
        plans = []
        wanted: dict[tuple[int, int], int] = {}
        for x, y in pixels:
            block = block_samples(opts, x, y)
            weights = filter_weights(opts, x, y) if opts.filter else {}
            samples = block + [s for s in weights if s not in block]
            plans.append((x, y, block, weights, samples))
            for s in samples:
                wanted.setdefault(s, len(wanted))
        order = list(wanted)
        trees, xs, ys = self.trees(order)
        raw, image = self.raw(), self.image()
        rh = opts.render_size[1]
        out = []
        for x, y, block, weights, samples in plans:
            idx = [wanted[s] for s in samples]
            rendered = [tuple(float(c) for c in raw[rh - 1 - j, i]) for i, j in samples]
            sums = [trees[k].contribution_sum().astype(np.float64) for k in idx]
            if weights:
                value = sum(weights[s] * v for s, v in zip(samples, sums, strict=True))
            elif opts.jitter:   # -jitter alone: the pixel's nine samples are nine saved pixels; show their mean
                value = np.mean(sums[:9], axis=0)
            else:
                value = sums[0]
            if opts.jitter and not opts.filter:
                img_val = raw[[rh - 1 - j for _, j in block], [i for i, _ in block]].astype(np.float64).mean(0)
            else:
                img_val = image[y, x].astype(np.float64)
            from a5mi.platform.imageio import quantize

            out.append(PixelTrace(
                x, y, (gw, gh), opts, samples, [float(xs[k]) for k in idx], [float(ys[k]) for k in idx],
                [trees[k] for k in idx], rendered, list(range(len(block))), weights,
                tuple(float(v) for v in value), tuple(float(v) for v in img_val),  # type: ignore[arg-type]
                tuple(int(b) for b in quantize(img_val.astype(np.float32)).ravel()[:3])))  # type: ignore[arg-type]
        return out
