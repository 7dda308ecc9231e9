"""``@syntax``: Dr.Jit's ``@dr.syntax`` with its output kept on disk (process start-up).

``@dr.syntax`` rewrites a function's loops and branches into Dr.Jit's symbolic ``while_loop`` / ``if_stmt``
when the decorator runs: it reads the source back (``inspect.getsource``), parses it, transforms the tree
and compiles it, in every process; ``mi.set_variant`` pays the same again for Mitsuba's own Python integrators
(``prb``, ``prbvolpath``, ...), which it imports and decorates anew in every process. Measured: variant
activation plus plugin registration 0.44 s with the cache, 0.64 s without (best of 5; 1.12 s and 2.00 s
on a loaded machine).

:func:`syntax` returns exactly the function ``dr.syntax`` returns (the same transformed code object, the
original globals and defaults) but keeps that code object in ``cache_dir()/syntax/`` (:func:`a5mi.cache_dir`),
named by the SHA-256 of the Dr.Jit and Python versions and the *original* code object (``marshal``: its
bytecode, constants, names, file and line numbers, so any edit of the function is another file; suffix
``.tagged``, so the untagged ``.code`` files of earlier versions are neither read nor overwritten). A file
that is missing, unreadable, unauthenticated or not a code object of that name and file is transformed again
and rewritten atomically; a folder that cannot be written, or that fails the checks below, means no cache.

Threat model. Loading a cache entry executes its bytecode, so an entry must come from this user's own earlier
run. Another local account, or a program this user runs with fewer rights (the sandboxes of ``a5mi grade`` and
``a5mi difftest``), must not be able to plant one:

* the cache folder, its ``syntax`` folder and every entry must be owned by the current user and writable by
  nobody else (no group or world write bit); otherwise the cache is not used at all (nothing read or written);
* every entry carries an HMAC-SHA256 (key: 32 random bytes in ``syntax/key``, created with the cache with mode
  0600 and refused if it is not the user's own or is readable or writable by anyone else) over its name and
  bytecode; an entry whose tag does not verify (a file copied in, edited, or written by a process that could not
  read the key) is ignored and rewritten.

Out of scope: code running as this user, which could edit the plugins themselves.

:func:`cached_drjit_syntax` makes ``dr.syntax`` itself this function for the duration of a ``with`` block:
:func:`a5mi.runtime.variant.activate` wraps ``mi.set_variant`` in it, so that Mitsuba's integrators are decorated
from the cache too; ``dr.syntax`` is restored afterwards.
"""

from __future__ import annotations

import contextlib
import hashlib
import hmac
import marshal
import os
import stat
import sys
import types
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

import drjit as dr

from a5mi import cache_dir

F = TypeVar("F", bound=Callable[..., Any])

#: ``dr.syntax`` as Dr.Jit defines it (captured before :func:`cached_drjit_syntax` can replace it).
TRANSFORM = dr.syntax


def cache_path(f: types.FunctionType, folder: Path | None = None) -> Path:
    """The cache file of ``f``'s transformed code (module docstring)."""
    h = hashlib.sha256(f"{dr.__version__}\0{sys.version}\0".encode())
    h.update(marshal.dumps(f.__code__))
    return (Path(cache_dir()) if folder is None else folder) / "syntax" / f"{h.hexdigest()}.tagged"


#: Bytes of an entry's tag (HMAC-SHA256), before its ``marshal`` payload.
TAG_BYTES = 32
#: The key file's name inside the ``syntax`` folder.
KEY_NAME = "key"


def _private(st: os.stat_result, mask: int) -> bool:
    """Owned by the current user, with none of the permission bits of ``mask``."""
    return st.st_uid == os.getuid() and not (st.st_mode & mask)


