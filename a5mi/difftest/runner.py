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
from a5mi.sandbox.bwrap import Limits, OutputRefused, run_sandboxed
from a5mi.sandbox.outputs import TOO_LARGE, decode_levels, open_output

#: Seconds a single run of the other executable may take.
DEFAULT_TIMEOUT = 60.0
#: The largest output file taken (bytes).
MAX_IMAGE_BYTES = 64 << 20


class BinaryError(UserError):
    """The other executable cannot be run (missing, not executable)."""


@dataclass(frozen=True)
class Outcome:
    """Result of one comparison: ``metrics`` (None when a side failed), ``status`` = ``ok``, ``timeout``,
    ``binary failed: ...`` or ``a5mi failed: ...``, and the seconds each side took."""

    metrics: Metrics | None
    status: str
    binary_s: float = 0.0
    a5mi_s: float = 0.0

    @property
    def psnr(self) -> float:
        return self.metrics.psnr if self.metrics is not None else float("-inf")


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
    b = _as_binary(binary)
    limits = Limits(timeout=timeout, require_sandbox=b.require_sandbox)
    run = run_sandboxed([str(b.path), "-input", "scene.txt", "-output", "out.bmp", *argv], folder, limits,
                        read_only=(str(b.path.parent), *read_only, *b.read_only))
    if run.timed_out:
        return None, "timeout"
    try:
        fd = open_output(folder, "out.bmp", owner=run.uid if run.uid is not None else os.geteuid(),
                         max_bytes=MAX_IMAGE_BYTES)
    except OutputRefused as exc:
        if exc.missing:
            tail = run.stderr_tail.strip().splitlines()[-1:] or [f"exit {run.returncode}"]
            return None, f"binary failed: {tail[0][:120]}"
        return None, f"binary failed: out.bmp: {exc.reason}"
    try:
        dec = decode_levels(fd, ".bmp", max_pixels, folder.parent)
    finally:
        os.close(fd)
    if dec.error == TOO_LARGE:
        return None, f"binary failed: image size {dec.width}x{dec.height} (not decoded)"
    if dec.levels is None:
        return None, f"binary failed: unreadable output ({dec.error})"
    return dec.levels, "ok"


def render_a5mi(scene_path: Path, scene: GenScene) -> np.ndarray:
    """a5mi's 8-bit render of ``scene_path`` with the scene's flags (as the ``a5`` command writes it)."""
    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.platform.imageio import quantize
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import render

    f = scene.flags
    opts = RenderOptions(width=f.size, height=f.size, bounces=f.bounces, shadows=f.shadows, jitter=f.jitter,
                         filter=f.filter)
    return quantize(render(describe(parse_file(scene_path)), opts).image).astype(np.float64)


def compare_scene(scene: GenScene, binary: Path | Binary, data: Path, timeout: float = DEFAULT_TIMEOUT) -> Outcome:
    """Render ``scene`` with both and compare (module docstring). The temporary folder is removed after."""
    with tempfile.TemporaryDirectory(prefix="a5mi-difftest-") as tmp:
        os.chmod(tmp, 0o755)  # the run's user id reaches its folder and the decoder's beside it
        folder = Path(tmp) / "run"
        folder.mkdir()
        path = stage(scene, folder, data)
        t0 = time.perf_counter()
        # -jitter without -filter: the 3x3 supersampled image (SPEC B.5), 9 times the pixels
        factor = 9 if scene.flags.jitter and not scene.flags.filter else 4
        theirs, status = run_binary(binary, folder, scene.flags.argv(), timeout, read_only=(str(data),),
                                    max_pixels=factor * (scene.flags.size + 10) ** 2)
        t1 = time.perf_counter()
        if theirs is None:
            return Outcome(None, status, t1 - t0)
        try:
            ours = render_a5mi(path, scene)
        except UserError as e:
            return Outcome(None, f"a5mi failed: {e}", t1 - t0, time.perf_counter() - t1)
        t2 = time.perf_counter()
        if ours.shape != theirs.shape:
            return Outcome(None, f"binary failed: image size {theirs.shape[1]}x{theirs.shape[0]}, expected "
                                 f"{ours.shape[1]}x{ours.shape[0]}", t1 - t0, t2 - t1)
        return Outcome(compare_arrays(ours, theirs), "ok", t1 - t0, t2 - t1)
