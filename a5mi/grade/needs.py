"""What a submission needs to start that the sandbox does not show it (``docs/GRADING.md`` "What a program
needs to start").

A sandboxed run sees ``/usr`` (and the ``/bin /lib /lib64 /sbin`` links), its submission, the scenes and the
``--allow-read`` paths. A wrapper ``exec /opt/venv/bin/a5 "$@"`` whose interpreter lives elsewhere (pyenv, conda,
a TA's virtual environment) fails there with ``exit status 127 ... not found``. :func:`missing_paths` finds, by
reading files only (nothing of the submission is executed on the grader):

* the ``#!`` interpreter of a script (``/usr/bin/env NAME`` resolves inside ``/usr``), and every absolute path
  the script's text names that exists on the host and is an executable file (what a wrapper ``exec``\\ s);
* for an ELF executable: its interpreter (``PT_INTERP``) and the libraries of ``DT_NEEDED`` as ``ldd`` resolves
  them: ``DT_RPATH`` / ``DT_RUNPATH`` (``$ORIGIN`` substituted), then the loader cache (``ldconfig -p``);

followed to a depth of :data:`DEPTH` (the wrapper, the virtual environment's script, its interpreter, its
libraries). Each such file outside the sandbox's view gives the folder to allow: an installation's prefix (the
folder above ``bin/`` or ``lib/``), else the file's folder. The grader never binds them by itself (a student
could name ``/root/.ssh`` in a script): :func:`allow_hint` names them in one ``--allow-read`` line.
"""

from __future__ import annotations

import functools
import os
import re
import shutil
import struct
import subprocess
from collections.abc import Sequence

#: How many files deep the search follows (wrapper -> script -> interpreter -> library).
DEPTH = 4
#: Bytes of a script read for paths (a wrapper is short).
SCRIPT_BYTES = 64 << 10
#: What every sandboxed run sees of the host (besides its submission, the scenes and ``--allow-read``).
SYSTEM_VIEW = ("/usr", "/bin", "/lib", "/lib64", "/sbin", "/lib32", "/libx32", "/etc")

_PATH = re.compile(rb"(?<![\w./-])(/[\w.+@%-]+(?:/[\w.+@%-]+)+)")


def _under(path: str, roots: Sequence[str]) -> bool:
    return any(path == r or path.startswith(r.rstrip("/") + "/") for r in roots)


def _read(path: str, n: int) -> bytes:
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError:
        return b""
    try:
        if not os.path.isfile(f"/proc/self/fd/{fd}"):
            return b""
        return os.read(fd, n)
    finally:
        os.close(fd)


@functools.cache
def _loader_cache() -> dict[str, str]:
    """soname -> path of the host's loader cache (``ldconfig -p``: reads ``/etc/ld.so.cache`` only)."""
    exe = shutil.which("ldconfig") or "/sbin/ldconfig"
    try:
        out = subprocess.run([exe, "-p"], capture_output=True, text=True, timeout=10, check=False).stdout
    except (OSError, subprocess.TimeoutExpired):
        return {}
    entries = [m.groups() for m in (re.match(r"\s*(\S+) \((.*)\) => (\S+)", ln) for ln in out.splitlines()) if m]
    found: dict[str, str] = {}
    for soname, _desc, where in sorted(entries, key=lambda e: "x86-64" not in e[1]):  # this machine's first
        found.setdefault(soname, where)
    return found


