"""The command layer's spine: commands, the dispatcher, the error guard, the console and the scene prologue.

Every command (``a5`` and each ``a5mi`` sub-command) is a :class:`Command`: its flag table
(:mod:`a5mi.cli.flags`), its positionals and a ``run(args, console)`` function that calls libraries (which
return data) and prints through the :class:`Console`, the only printer of the project. :func:`execute` parses,
answers ``-h`` / ``--version``, checks required flags and runs the command under :func:`guarded`, the one
error policy (docs/CLI.md "Exit status"), whose statuses are :class:`a5mi.platform.errors.ExitStatus`:

* a user error (:class:`~a5mi.platform.errors.UserError`, a scene's :class:`~a5mi.converters.errors.SceneError`)
  prints one line, ``FILE:LINE:COL: error: ...`` or ``PROG: error: ...``, and returns 2 (``USAGE``);
* anything else is a bug: one line ``PROG: internal error: Type: message (re-run with --debug for the
  traceback)`` and 70 (``SOFTWARE``, sysexits' EX_SOFTWARE); ``--debug`` prints tracebacks;
* SIGINT, SIGTERM and SIGHUP (:mod:`a5mi.platform.interrupts`, installed by :mod:`a5mi.entry`) return
  ``128 + signal`` (130 for Ctrl-C) with one line ``PROG: interrupted (SIGINT)``, also when native code
  handed the signal back wrapped in another exception (:func:`a5mi.platform.interrupts.signal_behind`: a Dr.Jit loop
  body or a plugin constructor was running); nothing is written and no temporary is left; a closed output
  pipe (``a5mi compare A B | head``) ends quietly with 141 (128 + SIGPIPE, as a shell reports for coreutils).

A command's own outcome is 0 (``OK``) or, for a command that gives a verdict, 1 (``DIFFER``: images differ,
a check does not hold). :data:`EXIT_STATUS_TABLE` is the one table of these statuses; every command's ``-h``
ends with one ``Exit status:`` paragraph made from it (:func:`exit_status_help`) with the command's own
meanings of 0 and 1 (:attr:`Command.exit_ok`, :attr:`Command.exit_differ`).

:func:`load_scene` is the one scene prologue: parse, print the parser's warnings, build the scene
description once (every file checked, images decoded) and print its warnings, all before Mitsuba is imported.
"""

from __future__ import annotations

import os
import re
import sys
import textwrap
import traceback
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, TextIO

from a5mi.cli.flags import COMMON, Args, Flag, Positional, format_help, parse
from a5mi.cli.streams import write_diagnostic
from a5mi.platform.errors import ExitStatus, UsageError, UserError

if TYPE_CHECKING:
    from a5mi.cli.progress import ProgressBar

#: The exit statuses of every command (docs/CLI.md "Exit status"): (status, meaning), one row per
#: :class:`~a5mi.platform.errors.ExitStatus` value (signals as one row). Each command words 0 and 1 for itself
#: (:attr:`Command.exit_ok`, :attr:`Command.exit_differ`); 1 belongs to the commands that give a verdict.
EXIT_STATUS_TABLE: tuple[tuple[str, str], ...] = (
    (str(int(ExitStatus.OK)), "success; for a comparison or a check: same, match, pass"),
    (str(int(ExitStatus.DIFFER)), "a verdict: the images differ, a check does not hold"),
    (str(int(ExitStatus.USAGE)), "a mistake you can fix (a flag, the scene, an input or output file; one line on "
     "stderr)"),
    (str(int(ExitStatus.SOFTWARE)), "internal error, a bug (sysexits EX_SOFTWARE; --debug shows the traceback)"),
    ("128+N", f"stopped by signal N ({int(ExitStatus.INTERRUPTED)} Ctrl-C, {ExitStatus.signal(15)} SIGTERM, "
     f"{ExitStatus.signal(1)} SIGHUP)"),
    (str(int(ExitStatus.BROKEN_PIPE)), "the output pipe was closed (128 + SIGPIPE)"),
)


def exit_status_help(ok: str, differ: str | None = None, note: str = "") -> str:
    """The one ``Exit status:`` paragraph of a command's ``-h``: the command's meaning of 0 (``ok``) and of 1
    (``differ``; None: the command gives no verdict and never exits 1), then the rows of
    :data:`EXIT_STATUS_TABLE` shared by every command, then ``note``."""
    parts = [f"{int(ExitStatus.OK)} {ok}"]
    if differ is not None:
        parts.append(f"{int(ExitStatus.DIFFER)} {differ}")
    parts += [f"{status} {meaning}" for status, meaning in EXIT_STATUS_TABLE[2:]]
    text = "Exit status: " + "; ".join(parts) + "." + (f" {note}" if note else "")
    return textwrap.fill(text, width=100, break_on_hyphens=False)


