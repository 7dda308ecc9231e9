"""What a sandboxed run is given and what it gives back (docs/GRADING.md "Bounds"): its :class:`Limits`, its
:class:`RunResult`, and the two refusals (:class:`SandboxUnavailable`, :class:`OutputRefused`). A leaf of
:mod:`a5mi.sandbox`."""

from __future__ import annotations

from dataclasses import dataclass, field

from a5mi.platform.errors import UserError


class SandboxUnavailable(UserError):
    """bubblewrap is missing or cannot make a sandbox here, and the run requires one (no ``--no-sandbox``)."""


class OutputRefused(Exception):
    """An output that is not a regular file the run wrote in its folder; ``reason`` says why (no bytes of the
    file are read)."""

    def __init__(self, reason: str, missing: bool = False) -> None:
        super().__init__(reason)
        self.reason = reason
        self.missing = missing


@dataclass(frozen=True)
class Limits:
    """Per-run bounds: ``timeout``, the wall-clock backstop (s, counted without the time the run waited for a
    CPU, :class:`RunCgroup`), ``cpu_seconds`` of CPU time of all its processes together (None: ``timeout``),
    address space ``memory_mb``, ``fsize_mb`` per written file, ``nproc`` processes/threads of the run's user,
    ``disk_mb`` and ``inodes`` of everything it writes (its folder and ``/tmp`` together, :func:`run_folder`),
    ``keep_bytes`` of stdout (head) and stderr (tail); ``require_sandbox``: refuse to run without bubblewrap
    (off = ``--no-sandbox``)."""

    timeout: float = 60.0
    memory_mb: int = 4096
    fsize_mb: int = 256
    nproc: int = 256
    keep_bytes: int = 64 * 1024
    require_sandbox: bool = True
    cpu_seconds: float | None = None
    disk_mb: int = 512
    inodes: int = 4096

    @property
    def cpu(self) -> float:
        """The CPU-time bound in seconds (``cpu_seconds``, else ``timeout``)."""
        return self.timeout if self.cpu_seconds is None else self.cpu_seconds


@dataclass
class RunResult:
    """What happened: ``returncode`` (negative = killed by that signal, as :mod:`subprocess`), ``timed_out``,
    ``over_memory`` (a memory failure per :data:`MEMORY_PATTERNS`), the kept ``stdout_head`` /
    ``stderr_tail``, the byte counts, ``wall`` seconds, the ``isolation`` used (``bwrap`` / ``rlimits``) and the
    run's user id ``uid`` (None: it ran as the grader's own user)."""

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
    uid: int | None = None
    cpu: float = 0.0
    ended_by: str = ""
    over_disk: bool = False
    waited: float = 0.0

    @property
    def crashed(self) -> bool:
        return self.returncode != 0 and not self.timed_out