def elf_needs(path: str) -> tuple[str | None, list[str], list[str]]:
    """``(PT_INTERP, DT_NEEDED sonames, DT_RPATH + DT_RUNPATH folders)`` of a 64-bit little-endian ELF file
    (``(None, [], [])`` for anything else), read from its program headers and dynamic section."""
    data = _read(path, 16 << 20)
    if len(data) < 64 or data[:4] != b"\x7fELF" or data[4] != 2 or data[5] != 1:
        return None, [], []
    phoff, = struct.unpack_from("<Q", data, 32)
    phentsize, phnum = struct.unpack_from("<HH", data, 54)
    interp, dyn, loads = None, None, []
    for k in range(phnum):
        off = phoff + k * phentsize
        if off + 56 > len(data):
            break
        ptype, _, poff, pvaddr, _, pfilesz, _, _ = struct.unpack_from("<IIQQQQQQ", data, off)
        if ptype == 3:  # PT_INTERP
            interp = data[poff:poff + pfilesz].split(b"\0")[0].decode("utf-8", "replace")
        elif ptype == 2:  # PT_DYNAMIC
            dyn = (poff, pfilesz)
        elif ptype == 1:  # PT_LOAD
            loads.append((pvaddr, poff, pfilesz))

    def at(vaddr: int) -> int | None:
        for v, o, size in loads:
            if v <= vaddr < v + size:
                return o + vaddr - v
        return None

    needed, paths = [], []
    if dyn is not None:
        entries = []
        strtab = None
        for k in range(dyn[1] // 16):
            tag, val = struct.unpack_from("<qQ", data, dyn[0] + 16 * k) if dyn[0] + 16 * k + 16 <= len(data) \
                else (0, 0)
            if tag == 0:
                break
            if tag == 5:  # DT_STRTAB
                strtab = at(val)
            entries.append((tag, val))
        if strtab is not None:
            def text(v: int) -> str:
                return data[strtab + v:].split(b"\0")[0].decode("utf-8", "replace")

            needed = [text(v) for t, v in entries if t == 1]
            origin = os.path.dirname(os.path.realpath(path))
            for t, v in entries:
                if t in (15, 29):  # DT_RPATH, DT_RUNPATH
                    paths += [p.replace("${ORIGIN}", origin).replace("$ORIGIN", origin)
                              for p in text(v).split(":") if p]
    return interp, needed, paths


def _resolve_library(soname: str, search: Sequence[str]) -> str | None:
    for d in search:
        p = os.path.join(d, soname)
        if os.path.isfile(p):
            return p
    return _loader_cache().get(soname)


def _prefix(path: str) -> str:
    """The folder to allow for a file: the installation prefix above ``bin/`` or ``lib*/``, else its folder."""
    parent = os.path.dirname(path)
    if os.path.basename(parent) in ("bin", "sbin", "lib", "lib64", "lib32"):
        return os.path.dirname(parent) or parent
    return parent


def _script_targets(path: str, text: bytes) -> list[str]:
    out = []
    first, _, body = text.partition(b"\n")
    words = first[2:].split()
    if words:
        interp = words[0].decode("utf-8", "replace")
        if os.path.basename(interp) == "env" and len(words) > 1:
            name = words[1].decode("utf-8", "replace")
            found = shutil.which(name, path="/usr/bin:/bin")
            out.append(found or f"/usr/bin/{name}")
        else:
            out.append(interp)
    for m in _PATH.finditer(body):
        p = m.group(1).decode("utf-8", "replace")
        if os.path.isfile(p) and os.access(p, os.X_OK):
            out.append(p)
    return out


def missing_paths(executable: str | os.PathLike[str], visible: Sequence[str] = ()) -> list[str]:
    """The folders a submission's ``executable`` needs to start that the sandbox does not show it (module
    docstring); ``visible``: what the run sees besides :data:`SYSTEM_VIEW` (its submission, the scenes, the
    ``--allow-read`` paths). Sorted, without a folder inside another."""
    seen_roots = [*SYSTEM_VIEW, *(os.path.realpath(v) for v in visible), *visible]
    if not _under(os.path.realpath(executable), seen_roots):
        return []  # a link out of the submission: it is not read (nothing of the host is looked at for it)
    todo, done = [(str(executable), 0)], set()
    missing: set[str] = set()
    while todo:
        path, depth = todo.pop()
        if path in done or depth > DEPTH:
            continue
        done.add(path)
        real = os.path.realpath(path)
        for p in {path, real}:
            if os.path.exists(p) and not _under(p, seen_roots):
                missing.add(_prefix(p))
        head = _read(real, SCRIPT_BYTES)
        if head.startswith(b"#!"):
            todo += [(t, depth + 1) for t in _script_targets(real, head)]
            continue
        interp, needed, rpaths = elf_needs(real)
        if interp:
            todo.append((interp, depth + 1))
        for soname in needed:
            lib = _resolve_library(soname, rpaths)
            if lib:
                todo.append((lib, depth + 1))
    roots = sorted(missing)
    return [r for r in roots if not any(r != o and _under(r, (o,)) for o in roots)]


def allow_hint(paths: Sequence[str]) -> str:
    """One line naming what to allow: ``needs /opt/venv, /root/.pyenv/versions/3.11.7 outside the sandbox: add
    --allow-read /opt/venv:/root/.pyenv/versions/3.11.7``."""
    return (f"needs {', '.join(paths)} outside the sandbox: add --allow-read {':'.join(paths)}" if paths else "")


__all__ = ["DEPTH", "SYSTEM_VIEW", "allow_hint", "elf_needs", "missing_paths"]
