"""A whole class: references, one cluster task per (student, case), the journal and the report.

:func:`grade_class` is what ``a5mi grade`` runs (``docs/GRADING.md``):

0. the cluster: a local TLS one of ``workers`` processes, the one of ``scheduler``, or ``workers`` SLURM jobs
   (``slurm``: :mod:`a5mi.runtime.slurm`, docs/GRADING.md "On a SLURM cluster");
1. every path of the settings is made absolute here, before anything is sent to a worker (a worker resolves a
   relative path from its own folder), and every worker is asked to see each of them
   (:func:`check_workers_see`: the submissions, scenes, references, cache and report folders, the extra
   read-only paths; the report folder must hold the token file this process just wrote there): a worker that
   cannot is a :class:`~a5mi.platform.errors.UserError` ("the scheduler's workers need a shared filesystem");
2. the references are built on the cluster's workers (rendered by a5mi once per case and cached,
   :mod:`a5mi.grade.references`);
3. every (student, case) is one task of :func:`a5mi.grade.run.grade_one` through :func:`a5mi.runtime.cluster.run_units`
   (journal ``REPORT/journal.jsonl``). Each record carries the **fingerprint** of what decides it
   (:func:`fingerprint`): every field of the task (the case's command, output, reference name, points and
   render options; thresholds, FLIP, sandbox limits, extra paths and environment); the SHA-256 of the
   reference image and noise band; the scene's cache key (scene text, the files it names, the reference
   options); the SHA-256 of the student's folder (:func:`tree_digest`); the grader version (a5mi's version
   and the SHA-256 of the modules that decide a verdict, :func:`grader_version`).
   ``resume`` skips a unit only when its journaled record has the same fingerprint;
4. :mod:`a5mi.grade.report` writes ``report.html``, ``results.csv`` and ``results.json``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import secrets
import shutil
import stat
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from a5mi import __version__
from a5mi.grade.cases import Case
from a5mi.grade.references import build_reference, cache_key, render_cpu_seconds
from a5mi.grade.run import Task, grade_one
from a5mi.grade.verdict import Thresholds
from a5mi.platform.errors import UserError
from a5mi.runtime.cluster import Journal, Progress, run_units, start_client
from a5mi.sandbox.bwrap import isolation
from a5mi.sandbox.folders import mounts_under, unmount
from a5mi.sandbox.records import Limits

#: A case's CPU-time bound is ``max(cpu floor, CPU_FACTOR x a5mi's CPU seconds for the case)``: the sample
#: solution needs 70-143 CPU-s for the vase at the handout's flags where a5mi needs ~1.6 s (90x), so 250x
#: leaves a5soln-class programs a margin of 1.7x or more (docs/GRADING.md "Bounds").
CPU_FACTOR = 250.0
#: Default floor of the CPU-time bound (s) and the wall-clock backstop as a multiple of the CPU bound.
CPU_FLOOR, WALL_FACTOR = 120.0, 2.0


@dataclass
class GradeSettings:
    """Everything ``a5mi grade`` was asked (the flags of ``a5mi grade -h``)."""

    submissions: str
    report_dir: str
    cases: list[Case]
    scenes: str
    cache_dir: str
    reference_dir: str | None = None
    workers: int = 2
    scheduler: str | None = None
    limits: Limits = Limits()
    resume: bool = False
    read_only: tuple[str, ...] = ()
    env: tuple[tuple[str, str], ...] = ()
    thresholds: Thresholds = Thresholds()
    flip: bool = True
    work_root: str | None = None
    security: Any = None  # distributed.security.Security of ``scheduler`` (None: Dask's configuration)
    slurm: Any = None  # a5mi.runtime.slurm.SlurmOptions: ``workers`` SLURM jobs instead of a local cluster
    cpu: float | None = None   # --cpu: a fixed CPU-time bound (s); None: calibrated (:func:`bounds`)
    wall: float | None = None  # --timeout: the wall-clock backstop (s); None: WALL_FACTOR x the CPU bound

    def bounds(self, a5mi_cpu: float) -> Limits:
        """The limits of one case whose a5mi render took ``a5mi_cpu`` CPU seconds on a worker:
        ``cpu = --cpu`` or ``max(CPU_FLOOR, CPU_FACTOR x a5mi_cpu)``; wall backstop ``--timeout`` or
        ``WALL_FACTOR x cpu`` (counted without the time the run waits for a CPU)."""
        cpu = self.cpu if self.cpu is not None else max(CPU_FLOOR, CPU_FACTOR * a5mi_cpu)
        return dataclasses.replace(self.limits, cpu_seconds=round(cpu, 1),
                                   timeout=self.wall if self.wall is not None else WALL_FACTOR * round(cpu, 1))

    def absolute(self) -> GradeSettings:
        """These settings with every path absolute (from this process's folder)."""
        def a(p: str | None) -> str | None:
            return None if p is None else os.path.abspath(p)

        return dataclasses.replace(self, submissions=a(self.submissions), report_dir=a(self.report_dir),
                                   scenes=a(self.scenes), cache_dir=a(self.cache_dir),
                                   reference_dir=a(self.reference_dir), work_root=a(self.work_root),
                                   read_only=tuple(os.path.abspath(p) for p in self.read_only))


#: Verdicts that mean nothing was judged: no image to look at, or the grader failed.
UNGRADED = ("no output", "error")


@dataclass
class GradeOutcome:
    """The records (one per student x case), the students, the isolation used and the files written."""

    records: list[dict[str, Any]]
    students: list[str]
    isolation: str
    files: dict[str, str] = field(default_factory=dict)
    skipped: int = 0

    @property
    def nothing_graded(self) -> bool:
        """True when every record is ``no output`` or a grader error: a set-up mistake (wrong folders, a
        cluster whose workers see other files), not a class of zeros."""
        return bool(self.records) and all(r.get("verdict", "error") in UNGRADED for r in self.records)


#: Modules whose code decides a record (verdict, cause); their source is part of the grader version
#: (:func:`grader_version`).
VERDICT_MODULES = ("a5mi.grade.run", "a5mi.grade.verdict", "a5mi.grade.cause", "a5mi.grade.needs",
                   "a5mi.sandbox.bwrap", "a5mi.sandbox.outputs", "a5mi.compare", "a5mi.platform.imageio")


def grader_version() -> str:
    """a5mi's version and the SHA-256 of the source of :data:`VERDICT_MODULES`."""
    import importlib

    h = hashlib.sha256(__version__.encode())
    for name in VERDICT_MODULES:
        src = importlib.import_module(name).__file__
        h.update(Path(src).read_bytes() if src else name.encode())
    return f"{__version__}+{h.hexdigest()[:16]}"


def tree_digest(folder: str | Path) -> str:
    """SHA-256 of a folder: for every entry below it, in sorted order, its relative path, its type and mode,
    and the bytes of a regular file or the target of a symbolic link (links are not followed; FIFOs, sockets
    and devices count by name and type only, never read)."""
    h = hashlib.sha256()
    root = Path(folder)
    stack = [root]
    while stack:
        d = stack.pop()
        try:
            entries = sorted(os.scandir(d), key=lambda e: e.name)
        except OSError as exc:
            h.update(f"{d.relative_to(root)}\0unlistable {exc.errno}\0".encode())
            continue
        for e in reversed(entries):
            rel = os.path.relpath(e.path, root)
            try:
                st = e.stat(follow_symlinks=False)
            except OSError:
                h.update(f"{rel}\0vanished\0".encode())
                continue
            h.update(f"{rel}\0{stat.S_IFMT(st.st_mode)}\0{stat.S_IMODE(st.st_mode)}\0".encode("utf-8", "replace"))
            if stat.S_ISLNK(st.st_mode):
                h.update(os.readlink(e.path).encode("utf-8", "replace") + b"\0")
            elif stat.S_ISDIR(st.st_mode):
                stack.append(Path(e.path))
            elif stat.S_ISREG(st.st_mode):
                try:
                    with open(e.path, "rb", opener=lambda p, f: os.open(p, f | os.O_NOFOLLOW | os.O_NONBLOCK)) as f:
                        h.update(hashlib.file_digest(f, "sha256").digest())
                except OSError as exc:
                    h.update(f"unreadable {exc.errno}\0".encode())
    return h.hexdigest()


def _file_digest(*paths: str) -> str:
    h = hashlib.sha256()
    for p in paths:
        with open(p, "rb") as f:
            h.update(hashlib.file_digest(f, "sha256").digest())
    return h.hexdigest()


def fingerprint(task: Task, reference_digest: str, scene_key: str, submission_digest: str, version: str) -> str:
    """SHA-256 of everything that decides one (student, case) record (module docstring, step 3): the contents
    (``reference_digest`` of the reference image and noise band, ``scene_key`` of the scene and the files it
    names, ``submission_digest`` of the student's folder), the grader ``version``, and every field of the
    ``task`` (case command, output, reference name and points, render options, thresholds, FLIP, sandbox
    limits, extra paths, environment, folders)."""
    doc = {"task": repr(task), "reference": reference_digest, "scene": scene_key, "submission": submission_digest,
           "grader": version}
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


TOKEN_FILE = ".a5mi-shared-check"


def _sees(paths: Sequence[str], token_path: str, token: str) -> str | None:
    """Run on a worker: the first of ``paths`` it cannot stat, or ``token_path`` if that file does not hold
    ``token`` (the worker sees another folder of the same name); None when it sees them all."""
    for p in paths:
        if not os.path.exists(p):
            return p
    try:
        with open(token_path, encoding="utf-8") as f:
            if f.read() == token:
                return None
    except OSError:
        pass
    return os.path.dirname(token_path)


def check_workers_see(client: Any, paths: Sequence[str], report_dir: str | Path) -> None:
    """Ask every worker of ``client`` whether it sees ``paths`` and this process's ``report_dir`` (a fresh
    token file written there and read back); a :class:`UserError` naming the first worker and path that it
    cannot see."""
    token = secrets.token_hex(16)
    token_path = Path(report_dir) / TOKEN_FILE
    token_path.write_text(token, encoding="utf-8")
    try:
        answers = client.run(_sees, list(paths), str(token_path), token)
    finally:
        token_path.unlink(missing_ok=True)
    for worker, missing in sorted(answers.items()):
        if missing is not None:
            raise UserError(f"worker {worker} cannot see {missing}: the scheduler's workers need a shared "
                            f"filesystem")


def students_of(submissions: str | Path) -> list[str]:
    """The sub-folders of ``submissions``, sorted (each one student); a UserError if there are none."""
    root = Path(submissions)
    if not root.is_dir():
        raise UserError(f"submissions folder '{root}' does not exist")
    names = sorted(p.name for p in root.iterdir() if p.is_dir() and not p.name.startswith("."))
    if not names:
        raise UserError(f"'{root}' holds no student folders")
    return names


def _reference_unit(args: tuple[Case, str, str, str | None, bool]) -> Any:
    """On a worker: the case's reference, and the CPU seconds of a5mi's own render of it there (when
    ``calibrate``; else 0)."""
    case, scenes, cache, ref_dir, calibrate = args
    ref_file = None if ref_dir is None else Path(ref_dir) / case.reference
    ref = build_reference(Path(scenes) / case.scene, case.options, cache, reference_file=ref_file)
    return ref, (render_cpu_seconds(Path(scenes) / case.scene, case.options) if calibrate else 0.0)


def grade_class(s: GradeSettings, progress: Progress | None = None, client: Any = None) -> GradeOutcome:
    """Grade every student on every case (module docstring); ``client`` reuses a Dask client (else one is
    started from ``s.workers`` / ``s.scheduler`` / ``s.security`` and closed; with ``s.slurm``, ``s.workers``
    SLURM jobs, :func:`a5mi.runtime.slurm.start_slurm_client`, logs in ``REPORT/slurm/logs``, and the paths
    are checked from the first worker that starts). The report's sandbox line is what a worker reports."""
    from a5mi.grade import report

    s = s.absolute()
    students = students_of(s.submissions)
    report_dir = Path(s.report_dir)
    report_dir.mkdir(parents=True, exist_ok=True)
    for case in s.cases:
        if s.reference_dir is not None and not (Path(s.reference_dir) / case.reference).is_file():
            raise UserError(f"reference image '{Path(s.reference_dir) / case.reference}' not found "
                            f"(case '{case.name}')")
        if not (Path(s.scenes) / case.scene).is_file():
            raise UserError(f"case '{case.name}': scene '{Path(s.scenes) / case.scene}' not found")
    work_root = Path(s.work_root or report_dir / ".work")
    work_root.mkdir(parents=True, exist_ok=True)
    work_root.chmod(0o755)
    Path(s.cache_dir).mkdir(parents=True, exist_ok=True)
    if client is None and s.slurm is not None:
        from a5mi.runtime.slurm import start_slurm_client

        with start_slurm_client(s.slurm, report_dir / "slurm") as c:
            c.wait_for_workers(1)  # SLURM starts the jobs when it can; the paths are checked from a worker
            return grade_class(s, progress, c)
    if client is None:
        with start_client(s.workers, s.scheduler, security=s.security) as c:
            return grade_class(s, progress, c)

    seen = [s.submissions, s.scenes, s.cache_dir, str(work_root), *(p for p in s.read_only if os.path.exists(p))]
    check_workers_see(client, seen + ([s.reference_dir] if s.reference_dir is not None else []), report_dir)
    calibrate = s.cpu is None
    built = client.gather([client.submit(_reference_unit, (c, s.scenes, s.cache_dir, s.reference_dir, calibrate),
                                         pure=False, retries=2) for c in s.cases])
    refs = [r for r, _ in built]
    a5mi_cpu = [t for _, t in built]
    (report_dir / "img" / "ref").mkdir(parents=True, exist_ok=True)
    for case, ref in zip(s.cases, refs, strict=True):
        shutil.copyfile(ref.image_path, report_dir / "img" / "ref" / f"{case.name}.png")
    version = grader_version()
    case_keys = [(_file_digest(ref.image_path, ref.sigma_path), cache_key(Path(s.scenes) / case.scene, case.options))
                 for case, ref in zip(s.cases, refs, strict=True)]
    units, prints = [], {}
    for student in students:
        sub_digest = tree_digest(Path(s.submissions) / student)
        for case, ref, (ref_digest, scene_key), t in zip(s.cases, refs, case_keys, a5mi_cpu, strict=True):
            task = Task(student, str(Path(s.submissions) / student), case, s.scenes, ref.image_path, ref.sigma_path,
                        str(work_root), str(report_dir), s.bounds(t), s.read_only, s.env, s.thresholds, s.flip, t)
            units.append((task.key, task))
            # the measured calibration varies from run to run: the policy (flags, factors) is fingerprinted
            policy = dataclasses.replace(task, limits=s.limits, a5mi_cpu=0.0)
            rule = f"cpu={s.cpu} wall={s.wall} {CPU_FACTOR} {CPU_FLOOR} {WALL_FACTOR}"
            prints[task.key] = fingerprint(policy, ref_digest, scene_key, sub_digest, f"{version} {rule}")
    journal = Journal(report_dir / "journal.jsonl")
    before = journal.done(prints) if s.resume else set()
    records = run_units(client, units, grade_one, journal, resume=s.resume, progress=progress, fingerprints=prints)
    order = {k: i for i, (k, _) in enumerate(units)}
    records.sort(key=lambda r: order[r["key"]])
    outcome = GradeOutcome(records, students, client.submit(isolation, pure=False).result(),
                           skipped=len(before & set(order)))
    outcome.files = report.write_all(report_dir, s.cases, students, records,
                                     {"isolation": outcome.isolation, "thresholds": vars(s.thresholds),
                                      "references": {c.name: r.source for c, r in zip(s.cases, refs, strict=True)}})
    for point in mounts_under(work_root):  # a run folder of a worker killed mid-run
        unmount(point)
    shutil.rmtree(work_root, ignore_errors=True)
    return outcome


def run_plain(units: Sequence[Task]) -> list[dict[str, Any]]:
    """The same tasks in a plain loop in this process (the benchmark's baseline)."""
    return [grade_one(t) for t in units]


__all__ = ["CPU_FACTOR", "CPU_FLOOR", "UNGRADED", "VERDICT_MODULES", "WALL_FACTOR", "GradeOutcome", "GradeSettings",
           "check_workers_see", "fingerprint", "grade_class", "grader_version", "run_plain", "students_of",
           "tree_digest"]
