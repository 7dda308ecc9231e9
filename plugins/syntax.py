"""``@syntax``: Dr.Jit's ``@dr.syntax`` with its output kept on disk (process start-up).

``@dr.syntax`` rewrites a function's loops and branches into Dr.Jit's symbolic ``while_loop`` / ``if_stmt``
when the decorator runs: it reads the source back (``inspect.getsource``), parses it, transforms the tree
and compiles it, in every process. For the a5mi plugins' eight decorated functions that is ~0.13 s of each
``a5`` run, and ``mi.set_variant`` pays the same again for Mitsuba's own Python integrators (``prb``,
``prbvolpath``, ...), which it imports and decorates anew in every process (measured: BENCHMARKS.md).

:func:`syntax` returns exactly the function ``dr.syntax`` returns (the same transformed code object, the
original globals and defaults) but keeps that code object in ``cache_dir()/syntax/`` (:func:`a5mi.cache_dir`),
named by the SHA-256 of the Dr.Jit and Python versions and the *original* code object (``marshal``: its
bytecode, constants, names, file and line numbers, so any edit of the function is another file). A file
that is missing, unreadable or not a code object of that name and file is transformed again and rewritten
atomically; a folder that cannot be written means no cache. The files hold Python bytecode, like
``__pycache__``: the cache folder must be the user's own (the sandboxes of ``a5mi grade`` and ``a5mi
difftest`` see it read-only, if at all).

:func:`cached_drjit_syntax` makes ``dr.syntax`` itself this function for the duration of a ``with`` block:
:func:`a5mi.variant.activate` wraps ``mi.set_variant`` in it, so that Mitsuba's integrators are decorated
from the cache too; ``dr.syntax`` is restored afterwards.
"""

from __future__ import annotations

import contextlib
import hashlib
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
    return (Path(cache_dir()) if folder is None else folder) / "syntax" / f"{h.hexdigest()}.code"


def _load(path: Path, f: types.FunctionType) -> types.CodeType | None:
    try:
        if not stat.S_ISREG(os.stat(path).st_mode):
            return None
        code = marshal.loads(path.read_bytes())
    except Exception:  # noqa: BLE001 - a cache must never be fatal (empty, truncated, garbage files)
        return None
    ok = isinstance(code, types.CodeType) and code.co_name == f.__name__ and code.co_filename == f.__code__.co_filename
    return code if ok else None


def _save(path: Path, code: types.CodeType) -> None:
    from a5mi.imageio import atomic_file

    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_file(path, "wb") as out:
            out.write(marshal.dumps(code))
    except (OSError, ValueError):
        pass


def syntax(f: F | None = None, **options: Any) -> Any:
    """``dr.syntax(f)``, its transformed code read from the cache when present (module docstring). With any
    of ``dr.syntax``'s options (``recursive``, ``print_ast``, ``print_code``) it is ``dr.syntax`` itself."""
    if f is None:
        return lambda g: syntax(g, **options)
    if options or not isinstance(f, types.FunctionType) or f.__closure__:
        return TRANSFORM(f, **options)
    path = cache_path(f)
    code = _load(path, f)
    if code is None:
        new = TRANSFORM(f)
        _save(path, new.__code__)
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
