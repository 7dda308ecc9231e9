"""The grader's name for :mod:`a5mi.sandbox`, the one sandbox of ``a5mi grade`` and ``a5mi difftest``.

Everything is defined there (``docs/GRADING.md`` "Threat model"); this module re-exports it for the
modules that import it under this name (:mod:`a5mi.grade.batch`, ``benchmarks/grade_class.py``).
"""

from __future__ import annotations

from a5mi.sandbox import (
    MEMORY_PATTERNS,
    UID_BASE,
    UID_SPAN,
    Limits,
    RunResult,
    SandboxUnavailable,
    bwrap_path,
    command_line,
    isolation,
    kill_uid,
    run_sandboxed,
)

__all__ = ["Limits", "MEMORY_PATTERNS", "RunResult", "SandboxUnavailable", "UID_BASE", "UID_SPAN", "bwrap_path",
           "command_line", "isolation", "kill_uid", "run_sandboxed"]
