"""A run's folder (docs/GRADING.md "Bounds"): as root a size-limited tmpfs holding its working folder and its
``/tmp``, so every byte and inode it writes counts against one bound and never reaches the grader's disk; the
mount helpers that clean up after a killed run."""

from __future__ import annotations

import contextlib
import ctypes
import functools
import os
import shutil
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

#: mount(2) and umount2(2) flags
MS_NOSUID, MS_NODEV, MNT_DETACH = 2, 4, 2


def is_under(path: str, roots: Sequence[str]) -> bool:
    """Whether ``path`` is one of ``roots`` or inside one (as strings, no file-system access)."""
    return any(path == r or path.startswith(r.rstrip("/") + "/") for r in roots)


@functools.cache
def _libc() -> ctypes.CDLL:
    return ctypes.CDLL(None, use_errno=True)


def _mount_tmpfs(path: Path, size_mb: int, inodes: int) -> bool:
    """Mount a tmpfs of ``size_mb`` MiB and ``inodes`` inodes on ``path`` (root only); whether it worked."""
    if os.geteuid() != 0:
        return False
    opts = f"size={size_mb}m,nr_inodes={inodes},mode=0755".encode()
    rc = _libc().mount(b"a5mi-run", os.fsencode(path), b"tmpfs", ctypes.c_ulong(MS_NOSUID | MS_NODEV), opts)
    return rc == 0


def unmount(path: str | os.PathLike[str]) -> None:
    """Detach the mount at ``path`` (a :func:`run_folder` left by a killed worker)."""
    _libc().umount2(os.fsencode(path), MNT_DETACH)


def mounts_under(root: str | os.PathLike[str]) -> list[str]:
    """Mount points at or below ``root`` (from ``/proc/self/mountinfo``), deepest first."""
    real = os.path.realpath(root)
    found = []
    try:
        for ln in Path("/proc/self/mountinfo").read_text().splitlines():
            point = ln.split()[4].encode().decode("unicode_escape")
            if is_under(point, (real,)):
                found.append(point)
    except (OSError, IndexError):
        return []
    return sorted(found, key=len, reverse=True)


@dataclass(frozen=True)
class RunFolder:
    """A run's private folders: ``work`` (its working folder) and ``tmp`` (bound as its ``/tmp``; None: a
    fresh tmpfs made by bubblewrap); ``bounded``: both live on one tmpfs of ``disk_mb`` and ``inodes``."""

    work: Path
    tmp: Path | None
    bounded: bool


@contextlib.contextmanager
def run_folder(path: str | os.PathLike[str], disk_mb: int, inodes: int) -> Iterator[RunFolder]:
    """A fresh folder ``path`` for one run, removed afterwards. As root it is a **tmpfs of ``disk_mb``
    MiB and ``inodes`` inodes** (the kernel refuses the write or the file past either: ENOSPC) holding
    ``work/`` and ``tmp/`` (the run's ``/tmp``), so everything the run writes counts against one bound and
    never touches the grader's disk. Otherwise a plain folder (``work/`` only): per-file ``fsize_mb`` and
    bubblewrap's ``/tmp`` of ``fsize_mb`` bound it."""
    root = Path(path)
    if os.path.lexists(root):
        for point in mounts_under(root):
            unmount(point)
        shutil.rmtree(root)
    root.mkdir(parents=True)
    mounted = _mount_tmpfs(root, disk_mb, inodes)
    try:
        work = root / "work"
        work.mkdir()
        tmp = None
        if mounted:
            tmp = root / "tmp"
            tmp.mkdir()
            tmp.chmod(0o1777)
        yield RunFolder(work, tmp, mounted)
    finally:
        if mounted:
            unmount(root)
        shutil.rmtree(root, ignore_errors=True)


def disk_full(folder: str | os.PathLike[str]) -> bool:
    """Whether the file system of ``folder`` (a :func:`run_folder` tmpfs) has under 1 MiB or 8 inodes left."""
    try:
        st = os.statvfs(folder)
    except OSError:
        return False
    return st.f_bavail * st.f_frsize < (1 << 20) or (st.f_files > 0 and st.f_favail < 8)
