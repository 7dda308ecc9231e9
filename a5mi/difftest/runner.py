"""One differential test: a scene rendered by a5mi and by another a5 executable, compared on 8-bit images.

The other executable (the course's ``a5soln``, a student's ``a5``) is untrusted: :func:`run_binary` runs it
without a shell, in a fresh temporary folder holding only the scene and links to the course files it names
(meshes, textures, cube maps; the binary resolves paths against its working directory, SPEC A.0), in the same
sandbox as ``a5mi grade`` (:func:`a5mi.sandbox.bwrap.run_sandboxed`: an unprivileged user id without capabilities, no
network, its own PID namespace, only ``/usr``, the course data, its own folder and ``--allow-read`` paths visible,
the time limit). Without bubblewrap it does not run unless asked by name (``--no-sandbox``,
:attr:`Binary.require_sandbox` off). It writes BMP; only a regular file it created itself is taken
(:func:`a5mi.sandbox.outputs.open_output`) and decoded without privileges
(:func:`a5mi.sandbox.outputs.decode_levels`). a5mi renders the same folder's scene in this process
(:func:`a5mi.render.session.render`), so compiled kernels are reused across scenes.

Metrics (:func:`a5mi.compare.compare_arrays`): PSNR ``10 log10(255² / MSE)`` over all channels, the share of
pixels whose largest channel error is > 2/255, and the maximum error.

The ``-normals`` and ``-depth`` images (SPEC B.6) are compared too, unless ``aovs="none"``: both sides write
them (``-normals normals.bmp -depth 3 16 depth.bmp``, :data:`AOV_DEPTH`), a5mi with the rays the other side
uses: ``quadrant`` (the sample solution's top-right-quadrant rays, the default) or ``main`` (the main image's,
a5mi's own default). A scene's figure for pass or fail is the lowest PSNR of its images (:attr:`Outcome.worst`).
"""

from __future__ import annotations

import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from a5mi.compare import Metrics, compare_arrays
from a5mi.difftest.generate import GenScene
from a5mi.platform.errors import UserError
from a5mi.sandbox.bwrap import run_sandboxed
from a5mi.sandbox.outputs import TOO_LARGE, decode_levels, open_output
from a5mi.sandbox.records import Limits, OutputRefused

#: Seconds a single run of the other executable may take.
DEFAULT_TIMEOUT = 60.0
#: The largest output file taken (bytes).
MAX_IMAGE_BYTES = 64 << 20
#: ``dmin dmax`` of the compared ``-depth`` images: the scenes' cameras stand 6-12 units from objects about
#: 2 units around the origin (:mod:`.generate`), so their depths fall inside.
AOV_DEPTH = (3.0, 16.0)
#: Which rays the compared AOV images use: the other renderer's (``quadrant``: a5soln's, SPEC B.6; ``main``),
#: or ``none`` (the main image alone).
AOV_CHOICES: tuple[str, ...] = ("quadrant", "main", "none")
#: The AOV images: name, the file the other side writes.
AOV_FILES: tuple[tuple[str, str], ...] = (("normals", "normals.bmp"), ("depth", "depth.bmp"))


def aov_argv() -> list[str]:
    """The flags that make an a5 executable write the compared AOV images (module docstring)."""
    dmin, dmax = AOV_DEPTH
    return ["-normals", AOV_FILES[0][1], "-depth", f"{dmin:g}", f"{dmax:g}", AOV_FILES[1][1]]


class BinaryError(UserError):
    """The other executable cannot be run (missing, not executable)."""


