"""Run one untrusted program, bounded and confined; take back only the files it wrote; decode them unprivileged.

The one sandbox of ``a5mi grade`` (a student's ``a5``) and ``a5mi difftest --binary`` (a5soln, a student's
``a5``); ``docs/GRADING.md`` "Threat model" lists what a program run here can and cannot do.

**Every run** gets, whatever the machine offers:

* **rlimits** (``prlimit`` before the program starts): address space (``memory_mb``), CPU seconds
  (``timeout`` + 1), file size (``fsize_mb``), processes (``nproc``), no core files;
* a **unique user id** when the grader is root (one per run, ``UID_BASE`` + a hash of pid and clock), so that
  ``RLIMIT_NPROC`` (never enforced on root) holds, the run owns nothing of the host, and every process it
  leaves behind is found and killed after it (:func:`kill_uid`); its working folder is chowned to that id;
* its **own session**, SIGKILLed on timeout;
* a **scrubbed environment**: ``PATH=/usr/bin:/bin``, ``HOME`` = the working folder (absolute), ``LANG=C.UTF-8``,
  ``TMPDIR`` = a private writable temporary folder, plus ``env`` given by the caller;
* **capped output**: the first ``keep_bytes`` of stdout and the last ``keep_bytes`` of stderr are kept, the rest
  is counted and dropped.

**With bubblewrap** (``bwrap`` >= 0.8, checked once per process by running a sandbox, :func:`isolation`) the
program also runs

* in fresh PID, network, IPC, UTS (and cgroup) namespaces, killed with its parent. The network namespace has
  only its own loopback device (up, 127.0.0.1, reaching nothing of the host: a port the grader listens on is
  not there), no other interface and no route, so ``connect`` to any other address fails at once;
* on a root file system that holds only ``/usr`` (with the ``/bin /lib /lib64 /sbin`` links), the loader's
  and the shell's files of ``/etc`` (:data:`ETC_FILES`), a fresh ``/proc`` and ``/dev``, a private ``/tmp``
  (tmpfs of ``fsize_mb``, mode 1777), the ``read_only`` paths read-only and the working folder writable;
* as an **unprivileged user with no capabilities**, in a user namespace in which no further user namespace can
  be made (``bwrap --unshare-user --disable-userns --cap-drop ALL``; setuid binaries do not elevate:
  ``no_new_privs``). When the grader is root the file system is set up by a root ``bwrap`` (so the bound paths
  need not be reachable for the run's user id), which then drops to the run's user id with ``setpriv`` and
  starts the unprivileged ``bwrap`` that makes the user namespace;

so it cannot read ``/etc/shadow``, the checkout or the grader's home, write outside its folder, remount,
``unshare -r``, connect to the host (the Dask scheduler included) or signal a process that is not its own.

**Without bubblewrap** a run is refused (:class:`SandboxUnavailable`) unless ``Limits.require_sandbox`` is off
(``--no-sandbox``): it then has the rlimits, user id, session and private folder only, and can reach the host's
network and read what its user id may read.

**Outputs**: what a run wrote is taken back only through :mod:`a5mi.sandbox.outputs` (regular files the run
created, ``O_NOFOLLOW``, one link, its owner, a size bound) and decoded there in a child confined by
:func:`run_sandboxed`.
"""

from __future__ import annotations

import functools
import math
import os
import selectors
import shutil
import signal
import subprocess
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from a5mi.sandbox.accounting import RunCgroup, kill_uid, live_processes
from a5mi.sandbox.folders import RunFolder, disk_full, is_under, mounts_under, run_folder, unmount
from a5mi.sandbox.records import Limits, OutputRefused, RunResult, SandboxUnavailable

#: Patterns in stderr that say the program ran out of disk space or inodes (errno ENOSPC, EDQUOT).
DISK_PATTERNS: tuple[str, ...] = ("No space left on device", "Disk quota exceeded")
#: Patterns in stderr that say the program ran out of memory (C++, Python, glibc, Rust, Go, the shell).
MEMORY_PATTERNS: tuple[str, ...] = ("bad_alloc", "MemoryError", "Cannot allocate memory", "out of memory",
                                    "memory allocation", "Out of memory")
