"""``a5mi render`` with several jobs: one process, each scene loaded once, kernels reused.

Two ways to give the jobs (they may be combined; the jobs run in the order given, positionals first):

* ``a5mi render A.txt B.txt ... --output-dir DIR [a5 flags]``: every scene with the same flags, written to
  ``DIR/<scene stem>.<--output-ext>`` (default ``png``). ``-input``, ``-output``, ``-normals`` and ``-depth``
  name one file each and are refused here (give them per job in a jobs file).
* ``a5mi render --jobs FILE [a5 flags]``: one job per line of FILE, each line an ``a5`` argument list in
  ``a5``'s strict grammar (shell quoting; blank lines and lines starting with ``#`` are skipped), laid over
  the command line's flags: a flag on the line wins, the others keep the command line's value (so
  ``a5mi render -size 300 300 -shadows --jobs J`` with lines ``-input s.txt -output s.png -bounces 2``).
  Every line needs ``-input`` and ``-output`` (its own or the command line's). Relative paths are relative to
  the working directory, as for ``a5``; a relative ``-output`` / ``-normals`` / ``-depth`` is put in
  ``--output-dir`` when one is given.

Each job is checked, rendered and written on its own (:func:`a5mi.commands.render.outputs_of`, the scene checks,
:func:`a5mi.platform.imageio.write_images`: atomic, all or nothing for one job's images) through one
:class:`a5mi.render.session.RenderSession`, so its images are bit-identical to a separate ``a5`` run of the same
arguments. **Error rule**: a job that fails (a bad line, a missing file, a scene error, a write error) prints
one line, ``a5mi render: job K (NAME): error: ...`` (or the scene's ``FILE:LINE:COL: error: ...``), writes
nothing, and the others go on; at the end one line counts the failures. Exit status
(:class:`a5mi.platform.errors.ExitStatus`): 0 when every job was written, 70 when any failed with an internal error (a
bug), else 2 when any failed with a user error, 128 + N when signal N stopped the batch (the jobs already
written stay). Two jobs writing the same file, or a job writing over another job's scene, is refused before
anything renders (exit 2).
"""

from __future__ import annotations

import dataclasses
import os
import shlex
import time
from pathlib import Path
from typing import Any

from a5mi.cli.app import Console, guarded
from a5mi.cli.flags import Args, Flag, parse, text
from a5mi.platform import clobber
from a5mi.platform.errors import ExitStatus, UsageError

#: Flags of ``a5mi render`` beyond the a5 ones (module docstring).
BATCH_FLAGS: tuple[Flag, ...] = (
    Flag(("--jobs",), "jobs", "jobs, one a5 argument list per line (# comments), laid over these flags", 1, text,
         metavar="FILE"),
    Flag(("--output-dir", "-O"), "output_dir", "folder of the scenes' images (and of relative outputs of --jobs)",
         1, text, metavar="DIR"),
    Flag(("--output-ext",), "output_ext", "image format of the scenes given as positionals", 1, text, "png",
         "EXT"),
)

EPILOG = ("Several scenes (positionals, --output-dir DIR) or --jobs FILE render in one process; each job is "
          "written atomically on its own, a failing job prints one line and the others go on.")
#: The batch's words in the one "Exit status:" paragraph of ``a5mi render -h``.
EXIT_NOTE = (f"A batch ends with the status of its worst failed job ({int(ExitStatus.SOFTWARE)} before "
             f"{int(ExitStatus.USAGE)}); two jobs writing one file is a {int(ExitStatus.USAGE)} before anything "
             "renders.")

#: Largest jobs file read (bytes).
MAX_JOBS_BYTES = 64 << 20

#: Dests of a job line that name an output file (relative ones go into --output-dir).
_OUTPUTS = ("output", "normals_output", "depth_output")


@dataclasses.dataclass
class Job:
    """One render: its 1-based number, a name for messages, its a5 arguments (or the error that stops it
    before it starts, e.g. a bad jobs-file line)."""

    number: int
    name: str
    args: Args | None
    error: str | None = None


def is_batch(args: Args) -> bool:
    """True when ``a5mi render`` was given scenes as positionals or ``--jobs``."""
    return bool(args.get("scenes")) or args.get("jobs") is not None


def _in_dir(path: str | None, folder: str | None) -> str | None:
    if path is None or folder is None or os.path.isabs(path):
        return path
    return os.path.join(folder, path)


def make_jobs(args: Args, render_flags: tuple[Flag, ...], check: Any) -> list[Job]:
    """The jobs of the command line (module docstring); ``check(args)`` validates one job's arguments (the
    a5 checks). Raises :class:`UsageError` for what concerns the whole command."""
    given = [f"-{d}" for d in ("input", "output") if args.get(d) is not None]
    if args.get("scenes"):
        given += [n for d, n in (("normals_output", "-normals"), ("depth_output", "-depth")) if args.get(d)]
        if given:
            raise UsageError(f"{', '.join(given)} name one file; with scenes as arguments use --output-dir (or give "
                             "them per job in --jobs)")
        if args.get("output_dir") is None:
            raise UsageError("scenes given as arguments need --output-dir DIR")
    ext = args.output_ext.lstrip(".")
    base = Args({k: v for k, v in args.items() if k in _dests(render_flags) or k == "debug"})
    jobs: list[Job] = []
    for scene in args.get("scenes") or ():
        job = Args(base, input=scene, output=os.path.join(args.output_dir, f"{Path(scene).stem}.{ext}"))
        jobs.append(_checked(Job(len(jobs) + 1, scene, job), check))
    if args.get("jobs") is not None:
        jobs += _file_jobs(args.jobs, base, render_flags, args.get("output_dir"), check, len(jobs))
    _check_distinct(jobs)
    return jobs


