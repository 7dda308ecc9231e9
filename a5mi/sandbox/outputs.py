"""What a sandboxed run wrote, taken back safely: only regular files it created, decoded without privileges.

:func:`open_output` takes only a regular file that the run created in its own folder: every path component
opened with ``O_NOFOLLOW`` relative to the folder's descriptor (no symbolic link anywhere), one link
(``st_nlink == 1``: no hard link to another file), owned by the run's user id, within a size bound.
:func:`decode_levels` decodes it in a child confined by :func:`a5mi.sandbox.bwrap.run_sandboxed` (this module's
``decode`` entry, the descriptor as its stdin), so a hostile image meets the decoder without privileges and
without the grader's files; an image of more pixels than the caller's bound is never decoded (:data:`TOO_LARGE`).
``docs/GRADING.md`` "Threat model".
"""

from __future__ import annotations

import json
import os
import shutil
import stat
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from a5mi.sandbox.bwrap import fresh_uid, run_sandboxed, sandbox_problem
from a5mi.sandbox.records import Limits, OutputRefused

#: How the decoder child is told no pixels were decoded (too many for the caller's bound).
TOO_LARGE = "too large"
#: The largest image file the decoder child reads.
MAX_IMAGE_BYTES = 256 << 20

_KINDS = ((stat.S_ISLNK, "a symbolic link"), (stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO"),
          (stat.S_ISSOCK, "a socket"), (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"))


def _kind(mode: int) -> str:
    return next((name for test, name in _KINDS if test(mode)), "not a plain file")


def open_output(folder: str | os.PathLike[str], rel: str, *, owner: int | None = None,
                max_bytes: int = 256 << 20) -> int:
    """A read-only descriptor of the regular file ``folder/rel`` (module docstring, "Outputs"): each component
    of ``rel`` is looked up without following links (``lstat`` then ``O_NOFOLLOW``, relative to the parent's
    descriptor; the two must be the same inode), the file must have one link, belong to ``owner`` (when given)
    and hold at most ``max_bytes``. Raises :class:`OutputRefused` (``missing`` when it does not exist)."""
    parts = [p for p in Path(rel).parts if p not in ("", ".")]
    if not parts or any(p in ("..", "/") for p in parts):
        raise OutputRefused(f"'{rel}' is not a name inside the folder")
    flags = os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC | os.O_NOCTTY | os.O_NONBLOCK
    try:
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    except OSError as exc:
        raise OutputRefused(f"cannot open the folder: {exc.strerror}") from None
    try:
        for i, part in enumerate(parts):
            last = i == len(parts) - 1
            try:
                st = os.stat(part, dir_fd=fd, follow_symlinks=False)
            except FileNotFoundError:
                raise OutputRefused("no such file", missing=True) from None
            except OSError as exc:
                raise OutputRefused(f"cannot look it up: {exc.strerror}") from None
            want = stat.S_ISREG if last else stat.S_ISDIR
            if not want(st.st_mode):
                what = "not a regular file" if last else f"'{part}' is not a folder"
                raise OutputRefused(f"{what} ({_kind(st.st_mode)})")
            try:
                nfd = os.open(part, flags | (0 if last else os.O_DIRECTORY), dir_fd=fd)
            except OSError as exc:
                raise OutputRefused(f"cannot open it: {exc.strerror}") from None
            os.close(fd)
            fd = nfd
            now = os.fstat(fd)
            if (now.st_dev, now.st_ino) != (st.st_dev, st.st_ino):
                raise OutputRefused("it was replaced while it was opened")
        if now.st_nlink != 1:
            raise OutputRefused(f"a hard link ({now.st_nlink} names for one file)")
        if owner is not None and now.st_uid != owner:
            raise OutputRefused(f"not written by the program (owner {now.st_uid})")
        if now.st_size > max_bytes:
            raise OutputRefused(f"{now.st_size} bytes is more than the limit of {max_bytes} bytes")
        if now.st_size == 0:
            raise OutputRefused("the file is empty")
        out, fd = fd, -1
        return out
    finally:
        if fd >= 0:
            os.close(fd)


@dataclass(frozen=True)
class Decoded:
    """An image decoded by :func:`decode_levels`: ``width`` x ``height`` (0 when unknown), ``levels`` (H, W, 3)
    float64 8-bit levels, None when it was not decoded: ``error`` says why (unreadable) or is
    :data:`TOO_LARGE` (more pixels than asked for: only the size is known)."""

    width: int
    height: int
    levels: np.ndarray | None
    error: str = ""


def _decoder_paths() -> list[str]:
    """What the decoder child needs to start: this interpreter, its packages and the a5mi sources."""
    from a5mi import PROJECT_ROOT

    paths = {sys.prefix, sys.base_prefix, os.path.dirname(os.path.realpath(sys.executable)), str(PROJECT_ROOT)}
    paths |= {p for p in sys.path if p and os.path.isdir(p)}
    return sorted(paths)


def decode_levels(fd: int, suffix: str, max_pixels: int, work_parent: str | os.PathLike[str], *,
                  timeout: float = 60.0) -> Decoded:
    """Decode the image file open on ``fd`` (its format guessed from ``suffix``, e.g. ``.png``, then from its
    content) in a child run by :func:`run_sandboxed` (2 GB of address space; in bubblewrap when it can be used,
    else with the rlimits and its own user id: never with the grader's privileges), as
    :func:`a5mi.platform.imageio.read_levels` would; images of more than ``max_pixels`` pixels are not decoded
    (``Decoded.error`` = :data:`TOO_LARGE`, their size given). A working folder is made in ``work_parent``."""
    work = Path(tempfile.mkdtemp(prefix="a5mi-decode-", dir=work_parent))
    try:
        os.chmod(work, 0o755)
        limits = Limits(timeout=timeout, memory_mb=2048, fsize_mb=max(64, (max_pixels * 24 >> 20) + 1), nproc=64,
                        keep_bytes=4096, require_sandbox=False)
        if sandbox_problem():  # no bubblewrap: a forked child of this process drops to the run's user id
            uid, why, timed_out = _decode_forked(fd, suffix, max_pixels, work, limits)
        else:
            run = run_sandboxed([sys.executable, "-I", "-m", "a5mi.sandbox.outputs", "decode", suffix,
                                 str(max_pixels), str(MAX_IMAGE_BYTES)], work, limits, read_only=_decoder_paths(),
                                env={"OPENIMAGEIO_THREADS": "1", "OMP_NUM_THREADS": "1"}, stdin=fd)
            uid, why, timed_out = run.uid, (run.stderr_tail.strip().splitlines() or [""])[-1], run.timed_out
        owner = uid if uid is not None else os.geteuid()
        try:
            info_fd = open_output(work, "info.json", owner=owner, max_bytes=4096)
            with os.fdopen(info_fd, "rb") as f:
                info = json.loads(f.read(4097))
            w, h, error = int(info["width"]), int(info["height"]), str(info["error"])
        except (OutputRefused, ValueError, KeyError, TypeError) as exc:
            why = "timed out" if timed_out else why or str(exc)
            return Decoded(0, 0, None, f"the image decoder failed: {why[:200]}")
        if error:
            return Decoded(w, h, None, error)
        try:
            npy_fd = open_output(work, "levels.npy", owner=owner, max_bytes=w * h * 24 + 4096)
            with os.fdopen(npy_fd, "rb") as f:
                import io

                levels = np.load(io.BytesIO(f.read()), allow_pickle=False)
        except (OutputRefused, ValueError, OSError) as exc:
            return Decoded(w, h, None, f"the image decoder failed: {exc}")
        if levels.dtype != np.float64 or levels.shape != (h, w, 3) or not np.isfinite(levels).all():
            return Decoded(w, h, None, "the image decoder failed: malformed pixels")
        return Decoded(w, h, levels)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _decode_forked(fd: int, suffix: str, max_pixels: int, work: Path, limits: Limits,
                   ) -> tuple[int | None, str, bool]:
    """:func:`_decode_child` in a forked child when bubblewrap cannot be used: the child already holds the
    decoder's modules (a fresh interpreter under the run's user id could not read a virtual environment in a
    folder only root may enter), then takes the rlimits of ``limits`` (the address space on top of what the
    fork inherited), its own session, the run's fresh user id (:func:`a5mi.sandbox.bwrap.fresh_uid`, when root)
    and ``work`` as its folder, and reads the image on ``fd``.
    Returns (user id, why it failed, timed out); the parent kills it after ``limits.timeout`` seconds."""
    import resource
    import signal
    import time

    import OpenImageIO  # noqa: F401 - imported before the fork, so the child needs no file of this process

    uid = fresh_uid()
    if uid is not None:
        os.chown(work, uid, uid)
    pid = os.fork()
    if pid == 0:  # the child: never returns
        code = 1
        try:
            os.setsid()
            # a forked child keeps this process's address space: the decoder's bound comes on top of it
            in_use = int(Path("/proc/self/statm").read_text().split()[0]) * os.sysconf("SC_PAGE_SIZE")
            for kind, value in ((resource.RLIMIT_AS, in_use + (limits.memory_mb << 20)), (resource.RLIMIT_CORE, 0),
                                (resource.RLIMIT_CPU, int(limits.timeout) + 1),
                                (resource.RLIMIT_FSIZE, limits.fsize_mb << 20)):
                hard = resource.getrlimit(kind)[1]
                value = value if hard == resource.RLIM_INFINITY else min(value, hard)
                resource.setrlimit(kind, (value, value))
            os.chdir(work)
            os.environ["TMPDIR"] = tempfile.tempdir = str(work)  # scratch files of the decoder: its own folder
            if uid is not None:
                os.setgroups([])
                os.setgid(uid)
                os.setuid(uid)
            os.dup2(fd, 0)
            code = _decode_child(suffix, max_pixels, MAX_IMAGE_BYTES)
        finally:
            os._exit(code)
    deadline = time.monotonic() + limits.timeout
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        if time.monotonic() > deadline:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            return uid, "", True
        time.sleep(0.01)
    code = os.waitstatus_to_exitcode(status)
    return uid, "" if code == 0 else f"exit status {code}", False


def _decode_child(suffix: str, max_pixels: int, max_bytes: int) -> int:
    """The decoder child (``python -m a5mi.sandbox.outputs decode SUFFIX MAX_PIXELS MAX_BYTES``): stdin's image to
    ``info.json`` (``width``, ``height``, ``error``) and ``levels.npy`` in the working folder."""
    from a5mi.platform.errors import ImageReadError
    from a5mi.platform.imageio import read_levels

    def finish(w: int, h: int, error: str) -> int:
        Path("info.json").write_text(json.dumps({"width": w, "height": h, "error": error}))
        return 0

    data = os.read(0, max_bytes + 1)
    while len(data) <= max_bytes and (more := os.read(0, max_bytes + 1 - len(data))):
        data += more
    if len(data) > max_bytes:
        return finish(0, 0, f"more than {max_bytes} bytes")
    safe = "".join(c for c in suffix if c.isalnum() or c == ".")[:12]
    path = Path(f"image{safe}")  # in the working folder: the child's own
    path.write_bytes(data)
    import OpenImageIO as oiio

    oiio.attribute("threads", 1)
    inp = oiio.ImageInput.open(str(path))
    if inp is not None:
        spec = inp.spec()
        w, h = int(spec.width), int(spec.height)
        inp.close()
        if w * h > max_pixels:
            return finish(w, h, TOO_LARGE)
    try:
        levels = np.ascontiguousarray(read_levels(path), dtype=np.float64)
    except ImageReadError as exc:
        return finish(0, 0, exc.reason)
    np.save("levels.npy", levels, allow_pickle=False)
    return finish(levels.shape[1], levels.shape[0], "")


if __name__ == "__main__" and len(sys.argv) == 5 and sys.argv[1] == "decode":
    sys.exit(_decode_child(sys.argv[2], int(sys.argv[3]), int(sys.argv[4])))



__all__ = ["Decoded", "TOO_LARGE", "decode_levels", "open_output"]