@dataclass(frozen=True)
class Command:
    """One command: ``name`` (``a5`` or the sub-command), its one-line ``summary``, ``flags`` (the common
    ``-q --debug --version -h`` are added), ``positionals``, ``run(args, console) -> exit status``, the
    ``grammar`` (:func:`a5mi.cli.flags.parse`), the dests that must be given (``required``), an ``epilog``
    for ``-h``, ``check(args)``: limits across several flags, raising :class:`UsageError`, and the command's
    meanings of exit status 0 (``exit_ok``) and 1 (``exit_differ``: only a command that gives a verdict;
    None: it never exits 1), with ``exit_note`` (:func:`exit_status_help`)."""

    name: str
    summary: str
    flags: tuple[Flag, ...]
    run: Callable[[Args, Console], int]
    positionals: tuple[Positional, ...] = ()
    grammar: Literal["a5", "gnu"] = "gnu"
    required: tuple[str, ...] = ()
    epilog: str = ""
    check: Callable[[Args], None] | None = None
    exit_ok: str = "done"
    exit_differ: str | None = None
    exit_note: str = ""

    @property
    def prog(self) -> str:
        return self.name if self.name == "a5" else f"a5mi {self.name}"

    @property
    def all_flags(self) -> tuple[Flag, ...]:
        return (*self.flags, *COMMON)

    def parse(self, argv: Sequence[str]) -> Args:
        """Parse and validate ``argv``: flags, required flags, :attr:`check` (not for ``-h`` / ``--version``)."""
        args = parse(argv, self.all_flags, self.positionals, grammar=self.grammar, see=f"{self.prog} -h")
        if args.help or args.version:
            return args
        for dest in self.required:
            if args.get(dest) is None:
                f = next(f for f in self.flags if dest in f.dests)
                raise UsageError(f"missing {f.names[0]}{' ' + f.metavar if f.metavar else ''}")
        if self.check is not None:
            self.check(args)
        return args

    def help(self) -> str:
        """``-h``: usage, one line per flag, the epilog and the one ``Exit status:`` paragraph."""
        status = exit_status_help(self.exit_ok, self.exit_differ, self.exit_note)
        epilog = f"{self.epilog}\n\n{status}" if self.epilog else status
        return format_help(self.prog, self.summary, self.all_flags, self.positionals, grammar=self.grammar,
                           required=self.required, epilog=epilog)


class Console:
    """The only printer: results on stdout, warnings / notes / errors on stderr (one line each).

    ``quiet`` drops warnings (``-q``); errors and results are always printed. A diagnostic that cannot be
    printed (stderr closed, a full disk, a hung-up terminal) is dropped: it never costs the command its
    outputs. A result that cannot be printed is the command's failure: a closed pipe raises
    ``BrokenPipeError`` (exit 141 through :func:`guarded`), any other write error a :class:`UserError`
    (``cannot write to standard output: No space left on device``, exit 2)."""

    def __init__(self, prog: str, *, quiet: bool = False, out: TextIO | None = None,
                 err: TextIO | None = None) -> None:
        self.prog, self.quiet = prog, quiet
        self._out, self._err = out, err

    @property
    def out(self) -> TextIO:
        return self._out or sys.stdout or _NullStream()

    @property
    def err(self) -> TextIO:
        return self._err or sys.stderr or _NullStream()

    def result(self, text: str) -> None:
        """A command's answer (a table, JSON, help): stdout, flushed at once so that a write error is this
        command's (see the class docstring)."""
        write_result(self.out, text + "\n")

    def _diagnostic(self, text: str) -> None:
        write_diagnostic(self.err, text + "\n")

    def note(self, text: str) -> None:
        """Progress and statistics (``-v``): stderr."""
        self._diagnostic(text)

    def warnings(self, items: Iterable[tuple[Any, str]]) -> None:
        """``FILE:LINE:COL: warning: ...`` per (loc, message), unless quiet."""
        for loc, msg in items:
            if not self.quiet:
                self._diagnostic(f"{loc}: warning: {msg}")

    def error(self, msg: str) -> None:
        """One error line: positioned messages as they are, others as ``PROG: error: msg``."""
        line = msg if ": error: " in msg else f"{self.prog}: error: {msg}"
        self._diagnostic(line.split("\n")[0])

    def progress(self, enabled: bool, *, log: bool = False, rays: float | None = None,
                 seconds: float | None = None, unit: str = "samples") -> ProgressBar:
        """The render progress (:class:`a5mi.cli.progress.ProgressBar`): a bar on a terminal (``enabled``),
        whole ``-v`` lines elsewhere (``log``); ``rays`` / ``seconds``: the work estimate."""
        from a5mi.cli.progress import ProgressBar

        return ProgressBar(self.err, enabled=enabled, log=log, rays=rays, seconds=seconds, unit=unit,
                           prog=self.prog)


