"""A whole class: references, one cluster task per (student, case), the journal and the report (issue 13).

:func:`grade_class` is what ``a5mi grade`` runs: the references are built on the cluster's workers (rendered by
a5mi once per case and cached, :mod:`a5mi.grade.references`), then every (student, case) is one task of
:func:`a5mi.grade.run.grade_one` through :func:`a5mi.cluster.run_units` (journal ``REPORT/journal.jsonl``,
``resume``), then :mod:`a5mi.grade.report` writes ``report.html``, ``results.csv`` and ``results.json``.
"""

from __future__ import annotations

import shutil
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from a5mi.cluster import Journal, Progress, run_units, start_client
from a5mi.errors import UserError
from a5mi.grade.cases import Case
from a5mi.grade.references import build_reference
from a5mi.grade.run import Task, grade_one
from a5mi.grade.sandbox import Limits, isolation
from a5mi.grade.verdict import Thresholds


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


@dataclass
class GradeOutcome:
    """The records (one per student x case), the students, the isolation used and the files written."""

    records: list[dict[str, Any]]
    students: list[str]
    isolation: str
    files: dict[str, str] = field(default_factory=dict)
    skipped: int = 0


def students_of(submissions: str | Path) -> list[str]:
    """The sub-folders of ``submissions``, sorted (each one student); a UserError if there are none."""
    root = Path(submissions)
    if not root.is_dir():
        raise UserError(f"submissions folder '{root}' does not exist")
    names = sorted(p.name for p in root.iterdir() if p.is_dir() and not p.name.startswith("."))
    if not names:
        raise UserError(f"'{root}' holds no student folders")
    return names


def _reference_unit(args: tuple[Case, str, str, str | None]) -> Any:
    case, scenes, cache, ref_dir = args
    ref_file = None if ref_dir is None else Path(ref_dir) / case.reference
    return build_reference(Path(scenes) / case.scene, case.options, cache, reference_file=ref_file)


def grade_class(s: GradeSettings, progress: Progress | None = None, client: Any = None) -> GradeOutcome:
    """Grade every student on every case (module docstring); ``client`` reuses a Dask client (else one is
    started from ``s.workers`` / ``s.scheduler`` and closed)."""
    from a5mi.grade import report

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
    if client is None:
        with start_client(s.workers, s.scheduler) as c:
            return grade_class(s, progress, c)

    refs = client.gather([client.submit(_reference_unit, (c, s.scenes, s.cache_dir, s.reference_dir), pure=False,
                                        retries=2) for c in s.cases])
    (report_dir / "img" / "ref").mkdir(parents=True, exist_ok=True)
    for case, ref in zip(s.cases, refs, strict=True):
        shutil.copyfile(ref.image_path, report_dir / "img" / "ref" / f"{case.name}.png")
    units = []
    for student in students:
        for case, ref in zip(s.cases, refs, strict=True):
            task = Task(student, str(Path(s.submissions) / student), case, s.scenes, ref.image_path, ref.sigma_path,
                        str(work_root), str(report_dir), s.limits, s.read_only, s.env, s.thresholds, s.flip)
            units.append((task.key, task))
    journal = Journal(report_dir / "journal.jsonl")
    before = journal.done() if s.resume else set()
    records = run_units(client, units, grade_one, journal, resume=s.resume, progress=progress)
    order = {k: i for i, (k, _) in enumerate(units)}
    records.sort(key=lambda r: order[r["key"]])
    outcome = GradeOutcome(records, students, isolation(),
                           skipped=len(before & set(order)))
    outcome.files = report.write_all(report_dir, s.cases, students, records,
                                     {"isolation": outcome.isolation, "thresholds": vars(s.thresholds),
                                      "references": {c.name: r.source for c, r in zip(s.cases, refs, strict=True)}})
    shutil.rmtree(work_root, ignore_errors=True)
    return outcome


def run_plain(units: Sequence[Task]) -> list[dict[str, Any]]:
    """The same tasks in a plain loop in this process (the benchmark's baseline)."""
    return [grade_one(t) for t in units]


__all__ = ["GradeOutcome", "GradeSettings", "grade_class", "run_plain", "students_of"]