def _dests(flags: tuple[Flag, ...]) -> set[str]:
    return {d for f in flags for d in f.dests}


def _checked(job: Job, check: Any) -> Job:
    try:
        assert job.args is not None
        for dest, name in (("input", "-input"), ("output", "-output")):
            if job.args.get(dest) is None:
                raise UsageError(f"missing {name}")
        check(job.args)
    except UsageError as exc:
        job.error, job.args = str(exc), None
    return job


def _file_jobs(path: str, base: Args, render_flags: tuple[Flag, ...], out_dir: str | None, check: Any,
               first: int) -> list[Job]:
    from a5mi.platform.errors import FileReadError, UserError
    from a5mi.platform.paths import read_regular

    try:  # a regular file only: a FIFO or device is refused, never waited on
        lines = read_regular(path, MAX_JOBS_BYTES, "the jobs file").decode("utf-8").splitlines()
    except FileReadError as exc:
        raise UserError(f"cannot read the jobs file '{path}': {exc.reason}") from None
    except UnicodeDecodeError as exc:
        raise UserError(f"cannot read the jobs file '{path}': {exc}") from None
    jobs: list[Job] = []
    for lineno, line in enumerate(lines, 1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        where = f"{path}:{lineno}"
        number = first + len(jobs) + 1
        try:
            given: set[str] = set()
            parsed = parse(shlex.split(line), render_flags, grammar="a5", see="a5 -h", given=given)
        except (UsageError, ValueError) as exc:
            jobs.append(Job(number, where, None, str(exc)))
            continue
        job = Args(base)
        job.update({d: parsed[d] for d in given})
        for dest in _OUTPUTS:
            if dest in given:
                job[dest] = _in_dir(job[dest], out_dir)
        name = f"{where}, {Path(job.input).name}" if job.get("input") else where
        jobs.append(_checked(Job(number, name, job), check))
    if not jobs:
        raise UsageError(f"the jobs file '{path}' has no job")
    return jobs


def _check_distinct(jobs: list[Job]) -> None:
    """No two jobs write the same file and no job writes over another job's scene (whole-command error)."""
    outs: list[tuple[str, str]] = []
    scenes: list[str] = []
    for job in jobs:
        if job.args is None:
            continue
        scenes.append(job.args.input)
        outs += [(f"job {job.number} {role}", job.args[dest]) for role, dest in
                 (("-output", "output"), ("-normals", "normals_output"), ("-depth", "depth_output"))
                 if job.args.get(dest)]
    clobber.check_outputs(outs, scenes)


def run_batch(jobs: list[Job], console: Console, render_one: Any) -> int:
    """Run every job (module docstring's error rule) under the one error policy (:func:`a5mi.cli.app.guarded`,
    with ``job K (NAME)`` in each line); ``render_one(args, console, session, scenes)`` renders and writes one
    job (``scenes``: the descriptions loaded so far, by path). Returns the exit status."""
    holder: list[Any] = []  # the RenderSession, made by the first job that gets to render
    scenes: dict[Any, Any] = {}
    statuses: list[int] = []
    t0 = time.perf_counter()
    for job in jobs:
        sub = Console(f"{console.prog}: job {job.number} ({job.name})", quiet=console.quiet,
                      out=console._out, err=console._err)
        if job.args is None:
            sub.error(job.error or "invalid job")
            statuses.append(ExitStatus.USAGE)
            continue

        def body(args: Args = job.args, sub: Console = sub) -> int:
            return render_one(args, sub, _session(holder, args), scenes)

        status = guarded(sub, bool(job.args.get("debug")), body)
        statuses.append(status)
        if status >= 128:  # a signal stops the batch; the jobs written so far stay
            return status
    failed = [j.number for j, s in zip(jobs, statuses, strict=True) if s != 0]
    if failed or any(j.args is not None and j.args.get("verbose") for j in jobs):
        console.note(f"{console.prog}: {len(jobs) - len(failed)} of {len(jobs)} jobs written in "
                     f"{time.perf_counter() - t0:.2f} s" + (f"; failed: job {', '.join(map(str, failed))}"
                                                             if failed else ""))
    if not failed:
        return ExitStatus.OK
    return ExitStatus.SOFTWARE if ExitStatus.SOFTWARE in statuses else ExitStatus.USAGE


def _session(holder: list[Any], args: Args) -> Any:
    """The batch's :class:`a5mi.render.session.RenderSession`, made on first use with the job's ``-variant``; later
    jobs must not ask for another variant (one process holds one)."""
    from a5mi.platform.errors import UserError
    from a5mi.render.session import RenderSession
    from a5mi.runtime import variant

    if not holder:
        try:
            with _deferred():
                holder.append(RenderSession(args.get("variant")))
        except variant.VariantError as exc:
            raise UserError(str(exc)) from None
    elif args.get("variant") is not None and _variant(args) != holder[0].variant:
        raise UsageError(f"-variant {args.variant}: every job of one batch uses the first job's variant "
                         f"({holder[0].variant})")
    return holder[0]


def _deferred() -> Any:
    from a5mi.platform import interrupts

    return interrupts.deferred()  # a signal in the middle of loading Dr.Jit would break the interpreter


def _variant(args: Args) -> str:
    """The full variant name of a job's ``-variant`` (or the default), as :func:`a5mi.runtime.variant.resolve`."""
    from a5mi.runtime import variant

    try:
        return variant.resolve(args.get("variant"))
    except variant.VariantError as exc:
        raise UsageError(str(exc)) from None


__all__ = ["BATCH_FLAGS", "EPILOG", "EXIT_NOTE", "Job", "is_batch", "make_jobs", "run_batch"]
