"""``a5mi grade SUBMISSIONS -o REPORT_DIR``: grade a class's ray tracers, sandboxed, on Dask (docs/GRADING.md).

The library is :mod:`a5mi.grade` (cases, sandbox, references, verdicts, report) and :mod:`a5mi.runtime.cluster`;
this module turns the flags into :class:`~a5mi.grade.batch.GradeSettings`, parses each case's a5 command line
with the ``a5`` parser (a bad case is a user error before anything runs), shows a progress bar with ETA
(tqdm) and prints one line per student.
"""

from __future__ import annotations

import os
from pathlib import Path

from a5mi.cli.app import Command, Console
from a5mi.cli.flags import Args, Flag, Positional, integer, real, real_in, text
from a5mi.cli.scheduler import SCHEDULER_FLAGS, scheduler_security
from a5mi.platform.errors import ExitStatus, UsageError, UserError
from a5mi.runtime.extras import require

FLAGS: tuple[Flag, ...] = (
    Flag(("-o", "--output"), "output", "report folder (report.html, results.csv, results.json, journal.jsonl)",
         1, text, metavar="REPORT_DIR"),
    Flag(("--cases",), "cases", "cases file (default: the handout's four test commands)", 1, text,
         metavar="CASES.toml"),
    Flag(("--reference",), "reference", "read reference images from DIR instead of rendering them", 1, text,
         metavar="DIR"),
    Flag(("--scenes",), "scenes", "scenes folder (default: the course data's scenes/)", 1, text, metavar="DIR"),
    Flag(("--workers",), "workers", "local Dask worker processes (with --slurm: SLURM jobs, one worker each)", 1,
         integer(1, 512), 2, "N"),
    Flag(("--scheduler",), "scheduler", "join an existing Dask cluster instead of starting one (its workers must "
         "see every path on a shared filesystem)", 1, text, metavar="tls://HOST:PORT"),
    *SCHEDULER_FLAGS,
    Flag(("--slurm",), "slurm", "start the --workers as SLURM jobs from this submit node (dask-jobqueue; per-run "
         "TLS as on the local cluster; every path on a file system the nodes share)", default=False,
         show_default=False),
    Flag(("--slurm-partition",), "slurm_partition", "with --slurm: the jobs' partition (default: the site's)", 1,
         text, metavar="NAME"),
    Flag(("--slurm-account",), "slurm_account", "with --slurm: the account charged", 1, text, metavar="NAME"),
    Flag(("--slurm-walltime",), "slurm_walltime", "with --slurm: each job's time limit (a job that reaches it is "
         "submitted again)", 1, text, "01:00:00", "[D-]HH:MM:SS"),
    Flag(("--slurm-memory",), "slurm_memory", "with --slurm: each job's memory (sbatch --mem; the worker's limit)",
         1, text, "4GB", "SIZE"),
    Flag(("--slurm-interface",), "slurm_interface", "with --slurm: the nodes' network interface the scheduler and "
         "workers listen on (default: 127.0.0.1, jobs on this node only)", 1, text, metavar="IFACE"),
    Flag(("--slurm-sbatch",), "slurm_sbatch", "with --slurm: more #SBATCH options, split like a shell line", 1,
         text, metavar="'OPTIONS'"),
    Flag(("--cpu",), "cpu", "CPU seconds per case, all its processes together (default: max(120, 250 x a5mi's "
         "own CPU seconds for the case, measured on a worker))", 1, real_in(0.0, 1e6, open_lo=True), metavar="S"),
    Flag(("--timeout",), "timeout", "wall-clock backstop per case, not counting time spent waiting for a CPU "
         "(default: twice the CPU bound)", 1, real_in(0.0, 1e6, open_lo=True), metavar="S"),
    Flag(("--memory",), "memory", "address-space limit per case", 1, integer(64, 1 << 22), 4096, "MB"),
    Flag(("--disk",), "disk", "bytes a case may write, its folder and /tmp together (a tmpfs per run)", 1,
         integer(1, 1 << 20), 512, "MB"),
    Flag(("--inodes",), "inodes", "files and folders a case may create, its folder and /tmp together", 1,
         integer(64, 1 << 24), 4096, "N"),
    Flag(("--resume",), "resume", "skip the cases already in REPORT_DIR/journal.jsonl", default=False,
         show_default=False),
    Flag(("--allow-read",), "allow_read", "extra paths the sandbox may read (':'-separated), e.g. a toolchain", 1,
         text, metavar="PATHS"),
    Flag(("--cache",), "cache", "reference cache (default: ~/.cache/a5mi/grade or $A5MI_CACHE_DIR/grade)", 1, text,
         metavar="DIR"),
    Flag(("--match",), "match", "largest share of pixels beyond noise for 'match'", 1, real, 0.01, "SHARE"),
    Flag(("--close",), "close", "largest share of pixels beyond noise for 'close'", 1, real, 0.015, "SHARE"),
    Flag(("--no-flip",), "flip", "skip NVIDIA FLIP (faster)", const=False, default=True, show_default=False),
    Flag(("--no-sandbox",), "no_sandbox", "run executables even without bubblewrap (rlimits and a user id only: "
         "they can read what that user may and reach the network); said in the report", default=False,
         show_default=False),
)