class _NullStream:
    """Stands for a standard stream the interpreter could not open (``2>&-``): takes every write, no terminal."""

    def write(self, text: str) -> int:
        return len(text)

    def flush(self) -> None:
        pass

    def isatty(self) -> bool:
        return False

    def fileno(self) -> int:
        raise OSError("standard stream closed")


class _ClosedOutput(_NullStream):
    """Standard output that was closed when the program started: a result written to it is an error
    (``EBADF``, as coreutils report it), reported as one line (:func:`write_result`)."""

    def write(self, text: str) -> int:
        import errno

        raise OSError(errno.EBADF, os.strerror(errno.EBADF))


def standard_streams(closed: Iterable[int]) -> None:
    """The stream objects of descriptors that were closed at start (``closed``; :mod:`a5mi.entry` has
    re-opened them on ``/dev/null``): stdout writes fail with ``EBADF`` (a result has nowhere to go), stderr
    and stdin read and write ``/dev/null`` (diagnostics are dropped)."""
    for fd in closed:
        if fd == 1:
            sys.stdout = _ClosedOutput()  # type: ignore[assignment]
        elif fd == 2 and sys.stderr is None:
            sys.stderr = open(2, "w", closefd=False, errors="backslashreplace")  # noqa: SIM115 - the process's
        elif fd == 0 and sys.stdin is None:
            sys.stdin = open(0, closefd=False)  # noqa: SIM115 - the process's


def flush_standard_streams() -> None:
    """Flush stdout and stderr at the end; one that cannot be flushed (a closed pipe, a full disk) is pointed
    at ``/dev/null``, so the interpreter's own flush at exit prints no ``Exception ignored`` lines."""
    for fd, stream in ((1, sys.stdout), (2, sys.stderr)):
        if stream is None:
            continue
        try:
            stream.flush()
        except (OSError, ValueError):
            try:
                null = os.open(os.devnull, os.O_WRONLY)
                os.dup2(null, fd)
                os.close(null)
            except OSError:
                pass


def write_result(stream: Any, text: str) -> None:
    """Write ``text`` to the result stream and flush: ``BrokenPipeError`` as it is (exit 141), other write
    errors as one-line :class:`UserError`s (exit 2)."""
    try:
        stream.write(text)
        stream.flush()
    except BrokenPipeError:
        raise
    except (OSError, ValueError) as exc:
        _silence_stdout()  # the unwritten buffer must not fail again at exit
        reason = getattr(exc, "strerror", None) or str(exc)
        raise UserError(f"cannot write to standard output: {reason}") from None


def execute(command: Command, argv: Sequence[str], console: Console | None = None) -> int:
    """Parse ``argv`` for ``command`` and run it under :func:`guarded`; returns the exit status."""
    console = console or Console(command.prog)
    debug = any(a in ("--debug", "-debug") for a in argv)

    def body() -> int:
        args = command.parse(argv)
        if args.help:
            console.result(command.help().rstrip("\n"))
            return ExitStatus.OK
        if args.version:
            from a5mi import __version__

            console.result(f"{command.prog} {__version__}")
            return ExitStatus.OK
        console.quiet = bool(args.quiet)
        return command.run(args, console)

    return guarded(console, debug, body)


def guarded(console: Console, debug: bool, body: Callable[[], int]) -> int:
    """Run ``body`` with the error policy of the module docstring; returns the exit status."""
    from a5mi.converters.errors import SceneError

    try:
        return body()
    except SceneError as exc:
        if debug:
            write_diagnostic(console.err, traceback.format_exc())
        console.error(str(exc) if exc.loc is not None else exc.msg)
        return ExitStatus.USAGE
    except UserError as exc:
        if debug:
            write_diagnostic(console.err, traceback.format_exc())
        console.error(str(exc))
        return ExitStatus.USAGE
    except KeyboardInterrupt as exc:
        from a5mi.platform import interrupts

        signum = exc.signum if isinstance(exc, interrupts.Interrupted) else 2
        interrupts.report_once(lambda: console.error(f"interrupted ({signal_name(signum)})"))
        return ExitStatus.signal(signum)
    except BrokenPipeError:
        _silence_stdout()
        return ExitStatus.BROKEN_PIPE
    except Exception as exc:  # noqa: BLE001 - the last line of defence: report a bug, not a traceback
        from a5mi.platform import interrupts

        signum = interrupts.signal_behind(exc)  # a signal that native code wrapped (a5mi.platform.interrupts)
        if signum:
            if debug:
                write_diagnostic(console.err, traceback.format_exc())
            interrupts.report_once(lambda: console.error(f"interrupted ({signal_name(signum)})"))
            return ExitStatus.signal(signum)
        if debug:
            write_diagnostic(console.err, traceback.format_exc())
        else:
            detail = exception_summary(exc)
            console.note(f"{console.prog}: internal error: {type(exc).__name__}{': ' + detail if detail else ''} "
                         "(re-run with --debug for the traceback)")
        return ExitStatus.SOFTWARE


