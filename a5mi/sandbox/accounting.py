"""What a sandboxed run uses and how it is ended (docs/GRADING.md "Bounds"): its processes, found by the run's
own user id (never the machine's other processes), and its cgroup v2: the CPU time of all its processes
together, the time it waited for a CPU, and the kill of the whole group."""

from __future__ import annotations

import contextlib
import functools
import os
import signal
import time
from pathlib import Path


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


def live_processes(uid: int) -> list[int]:
    """The live processes of a run's user id ``uid`` (:attr:`RunResult.uid`): none once its run returned."""
    return _live_processes(uid)


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


# ------------------------------------------------------------------------------------------- CPU accounting
@functools.cache
def _cgroup2_base() -> Path | None:
    """This process's own cgroup v2 folder (``/proc/self/cgroup``'s ``0::`` line under the ``cgroup2`` mount),
    when it is writable; None otherwise."""
    try:
        mounts = Path("/proc/self/mounts").read_text().splitlines()
        own = next(ln[3:] for ln in Path("/proc/self/cgroup").read_text().splitlines() if ln.startswith("0::"))
    except (OSError, StopIteration):
        return None
    for ln in mounts:
        parts = ln.split()
        if len(parts) > 2 and parts[2] == "cgroup2":
            base = Path(parts[1]) / own.lstrip("/")
            if os.access(base, os.W_OK) and (base / "cgroup.procs").exists():
                return base
    return None


class RunCgroup:
    """A cgroup v2 of one run: every process the run starts is in it from its first instruction (the run is
    started by ``sh -c 'echo $$ > cgroup.procs; exec ...'``) and cannot leave it (no ``/sys`` in the sandbox).

    * CPU time of all its processes together: ``cpu.stat`` ``usage_usec`` / 1e6 (Linux, cgroup v2 core);
    * time kept waiting for a CPU: ``cpu.pressure`` ``some total`` / 1e6 (PSI: the time at least one of its
      runnable tasks waited on a run queue), subtracted from the wall clock before the backstop applies;
    * end: ``cgroup.kill`` (every process at once), then the folder is removed."""

    _count = 0

    def __init__(self, path: Path) -> None:
        self.path = path

    @classmethod
    def create(cls) -> RunCgroup | None:
        """A fresh child of this process's cgroup, or None where none can be made (no cgroup v2, not root)."""
        base = _cgroup2_base()
        if base is None:
            return None
        cls._count += 1
        path = base / f"a5mi-run-{os.getpid()}-{cls._count}-{time.monotonic_ns() % 10**9}"
        try:
            path.mkdir()
        except OSError:
            return None
        return cls(path)

    def enter(self) -> list[str]:
        """The command prefix that moves the process into this cgroup, then execs the rest."""
        return ["/bin/sh", "-c", 'echo $$ > "$0" && exec "$@"', str(self.path / "cgroup.procs")]

    def _read(self, name: str, key: str) -> float:
        try:
            for ln in (self.path / name).read_text().splitlines():
                parts = ln.split()
                if parts and parts[0] == key:
                    if key == "some":
                        return float(dict(p.split("=") for p in parts[1:])["total"]) / 1e6
                    return float(parts[1]) / 1e6
        except (OSError, KeyError, ValueError, IndexError):
            pass
        return 0.0

    def cpu_seconds(self) -> float:
        return self._read("cpu.stat", "usage_usec")

    def waited_seconds(self) -> float:
        return self._read("cpu.pressure", "some")

    def kill(self) -> None:
        try:
            (self.path / "cgroup.kill").write_text("1")
            return
        except OSError:
            pass
        try:
            pids = [int(p) for p in (self.path / "cgroup.procs").read_text().split()]
        except OSError:
            return
        for pid in pids:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)

    def remove(self) -> None:
        """Kill what is left and remove the cgroup (retried while the killed processes exit)."""
        for _ in range(300):
            self.kill()
            try:
                self.path.rmdir()
                return
            except FileNotFoundError:
                return
            except OSError:
                time.sleep(0.01)


# ----------------------------------------------------------------------------------------------- disk bound
