"""Paths a5mi writes and reads, checked before the work: output targets (:func:`check_target`), what kind of
file a path is, our temporary names and their leftovers, and reads of regular files only (a FIFO or a device
would block). A leaf: standard library and the errors leaf only (:mod:`a5mi.platform.imageio` writes images through it).
"""

from __future__ import annotations

import errno
import os
import re
import stat
from pathlib import Path

from a5mi.platform.errors import FileReadError, ImageWriteError

#: Our temporaries: ``.{target name}.a5mi-{pid}-{random}...``.
_TEMP_RE = re.compile(r"\.(?P<name>.+)\.a5mi-(?P<pid>[0-9]+)-[A-Za-z0-9_]+(?:\.[A-Za-z0-9]+)?")


def short(p: str | os.PathLike[str], limit: int = 120) -> str:
    s = str(p)
    return s if len(s) <= limit else f"{s[:40]}...{s[-60:]} ({len(os.fsencode(s))} bytes)"


#: ``FS_IOC_GETFLAGS`` and its immutable / append-only bits (linux/fs.h): such a file cannot be replaced.
_FS_IOC_GETFLAGS, _FS_LOCKED = 0x80086601, 0x10 | 0x20


def _locked(p: Path) -> bool:
    """True when the existing regular file ``p`` is immutable or append-only (``chattr +i`` / ``+a``)."""
    try:
        import fcntl
        import struct

        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0))
    except (ImportError, OSError):
        return False
    try:
        flags = struct.unpack("l", fcntl.ioctl(fd, _FS_IOC_GETFLAGS, struct.pack("l", 0)))[0]
    except OSError:
        return False
    finally:
        os.close(fd)
    return bool(flags & _FS_LOCKED)