def _options_of(argv: list[str]):  # noqa: ANN202 - RenderOptions, imported lazily
    from a5mi.cli import parse_a5_args
    from a5mi.commands.render import render_options

    return render_options(parse_a5_args(argv))


def slurm_options(args: Args):  # noqa: ANN201 - SlurmOptions or None
    """The :class:`~a5mi.runtime.slurm.SlurmOptions` of ``--slurm`` and its flags (``--workers`` jobs), or None;
    a ``--slurm-*`` flag without ``--slurm``, or ``--slurm`` with ``--scheduler``, is a usage error."""
    import re
    import shlex

    given = [f"--slurm-{d}" for d in ("partition", "account", "interface", "sbatch")
             if args.get(f"slurm_{d}") is not None]
    if not args.slurm:
        if given:
            raise UsageError(f"{given[0]} needs --slurm")
        return None
    if args.scheduler is not None:
        raise UsageError("give --slurm or --scheduler, not both")
    if not re.fullmatch(r"(\d+-)?\d{1,2}(:\d{2}){0,2}", args.slurm_walltime):
        raise UsageError(f"--slurm-walltime expects [D-]HH:MM:SS, found '{args.slurm_walltime[:40]}'")
    if not re.fullmatch(r"\d+(\.\d+)?\s*[KMGT]i?B", args.slurm_memory, re.IGNORECASE):
        raise UsageError(f"--slurm-memory expects a size like 4GB, found '{args.slurm_memory[:40]}'")
    try:
        directives = tuple(shlex.split(args.slurm_sbatch or ""))
    except ValueError as exc:
        raise UsageError(f"--slurm-sbatch: {exc}") from None
    from a5mi.runtime.slurm import SlurmOptions

    return SlurmOptions(jobs=args.workers, partition=args.slurm_partition, account=args.slurm_account,
                        walltime=args.slurm_walltime, memory=args.slurm_memory.replace(" ", ""),
                        interface=args.slurm_interface, directives=directives)


def settings_of(args: Args):  # noqa: ANN201 - GradeSettings
    """The :class:`~a5mi.grade.batch.GradeSettings` of the flags (raises user errors for bad values)."""
    from a5mi import require_data_dir
    from a5mi.grade.batch import GradeSettings
    from a5mi.grade.cases import load_cases
    from a5mi.grade.references import default_cache_dir
    from a5mi.grade.verdict import Thresholds
    from a5mi.sandbox.records import Limits

    if not 0 <= args.match <= args.close <= 1:
        raise UsageError(f"--match and --close must satisfy 0 <= match <= close <= 1 (found {args.match:g}, "
                         f"{args.close:g})")
    slurm = slurm_options(args)
    security = scheduler_security(args)
    if not Path(args.submissions).is_dir():   # the user's own inputs first, the course data after them
        raise UserError(f"submissions folder '{args.submissions}' does not exist")
    if args.reference is not None and not Path(args.reference).is_dir():
        raise UsageError(f"--reference: '{args.reference}' is not a folder")
    cases = load_cases(args.cases, _options_of)
    check_reachable(args.scheduler)
    scenes = args.scenes or str(require_data_dir() / "scenes")
    if not Path(scenes).is_dir():
        raise UsageError(f"--scenes: '{scenes}' is not a folder")
    allow = tuple(p for p in (args.allow_read or "").split(":") if p)
    return GradeSettings(
        submissions=args.submissions, report_dir=args.output, cases=cases, scenes=os.path.abspath(scenes),
        cache_dir=args.cache or str(default_cache_dir()), reference_dir=args.reference, workers=args.workers,
        scheduler=args.scheduler, security=security, slurm=slurm, resume=args.resume,
        limits=Limits(timeout=args.timeout or 0.0, memory_mb=args.memory, require_sandbox=not args.no_sandbox,
                      cpu_seconds=args.cpu, disk_mb=args.disk, inodes=args.inodes),
        cpu=args.cpu, wall=args.timeout, read_only=allow, thresholds=Thresholds(args.match, args.close),
        flip=args.flip)


def check_report_dir(args: Args) -> None:
    """``-o``: a folder or nothing yet (never a file), and neither the submissions, scenes or reference folder
    nor inside one of them (the report would be graded, or overwrite an input; a5mi.platform.clobber's rule: resolved
    paths and inodes)."""
    from a5mi.platform import clobber

    out = args.output
    if os.path.lexists(out) and not os.path.isdir(out):
        raise UsageError(f"-o '{out}': exists and is not a folder")
    real = os.path.realpath(out)
    for flag, folder in (("SUBMISSIONS", args.submissions), ("--scenes", args.scenes),
                         ("--reference", args.reference)):
        if folder is None:
            continue
        root = os.path.realpath(folder)
        if clobber.same_file(out, folder) or real.startswith(root.rstrip(os.sep) + os.sep):
            raise UsageError(f"-o '{out}' is {'' if clobber.same_file(out, folder) else 'inside '}the {flag} folder "
                             f"'{folder}': the report would be written among the inputs")


