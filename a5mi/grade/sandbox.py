"""Run one untrusted student program, bounded (issue 13, ``docs/GRADING.md`` "Sandbox").

Every run gets, whatever the machine offers:

* **rlimits** (``prlimit`` before the program starts): address space (``memory_mb``), CPU seconds
  (``timeout`` + 1), file size (``fsize_mb``), processes (``nproc``), no core files;
* a **unique user id** when the grader is root (``setpriv`` drops to it, so ``RLIMIT_NPROC``, which the kernel
  never enforces on root, holds: a fork bomb stops at ``nproc`` processes) and a private working folder owned
  by that id;
* its **own process group / session**, killed (SIGKILL) on timeout, and after the run every process still
  owned by the run's user id is killed too;
* a **scrubbed environment**: ``PATH=/usr/bin:/bin``, ``HOME`` = the working folder, ``LANG=C.UTF-8``, plus
  ``env`` given by the caller;
* **capped output**: stdout and stderr are drained as they come; the first ``keep_bytes`` of stdout and the
  last ``keep_bytes`` of stderr are kept, the rest is counted and dropped (a program printing 1 GB costs the
  grader ``keep_bytes``, not 1 GB).

With bubblewrap (``bwrap``) on the PATH it also runs in fresh PID, network, IPC and UTS namespaces (no network
at all: only a loopback device that is down), with a root file system that holds only ``/usr`` (and the
``/bin /lib /lib64 /sbin`` links), ``/etc``, a private ``/tmp``, the ``read_only`` paths (scene data, the
submission) read-only and the working folder writable; nothing else of the host is visible. Without it
:func:`isolation` says so once and the run has the rlimits, user id and private folder only.
"""

from __future__ import annotations

import os
import selectors
import shutil
import signal
import subprocess
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

#: Patterns in stderr that say the program ran out of memory (C++, Python, glibc, Rust, Go, the shell).
MEMORY_PATTERNS: tuple[str, ...] = ("bad_alloc", "MemoryError", "Cannot allocate memory", "out of memory",
                                    "memory allocation", "Out of memory")
#: First user id handed to sandboxed runs when the grader is root (one id per run: 100000 + run number).
UID_BASE = 100_000
UID_SPAN = 800_000


@dataclass(frozen=True)
class Limits:
    """Per-run bounds: wall ``timeout`` (s), address space ``memory_mb``, ``fsize_mb`` per written file,
    ``nproc`` processes/threads of the run's user, ``keep_bytes`` of stdout (head) and stderr (tail)."""

    timeout: float = 60.0
    memory_mb: int = 4096
    fsize_mb: int = 256
    nproc: int = 256
    keep_bytes: int = 64 * 1024


@dataclass
class RunResult:
    """What happened: ``returncode`` (negative = killed by that signal, as :mod:`subprocess`), ``timed_out``,
    ``over_memory`` (a memory failure per :data:`MEMORY_PATTERNS` or peak RSS near the limit), the kept
    ``stdout_head`` / ``stderr_tail``, the byte counts, ``wall`` seconds and the ``isolation`` used."""

    returncode: int
    timed_out: bool
    over_memory: bool
    stdout_head: str
    stderr_tail: str
    stdout_bytes: int
    stderr_bytes: int
    wall: float
    isolation: str
    argv: list[str] = field(default_factory=list)

    @property
    def crashed(self) -> bool:
        return self.returncode != 0 and not self.timed_out


def bwrap_path() -> str | None:
    """The bubblewrap executable, unless ``A5MI_NO_BWRAP`` is set (to test the fallback)."""
    if os.environ.get("A5MI_NO_BWRAP"):
        return None
    return shutil.which("bwrap")


def isolation() -> str:
    """``"bwrap"`` or ``"rlimits"``: the isolation :func:`run_sandboxed` will use on this machine."""
    return "bwrap" if bwrap_path() else "rlimits"


