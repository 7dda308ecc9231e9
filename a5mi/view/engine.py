"""What the live page shows, computed on the one thread that owns Mitsuba (docs/VIEW.md).

:class:`ViewEngine` holds a warm :class:`a5mi.render.session.RenderSession` and the scene file. :meth:`~ViewEngine.load`
parses and describes the scene (SPEC A; every mesh, texture and cube-map face read once, and read again on a
later load only when its file changed) and lists the files it
read for :mod:`a5mi.view.watcher`; :meth:`~ViewEngine.render` renders it with a
:class:`~a5mi.render.options.RenderOptions`
(SPEC B.1-B.5) and returns a :class:`Frame`:

* ``render_png``: the PNG file ``a5 -output X.png`` writes for the same flags (:func:`a5mi.view.png.png_bytes`:
  the encoder of :func:`a5mi.platform.imageio.write_image` on the saved image, SPEC B.1 quantisation
  ``clamp(int(255 c), 0, 255)``, float32 product truncated, without writing a checked file), byte for byte;
* the reference: ``--reference IMG`` (read once), or ``--binary PATH``'s render of the same scene with the same
  SPEC B.1 flags, run sandboxed as ``a5mi difftest`` runs it (:func:`a5mi.difftest.runner.run_binary`);
* ``compare``'s metrics of the pair (:func:`a5mi.compare.compare_arrays`: PSNR ``10 log10(255² / MSE)``, mean
  error, share of pixels > 2/255, max), its grading verdict (:func:`a5mi.grade.verdict.judge` of the share of
  pixels beyond 1/255) and the heatmap of the largest channel error (:func:`a5mi.compare.heatmap`, full scale
  :data:`a5mi.compare.DEFAULT_SCALE` levels).

:meth:`~ViewEngine.trace` is ``a5mi trace`` of one pixel (:mod:`a5mi.trace`): the ray tree recorded by the render
kernel, every term and the sum, with each hit point projected into the image (SPEC B.2 inverted:
``x = f (q·u)/(q·w)``, ``y = f (q·v)/(q·w)`` for ``q = p - eye``) and, with a reference, ``trace --diff``'s ranked
terms (:func:`a5mi.trace.report.explain`). Nothing here prints; failures are exceptions.
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import tempfile
import time
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from a5mi.platform.errors import UserError
from a5mi.render.options import RenderOptions
from a5mi.view.binary import binary_argv, scene_inputs, staged_links
from a5mi.view.png import png_bytes

#: Largest render buffer (samples) rendered without per-tile progress: each progress step re-traces the
#: integrator (about 50 ms), so small renders report their stages only.
QUIET_SAMPLES = 1 << 20
#: A render whose work estimate (a5mi.render.estimate) is over a minute (``WARN_SECONDS``, the one ``a5`` warns
#: for) reports every tile and is cut into up to this many tiles of equal estimated work, so that a newer
#: request pre-empts it at the next tile (a5mi.view.live). Not for shorter ones: each launch re-traces the
#: integrator (~50-90 ms), and 57 tiles of scene10 at 300 x 300 with -jitter took 20 s against 4 s in one.
MAX_STEPS = 16


@dataclass
class Frame:
    """One rendered state of the page: ``version`` counts renders; PNG bytes of the render, the reference and
    the heatmap (None without a reference); ``metrics`` (compare's figures and the verdict) or
    ``reference_error`` (why there is no comparison); ``seconds`` per stage."""

    version: int
    options: RenderOptions
    image: np.ndarray
    render_png: bytes
    size: tuple[int, int]
    reference_png: bytes | None = None
    diff_png: bytes | None = None
    metrics: dict[str, Any] | None = None
    reference_error: str | None = None
    reference_levels: np.ndarray | None = None
    seconds: dict[str, float] = field(default_factory=dict)
    #: a quick image shown before the full one (:func:`preview_options`), never compared
    preview: bool = False
    #: the render's kernel launches by where the kernel came from (:attr:`a5mi.render.driver.RenderResult.kernels`)
    kernels: dict[str, int] = field(default_factory=dict)
    #: a composite (:mod:`a5mi.view.region`): ``{"region": [X0, X1, Y0, Y1], "base": ...}``, the marked region at
    #: full quality pasted on another image, never compared; None: the image is one render's
    composite: dict[str, Any] | None = None


def preview_options(options: RenderOptions) -> RenderOptions | None:
    """The options of the page's preview of a render with ``options``: one ray per pixel, W x H, neither
    ``-jitter`` nor ``-filter`` nor E.5 passes (the image ``a5`` writes without those flags, about a ninth of the
    samples); None where the render is that already or its integrator is not SPEC B.3's Whitted tracer (the others
    build per-scene maps or caches that a preview would pay for twice)."""
    if options.integrator != "whitted" or not (options.jitter or options.filter or options.spp > 1):
        return None
    return dataclasses.replace(options, jitter=False, filter=False, spp=1)


def render_stages(timings: dict[str, float]) -> dict[str, float]:
    """The render's stages (seconds) from :attr:`a5mi.render.driver.RenderResult.timings`: ``build`` (the Mitsuba
    objects, 0 when kept), ``compile`` (Dr.Jit codegen + LLVM), ``execute`` (the kernels), ``trace`` (the rest
    of the tile loop: the Python trace of the integrator that builds the kernel's IR, the camera rays, the
    buffer copies) and ``filter`` (-filter's blur and downsample)."""
    out = {k: timings.get(k, 0.0) for k in ("build", "compile", "execute", "filter")}
    out["trace"] = max(0.0, timings.get("render", 0.0) - out["compile"] - out["execute"])
    return out


def project(camera: Any, options: RenderOptions, image_size: tuple[int, int], p: Any) -> list[float] | None:
    """Where the world point ``p`` lies in the saved image (x right, y down, pixel centres at integers), by
    inverting SPEC B.2's camera ray ``d = f w + x u + y v`` (module docstring); None behind the eye."""
    from a5mi.plugins.sensors.camera import camera_basis, focal_factor

    w, u, v = (np.asarray(a, np.float64) for a in camera_basis(camera.direction, camera.up))
    q = np.asarray(p, np.float64) - np.asarray(camera.center, np.float64)
    depth = float(q @ w)
    if not depth > 1e-9:
        return None
    f = float(focal_factor(camera.angle))
    x, y = f * float(q @ u) / depth, f * float(q @ v) / depth
    rw, rh = options.render_size
    i, j = (x + 1.0) * 0.5 * (rw - 1), (y + 1.0) * 0.5 * (rh - 1)
    sx, sy = image_size[0] / rw, image_size[1] / rh
    return [(i + 0.5) * sx - 0.5, (rh - 1 - j + 0.5) * sy - 0.5]


class ViewEngine:
    """The scene file, its description and the warm session (module docstring). ``reference``: an image
    path; ``binary``: a :class:`a5mi.difftest.runner.Binary`; ``timeout``: seconds a binary run may take."""

    def __init__(self, scene: str, session: Any, *, reference: str | None = None, binary: Any = None,
                 timeout: float = 60.0, force: bool = False) -> None:
        self.scene = scene
        #: ``-force``: render even when the work estimate is over an hour (else a positioned scene error)
        self.force = force
        self.session = session
        self.reference, self.binary, self.timeout = reference, binary, timeout
        self.desc: Any = None
        self.bump = False
        self.warnings: list[str] = []
        self.inputs: list[Path] = [Path(scene).absolute()]
        self.loaded_at = 0
        self.frame: Frame | None = None
        self._versions = 0
        self._ref_image: np.ndarray | None = None
        self._ref_png: tuple[np.ndarray, bytes] | None = None
        #: images and OBJ meshes read by earlier loads, kept while their files stay (converters.files.KeptFiles)
        from a5mi.converters.files import KeptFiles

        self._kept = KeptFiles()
        self._meshes = self._kept.meshes
        self._binary_cache: dict[tuple[int, tuple[str, ...]], np.ndarray] = {}
        self._scratch = tempfile.mkdtemp(prefix="a5mi-view-")
        # removed by close(), else when the engine is collected or the interpreter exits (an engine a caller
        # forgot to close left its folder in /tmp)
        self._remove_scratch = weakref.finalize(self, shutil.rmtree, self._scratch, ignore_errors=True)

    def close(self) -> None:
        """Remove the scratch folder of the PNG encodings."""
        self._remove_scratch()

    # ------------------------------------------------------------------------------------------ the scene
    def load(self, bump: bool | None = None) -> None:
        """Parse and describe the scene file (SPEC A; ``bump``: with its bump and normal maps, EXTENSIONS E.7;
        None: as last time); raises the positioned :class:`~a5mi.converters.errors.SceneError` and keeps the
        last good description. The watched files grow by what this description read (a missing mesh stays
        watched, so creating it reloads)."""
        from a5mi.converters.a5_parser import parse_file
        from a5mi.converters.describe import describe

        started = self._kept.begin()
        try:
            model = parse_file(self.scene)
        except OSError as exc:
            raise UserError(f"cannot read '{self.scene}': {exc.strerror or exc}") from None
        bump = self.bump if bump is None else bump
        try:
            desc = describe(model, bump=bump, decoded=self._kept.decoded, meshes=self._kept.meshes)
        finally:
            self._kept.end(started)
        self._kept.keep_meshes({getattr(s, "obj_file", None) for s in desc.shapes})
        self.inputs = list(dict.fromkeys([*self.inputs, *scene_inputs(desc, model)]))
        if self.desc is not None:
            self.session.forget(self.desc)
        self.desc, self.bump = desc, bump
        self.warnings = [f"{loc}: warning: {msg}" for loc, msg in [*model.warnings, *desc.warnings]]
        self.loaded_at += 1

    def watch_on_error(self) -> list[Path]:
        """What to watch after a failed load: the files read so far, and the scene's folder and the working
        directory (their mtime changes when a missing mesh or texture is created there)."""
        return list(dict.fromkeys([*self.inputs, Path(self.scene).absolute().parent, Path.cwd()]))

    # ------------------------------------------------------------------------------------------ rendering
    @property
    def compares(self) -> bool:
        """Whether frames are compared with a reference (``--reference`` or ``--binary``)."""
        return self.reference is not None or self.binary is not None

    def render(self, options: RenderOptions, progress: Callable[[str, int, int], None] | None = None, *,
               preview: bool = False, compare: bool = True) -> Frame:
        """Render the loaded description with ``options`` and compare it with the reference (module docstring);
        ``preview``: the frame is a preview (:func:`preview_options`), not compared; ``compare=False``: compared
        later by :meth:`compare`. ``progress(stage, done, total)``: stage ``render`` (``preview``) per tile for
        large renders, then ``reference``, ``compare``. ``Frame.seconds``: ``render`` (wall) and its
        :func:`render_stages`, ``png``, ``reference``, ``compare``."""
        if self.desc is None or options.bump != self.bump:
            self.load(options.bump)
        from a5mi.converters.errors import SceneError
        from a5mi.render import estimate as est

        opts = options
        seconds: dict[str, float] = {}
        t0 = time.perf_counter()
        rw, rh = opts.render_size
        work = est.estimate(self.desc, opts)
        if work.seconds > est.REFUSE_SECONDS and not self.force:
            raise SceneError(est.refusal(work), work.loc)
        long = work.seconds > est.WARN_SECONDS
        run = opts
        if long:  # MAX_STEPS tiles
            run = dataclasses.replace(opts, tile_rays=est.progress_tile_rays(work, opts, tile_seconds=1.0,
                                                                             max_tiles=MAX_STEPS))
        stage = "preview" if preview else "render"
        summary = est.summary(work)

        def status(done: int, total: int) -> dict[str, Any]:
            elapsed = time.perf_counter() - t0
            eta = elapsed * (total - done) / done if done else max(work.seconds - elapsed, 0.0)
            return {"rays": work.rays * done / max(total, 1), "eta": eta, "estimate": summary}

        tiles = (lambda d, t: progress(stage, d, t, **status(d, t))) if progress and (
            rw * rh > QUIET_SAMPLES or long) else None
        if progress:
            progress(stage, 0, rw * rh, **status(0, rw * rh))
        result = self.session.render(self.desc, run, progress=tiles)
        seconds["render"] = time.perf_counter() - t0
        seconds.update(render_stages(result.timings))
        t0 = time.perf_counter()
        frame = self.frame_of(opts, result.image, preview=preview, kernels=dict(result.kernels))
        seconds["png"] = time.perf_counter() - t0
        frame.seconds = seconds
        if compare and not preview:
            self.compare(frame, progress)
        self.frame = frame
        return frame

    def frame_of(self, options: RenderOptions, image: np.ndarray, **extra: Any) -> Frame:
        """A new :class:`Frame` (the next version) of the saved ``image`` with its PNG bytes; ``extra``: its other
        fields."""
        h, w = image.shape[:2]
        return Frame(self.new_version(), options, image, png_bytes(image, self._scratch), (w, h), **extra)

    def new_version(self) -> int:
        """The next frame number (each image the page is sent has its own)."""
        self._versions += 1
        return self._versions

    def compare(self, frame: Frame, progress: Callable[[str, int, int], None] | None = None) -> None:
        """Fill ``frame``'s reference, heatmap and metrics (or ``reference_error``) when there is a reference."""
        from a5mi.platform.imageio import quantize

        if self.compares:
            self._compare(frame, quantize(frame.image)[..., :3].astype(np.float64), progress, frame.seconds)

    def _reference_levels(self, options: RenderOptions) -> np.ndarray:
        from a5mi.platform.imageio import read_levels

        if self.reference is not None:
            if self._ref_image is None:
                self._ref_image = read_levels(self.reference)
            return self._ref_image
        argv = binary_argv(options)
        key = (self.loaded_at, tuple(argv))
        if key not in self._binary_cache:
            self._binary_cache.clear()
            self._binary_cache[key] = self._run_binary(argv)
        return self._binary_cache[key]

    def _run_binary(self, argv: list[str]) -> np.ndarray:
        """``binary -input scene.txt -output out.bmp ARGV`` in a fresh folder holding the scene's text and links
        to the files it names, sandboxed (docs/VIEW.md). Each named file that exists is linked at its name
        relative to the scene's folder (else the working directory: SPEC A.0 resolves names against the
        working directory) and only that file is bound read-only: neither folder is visible as a whole."""
        from a5mi.difftest.runner import run_binary

        scene = Path(self.scene).absolute()
        with tempfile.TemporaryDirectory(prefix="a5mi-view-run-") as tmp:
            os.chmod(tmp, 0o755)
            folder = Path(tmp) / "run"
            folder.mkdir()
            (folder / "scene.txt").write_bytes(scene.read_bytes())
            files = staged_links(folder, self.inputs[1:], (scene.parent, Path.cwd()))
            levels, status = run_binary(self.binary, folder, argv, self.timeout, read_only=files)
        if levels is None:
            raise UserError(f"--binary {self.binary.path}: {status}")
        return levels

    def _compare(self, frame: Frame, ours: np.ndarray, progress: Callable[[str, int, int], None] | None,
                 seconds: dict[str, float]) -> None:
        from a5mi import compare
        from a5mi.grade import verdict

        t0 = time.perf_counter()
        if progress:
            progress("reference", 0, 1)
        try:
            ref = self._reference_levels(frame.options)
        except UserError as exc:
            frame.reference_error = str(exc)
            return
        finally:
            seconds["reference"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        if progress:
            progress("compare", 0, 1)
        frame.reference_levels = ref
        if self._ref_png is None or self._ref_png[0] is not ref:  # encoded once per reference image
            self._ref_png = (ref, png_bytes(np.clip(ref, 0, 255).astype(np.uint8), self._scratch))  # .exr: not wrapped
        frame.reference_png = self._ref_png[1]
        if ref.shape != ours.shape:
            frame.reference_error = (f"image sizes differ: the render is {ours.shape[1]}x{ours.shape[0]}, the "
                                     f"reference {ref.shape[1]}x{ref.shape[0]} (verdict: wrong size)")
            return
        m = compare.compare_arrays(ours, ref)
        graded, _ = verdict.measure(ref, ours, None, flip=False)
        heat = np.rint(compare.heatmap(ours, ref, compare.DEFAULT_SCALE)).clip(0, 255).astype(np.uint8)
        frame.diff_png = png_bytes(heat, self._scratch)
        frame.metrics = {"psnr": m.psnr if np.isfinite(m.psnr) else None, "mean_error": m.mean_error,
                         "share_over": m.share_over, "max_error": m.max_error, "threshold": m.threshold,
                         "bbox": m.bbox, "summary": m.summary(), "verdict": verdict.judge(graded),
                         "beyond_noise": graded.beyond_noise, "noise_floor": verdict.NOISE_FLOOR,
                         "scale": compare.DEFAULT_SCALE,
                         "stops": [[int(255 * c) for c in s] for s in compare.STOPS]}
        seconds["compare"] = time.perf_counter() - t0

    # ------------------------------------------------------------------------------------------ tracing
    def trace(self, x: int, y: int) -> dict[str, Any]:
        """``a5mi trace`` of pixel ``(x, y)`` (top-left, of :func:`a5mi.trace.core.pixel_grid`) of the current
        frame: the whole trace JSON (:func:`a5mi.trace.report.trace_json`), the shown tree's text lines and
        hit points in image coordinates, and with a reference the ranked ``trace --diff`` terms."""
        from a5mi.trace import report

        frame = self.frame
        if frame is None or self.desc is None:
            raise UserError("nothing rendered yet")
        tracer = session_tracer(self.desc, frame.options, self.session, frame.image)
        if frame.options.integrator != "whitted" or not _records(tracer.integrator):
            from a5mi.trace.core import TraceError

            raise TraceError(f"-integrator {frame.options.integrator} records no ray tree (the page shows the Whitted "
                             "integrator's SPEC B.3 tree): set -integrator whitted to trace a pixel here")
        (pt,) = tracer.pixels([(x, y)])
        shown = 4 if len(pt.block) > 1 else 0
        tree = pt.trees[shown]
        doc = report.trace_json(pt)
        from a5mi.platform.imageio import quantize

        for sample in doc["samples"]:  # each tree's sum as the 8-bit level a5 would save (SPEC B.1)
            sample["sum_byte"] = [int(b) for b in quantize(np.array(sample["sum"], np.float32)).ravel()[:3]]
        doc["shown"] = shown
        doc["lines"] = report.tree_lines(tree, frame.options.fresnel, self.desc.ambient)
        doc["text"] = report.format_trace(pt, self.desc.ambient)
        doc["marks"] = [project(self.desc.camera, frame.options, frame.size, n.p) if n.is_hit else None
                        for n in tree.nodes]
        doc["value_byte"] = list(pt.value_byte)
        doc["diff"] = self._explain(pt, frame) if frame.reference_levels is not None else None
        return doc

    def _explain(self, pt: Any, frame: Frame) -> dict[str, Any] | None:
        from a5mi.trace import report

        ref = frame.reference_levels
        if ref is None or ref.shape[:2] != (frame.size[1], frame.size[0]) or frame.size != pt.grid:
            return None
        other = ref[pt.y, pt.x]
        err = float(np.max(np.abs(other - np.array(pt.image_byte, np.float64))))
        ranked = report.explain(pt, other / 255.0) if report.differs(err) else []
        return {"other_byte": [int(v) for v in other], "off_by": err, "noise": report.DIFF_NOISE,
                "terms": [{"label": t.label, "kind": t.kind, "value": list(t.value), "sign": t.sign,
                           "node": t.node, "residual": r} for t, r in ranked[:5]]}


def _records(integrator: Any) -> bool:
    """Whether ``integrator.trace`` takes the ``record`` argument of the trace library's record mode."""
    import inspect

    trace = getattr(integrator, "trace", None)
    try:
        return trace is not None and "record" in inspect.signature(trace).parameters
    except (TypeError, ValueError):
        return False


def session_tracer(desc: Any, options: RenderOptions, session: Any, image: np.ndarray) -> Any:
    """An :class:`a5mi.trace.core.Tracer` on the session's built scene and integrator and the frame's saved
    ``image``: no second build, and no second render unless ``-filter`` needs the unfiltered buffer."""
    from a5mi.trace.core import Tracer

    class SessionTracer(Tracer):
        def __init__(self) -> None:
            self.desc = desc
            self.options = dataclasses.replace(options, normals=False, depth=None, classes=False, count_rays=False)
            self.scene, self.integrator, _ = session.integrator(desc, self.options)
            self._image = image
            self._raw = None if self.options.filter else image

        def raw(self) -> np.ndarray:
            if self._raw is None:
                self._raw = session.render(desc, dataclasses.replace(self.options, filter=False)).image
            return self._raw

    return SessionTracer()


__all__ = ["Frame", "ViewEngine", "png_bytes", "preview_options", "project", "render_stages", "session_tracer"]