def check_reachable(address: str | None, timeout: float = 5.0) -> None:
    """Fail fast, before anything is written, when nothing listens at ``--scheduler`` (a TCP connection to its
    host and port, default 8786, within ``timeout`` seconds) instead of after Dask's 30 s."""
    import socket
    from urllib.parse import urlsplit

    if address is None or not address.startswith(("tcp://", "tls://")):
        return
    try:
        parts = urlsplit(address)
        host, port = parts.hostname, parts.port or 8786
    except ValueError as exc:
        raise UsageError(f"--scheduler '{address[:60]}': {exc}") from None
    if not host:
        raise UsageError(f"--scheduler '{address[:60]}': no host")
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except OSError as exc:
        raise UsageError(f"--scheduler {address[:60]}: cannot connect: {exc.strerror or exc}") from None


def _remove_if_empty(folder: str) -> None:
    """Remove ``folder`` when it holds folders only (what a run that failed before grading made)."""
    import shutil

    for _, _, files in os.walk(folder):
        if files:
            return
    shutil.rmtree(folder, ignore_errors=True)


def _has_executables(submissions: str) -> bool:
    """Whether a student folder of ``submissions`` holds an executable ``a5`` (a program to run)."""
    root = Path(submissions)
    return root.is_dir() and any(os.access(d / "a5", os.X_OK) and (d / "a5").is_file()
                                 for d in root.iterdir() if d.is_dir())


def run_grade(args: Args, console: Console) -> int:
    from a5mi.grade.batch import grade_class
    from a5mi.sandbox import bwrap as sandbox

    for module in ("distributed", "cryptography", "tqdm") + (("flip_evaluator",) if args.flip else ()):
        require(module, "grade")  # before the cluster starts: a worker would journal it as each case's error
    if args.slurm:
        require("dask_jobqueue", "slurm")
    check_report_dir(args)
    settings = settings_of(args)
    fresh = not os.path.lexists(args.output)
    why = sandbox.refusal()
    if why and _has_executables(args.submissions):
        if not args.no_sandbox:
            raise UsageError(why)
        console.note(f"a5mi grade: WARNING: --no-sandbox: {sandbox.sandbox_problem()}: student programs run NOT "
                     "SANDBOXED (rlimits, their own user id and a private folder only: they can read what that user "
                     "may and reach the network and the Dask scheduler)")
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
    except BaseException:
        if fresh:
            _remove_if_empty(args.output)  # leave no empty report folder behind
        raise
    finally:
        if bar is not None:
            bar.close()
    from a5mi.grade.report import totals

    tot = totals([r for r in outcome.records if "student" in r], outcome.students)
    by = {(r.get("student"), r.get("case")): r.get("verdict", "error") for r in outcome.records}
    width = max(len(s) for s in outcome.students)
    from a5mi.grade.feedback import same_failure

    for s in outcome.students:
        p, m = tot[s]
        verdicts = ", ".join(f"{c.name} {by.get((s, c.name), 'error')}" for c in settings.cases)
        console.result(f"{s:<{width}}  {p:6g} / {m:g}  {verdicts}")
    for s in outcome.students:  # a failure shared by every case of a student: said once
        common = same_failure([r for r in outcome.records if r.get("student") == s])
        if common:
            console.note(f"a5mi grade: {s}: {common}")
    if outcome.skipped:
        console.note(f"a5mi grade: {outcome.skipped} cases taken from the journal (--resume)")
    console.note(f"a5mi grade: report in {outcome.files['html']} (sandbox: {outcome.isolation})")
    errors = [r for r in outcome.records if "error" in r and "verdict" not in r]
    for r in errors[:5]:
        console.error(f"{r['key']}: grader error: {r['error']}")
    if outcome.nothing_graded:
        raise UserError(f"nothing could be graded: every case of all {len(outcome.students)} students is 'no "
                        f"output' or a grader error (check SUBMISSIONS, the cases' -output names and --scheduler's "
                        f"filesystem; report in {outcome.files['html']})")
    return ExitStatus.DIFFER if errors else ExitStatus.OK


GRADE = Command("grade", "Grade every student folder of SUBMISSIONS (an executable a5, or the images) on the cases, "
                "sandboxed, on a Dask cluster; writes an HTML report, CSV and JSON.", FLAGS, run_grade,
                (Positional("submissions", "SUBMISSIONS", "folder with one sub-folder per student"),),
                required=("output",), exit_ok="every case graded",
                exit_differ="a case could not be graded (a grader error, named on stderr)",
                exit_note="Nothing graded (every case 'no output' or a grader error) and a --scheduler worker that "
                          "cannot see a path are mistakes you can fix: 2.")