def _trusted_folder(folder: Path) -> bool:
    """``folder`` and its parent (the cache folder) are real folders of the current user, writable by nobody else
    (module docstring)."""
    try:
        return all(stat.S_ISDIR(st.st_mode) and _private(st, stat.S_IWGRP | stat.S_IWOTH)
                   for st in (os.lstat(folder), os.lstat(folder.parent)))
    except OSError:
        return False


def _key(folder: Path, create: bool) -> bytes | None:
    """The cache's HMAC key: ``folder/key``, the user's own, mode 0600 (nothing for group or others), 32 bytes;
    with ``create`` made (exclusively, 0600) when missing. None when there is none or it fails the checks."""
    path = folder / KEY_NAME
    if create and not path.exists():
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o600)
            with os.fdopen(fd, "wb") as out:
                out.write(os.urandom(TAG_BYTES))
        except FileExistsError:
            pass
        except OSError:
            return None
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
        with os.fdopen(fd, "rb") as src:
            st = os.fstat(src.fileno())
            key = src.read()
    except OSError:
        return None
    ok = stat.S_ISREG(st.st_mode) and _private(st, 0o077) and len(key) == TAG_BYTES
    return key if ok else None


def _tag(key: bytes, path: Path, payload: bytes) -> bytes:
    return hmac.new(key, path.name.encode() + b"\0" + payload, hashlib.sha256).digest()


def _load(path: Path, f: types.FunctionType, key: bytes) -> types.CodeType | None:
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
        with os.fdopen(fd, "rb") as src:
            st = os.fstat(src.fileno())
            data = src.read()
        if not (stat.S_ISREG(st.st_mode) and _private(st, stat.S_IWGRP | stat.S_IWOTH)):
            return None
        tag, payload = data[:TAG_BYTES], data[TAG_BYTES:]
        if not hmac.compare_digest(tag, _tag(key, path, payload)):
            return None     # tampered, foreign or from before the tags: not executed, transformed again
        code = marshal.loads(payload)
    except Exception:  # noqa: BLE001 - a cache must never be fatal (empty, truncated, garbage files)
        return None
    ok = isinstance(code, types.CodeType) and code.co_name == f.__name__ and code.co_filename == f.__code__.co_filename
    return code if ok else None


def _save(path: Path, code: types.CodeType, key: bytes) -> None:
    from a5mi.platform.imageio import atomic_file

    payload = marshal.dumps(code)
    try:
        with atomic_file(path, "wb") as out:
            out.write(_tag(key, path, payload) + payload)
    except (OSError, ValueError):
        pass


def _cache_key(folder: Path) -> bytes | None:
    """The key of a usable cache in ``folder`` (created with the folder, mode 0700, when missing), or None."""
    try:
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    except OSError:
        return None
    return _key(folder, create=True) if _trusted_folder(folder) else None


def syntax(f: F | None = None, **options: Any) -> Any:
    """``dr.syntax(f)``, its transformed code read from the cache when present (module docstring). With any
    of ``dr.syntax``'s options (``recursive``, ``print_ast``, ``print_code``) it is ``dr.syntax`` itself."""
    if f is None:
        return lambda g: syntax(g, **options)
    if options or not isinstance(f, types.FunctionType) or f.__closure__:
        return TRANSFORM(f, **options)
    path = cache_path(f)
    key = _cache_key(path.parent)
    code = _load(path, f, key) if key is not None else None
    if code is None:
        new = TRANSFORM(f)
        if key is not None:
            _save(path, new.__code__, key)
        return new
    new = types.FunctionType(code, f.__globals__)
    new.__defaults__ = f.__defaults__
    return new


@contextlib.contextmanager
def cached_drjit_syntax() -> Iterator[None]:
    """Within the block ``dr.syntax`` is :func:`syntax` (module docstring); restored on exit."""
    saved = dr.syntax
    dr.syntax = syntax
    try:
        yield
    finally:
        dr.syntax = saved


__all__ = ["TRANSFORM", "cache_path", "cached_drjit_syntax", "syntax"]