@dataclass(frozen=True)
class Outcome:
    """Result of one comparison: ``metrics`` of the main image (None when a side failed), ``status`` = ``ok``,
    ``timeout``, ``binary failed: ...`` or ``a5mi failed: ...``, the seconds each side took, and ``aovs``: the
    metrics of the AOV images compared (name, metrics; empty with ``aovs="none"``)."""

    metrics: Metrics | None
    status: str
    binary_s: float = 0.0
    a5mi_s: float = 0.0
    aovs: tuple[tuple[str, Metrics], ...] = ()

    @property
    def psnr(self) -> float:
        """The main image's PSNR (−inf when nothing was compared)."""
        return self.metrics.psnr if self.metrics is not None else float("-inf")

    def aov_psnr(self, name: str) -> float | None:
        """The PSNR of AOV image ``name``, None when it was not compared."""
        return next((m.psnr for n, m in self.aovs if n == name), None)

    @property
    def worst(self) -> float:
        """The lowest PSNR of the images compared: the scene's figure for pass or fail."""
        return min([self.psnr, *(m.psnr for _, m in self.aovs)])


@dataclass(frozen=True)
class Binary:
    """The other executable (absolute ``path``) and how it may run: extra ``read_only`` paths it needs (an
    interpreter, a toolchain: ``--allow-read``) and ``require_sandbox`` (off: ``--no-sandbox``)."""

    path: Path
    read_only: tuple[str, ...] = ()
    require_sandbox: bool = True

    def __fspath__(self) -> str:
        return str(self.path)


def _as_binary(binary: Path | Binary) -> Binary:
    return binary if isinstance(binary, Binary) else Binary(Path(binary))


def check_binary(path: str | os.PathLike[str]) -> Path:
    """``path`` as an absolute executable file, else :class:`BinaryError`."""
    p = Path(path).expanduser()
    if not p.is_file():
        raise BinaryError(f"--binary: '{path}' is not a file")
    if not os.access(p, os.X_OK):
        raise BinaryError(f"--binary: '{path}' is not executable")
    return p.resolve()


def stage(scene: GenScene, folder: Path, data: Path) -> Path:
    """Write ``scene.txt`` into ``folder`` with links to the course files it names (from ``data``, the
    course ``scenes/`` folder); returns the scene path."""
    for rel in scene.files:
        dst = folder / rel
        dst.parent.mkdir(parents=True, exist_ok=True)
        if not dst.exists():
            os.symlink((data / rel).resolve(), dst)
    path = folder / "scene.txt"
    path.write_text(scene.text())
    return path


def run_binary(binary: Path | Binary, folder: Path, argv: list[str], timeout: float,
               read_only: tuple[str, ...] = (), max_pixels: int = 4 << 20) -> tuple[np.ndarray | None, str]:
    """Run ``binary -input scene.txt -output out.bmp ARGV`` in ``folder`` (sandboxed, no shell, time limit,
    ``read_only`` paths visible besides the binary's folder); ``(levels, "ok")`` or ``(None, why)``. An image of
    more than ``max_pixels`` pixels is not decoded."""
    images, why = run_binary_images(binary, folder, argv, timeout, read_only, max_pixels)
    return (images["out.bmp"] if images is not None else None), why


def run_binary_images(binary: Path | Binary, folder: Path, argv: list[str], timeout: float,
                      read_only: tuple[str, ...] = (), max_pixels: int = 4 << 20,
                      extra: tuple[str, ...] = ()) -> tuple[dict[str, np.ndarray] | None, str]:
    """As :func:`run_binary`, and also decode the files ``extra`` that ``argv`` asks the binary to write (the
    AOV images): ``({file name: levels}, "ok")`` or ``(None, why)``."""
    b = _as_binary(binary)
    limits = Limits(timeout=timeout, require_sandbox=b.require_sandbox)
    run = run_sandboxed([str(b.path), "-input", "scene.txt", "-output", "out.bmp", *argv], folder, limits,
                        read_only=(str(b.path.parent), *read_only, *b.read_only))
    if run.timed_out:
        return None, "timeout"
    images = {}
    for name in ("out.bmp", *extra):
        try:
            fd = open_output(folder, name, owner=run.uid if run.uid is not None else os.geteuid(),
                             max_bytes=MAX_IMAGE_BYTES)
        except OutputRefused as exc:
            if exc.missing:
                tail = run.stderr_tail.strip().splitlines()[-1:] or [f"exit {run.returncode}"]
                return None, f"binary failed: {tail[0][:120]}" if name == "out.bmp" else \
                    f"binary failed: no {name} ({tail[0][:80]})"
            return None, f"binary failed: {name}: {exc.reason}"
        try:
            dec = decode_levels(fd, ".bmp", max_pixels, folder.parent)
        finally:
            os.close(fd)
        if dec.error == TOO_LARGE:
            return None, f"binary failed: {name}: image size {dec.width}x{dec.height} (not decoded)"
        if dec.levels is None:
            return None, f"binary failed: unreadable {name} ({dec.error})"
        images[name] = dec.levels
    return images, "ok"


