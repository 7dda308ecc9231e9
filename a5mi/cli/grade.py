"""``a5mi grade SUBMISSIONS -o REPORT_DIR``: grade a class's ray tracers, sandboxed, on Dask (issue 13).

The library is :mod:`a5mi.grade` (cases, sandbox, references, verdicts, report) and :mod:`a5mi.cluster`;
this module turns the flags into :class:`~a5mi.grade.batch.GradeSettings`, parses each case's a5 command line
with the ``a5`` parser (a bad case is a user error before anything runs), shows a progress bar with ETA
(tqdm) and prints one line per student.
"""

from __future__ import annotations

import os
from pathlib import Path

from a5mi.cli.app import Command, Console
from a5mi.cli.flags import Args, Flag, Positional, integer, real, text
from a5mi.errors import UsageError
from a5mi.extras import require

FLAGS: tuple[Flag, ...] = (
    Flag(("-o", "--output"), "output", "report folder (report.html, results.csv, results.json, journal.jsonl)",
         1, text, metavar="REPORT_DIR"),
    Flag(("--cases",), "cases", "cases file (default: the handout's four test commands)", 1, text,
         metavar="CASES.toml"),
    Flag(("--reference",), "reference", "read reference images from DIR instead of rendering them", 1, text,
         metavar="DIR"),
    Flag(("--scenes",), "scenes", "scenes folder (default: the course data's scenes/)", 1, text, metavar="DIR"),
    Flag(("--workers",), "workers", "local Dask worker processes", 1, integer(1, 512), 2, "N"),
    Flag(("--scheduler",), "scheduler", "join an existing Dask cluster instead of starting one", 1, text,
         metavar="tcp://HOST:PORT"),
    Flag(("--timeout",), "timeout", "wall-clock seconds per case", 1, real, 120.0, "S"),
    Flag(("--memory",), "memory", "address-space limit per case", 1, integer(64, 1 << 22), 4096, "MB"),
    Flag(("--resume",), "resume", "skip the cases already in REPORT_DIR/journal.jsonl", default=False,
         show_default=False),
    Flag(("--allow-read",), "allow_read", "extra paths the sandbox may read (':'-separated), e.g. a toolchain", 1,
         text, metavar="PATHS"),
    Flag(("--cache",), "cache", "reference cache (default: ~/.cache/a5mi/grade or $A5MI_CACHE_DIR/grade)", 1, text,
         metavar="DIR"),
    Flag(("--match",), "match", "largest share of pixels beyond noise for 'match'", 1, real, 0.01, "SHARE"),
    Flag(("--close",), "close", "largest share of pixels beyond noise for 'close'", 1, real, 0.015, "SHARE"),
    Flag(("--no-flip",), "flip", "skip NVIDIA FLIP (faster)", const=False, default=True, show_default=False),
)


def _options_of(argv: list[str]):  # noqa: ANN202 - RenderOptions, imported lazily
    from a5mi.cli import parse_a5_args
    from a5mi.cli.render import render_options

    return render_options(parse_a5_args(argv))


def settings_of(args: Args):  # noqa: ANN201 - GradeSettings
    """The :class:`~a5mi.grade.batch.GradeSettings` of the flags (raises user errors for bad values)."""
    from a5mi import require_data_dir
    from a5mi.grade.batch import GradeSettings
    from a5mi.grade.cases import load_cases
    from a5mi.grade.references import default_cache_dir
    from a5mi.grade.sandbox import Limits
    from a5mi.grade.verdict import Thresholds

    if not 0 <= args.match <= args.close <= 1:
        raise UsageError(f"--match and --close must satisfy 0 <= match <= close <= 1 (found {args.match:g}, "
                         f"{args.close:g})")
    if args.scheduler is not None and not args.scheduler.startswith(("tcp://", "tls://", "inproc://")):
        raise UsageError(f"--scheduler expects tcp://HOST:PORT, found '{args.scheduler[:40]}'")
    scenes = args.scenes or str(require_data_dir() / "scenes")
    if not Path(scenes).is_dir():
        raise UsageError(f"--scenes: '{scenes}' is not a folder")
    if args.reference is not None and not Path(args.reference).is_dir():
        raise UsageError(f"--reference: '{args.reference}' is not a folder")
    cases = load_cases(args.cases, _options_of)
    allow = tuple(p for p in (args.allow_read or "").split(":") if p)
    return GradeSettings(
        submissions=args.submissions, report_dir=args.output, cases=cases, scenes=os.path.abspath(scenes),
        cache_dir=args.cache or str(default_cache_dir()), reference_dir=args.reference, workers=args.workers,
        scheduler=args.scheduler, limits=Limits(timeout=args.timeout, memory_mb=args.memory), resume=args.resume,
        read_only=allow, thresholds=Thresholds(args.match, args.close), flip=args.flip)


def run_grade(args: Args, console: Console) -> int:
    from a5mi.grade import sandbox
    from a5mi.grade.batch import grade_class

    settings = settings_of(args)
    for module in ("distributed", "tqdm") + (("flip_evaluator",) if settings.flip else ()):
        require(module, "grade")  # before the cluster starts: a worker would journal it as each case's error
    if sandbox.isolation() != "bwrap":
        console.note("a5mi grade: bubblewrap (bwrap) not found: student programs run with rlimits, their own "
                     "user id (as root) and a private folder only, not in namespaces (apt-get install bubblewrap)")
    bar = None

    def progress(done: int, total: int) -> None:
        nonlocal bar
        if bar is None:
            tqdm = require("tqdm", "grade").tqdm

            bar = tqdm(total=total, initial=done, unit="case", file=console.err, dynamic_ncols=True,
                       disable=console.quiet, desc="grading")
        else:
            bar.update(done - bar.n)

    try:
        outcome = grade_class(settings, progress)
    finally:
        if bar is not None:
            bar.close()
    from a5mi.grade.report import totals

    tot = totals([r for r in outcome.records if "student" in r], outcome.students)
    by = {(r.get("student"), r.get("case")): r.get("verdict", "error") for r in outcome.records}
    width = max(len(s) for s in outcome.students)
    for s in outcome.students:
        p, m = tot[s]
        verdicts = ", ".join(f"{c.name} {by.get((s, c.name), 'error')}" for c in settings.cases)
        console.result(f"{s:<{width}}  {p:6g} / {m:g}  {verdicts}")
    if outcome.skipped:
        console.note(f"a5mi grade: {outcome.skipped} cases taken from the journal (--resume)")
    console.note(f"a5mi grade: report in {outcome.files['html']} (sandbox: {outcome.isolation})")
    errors = [r for r in outcome.records if "error" in r and "verdict" not in r]
    for r in errors[:5]:
        console.error(f"{r['key']}: grader error: {r['error']}")
    return 1 if errors else 0


GRADE = Command("grade", "Grade every student folder of SUBMISSIONS (an executable a5, or the images) on the cases, "
                "sandboxed, on a Dask cluster; writes an HTML report, CSV and JSON.", FLAGS, run_grade,
                (Positional("submissions", "SUBMISSIONS", "folder with one sub-folder per student"),),
                required=("output",),
                epilog="Exit status: 0 graded, 1 a case could not be graded (grader error), 2 user error.")
