"""Grade one (student, case): run the submission sandboxed or take its image, then judge.

:func:`grade_one` is the unit of work a cluster worker runs (:mod:`a5mi.runtime.cluster`); it takes a picklable
:class:`Task` and returns a plain dict (one journal record). Verdict order (``docs/GRADING.md``):

1. the submission has an executable ``a5``: it runs with the case's a5 command line in a private working
   folder that holds links to every scene file (:mod:`a5mi.sandbox`; inside bubblewrap the folder is
   :data:`WORK_VIEW`, the submission :data:`SUBMISSION_VIEW` and the scenes :data:`SCENES_VIEW`); ``over disk``
   if it filled its folder's tmpfs (bytes or inodes, :func:`a5mi.sandbox.bwrap.run_folder`), ``timeout`` if killed
   at its CPU-time bound or the wall-clock backstop (the record's ``ended_by`` says which), ``over memory``
   on a memory failure, ``crash`` on a signal or a non-zero exit (with stderr's tail);
2. otherwise the image the case names must be in the submission folder (a student who rendered at home);
3. every record gets a one-line ``cause`` (:func:`a5mi.grade.cause.cause_of`: for a wrong image, the docs/MISTAKES.md
   mistake ``a5mi diagnose`` finds, else the ray-tree term that explains its worst pixels); ``no output`` without
   the image; ``unreadable`` if it is not a regular file the program wrote
   (:func:`a5mi.sandbox.outputs.open_output`: a symbolic link anywhere on its path, a hard link, a FIFO, another
   owner, too many bytes; no byte of such a file is read) or cannot be decoded (decoded without privileges,
   :func:`a5mi.sandbox.outputs.decode_levels`); ``wrong size`` if its size is not the reference's (an image of more
   than :data:`MAX_PIXELS_FACTOR` times the reference's pixels is not decoded at all), else ``match`` /
   ``close`` / ``wrong`` by :func:`a5mi.grade.verdict.judge`.
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

from a5mi.grade.cases import Case
from a5mi.grade.cause import cause_of
from a5mi.grade.needs import missing_paths
from a5mi.grade.verdict import Thresholds, judge, measure, points_for
from a5mi.platform.imageio import read_levels, write_image
from a5mi.sandbox.bwrap import run_sandboxed, sandbox_problem
from a5mi.sandbox.folders import run_folder
from a5mi.sandbox.outputs import TOO_LARGE, decode_levels, open_output
from a5mi.sandbox.records import Limits, OutputRefused, RunResult

#: Characters of stderr kept in a result (the tail).
STDERR_KEEP = 2000
#: An output of more pixels than this many times the reference's is ``wrong size`` without being decoded.
MAX_PIXELS_FACTOR = 4
#: The largest output file taken (bytes): a 16384 x 16384 RGBA 8-bit image uncompressed is 1 GiB.
MAX_IMAGE_BYTES = 256 << 20
#: Where a sandboxed run sees its submission, the scenes and its working folder (no host path).
SUBMISSION_VIEW, SCENES_VIEW, WORK_VIEW = "/a5/submission", "/a5/scenes", "/a5/work"


@dataclass(frozen=True)
class Task:
    """One unit of work: ``student`` (folder name), its ``submission`` folder, the ``case``, the ``scenes``
    folder, the reference files (``reference_png``, ``sigma_npy``), where to work (``work_root``) and to put
    images (``report_dir``), sandbox ``limits``, extra read-only paths and environment for the sandbox;
    ``a5mi_cpu``: the CPU seconds of a5mi's own render of the case on a worker (how ``limits.cpu`` was
    calibrated; 0: not calibrated)."""

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
    a5mi_cpu: float = 0.0

    @property
    def key(self) -> str:
        return f"{self.student}/{self.case.name}"


def executable(submission: Path) -> Path | None:
    p = submission / "a5"
    return p if p.is_file() and os.access(p, os.X_OK) else None


def prepare_workdir(task: Task, work: Path | None = None, scenes_at: str | None = None) -> Path:
    """A private folder holding a link to every entry of the scenes folder: ``work`` (made by the caller), or a
    fresh ``work_root/student/case`` (absolute). Links point to ``scenes_at/NAME`` (where the run sees the
    scenes), else to the scenes' own paths."""
    if work is None:
        work = Path(task.work_root).resolve() / task.student / task.case.name
        if work.exists():
            shutil.rmtree(work)
        work.mkdir(parents=True)
    for entry in sorted(Path(task.scenes).iterdir()):
        (work / entry.name).symlink_to(f"{scenes_at}/{entry.name}" if scenes_at else entry.resolve())
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
    if sub.is_symlink():
        return _record(task, "no output", "the submission folder is a symbolic link: refused",
                       isolation="none (refused)")
    prog = executable(sub)
    run_info: dict[str, Any] = {}
    if prog is not None:
        lim = task.limits
        views = not sandbox_problem()  # bubblewrap: the run sees neutral paths, not the grader's
        with run_folder(Path(task.work_root).resolve() / task.student / task.case.name, lim.disk_mb,
                        lim.inodes) as folder:
            work = prepare_workdir(task, folder.work, SCENES_VIEW if views else None)
            argv0 = f"{SUBMISSION_VIEW}/a5" if views else str(prog.resolve())
            subs, scenes = str(sub.resolve()), str(Path(task.scenes).resolve())
            where: dict[str, Any] = (
                {"read_only": task.read_only, "views": ((subs, SUBMISSION_VIEW), (scenes, SCENES_VIEW)),
                 "work_view": WORK_VIEW} if views else {"read_only": (subs, scenes, *task.read_only)})
            run = run_sandboxed([argv0, *task.case.argv], work, lim, env=dict(task.env), folder=folder, **where)
            run_info = {"stderr_tail": run.stderr_tail[-STDERR_KEEP:], "wall": round(run.wall, 3),
                        "isolation": run.isolation, "stdout_bytes": run.stdout_bytes,
                        "stderr_bytes": run.stderr_bytes, "cpu": run.cpu, "waited": run.waited,
                        "ended_by": run.ended_by, "cpu_bound": lim.cpu, "wall_bound": lim.timeout, "uid": run.uid}
            if run.over_disk:
                rec = _record(task, "over disk", f"filled its {lim.disk_mb} MB / {lim.inodes} inodes of disk"
                              f"{'' if run.returncode == 0 else ', ' + _crash_detail(run)}", **run_info)
            elif run.timed_out:
                rec = _record(task, "timeout", _bound_detail(task, run), **run_info)
            elif run.over_memory:
                rec = _record(task, "over memory", f"out of memory (limit {lim.memory_mb} MB), "
                              f"{_crash_detail(run)}", **run_info)
            elif run.crashed:
                rec = _record(task, "crash", _crash_detail(run), **run_info)
            else:
                owner = run.uid if run.uid is not None else os.geteuid()
                rec = _judge_output(task, work, task.case.output, owner, run_info)
            if rec["verdict"] in ("crash", "no output"):  # could it start? (docs/GRADING.md, a5mi.grade.needs)
                rec["needs"] = missing_paths(prog, (str(sub.resolve()), str(Path(task.scenes).resolve()),
                                                    *task.read_only))
    else:
        rec = _judge_output(task, sub.parent, f"{sub.name}/{task.case.output}", None,
                            {"isolation": "none (image submitted)"})
        rec["wall"] = round(time.perf_counter() - t0, 3)
    if "cause" not in rec:
        rec["cause"] = cause_of(rec)
    return rec


