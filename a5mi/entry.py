"""The console scripts ``a5`` and ``a5mi``: signals first (:mod:`a5mi.platform.interrupts`), then the command layer.

The scripts import this small module instead of :mod:`a5mi.cli` so that SIGINT, SIGTERM and SIGHUP are routed
before the ~50 ms of imports of the command layer: a handler that only records the signal is this module's
first statement (the console-script wrapper's ``from a5mi.entry import ...`` is its first statement after
``import sys``; only the package's ``__init__`` runs before it), the full handlers of :mod:`a5mi.platform.interrupts`
follow and raise a recorded signal at their first check, so a Ctrl-C at any moment after that ends with one
line and ``128 + signal``
(:meth:`a5mi.platform.errors.ExitStatus.signal`; docs/CLI.md "Exit status"), never a traceback. Earlier moments belong
to the interpreter: before it installs its own SIGINT handler the signal's default action ends the process
(the shell reports 130, nothing is written); while it imports ``site`` (the ``.pth`` files of the
environment) a SIGINT is ``Fatal Python error: init_import_site``, which no code of this package can reach.

Standard streams (docs/CLI.md "Exit status"): a closed descriptor 0, 1 or 2 (``2>&-``) is re-opened on
``/dev/null`` before anything else, so no file the program opens can take its number and receive
diagnostics, and a diagnostic that cannot be printed never costs the outputs (:class:`a5mi.cli.app.Console`).
A closed output pipe ends with 141 (``a5mi -h | true``), a result that cannot be written (a closed stdout,
a full disk) with one line and 2. The console scripts exit with the status the command layer returns.
"""

from __future__ import annotations

import _signal  # the interpreter's built-in module: no search of the import path
import sys

_EARLY: list[int] = []
#: True in a process that ``multiprocessing`` spawned from the console script (a ``-workers`` Dask worker
#: runs the parent's main script again as ``__mp_main__``): it is not a command and gets no handlers.
_CHILD = "__mp_main__" in sys.modules


def _early(signum: int, frame: object) -> None:
    _EARLY.append(signum)  # held until :mod:`a5mi.platform.interrupts` is installed, then raised at its first check


if _CHILD:
    # A terminal's Ctrl-C goes to the whole foreground process group: the parent command owns it (it closes the
    # cluster, which ends its workers with SIGTERM); a worker that died of it first would lose its band and
    # leave the parent's semaphores to the resource tracker.
    _signal.signal(_signal.SIGINT, _signal.SIG_IGN)
else:
    for _sig in (_signal.SIGINT, _signal.SIGTERM, _signal.SIGHUP):  # first thing: before any other import
        if _sig == _signal.SIGINT or _signal.getsignal(_sig) != _signal.SIG_IGN:  # nohup's SIG_IGN stays
            _signal.signal(_sig, _early)

import os  # noqa: E402 - after the handlers above
import signal  # noqa: E402

from a5mi.platform import interrupts  # noqa: E402

_PROG = {"name": "a5" if os.path.basename(sys.argv[0] if sys.argv else "") == "a5" else "a5mi"}


def _report(signum: int) -> None:  # the watchdog's line (the command layer's guard prints the others)
    try:
        os.write(2, f"{_PROG['name']}: error: interrupted ({signal.Signals(signum).name})\n".encode())
    except (OSError, ValueError):
        pass


def _reopen_closed() -> tuple[int, ...]:
    """Re-open a closed descriptor 0, 1 or 2 on ``/dev/null`` (descriptors only: the stream objects are the
    command layer's, :func:`a5mi.cli.app.standard_streams`); returns the descriptors that were closed."""
    closed = []
    for fd in (0, 1, 2):
        try:
            os.fstat(fd)
            continue
        except OSError:
            pass
        try:
            null = os.open(os.devnull, os.O_RDWR)
            if null != fd:
                os.dup2(null, fd)
                os.close(null)
        except OSError:
            continue
        closed.append(fd)
    return tuple(closed)


_CLOSED = _reopen_closed()  # before any descriptor is opened (the watchdog's pipe would take a closed 0, 1 or 2)
if not _CHILD:
    interrupts.install(_report)  # replaces the early handler
if _EARLY:
    interrupts.hold(_EARLY[0])  # raised by the first interrupts.check()


def _interrupted(prog: str, exc: interrupts.Interrupted) -> int:
    """The one line of a signal that came before the command layer's guard; returns ``128 + N``."""
    line = f"{prog}: error: interrupted ({exc.name})\n".encode()

    def emit() -> None:
        try:
            os.write(2, line)
        except OSError:
            pass

    interrupts.report_once(emit)
    return exc.status


def _run(prog: str) -> int:
    _PROG["name"] = prog
    try:
        from a5mi import cli
        from a5mi.cli.app import standard_streams
        from a5mi.platform.errors import ExitStatus, UserError

        standard_streams(_CLOSED)
        interrupts.check()  # a signal that arrived during the imports
        try:
            status = cli.run(sys.argv[1:]) if prog == "a5" else cli.run_a5mi(sys.argv[1:])
        except BrokenPipeError:  # a result printed outside the command's guard (``a5mi -h``)
            status = ExitStatus.BROKEN_PIPE
        except UserError as exc:  # a result that could not be written outside the guard
            cli.Console(prog).error(str(exc))
            status = ExitStatus.USAGE
    except interrupts.Interrupted as exc:  # before the guard runs
        status = _interrupted(prog, exc)
    interrupts.ignore()  # the outcome is decided: shutdown is not interrupted
    from a5mi.cli.app import flush_standard_streams  # loaded already unless a signal came first

    flush_standard_streams()
    return int(status)


def _fast_exit(status: int) -> None:
    """End an ``a5`` process that loaded Dr.Jit without the interpreter's finalisation: tearing down Mitsuba's
    and Dr.Jit's modules (their native shutdown: thread pool, LLVM, every variable and kernel freed) costs
    0.25-0.45 s of wall time on the shared 2-core machine, after every output was written and flushed and
    nothing is left to do (docs/SPEED.md). The ``atexit`` functions run first, as at a normal exit; kernels
    are already in Dr.Jit's disk cache (written when compiled). Without Dr.Jit loaded: the normal exit."""
    if "drjit" not in sys.modules:
        sys.exit(status)
    import atexit

    atexit._run_exitfuncs()  # what the interpreter's exit would run first; _run flushed the standard streams
    os._exit(status)


def _served() -> int | None:
    """The exit status of this ``a5`` command run by a warm ``a5mi serve`` (:mod:`a5mi.serve.client`; standard
    library only, so a served command never loads the command layer or Mitsuba here), or None to run it here."""
    if os.environ.get("A5MI_NO_SERVE"):
        return None
    try:
        from a5mi.serve import client

        return client.run("a5", sys.argv[1:], _CLOSED)
    except interrupts.Interrupted as exc:
        return _interrupted("a5", exc)


def a5() -> None:
    """Console script ``a5`` (SPEC B.1): handed to ``a5mi serve`` when one runs (docs/SERVE.md), else run here."""
    status = _served()
    _fast_exit(_run("a5") if status is None else status)


def a5mi() -> None:
    """Console script ``a5mi``."""
    sys.exit(_run("a5mi"))