#: First user id handed to sandboxed runs when the grader is root (one id per run: 100000 + run number).
UID_BASE = 100_000
UID_SPAN = 800_000
#: What of ``/etc`` a run sees (read-only): the dynamic loader's cache and configuration, the alternatives
#: links of ``/usr/bin``, the time zone, name-service switch, users and groups (no password hashes).
ETC_FILES: tuple[str, ...] = ("ld.so.cache", "ld.so.conf", "ld.so.conf.d", "ld.so.preload", "alternatives",
                              "localtime", "nsswitch.conf", "passwd", "group")

INSTALL_HINT = "apt-get install bubblewrap"


def bwrap_path() -> str | None:
    """The bubblewrap executable, unless ``A5MI_NO_BWRAP`` is set (to test the fallback)."""
    if os.environ.get("A5MI_NO_BWRAP"):
        return None
    return shutil.which("bwrap")


@functools.cache
def _probe(bwrap: str, as_root: bool) -> str:
    """Run ``/bin/true`` in a sandbox as a run would; ``""`` if it works, else why not (one line)."""
    with tempfile.TemporaryDirectory(prefix="a5mi-probe-") as tmp:
        work = Path(tmp)
        uid = fresh_uid() if as_root else None
        if uid is not None:
            os.chown(work, uid, uid)
        cmd = _bwrap_command(bwrap, ["/bin/true"], work, View(), uid, 16)
        try:
            proc = subprocess.run(cmd, cwd=work, stdin=subprocess.DEVNULL, capture_output=True, timeout=30,
                                  check=False)
        except (OSError, subprocess.TimeoutExpired) as exc:
            return str(exc)
        if proc.returncode == 0:
            return ""
        lines = proc.stderr.decode("utf-8", "replace").strip().splitlines()
        return lines[-1] if lines else f"exit status {proc.returncode}"


def sandbox_problem() -> str:
    """``""`` when bubblewrap can confine a run here, else why not (not installed, too old, no user
    namespaces)."""
    bwrap = bwrap_path()
    if bwrap is None:
        return "bubblewrap (bwrap) is not installed"
    why = _probe(bwrap, os.geteuid() == 0 and shutil.which("setpriv") is not None)
    return "" if not why else f"bubblewrap ({bwrap}) cannot make a sandbox here: {why}"


#: What :func:`isolation` says when runs are not sandboxed (shown in the grade report).
NOT_SANDBOXED = "rlimits: NOT SANDBOXED (no bubblewrap: rlimits, a user id and a private folder only)"


def isolation() -> str:
    """``"bwrap"``, or :data:`NOT_SANDBOXED`: the isolation :func:`run_sandboxed` gives a run on this machine
    (a run's :attr:`RunResult.isolation` is ``bwrap`` or ``rlimits``)."""
    return NOT_SANDBOXED if sandbox_problem() else "bwrap"


def refusal(flag: str = "--no-sandbox") -> str:
    """The one-line reason to refuse to run an executable without a sandbox (empty when there is one)."""
    why = sandbox_problem()
    if not why:
        return ""
    return (f"{why}: refusing to run untrusted executables unsandboxed (they could read the grader's files and "
            f"reach the network and the Dask scheduler); install bubblewrap ({INSTALL_HINT}) or pass {flag} to "
            f"run them with rlimits and their own user id only")