def _bound_detail(task: Task, run: RunResult) -> str:
    """Which bound ended a run: ``CPU time: 412.0 s used, bound 400 s (a5mi: 1.60 s)`` or ``wall-clock
    backstop: ...`` (the seconds it waited for a CPU are not counted)."""
    lim = task.limits
    calibrated = f" (a5mi renders this case in {task.a5mi_cpu:.2f} s of CPU)" if task.a5mi_cpu > 0 else ""
    if run.ended_by == "cpu":
        return f"CPU time: {run.cpu:.1f} s used, bound {lim.cpu:g} s{calibrated}"
    return (f"wall-clock backstop: {run.wall:.1f} s, {run.waited:.1f} s of it waiting for a CPU (not counted), "
            f"bound {lim.timeout:g} s; {run.cpu:.1f} s of CPU used")


def _judge_output(task: Task, folder: Path, rel: str, owner: int | None, run_info: dict[str, Any]) -> dict[str, Any]:
    """Judge ``folder/rel``, taken only as :func:`a5mi.sandbox.outputs.open_output` allows and decoded unprivileged."""
    out = task.case.output
    ref, sigma = read_levels(task.reference_png), np.load(task.sigma_npy)
    rh, rw = ref.shape[:2]
    try:
        fd = open_output(folder, rel, owner=owner, max_bytes=MAX_IMAGE_BYTES)
    except OutputRefused as exc:
        if exc.missing:
            return _record(task, "no output", f"no {out} written", **run_info)
        return _record(task, "unreadable", f"{out}: {exc.reason}", **run_info)
    try:
        dec = decode_levels(fd, Path(out).suffix, MAX_PIXELS_FACTOR * rw * rh, task.work_root)
    finally:
        os.close(fd)
    if dec.error == TOO_LARGE:
        return _record(task, "wrong size", f"{dec.width}x{dec.height}, expected {rw}x{rh} (not decoded)",
                       **run_info)
    if dec.levels is None:
        return _record(task, "unreadable", dec.error, **run_info)
    student = dec.levels
    img_dir = Path(task.report_dir) / "img" / task.student
    img_dir.mkdir(parents=True, exist_ok=True)
    base = task.case.name
    write_image(img_dir / f"{base}.png", student / 255.0 + 0.5 / 255.0)
    images = {"submission": f"img/{task.student}/{base}.png"}
    if student.shape != ref.shape:
        h, w = student.shape[:2]
        return _record(task, "wrong size", f"{w}x{h}, expected {rw}x{rh}", images=images, **run_info)
    metrics, heat = measure(student, ref, sigma if sigma.shape == ref.shape else None, flip=task.flip)
    verdict = judge(metrics, task.thresholds)
    cause = cause_of({"verdict": verdict, "detail": metrics.summary()}, scene=Path(task.scenes) / task.case.scene,
                     options=task.case.options, student=student, reference=ref,
                     sigma=sigma if sigma.shape == ref.shape else None)
    diff = np.clip(np.abs(student - ref).max(axis=2, keepdims=True) * 8.0, 0, 255).repeat(3, axis=2)
    write_image(img_dir / f"{base}.diff.png", diff / 255.0 + 0.5 / 255.0)
    images["diff"] = f"img/{task.student}/{base}.diff.png"
    if heat is not None:
        write_image(img_dir / f"{base}.flip.png", np.clip(heat, 0, 255) / 255.0 + 0.5 / 255.0)
        images["flip"] = f"img/{task.student}/{base}.flip.png"
    return _record(task, verdict, metrics.summary(), metrics=metrics.as_dict(), images=images, cause=cause,
                   **run_info)


__all__ = ["MAX_IMAGE_BYTES", "MAX_PIXELS_FACTOR", "STDERR_KEEP", "Task", "executable", "grade_one",
           "prepare_workdir"]
