"""Find the libLLVM that Dr.Jit will load, and refuse one that is too old.

Dr.Jit 1.5 emits ``llvm.minimum``/``llvm.maximum``; LLVM 15 cannot select them and aborts the whole
process (``LLVM ERROR: Cannot select ... fminimum``), LLVM 14 and older are refused outright. So before
Mitsuba loads an ``llvm_*`` variant we find the library the way Dr.Jit does (``DRJIT_LIBLLVM_PATH`` if set,
otherwise the newest ``libLLVM*`` on the library path) and check that it is LLVM >= 16.

This module uses the standard library only, so ``make setup`` can run it before any virtual environment
exists, through the command layer (:mod:`a5mi.cli.setup`)::

    python3 -m a5mi.cli.setup llvm    # check; on Debian/Ubuntu as root install libllvm19 if needed
"""

from __future__ import annotations

import glob
import os
import re
import shutil
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass

MIN_MAJOR = 16
DEBIAN_PACKAGE = "libllvm19"
INSTALL_HINT = f"apt-get update && apt-get install -y {DEBIAN_PACKAGE}"

_LIB_DIRS = (
    "/usr/lib/x86_64-linux-gnu",
    "/lib/x86_64-linux-gnu",
    "/usr/lib/aarch64-linux-gnu",
    "/lib/aarch64-linux-gnu",
    "/usr/lib64",
    "/usr/lib",
    "/usr/local/lib",
    "/opt/homebrew/opt/llvm/lib",
    "/usr/local/opt/llvm/lib",
)


class LLVMError(RuntimeError):
    """No usable libLLVM: the message is one line that names the fix."""


@dataclass(frozen=True)
class LLVMLibrary:
    path: str
    major: int | None  # None: could not be determined

    def usable(self) -> bool:
        return self.major is not None and self.major >= MIN_MAJOR


def _major_from_name(path: str) -> int | None:
    """``libLLVM-15.so`` -> 15, ``libLLVM.so.19.1`` -> 19, ``libLLVM-14.0.6.so.1`` -> 14."""
    name = os.path.basename(path)
    m = re.match(r"libLLVM-(\d+)", name) or re.match(r"libLLVM\.so\.(\d+)", name)
    if m:
        return int(m.group(1))
    m = re.match(r"libLLVM\.(\d+)\.dylib", name)
    return int(m.group(1)) if m else None


_VERSION_PROBE = """
import ctypes, sys
try:
    lib = ctypes.CDLL(sys.argv[1])
except OSError:
    sys.exit(3)
if not hasattr(lib, "LLVMGetVersion"):
    print(15)
else:
    major, minor, patch = ctypes.c_uint(), ctypes.c_uint(), ctypes.c_uint()
    lib.LLVMGetVersion(ctypes.byref(major), ctypes.byref(minor), ctypes.byref(patch))
    print(major.value)
"""


