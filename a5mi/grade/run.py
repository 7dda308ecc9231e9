"""Grade one (student, case): run the submission sandboxed or take its image, then judge (issue 13).

:func:`grade_one` is the unit of work a cluster worker runs (:mod:`a5mi.cluster`); it takes a picklable
:class:`Task` and returns a plain dict (one journal record). Verdict order (``docs/GRADING.md``):

1. the submission has an executable ``a5``: it runs with the case's a5 command line in a private working
   folder that holds links to every scene file (:mod:`a5mi.grade.sandbox`); ``timeout`` if killed at the wall
   limit, ``over memory`` on a memory failure, ``crash`` on a signal or a non-zero exit (with stderr's tail);
2. otherwise the image the case names must be in the submission folder (a student who rendered at home);
3. ``no output`` without the image, ``unreadable`` if it cannot be decoded, ``wrong size`` if its size is
   not the reference's, else ``match`` / ``close`` / ``wrong`` by :func:`a5mi.grade.verdict.judge`.
"""

from __future__ import annotations

import os
import shutil
import signal
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from a5mi.errors import ImageReadError
from a5mi.grade.cases import Case
from a5mi.grade.sandbox import Limits, RunResult, run_sandboxed
from a5mi.grade.verdict import Thresholds, judge, measure, points_for
from a5mi.imageio import read_levels, write_image

#: Characters of stderr kept in a result (the tail).
STDERR_KEEP = 2000


@dataclass(frozen=True)
class Task:
    """One unit of work: ``student`` (folder name), its ``submission`` folder, the ``case``, the ``scenes``
    folder, the reference files (``reference_png``, ``sigma_npy``), where to work (``work_root``) and to put
    images (``report_dir``), sandbox ``limits``, extra read-only paths and environment for the sandbox."""

    student: str
    submission: str
    case: Case
    scenes: str
    reference_png: str
    sigma_npy: str
    work_root: str
    report_dir: str
    limits: Limits = Limits()
    read_only: tuple[str, ...] = ()
    env: tuple[tuple[str, str], ...] = ()
    thresholds: Thresholds = Thresholds()
    flip: bool = True

    @property
    def key(self) -> str:
        return f"{self.student}/{self.case.name}"


def executable(submission: Path) -> Path | None:
    p = submission / "a5"
    return p if p.is_file() and os.access(p, os.X_OK) else None


def prepare_workdir(task: Task) -> Path:
    """A fresh private folder ``work_root/student/case`` with a link to every entry of the scenes folder."""
    work = Path(task.work_root) / task.student / task.case.name
    if work.exists():
        shutil.rmtree(work)
    work.mkdir(parents=True)
    for entry in sorted(Path(task.scenes).iterdir()):
        (work / entry.name).symlink_to(entry.resolve())
    return work


def _signal_name(n: int) -> str:
    try:
        return signal.Signals(n).name
    except ValueError:
        return f"signal {n}"


def _crash_detail(run: RunResult) -> str:
    """``killed by SIGSEGV``; inside bubblewrap the sandbox's init reports a signal as 128 + N, as a shell does:
    ``exit status 139 (SIGSEGV)``."""
    if run.returncode < 0:
        return f"killed by {_signal_name(-run.returncode)}"
    if run.isolation == "bwrap" and 128 < run.returncode < 128 + 65:
        return f"exit status {run.returncode} ({_signal_name(run.returncode - 128)})"
    return f"exit status {run.returncode}"


def _record(task: Task, verdict: str, detail: str, **more: Any) -> dict[str, Any]:
    rec: dict[str, Any] = {"key": task.key, "student": task.student, "case": task.case.name, "verdict": verdict,
                           "points": points_for(verdict, task.case.points), "max_points": task.case.points,
                           "detail": detail, "metrics": None, "images": {}, "stderr_tail": "", "wall": 0.0,
                           "isolation": "", "stdout_bytes": 0, "stderr_bytes": 0}
    rec.update(more)
    return rec


def grade_one(task: Task) -> dict[str, Any]:
    """Grade ``task`` (module docstring); the record has ``verdict``, ``points``, ``metrics``, ``detail``,
    ``stderr_tail``, ``images`` (paths relative to the report folder), ``wall`` and ``isolation``."""
    t0 = time.perf_counter()
    sub = Path(task.submission)
    prog = executable(sub)
    run_info: dict[str, Any] = {}
    if prog is not None:
        work = prepare_workdir(task)
        run = run_sandboxed([str(prog.resolve()), *task.case.argv], work, task.limits,
                            read_only=(str(sub.resolve()), str(Path(task.scenes).resolve()), *task.read_only),
                            env=dict(task.env))
        run_info = {"stderr_tail": run.stderr_tail[-STDERR_KEEP:], "wall": round(run.wall, 3),
                    "isolation": run.isolation, "stdout_bytes": run.stdout_bytes, "stderr_bytes": run.stderr_bytes}
        if run.timed_out:
            rec = _record(task, "timeout", f"killed after {task.limits.timeout:g} s", **run_info)
        elif run.over_memory:
            rec = _record(task, "over memory", f"out of memory (limit {task.limits.memory_mb} MB), "
                          f"{_crash_detail(run)}", **run_info)
        elif run.crashed:
            rec = _record(task, "crash", _crash_detail(run), **run_info)
        else:
            rec = _judge_image(task, work / task.case.output, run_info)
        shutil.rmtree(work, ignore_errors=True)
    else:
        rec = _judge_image(task, sub / task.case.output, {"isolation": "none (image submitted)"})
        rec["wall"] = round(time.perf_counter() - t0, 3)
    return rec


def _judge_image(task: Task, image: Path, run_info: dict[str, Any]) -> dict[str, Any]:
    if not image.is_file():
        return _record(task, "no output", f"no {task.case.output} written", **run_info)
    try:
        student = read_levels(image)
    except ImageReadError as exc:
        return _record(task, "unreadable", exc.reason, **run_info)
    ref, sigma = read_levels(task.reference_png), np.load(task.sigma_npy)
    img_dir = Path(task.report_dir) / "img" / task.student
    img_dir.mkdir(parents=True, exist_ok=True)
    base = task.case.name
    write_image(img_dir / f"{base}.png", student / 255.0 + 0.5 / 255.0)
    images = {"submission": f"img/{task.student}/{base}.png"}
    if student.shape != ref.shape:
        h, w = student.shape[:2]
        return _record(task, "wrong size", f"{w}x{h}, expected {ref.shape[1]}x{ref.shape[0]}", images=images,
                       **run_info)
    metrics, heat = measure(student, ref, sigma if sigma.shape == ref.shape else None, flip=task.flip)
    verdict = judge(metrics, task.thresholds)
    diff = np.clip(np.abs(student - ref).max(axis=2, keepdims=True) * 8.0, 0, 255).repeat(3, axis=2)
    write_image(img_dir / f"{base}.diff.png", diff / 255.0 + 0.5 / 255.0)
    images["diff"] = f"img/{task.student}/{base}.diff.png"
    if heat is not None:
        write_image(img_dir / f"{base}.flip.png", np.clip(heat, 0, 255) / 255.0 + 0.5 / 255.0)
        images["flip"] = f"img/{task.student}/{base}.flip.png"
    return _record(task, verdict, metrics.summary(), metrics=metrics.as_dict(), images=images, **run_info)


__all__ = ["STDERR_KEEP", "Task", "executable", "grade_one", "prepare_workdir"]