def signal_name(signum: int) -> str:
    import signal

    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


def _silence_stdout() -> None:
    """After EPIPE: point stdout at /dev/null so the interpreter's final flush cannot fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):
        pass


def exception_summary(exc: BaseException) -> str:
    """One line for an unexpected exception: its first line, plus the innermost cause when Mitsuba's
    ``load_dict`` has wrapped a plugin's Python exception (with its traceback text) into its message."""
    head, *embedded = str(exc).split("Traceback")
    head_lines = [ln.strip() for ln in head.strip().splitlines() if ln.strip()]
    first = head_lines[0] if head_lines else ""
    if first.endswith(":") and len(head_lines) > 1:  # a heading and its list ("Found unused parameters:\n - $x")
        first = f"{first} {', '.join(ln.lstrip('- ') for ln in head_lines[1:5])}"
    if embedded:
        lines = [ln.strip() for ln in embedded[-1].strip().splitlines() if ln.strip()]
        if lines and re.match(r"[A-Za-z_][\w.]*(Error|Exception|Exit|Interrupt)\b", lines[-1]):
            return f"{first} ({lines[-1]})" if first else lines[-1]
    return first


# ------------------------------------------------------------------------------------------ the scene prologue
def load_scene(path: str, console: Console, *, stock: bool = False, inputs: list[Any] | None = None,
               bump: bool = False, kept: Any = None) -> Any:
    """Parse ``path`` (SPEC A), print the parser's warnings, build the scene description once (every mesh,
    texture and cube-map face read and checked) and print its warnings; raises positioned scene errors.
    Mitsuba is not imported. Returns the description that the renderers and writers take. ``inputs``, when
    given, receives every file the scene reads or names (:func:`a5mi.platform.clobber.input_files`, plus textures
    the renderer does not look up), for the output checks. ``bump`` (``-bump``): also read the bump and
    normal maps (docs/EXTENSIONS.md E.7). ``kept``: a :class:`a5mi.converters.files.KeptFiles` whose images and
    meshes are reused while their files stay the same (``a5mi serve``)."""
    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe

    if path == "":
        raise UserError("the scene file name is empty")
    try:
        model = parse_file(path)
    except OSError as exc:
        raise UserError(f"cannot read '{path}': {exc.strerror or exc}") from None
    console.warnings(model.warnings)
    if kept is None:
        desc = describe(model, stock=stock, bump=bump)
    else:
        started = kept.begin()
        try:
            desc = describe(model, stock=stock, bump=bump, decoded=kept.decoded, meshes=kept.meshes)
        finally:
            kept.end(started)
        kept.keep_meshes({getattr(s, "obj_file", None) for s in desc.shapes})
    console.warnings(desc.warnings)
    if inputs is not None:
        from a5mi.platform.clobber import input_files

        inputs.extend(input_files(desc))
        for mat in model.materials or ():
            if getattr(mat, "texture", None):
                inputs.extend([model.base_dir / mat.texture, Path.cwd() / mat.texture])
    return desc


def activate_variant(requested: str | None = None) -> str:
    """:func:`a5mi.runtime.variant.activate` with its failures as user errors (the message names the fix). Mitsuba's
    own log is then limited to errors: its warnings would be printed on stdout, mixed with the results and
    outside the one-line rule (a sphere of radius 1e-40 or 3e38, whose float32 scale Mitsuba takes for a
    non-uniform one); its errors are raised as exceptions and reported by :func:`guarded`."""
    from a5mi.platform import interrupts
    from a5mi.runtime import variant

    try:
        with interrupts.deferred():  # a signal in the middle of loading Dr.Jit would break the interpreter
            name = variant.activate(requested)
    except variant.VariantError as exc:
        raise UserError(str(exc)) from None
    import mitsuba as mi

    mi.set_log_level(mi.LogLevel.Error)
    return name


__all__ = ["EXIT_STATUS_TABLE", "Command", "Console", "activate_variant", "exception_summary",
           "execute", "exit_status_help", "guarded", "load_scene"]