def _major_from_library(path: str) -> int | None:
    """Ask the library itself, in a child process (loading it here would map it into this process, where
    :func:`check_loaded` would then find it). ``LLVMGetVersion`` exists from LLVM 16 on, so its absence means
    < 16 (reported as 15: refused either way)."""
    try:
        p = subprocess.run([sys.executable, "-c", _VERSION_PROBE, path], capture_output=True, text=True,
                           timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return int(p.stdout) if p.returncode == 0 and p.stdout.strip().isdigit() else None


def probe(path: str) -> LLVMLibrary:
    major = _major_from_name(path)
    if major is None:
        major = _major_from_library(path)
    return LLVMLibrary(path, major)


def candidates() -> list[str]:
    """Every ``libLLVM*`` shared library on the usual library path (no symlink duplicates)."""
    dirs = [d for d in os.environ.get("LD_LIBRARY_PATH", "").split(":") if d] + list(_LIB_DIRS)
    seen: set[str] = set()
    found: list[str] = []
    for d in dirs:
        for p in sorted(glob.glob(os.path.join(d, "libLLVM*.so*")) + glob.glob(os.path.join(d, "libLLVM*.dylib"))):
            real = os.path.realpath(p)
            if real in seen or not os.path.isfile(real):
                continue
            seen.add(real)
            found.append(p)
    return found


def find() -> LLVMLibrary | None:
    """The library Dr.Jit will load: ``DRJIT_LIBLLVM_PATH``, else the newest ``libLLVM*`` found."""
    forced = os.environ.get("DRJIT_LIBLLVM_PATH")
    if forced:
        if not os.path.isfile(forced):
            return LLVMLibrary(forced, None)
        return probe(forced)
    libs = [probe(p) for p in candidates()]
    libs = [lib for lib in libs if lib.major is not None]
    if not libs:
        return None
    return max(libs, key=lambda lib: lib.major or 0)


def check() -> LLVMLibrary:
    """Return the usable library or raise :class:`LLVMError` with a one-line message naming the fix."""
    lib = find()
    forced = os.environ.get("DRJIT_LIBLLVM_PATH")
    if lib is None:
        raise LLVMError(
            f"no libLLVM found; the llvm variant needs LLVM >= {MIN_MAJOR}: run '{INSTALL_HINT}' "
            "(or use -variant cuda on a machine with an NVIDIA GPU)"
        )
    if forced and lib.major is None:
        raise LLVMError(
            f"DRJIT_LIBLLVM_PATH={forced} is not a readable libLLVM; unset it or point it at LLVM >= {MIN_MAJOR}"
        )
    if not lib.usable():
        where = f"DRJIT_LIBLLVM_PATH={forced}" if forced else lib.path
        raise LLVMError(
            f"Dr.Jit would load LLVM {lib.major} ({where}), but the llvm variant needs LLVM >= {MIN_MAJOR}: "
            f"run '{INSTALL_HINT}'" + (" and unset DRJIT_LIBLLVM_PATH" if forced else "")
        )
    return lib


def loaded(maps: str = "/proc/self/maps") -> list[LLVMLibrary]:
    """The libLLVM files mapped into this process (Linux ``/proc/self/maps``), each probed for its version."""
    try:
        with open(maps, encoding="utf-8", errors="replace") as f:
            paths = [ln.split(None, 5)[5].strip() for ln in f if "libLLVM" in ln and len(ln.split(None, 5)) == 6]
    except OSError:
        return []
    names = [p for p in dict.fromkeys(paths) if re.search(r"libLLVM[^/]*\.(so|dylib)", os.path.basename(p))]
    return [probe(p) for p in names]


def check_loaded(maps: str = "/proc/self/maps") -> None:
    """After Dr.Jit has initialised its LLVM backend, and before the first kernel is compiled: the library it
    *actually* loaded (``LD_LIBRARY_PATH`` or ``ld.so`` may pick another than :func:`find`) must be LLVM >= 16;
    raise :class:`LLVMError` naming it otherwise (LLVM 15 would abort the process at the first kernel)."""
    for lib in loaded(maps):
        if lib.major is not None and lib.major < MIN_MAJOR:
            env = os.environ.get("LD_LIBRARY_PATH", "")
            hint = f" (LD_LIBRARY_PATH={env} is searched first: remove its LLVM folder)" if env else ""
            raise LLVMError(f"Dr.Jit loaded LLVM {lib.major} ({lib.path}){hint}, but the llvm variant needs "
                            f"LLVM >= {MIN_MAJOR}: run '{INSTALL_HINT}'")


def ensure(log: Callable[[str], None]) -> LLVMLibrary:
    """``make setup``: check, and on Debian/Ubuntu as root install :data:`DEBIAN_PACKAGE` if needed.

    ``log`` receives progress lines; returns the usable library or raises :class:`LLVMError` (whose message
    names the fix)."""
    try:
        lib = check()
        log(f"libLLVM {lib.major} found ({lib.path})")
        return lib
    except LLVMError as exc:
        if os.environ.get("DRJIT_LIBLLVM_PATH"):
            raise
        can_apt = shutil.which("apt-get") is not None and hasattr(os, "geteuid") and os.geteuid() == 0
        if not can_apt:
            raise LLVMError(f"{exc}; as root on Debian/Ubuntu: {INSTALL_HINT}") from None
    log(f"installing {DEBIAN_PACKAGE} (Dr.Jit needs libLLVM >= {MIN_MAJOR})")
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    for cmd in (["apt-get", "update", "-qq"], ["apt-get", "install", "-y", "-qq", DEBIAN_PACKAGE]):
        if subprocess.call(cmd, env=env) != 0:
            raise LLVMError(f"'{' '.join(cmd)}' failed; install LLVM >= {MIN_MAJOR} by hand")
    lib = check()
    log(f"libLLVM {lib.major} installed ({lib.path})")
    return lib
