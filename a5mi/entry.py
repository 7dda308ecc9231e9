"""The console scripts ``a5`` and ``a5mi``: signals first (:mod:`a5mi.interrupts`), then the command layer.

The scripts import this small module instead of :mod:`a5mi.cli` so that SIGINT, SIGTERM and SIGHUP are routed
before the ~50 ms of imports of the command layer: a Ctrl-C at any moment after the interpreter has started
ends with one line and ``128 + signal`` (:meth:`a5mi.errors.ExitStatus.signal`; docs/CLI.md "Exit status"),
never a traceback. The console scripts exit with the status the command layer returns.
"""

from __future__ import annotations

import os
import sys


def _install(prog: str) -> None:
    from a5mi import interrupts

    def report(signum: int) -> None:  # the watchdog's line (the command layer's guard prints the others)
        import signal

        try:
            os.write(2, f"{prog}: error: interrupted ({signal.Signals(signum).name})\n".encode())
        except (OSError, ValueError):
            pass

    interrupts.install(report)


def _run(prog: str) -> int:
    _install(prog)
    from a5mi import interrupts

    try:
        from a5mi import cli

        interrupts.check()  # a signal that arrived during the imports
        status = cli.run(sys.argv[1:]) if prog == "a5" else cli.run_a5mi(sys.argv[1:])
    except interrupts.Interrupted as exc:  # before the guard runs
        line = f"{prog}: error: interrupted ({exc.name})\n".encode()
        interrupts.report_once(lambda: os.write(2, line) and None)
        status = exc.status
    interrupts.ignore()  # the outcome is decided: shutdown is not interrupted
    return status


def a5() -> None:
    """Console script ``a5`` (SPEC B.1)."""
    sys.exit(_run("a5"))


def a5mi() -> None:
    """Console script ``a5mi``."""
    sys.exit(_run("a5mi"))
