"""One differential test: a scene rendered by a5mi and by another a5 executable, compared on 8-bit images.

The other executable (the course's ``a5soln``, a student's ``a5``) is untrusted: :func:`run_binary` runs it
without a shell, in a fresh temporary folder holding only the scene and links to the course files it names
(meshes, textures, cube maps; the binary resolves paths against its working directory, SPEC A.0), with a
time limit, and, when ``bwrap`` (bubblewrap) is installed, in a sandbox: no network, its own PID namespace,
the file system read-only except that folder. It writes BMP; the image it wrote is read back with
:func:`a5mi.imageio.read_levels`. a5mi renders the same folder's scene in this process
(:func:`a5mi.session.render`), so compiled kernels are reused across scenes.

Metrics (:func:`a5mi.compare.compare_arrays`): PSNR ``10 log10(255² / MSE)`` over all channels, the share of
pixels whose largest channel error is > 2/255, and the maximum error.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from a5mi.compare import Metrics, compare_arrays
from a5mi.errors import UserError
from a5mi.imageio import read_levels

from .generate import GenScene

#: Seconds a single run of the other executable may take.
DEFAULT_TIMEOUT = 60.0


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


def sandbox_prefix(folder: Path, binary: Path | None = None) -> list[str]:
    """The bubblewrap command line that confines a process to ``folder`` (writable), everything else
    read-only, a private empty ``/tmp`` (the binary's own folder bound back, read-only), no network, own PID
    namespace; ``[]`` when ``bwrap`` is not installed."""
    bwrap = shutil.which("bwrap")
    if bwrap is None:
        return []
    own = [] if binary is None else ["--ro-bind", str(binary.parent), str(binary.parent)]
    # What a binary here may run from that the private /tmp would hide (a checkout or virtual environment
    # under /tmp: this Python, a5mi's own sources, the course data), bound back read-only.
    for path in sorted(_tmp_paths_needed()):
        own += ["--ro-bind", path, path]
    return [bwrap, "--ro-bind", "/", "/", "--dev", "/dev", "--proc", "/proc", "--tmpfs", "/tmp", *own,
            "--bind", str(folder), str(folder), "--chdir", str(folder), "--unshare-net", "--unshare-pid",
            "--die-with-parent", "--new-session"]


def _tmp_paths_needed() -> set[str]:
    """The interpreter's prefixes, the project and the course data, where they lie under ``/tmp``."""
    import sys

    from a5mi import PROJECT_ROOT, data_dir

    paths = {sys.prefix, sys.base_prefix, str(PROJECT_ROOT), str(data_dir())}
    return {os.path.realpath(p) for p in paths if os.path.realpath(p).startswith("/tmp/") and os.path.isdir(p)}


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


def run_binary(binary: Path, folder: Path, argv: list[str], timeout: float) -> tuple[np.ndarray | None, str]:
    """Run ``binary -input scene.txt -output out.bmp ARGV`` in ``folder`` (sandboxed, no shell, time limit);
    ``(levels, "ok")`` or ``(None, why)``."""
    out = folder / "out.bmp"
    cmd = [*sandbox_prefix(folder, binary), str(binary), "-input", "scene.txt", "-output", out.name, *argv]
    try:
        proc = subprocess.run(cmd, cwd=folder, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        return None, "timeout"
    if not out.is_file():
        tail = proc.stderr.decode(errors="replace").strip().splitlines()[-1:] or [f"exit {proc.returncode}"]
        return None, f"binary failed: {tail[0][:120]}"
    try:
        return read_levels(out), "ok"
    except UserError as e:
        return None, f"binary failed: unreadable output ({e})"


def render_a5mi(scene_path: Path, scene: GenScene) -> np.ndarray:
    """a5mi's 8-bit render of ``scene_path`` with the scene's flags (as the ``a5`` command writes it)."""
    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.imageio import quantize
    from a5mi.options import RenderOptions
    from a5mi.session import render

    f = scene.flags
    opts = RenderOptions(width=f.size, height=f.size, bounces=f.bounces, shadows=f.shadows, jitter=f.jitter,
                         filter=f.filter)
    return quantize(render(describe(parse_file(scene_path)), opts).image).astype(np.float64)


def compare_scene(scene: GenScene, binary: Path, data: Path, timeout: float = DEFAULT_TIMEOUT) -> Outcome:
    """Render ``scene`` with both and compare (module docstring). The temporary folder is removed after."""
    with tempfile.TemporaryDirectory(prefix="a5mi-difftest-") as tmp:
        folder = Path(tmp)
        path = stage(scene, folder, data)
        t0 = time.perf_counter()
        theirs, status = run_binary(binary, folder, scene.flags.argv(), timeout)
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