def fresh_uid() -> int | None:
    """A fresh user id for this run when root (pid and a clock make collisions between workers unlikely)."""
    if os.geteuid() != 0 or shutil.which("setpriv") is None:
        return None
    return UID_BASE + (os.getpid() * 7919 + time.monotonic_ns() // 1000) % UID_SPAN


@dataclass(frozen=True)
class View:
    """Where a run sees things (``docs/GRADING.md`` "What remains visible"): ``read_only`` paths bound at their
    own path (an interpreter a wrapper names), ``views`` (host path, path inside) bound read-only under neutral
    names, the working folder at ``work`` inside (None: its own path) and ``tmp`` the host folder bound as
    ``/tmp`` (None: a fresh tmpfs of ``fsize_mb``)."""

    read_only: tuple[str, ...] = ()
    views: tuple[tuple[str, str], ...] = ()
    work: str | None = None
    tmp: str | None = None


def _mounts(workdir: Path, view: View, tmp_mb: int, extra_ro: Sequence[str] = ()) -> list[str]:
    """bubblewrap's namespace and file-system options (module docstring), ending with ``--chdir``."""
    args = ["--unshare-pid", "--unshare-net", "--unshare-ipc", "--unshare-uts", "--unshare-cgroup-try",
            "--die-with-parent", "--new-session", "--ro-bind", "/usr", "/usr", "--proc", "/proc", "--dev", "/dev"]
    if view.tmp is None:
        args += ["--perms", "1777", "--size", str(tmp_mb << 20), "--tmpfs", "/tmp"]
    else:
        args += ["--bind", os.path.realpath(view.tmp), "/tmp"]
    args += ["--perms", "0755", "--dir", "/etc"]
    for name in ("bin", "lib", "lib64", "sbin", "lib32", "libx32"):
        p = Path("/") / name
        if p.is_symlink():
            args += ["--symlink", os.readlink(p), str(p)]
        elif p.is_dir():
            args += ["--ro-bind", str(p), str(p)]
    for name in ETC_FILES:
        p = Path("/etc") / name
        if p.exists() or p.is_symlink():
            args += ["--ro-bind", str(p), str(p)]
    binds: list[tuple[str, str, str]] = []  # (option, source, destination)
    for ro in [*view.read_only, *extra_ro]:
        real = os.path.realpath(ro)
        if not os.path.exists(real) or real in ("/", "/etc", "/tmp") or is_under(real, ("/usr", "/proc", "/dev")):
            continue  # already there, or never bound whole
        binds.append(("--ro-bind", real, real))
        alias = str(Path(ro).absolute())
        if alias != real and not is_under(alias, ("/usr", "/etc", "/proc", "/dev")):
            binds.append(("--ro-bind", real, alias))
    for src, dest in view.views:
        binds.append(("--ro-bind", os.path.realpath(src), dest))
    work = os.path.realpath(workdir)
    inside = view.work or work
    binds.append(("--bind", work, inside))
    mounted: list[str] = []
    made: set[str] = set()
    for opt, src, dest in sorted(set(binds), key=lambda b: (len(b[2]), b[2], b[0] == "--bind")):
        if is_under(dest, mounted) and opt == "--ro-bind" and (src, dest) not in view.views:
            continue  # already visible through an enclosing bind
        # parents that bwrap would otherwise create 0700 (unreadable for the run's user id)
        for parent in reversed(Path(dest).parents):
            sp = str(parent)
            if sp not in ("/", "/tmp") and sp not in made and not is_under(sp, mounted):
                args += ["--perms", "0755", "--dir", sp]
                made.add(sp)
        args += [opt, src, dest]
        mounted.append(dest)
    return [*args, "--chdir", inside]


def _bwrap_command(bwrap: str, argv: Sequence[str], workdir: Path, view: View, uid: int | None,
                   tmp_mb: int) -> list[str]:
    """``bwrap ... argv`` (module docstring); as root: ``bwrap MOUNTS setpriv UID bwrap --unshare-user ...``."""
    unpriv = ["--unshare-user", "--disable-userns", "--cap-drop", "ALL"]
    if uid is None:
        return [bwrap, *unpriv, *_mounts(workdir, view, tmp_mb), "--", *argv]
    tools = [os.path.realpath(bwrap), os.path.realpath(shutil.which("setpriv") or "/usr/bin/setpriv")]
    extra = [os.path.dirname(t) for t in tools if not is_under(t, ("/usr",))]
    inner = [tools[1], f"--reuid={uid}", f"--regid={uid}", "--clear-groups", "--no-new-privs", "--",
             tools[0], *unpriv, "--dev-bind", "/", "/", "--die-with-parent", "--chdir",
             view.work or os.path.realpath(workdir), "--"]
    return [bwrap, *_mounts(workdir, view, tmp_mb, extra), "--", *inner, *argv]


def command_line(argv: Sequence[str], workdir: Path, limits: Limits, read_only: Sequence[Path] | View = (),
                 uid: int | None = None, *, sandbox: bool = True) -> tuple[list[str], str]:
    """The full command: ``prlimit ... [bwrap ...] [setpriv ...] argv`` and the isolation name (``bwrap`` when
    ``sandbox``, else ``rlimits``). RLIMIT_CPU is ``ceil(cpu) + 1`` s soft (SIGXCPU), one more hard (SIGKILL):
    the bound of one process; the cgroup (:class:`RunCgroup`) bounds all of them together."""
    view = read_only if isinstance(read_only, View) else View(tuple(map(str, read_only)))
    cpu = math.ceil(limits.cpu) + 1
    prlimit = [shutil.which("prlimit") or "prlimit", f"--as={limits.memory_mb * 1024 * 1024}",
               f"--cpu={cpu}:{cpu + 1}", f"--fsize={limits.fsize_mb * 1024 * 1024}", f"--nproc={limits.nproc}",
               "--core=0", "--"]
    bwrap = bwrap_path()
    if sandbox and bwrap is not None:
        return [*prlimit, *_bwrap_command(bwrap, argv, workdir, view, uid, limits.fsize_mb)], "bwrap"
    drop = ([] if uid is None else
            [shutil.which("setpriv") or "setpriv", f"--reuid={uid}", f"--regid={uid}", "--clear-groups",
             "--no-new-privs", "--"])
    return [*prlimit, *drop, *argv], "rlimits"


# ------------------------------------------------------------------------------------------------ the run
def run_sandboxed(argv: Sequence[str], workdir: str | os.PathLike[str], limits: Limits | None = None, *,
                  read_only: Sequence[str | os.PathLike[str]] = (), env: dict[str, str] | None = None,
                  stdin: int | None = None, views: Sequence[tuple[str, str]] = (), work_view: str | None = None,
                  folder: RunFolder | None = None) -> RunResult:
    """Run ``argv`` in ``workdir`` (the private working folder, created by the caller; or ``folder.work`` of a
    :func:`run_folder`, whose ``tmp`` becomes the run's ``/tmp``) under the module's bounds; never raises for
    anything the program does (raises :class:`SandboxUnavailable` when bubblewrap is required and cannot be
    used). ``stdin``: a descriptor to read from (default ``/dev/null``). With bubblewrap, ``views`` (host path,
    path inside) are bound read-only under those names and the working folder appears as ``work_view``; its
    options (its mounts) reach bubblewrap through a file descriptor (``--args``), so ``/proc/1/cmdline``
    inside shows only the command after ``--``."""
    limits = limits or Limits()
    sandbox = not sandbox_problem()
    if not sandbox and limits.require_sandbox:
        raise SandboxUnavailable(refusal())
    work = Path(os.path.realpath(workdir))
    uid = fresh_uid()
    private_tmp = None
    if not sandbox:  # bubblewrap's /tmp is a private tmpfs; without it, a private folder beside the work folder
        if folder is not None and folder.tmp is not None:
            private_tmp = folder.tmp
        else:
            private_tmp = Path(tempfile.mkdtemp(prefix=f".{work.name}.tmp-", dir=work.parent))
    if uid is not None:
        for p in (work, *work.rglob("*"), *([private_tmp] if private_tmp else [])):
            os.lchown(p, uid, uid)
    view = View(tuple(str(p) for p in read_only), tuple(views) if sandbox else (),
                work_view if sandbox else None, str(folder.tmp) if folder is not None and folder.tmp else None)
    cmd, how = command_line(list(argv), work, limits, view, uid, sandbox=sandbox)
    here = view.work or str(work)
    environment = {"PATH": "/usr/bin:/bin", "HOME": here, "LANG": "C.UTF-8",
                   "TMPDIR": "/tmp" if private_tmp is None else str(private_tmp)}
    environment.update(env or {})
    group = RunCgroup.create()
    args_file = None
    if how == "bwrap":  # bubblewrap reads its arguments from a descriptor: /proc/1/cmdline is "bwrap --args N"
        at = cmd.index(bwrap_path() or "bwrap", 1)
        end = cmd.index("--", at)  # its options; the command after "--" stays on the command line
        args_file = tempfile.TemporaryFile()
        args_file.write(b"".join(os.fsencode(a) + b"\0" for a in cmd[at + 1:end]))
        args_file.seek(0)
        cmd = [*cmd[:at + 1], "--args", str(args_file.fileno()), *cmd[end:]]
    if group is not None:
        cmd = [*group.enter(), *cmd]
    t0 = time.perf_counter()
    try:
        proc = subprocess.Popen(cmd, cwd=work, env=environment,
                                stdin=subprocess.DEVNULL if stdin is None else stdin, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, start_new_session=True, close_fds=True,
                                pass_fds=() if args_file is None else (args_file.fileno(),))
    except OSError as exc:
        if group is not None:
            group.remove()
        return RunResult(127, False, False, "", f"cannot start: {exc}", 0, 0, 0.0, how, list(argv), uid)
    finally:
        if args_file is not None:
            args_file.close()
    cpu = 0.0
    try:
        out_head, err_tail, counts, ended = _drain(proc, limits, t0, group)
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except OSError:
            pass
        if group is not None:
            cpu = group.cpu_seconds()
            waited = group.waited_seconds()
            group.remove()
        if uid is not None:
            kill_uid(uid)
        if private_tmp is not None and (folder is None or private_tmp != folder.tmp):
            shutil.rmtree(private_tmp, ignore_errors=True)
    wall = time.perf_counter() - t0
    rc = proc.returncode if proc.returncode is not None else -signal.SIGKILL
    if not ended and rc in (-signal.SIGXCPU, 128 + signal.SIGXCPU):
        ended = "cpu"  # one process reached RLIMIT_CPU
    err_text = err_tail.decode("utf-8", "replace")
    if folder is not None and folder.bounded:  # the tmpfs says it (ENOSPC in stderr may be another limit's)
        over_disk = disk_full(folder.work)
    else:
        over_disk = rc != 0 and any(p in err_text for p in DISK_PATTERNS)
    over = (not ended and rc != 0 and any(p in err_text for p in MEMORY_PATTERNS))
    return RunResult(rc, bool(ended), over, out_head.decode("utf-8", "replace"), err_text, counts[0], counts[1],
                     wall, how, list(argv), uid, round(cpu, 3), ended, over_disk,
                     round(waited, 3) if group is not None else 0.0)


def _over(limits: Limits, t0: float, group: RunCgroup | None) -> tuple[str, float]:
    """Which bound the run has reached (``"cpu"``, ``"wall"`` or ``""``) and the seconds left to the wall
    backstop (wall time minus the time it waited for a CPU)."""
    waited = group.waited_seconds() if group is not None else 0.0
    left = limits.timeout - (time.perf_counter() - t0 - waited)
    if group is not None and group.cpu_seconds() >= limits.cpu:
        return "cpu", left
    return ("wall" if left <= 0 else ""), left


def _drain(proc: subprocess.Popen[bytes], limits: Limits, t0: float,
           group: RunCgroup | None = None) -> tuple[bytes, bytes, list[int], str]:
    """Read both pipes until they close or a bound is reached (:func:`_over`): keep stdout's head and
    stderr's tail; then wait for the process under the same bounds. Returns the bound that ended it or ``""``."""
    assert proc.stdout is not None and proc.stderr is not None
    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ, 0)
    sel.register(proc.stderr, selectors.EVENT_READ, 1)
    head, tail = bytearray(), bytearray()
    counts = [0, 0]
    ended = ""
    open_pipes = 2
    while open_pipes:
        ended, left = _over(limits, t0, group)
        if ended:
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
    while not ended:
        try:
            proc.wait(timeout=0.5)
            break
        except subprocess.TimeoutExpired:
            ended, _ = _over(limits, t0, group)
    if ended:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except OSError:
            pass
        if group is not None:
            group.kill()
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    sel.close()
    proc.stdout.close()
    proc.stderr.close()
    return bytes(head), bytes(tail[-limits.keep_bytes:]), counts, ended


__all__ = ["DISK_PATTERNS", "ETC_FILES", "INSTALL_HINT", "Limits", "MEMORY_PATTERNS", "NOT_SANDBOXED",
           "OutputRefused", "RunCgroup", "RunFolder", "RunResult", "SandboxUnavailable", "UID_BASE", "UID_SPAN",
           "View", "bwrap_path", "command_line", "disk_full", "fresh_uid", "isolation", "kill_uid",
           "live_processes", "mounts_under", "refusal", "run_folder", "run_sandboxed", "sandbox_problem",
           "unmount"]