def _run_uid() -> int | None:
    """A fresh user id for this run when root (pid and a clock make collisions between workers unlikely)."""
    if os.geteuid() != 0 or shutil.which("setpriv") is None:
        return None
    return UID_BASE + (os.getpid() * 7919 + time.monotonic_ns() // 1000) % UID_SPAN


def _bwrap_prefix(bwrap: str, workdir: Path, read_only: Sequence[Path]) -> list[str]:
    cmd = [bwrap, "--unshare-pid", "--unshare-net", "--unshare-ipc", "--unshare-uts", "--unshare-cgroup-try",
           "--die-with-parent", "--new-session", "--ro-bind", "/usr", "/usr", "--ro-bind", "/etc", "/etc",
           "--proc", "/proc", "--dev", "/dev", "--tmpfs", "/tmp"]
    for name in ("bin", "lib", "lib64", "sbin", "lib32", "libx32"):
        p = Path("/") / name
        if p.is_symlink():
            cmd += ["--symlink", os.readlink(p), str(p)]
        elif p.is_dir():
            cmd += ["--ro-bind", str(p), str(p)]
    binds: list[tuple[str, str, str]] = []  # (option, source, destination)
    for ro in read_only:
        real = os.path.realpath(ro)
        if not os.path.exists(real) or real.startswith(("/usr/", "/etc/")):
            continue
        binds.append(("--ro-bind", real, real))
        alias = str(Path(ro).absolute())
        if alias != real:
            binds.append(("--ro-bind", real, alias))
    work = os.path.realpath(workdir)
    binds.append(("--bind", work, work))
    mounted: list[str] = ["/usr", "/etc", "/proc", "/dev", "/tmp"]
    made: set[str] = set()
    for opt, src, dest in sorted(set(binds), key=lambda b: (len(b[2]), b[2])):
        if any(dest == m or dest.startswith(m + "/") for m in mounted[5:]):
            continue  # already visible through an enclosing bind
        # parents that bwrap would otherwise create 0700 (unreadable for the run's user id)
        for parent in reversed(Path(dest).parents):
            sp = str(parent)
            if sp != "/" and sp not in made and not any(sp == m or sp.startswith(m + "/") for m in mounted[5:]):
                cmd += ["--perms", "0755", "--dir", sp]
                made.add(sp)
        cmd += [opt, src, dest]
        mounted.append(dest)
    cmd += ["--chdir", work]
    return cmd


def command_line(argv: Sequence[str], workdir: Path, limits: Limits, read_only: Sequence[Path] = (),
                 uid: int | None = None) -> tuple[list[str], str]:
    """The full command: ``[bwrap ...] prlimit ... [setpriv ...] argv`` and the isolation name."""
    cpu = int(limits.timeout) + 1
    prlimit = ["prlimit", f"--as={limits.memory_mb * 1024 * 1024}", f"--cpu={cpu}",
               f"--fsize={limits.fsize_mb * 1024 * 1024}", f"--nproc={limits.nproc}", "--core=0", "--"]
    drop = ([] if uid is None else
            ["setpriv", f"--reuid={uid}", f"--regid={uid}", "--clear-groups", "--"])
    bwrap = bwrap_path()
    if bwrap is not None:
        return [*_bwrap_prefix(bwrap, workdir, read_only), "/usr/bin/prlimit", *prlimit[1:], *drop, *argv], "bwrap"
    return [shutil.which("prlimit") or "prlimit", *prlimit[1:], *drop, *argv], "rlimits"


def _live_processes(uid: int) -> list[int]:
    """Processes of real user id ``uid`` that are not zombies (a zombie holds no resources but its entry)."""
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/status", encoding="ascii", errors="replace") as f:
                fields = dict(ln.split(":", 1) for ln in f if ":" in ln)
        except OSError:
            continue
        if fields.get("Uid", "").split()[:1] == [str(uid)] and not fields.get("State", "").strip().startswith("Z"):
            found.append(int(entry))
    return found


def kill_uid(uid: int) -> int:
    """SIGKILL every live process whose real user id is ``uid`` (the run's leftovers, wherever they moved:
    another session, another process group), until none is left; returns how many signals were sent."""
    killed = 0
    for _ in range(200):
        found = _live_processes(uid)
        if not found:
            break
        for pid in found:
            try:
                os.kill(pid, signal.SIGKILL)
                killed += 1
            except OSError:
                pass
        time.sleep(0.01)
    return killed


def run_sandboxed(argv: Sequence[str], workdir: str | os.PathLike[str], limits: Limits | None = None, *,
                  read_only: Sequence[str | os.PathLike[str]] = (), env: dict[str, str] | None = None) -> RunResult:
    """Run ``argv`` in ``workdir`` (the private working folder, created by the caller) under the module's
    bounds; never raises for anything the program does. Returns its :class:`RunResult`."""
    limits = limits or Limits()
    work = Path(workdir)
    uid = _run_uid()
    if uid is not None:
        for p in (work, *work.rglob("*")):
            os.lchown(p, uid, uid)
    cmd, how = command_line(list(argv), work, limits, [Path(p) for p in read_only], uid)
    environment = {"PATH": "/usr/bin:/bin", "HOME": str(work), "LANG": "C.UTF-8", "TMPDIR": "/tmp"
                   if how == "bwrap" else str(work)}
    environment.update(env or {})
    t0 = time.perf_counter()
    try:
        proc = subprocess.Popen(cmd, cwd=work, env=environment, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, start_new_session=True, close_fds=True)
    except OSError as exc:
        return RunResult(127, False, False, "", f"cannot start: {exc}", 0, 0, 0.0, how, list(argv))
    out_head, err_tail, counts, timed_out = _drain(proc, limits, t0)
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except OSError:
        pass
    if uid is not None:
        kill_uid(uid)
    wall = time.perf_counter() - t0
    rc = proc.returncode if proc.returncode is not None else -signal.SIGKILL
    err_text = err_tail.decode("utf-8", "replace")
    over = (not timed_out and rc != 0 and any(p in err_text for p in MEMORY_PATTERNS))
    return RunResult(rc, timed_out, over, out_head.decode("utf-8", "replace"), err_text, counts[0], counts[1],
                     wall, how, list(argv))


def _drain(proc: subprocess.Popen[bytes], limits: Limits, t0: float) -> tuple[bytes, bytes, list[int], bool]:
    """Read both pipes until they close or the deadline: keep stdout's head and stderr's tail."""
    assert proc.stdout is not None and proc.stderr is not None
    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ, 0)
    sel.register(proc.stderr, selectors.EVENT_READ, 1)
    head, tail = bytearray(), bytearray()
    counts = [0, 0]
    timed_out = False
    open_pipes = 2
    while open_pipes:
        left = limits.timeout - (time.perf_counter() - t0)
        if left <= 0:
            timed_out = True
            break
        for key, _ in sel.select(timeout=min(left, 0.5)):
            chunk = os.read(key.fileobj.fileno(), 1 << 16)  # type: ignore[union-attr]
            if not chunk:
                sel.unregister(key.fileobj)
                open_pipes -= 1
                continue
            counts[key.data] += len(chunk)
            if key.data == 0:
                if len(head) < limits.keep_bytes:
                    head += chunk[: limits.keep_bytes - len(head)]
            else:
                tail += chunk
                if len(tail) > 2 * limits.keep_bytes:
                    del tail[: len(tail) - limits.keep_bytes]
    if timed_out:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except OSError:
            pass
    try:
        proc.wait(timeout=max(0.5, limits.timeout - (time.perf_counter() - t0)) if not timed_out else 5)
    except subprocess.TimeoutExpired:
        timed_out = True
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except OSError:
            pass
        proc.wait()
    sel.close()
    proc.stdout.close()
    proc.stderr.close()
    return bytes(head), bytes(tail[-limits.keep_bytes:]), counts, timed_out


__all__ = ["Limits", "MEMORY_PATTERNS", "RunResult", "bwrap_path", "command_line", "isolation", "kill_uid",
           "run_sandboxed"]