def check_target(path: str | os.PathLike[str]) -> Path:
    """Raise :class:`ImageWriteError` unless the file ``path`` can be written atomically (a temporary beside
    it, then ``os.replace``): its name and the temporary's fit ``NAME_MAX`` and ``PATH_MAX``, the folder
    exists and is writable, the path resolves (no symlink loop), it is not a folder or special file, and an
    existing file may be replaced (not immutable or append-only, not another user's in a sticky folder).
    Every check runs before anything renders. Returns the path."""
    p = Path(path)
    folder = p.parent if str(p.parent) else Path(".")
    try:
        name_max = os.pathconf(folder, "PC_NAME_MAX")
        path_max = os.pathconf(folder, "PC_PATH_MAX")
    except (OSError, ValueError):
        name_max, path_max = 255, 4096
    temp = f"{temp_prefix(p.name)}xxxxxxxx{p.suffix}"
    name_bytes, temp_bytes = len(os.fsencode(p.name)), len(os.fsencode(temp))
    if temp_bytes > name_max:
        raise ImageWriteError(f"{short(p)}: the file name is too long ({name_bytes} bytes; with its temporary "
                              f"name the limit is {name_max - temp_bytes + name_bytes})")
    if len(os.fsencode(str(folder / temp))) >= path_max:
        raise ImageWriteError(f"{short(p)}: the path is too long (the limit is {path_max} bytes, with the "
                              "temporary name)")
    try:
        os.stat(p)
    except OSError as exc:  # missing (or under a file: the folder checks below say so); else a loop, EACCES
        if exc.errno not in (errno.ENOENT, errno.ENOTDIR):
            raise ImageWriteError(f"{short(p)}: {exc.strerror or exc}") from None
    if not folder.is_dir():
        above = next((q for q in (folder, *folder.parents) if q.exists()), None)
        if above is not None and not above.is_dir():
            raise ImageWriteError(f"{p}: output folder '{folder}' is not a folder: '{above}' is a file")
        raise ImageWriteError(f"{p}: output folder '{folder}' does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ImageWriteError(f"{p}: output folder '{folder}' is not writable")
    if p.is_dir():
        raise ImageWriteError(f"{p}: is a directory")
    if p.exists() and not p.is_file():
        raise ImageWriteError(f"{p}: exists and is not a regular file ({file_kind(p)})")
    if p.is_symlink() or p.exists():
        check_replaceable(p, folder)
    if p.is_file() and not p.is_symlink() and _locked(p):
        raise ImageWriteError(f"{p}: cannot replace it: the file is immutable or append-only (chattr)")
    return p


def file_kind(p: str | os.PathLike[str]) -> str:
    """``regular file``, ``folder``, ``FIFO``, ``socket``, ``character device``, ``block device`` (or
    ``missing``), for messages."""
    try:
        mode = os.stat(p).st_mode
    except OSError:
        return "missing"
    for test, name in ((stat.S_ISREG, "regular file"), (stat.S_ISDIR, "folder"), (stat.S_ISFIFO, "FIFO"),
                       (stat.S_ISSOCK, "socket"), (stat.S_ISCHR, "character device"),
                       (stat.S_ISBLK, "block device")):
        if test(mode):
            return name
    return "special file"


def check_replaceable(p: Path, folder: Path) -> None:
    """``os.replace`` over an existing entry of a sticky folder (``/tmp``) needs the caller to own the entry
    or the folder (or CAP_FOWNER: root); refuse before rendering instead of failing after it."""
    try:
        fst = folder.stat()
        est = p.lstat()
    except OSError:
        return
    uid = os.geteuid()
    if fst.st_mode & stat.S_ISVTX and uid != 0 and uid not in (fst.st_uid, est.st_uid):
        raise ImageWriteError(f"{p}: cannot replace it: it belongs to another user in the sticky folder "
                              f"'{folder}'")


def temp_prefix(name: str) -> str:
    """The prefix of this process's temporaries for a target called ``name``."""
    return f".{name}.a5mi-{os.getpid()}-"


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def remove_stale(folder: str | os.PathLike[str], name: str) -> list[Path]:
    """Remove the temporaries of target ``name`` in ``folder`` left by processes that no longer run (regular
    files, and staging folders of :func:`a5mi.converters.to_xml.write_xml`, never through a symlink); returns
    what was removed. Never raises."""
    removed: list[Path] = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for e in entries:
        m = _TEMP_RE.fullmatch(e.name)
        if m is None or m["name"] != name or int(m["pid"]) == os.getpid() or _alive(int(m["pid"])):
            continue
        try:
            if e.is_file(follow_symlinks=False):
                os.unlink(e.path)
                removed.append(Path(e.path))
            elif e.is_dir(follow_symlinks=False):
                import shutil

                shutil.rmtree(e.path)  # rmtree never follows symlinks inside
                removed.append(Path(e.path))
        except OSError:
            pass
    return removed


def read_regular(path: str | os.PathLike[str], limit: int, what: str = "file") -> bytes:
    """The bytes of the regular file ``path``, at most ``limit`` of them. Opened with ``O_NONBLOCK`` (a FIFO
    does not block) and checked with ``fstat`` after opening: a FIFO, device, socket or folder is refused,
    as is a file larger than ``limit``. Raises :class:`~a5mi.platform.errors.FileReadError` (``OSError`` reasons as
    text in its ``reason``)."""

    def fail(reason: str) -> FileReadError:
        return FileReadError(f"cannot read {what} '{path}': {reason}", reason)

    if str(path) == "":
        raise fail("the file name is empty")
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise fail(str(exc.strerror or exc)) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise fail(f"not a regular file ({file_kind(path)})")
        if st.st_size > limit:
            raise fail(f"{st.st_size} bytes is more than the limit of {limit} bytes")
        chunks: list[bytes] = []
        total = 0
        while chunk := os.read(fd, min(1 << 20, limit + 1 - total)):
            chunks.append(chunk)
            total += len(chunk)
            if total > limit:
                raise fail(f"more than the limit of {limit} bytes")
        return b"".join(chunks)
    except OSError as exc:
        raise fail(str(exc.strerror or exc)) from None
    finally:
        os.close(fd)