def render_a5mi(scene_path: Path, scene: GenScene, aovs: str = "none") -> dict[str, np.ndarray]:
    """a5mi's 8-bit renders of ``scene_path`` with the scene's flags (as the ``a5`` command writes them): the
    main image (``"image"``) and, unless ``aovs`` is ``none``, the ``normals`` and ``depth`` images traced with
    the ``aovs`` rays (module docstring)."""
    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.platform.imageio import quantize
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import render

    f = scene.flags
    extra: dict[str, object] = {} if aovs == "none" else {"normals": True, "depth": AOV_DEPTH, "aov_mode": aovs}
    opts = RenderOptions(width=f.size, height=f.size, bounces=f.bounces, shadows=f.shadows, jitter=f.jitter,
                         filter=f.filter, **extra)  # type: ignore[arg-type]
    result = render(describe(parse_file(scene_path)), opts)
    out = {"image": quantize(result.image).astype(np.float64)}
    if aovs != "none":
        for name in ("normals", "depth"):
            out[name] = quantize(getattr(result, name)).astype(np.float64)
    return out


def compare_scene(scene: GenScene, binary: Path | Binary, data: Path, timeout: float = DEFAULT_TIMEOUT,
                  aovs: str = "quadrant") -> Outcome:
    """Render ``scene`` with both and compare the main image and, unless ``aovs`` is ``none``, the AOV images
    (module docstring). The temporary folder is removed after."""
    if aovs not in AOV_CHOICES:
        raise ValueError(f"aovs must be one of {', '.join(AOV_CHOICES)}, got {aovs!r}")
    with tempfile.TemporaryDirectory(prefix="a5mi-difftest-") as tmp:
        os.chmod(tmp, 0o755)  # the run's user id reaches its folder and the decoder's beside it
        folder = Path(tmp) / "run"
        folder.mkdir()
        path = stage(scene, folder, data)
        t0 = time.perf_counter()
        # -jitter without -filter: the 3x3 supersampled image (SPEC B.5), 9 times the pixels; the AOV images
        # are at the render buffer's resolution (3W x 3H with -jitter, SPEC B.6)
        factor = 9 if scene.flags.jitter else 4
        files = () if aovs == "none" else tuple(f for _, f in AOV_FILES)
        argv = scene.flags.argv() + ([] if aovs == "none" else aov_argv())
        theirs, status = run_binary_images(binary, folder, argv, timeout, read_only=(str(data),),
                                           max_pixels=factor * (scene.flags.size + 10) ** 2, extra=files)
        t1 = time.perf_counter()
        if theirs is None:
            return Outcome(None, status, t1 - t0)
        try:
            ours = render_a5mi(path, scene, aovs)
        except UserError as e:
            return Outcome(None, f"a5mi failed: {e}", t1 - t0, time.perf_counter() - t1)
        t2 = time.perf_counter()
        pairs = [("image", "out.bmp"), *(() if aovs == "none" else AOV_FILES)]
        for name, file in pairs:
            if ours[name].shape != theirs[file].shape:
                return Outcome(None, f"binary failed: {file} size {theirs[file].shape[1]}x{theirs[file].shape[0]}, "
                                     f"expected {ours[name].shape[1]}x{ours[name].shape[0]}", t1 - t0, t2 - t1)
        aov = tuple((name, compare_arrays(ours[name], theirs[file])) for name, file in pairs[1:])
        return Outcome(compare_arrays(ours["image"], theirs["out.bmp"]), "ok", t1 - t0, t2 - t1, aov)
