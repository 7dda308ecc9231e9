"""``a5mi serve``: keep one warm a5mi process that renders the ``a5`` commands of this user (docs/SERVE.md).

The server (:func:`a5mi.serve.server.serve`) loads the variant, the plugins and the render path once, then
runs each ``a5`` command handed to it by the ``a5`` console script (:mod:`a5mi.serve.client`) exactly as an
``a5`` process would: :func:`a5mi.cli.app.execute` of :data:`a5mi.commands.render.A5` with the client's argv,
on the client's standard descriptors (as ``sys.stdin`` / ``sys.stdout`` / ``sys.stderr`` opened anew on
them, with the interpreter's buffering and error rules), in the client's working folder, with its
environment and umask, and a clean signal state (:func:`a5mi.platform.interrupts.reset`); everything is
restored after the command. The image, the lines printed and the exit status are those of the same command
run in-process (tests/serve/test_serve.py). The server's own lines (one per request, on the stderr it was
started with) go to a descriptor duplicated at start, never to a client's stream.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import Any

from a5mi.cli.app import Command, Console
from a5mi.cli.flags import Args, Flag, real_in, text
from a5mi.platform.errors import ExitStatus, UserError

FLAGS: tuple[Flag, ...] = (
    Flag(("--socket",), "socket", "the socket to listen on (default: $A5MI_SERVE_SOCKET, else the per-user "
         "path of docs/SERVE.md, the one a5 looks at)", 1, text, metavar="PATH"),
    Flag(("--idle-timeout",), "idle_timeout", "stop after this many seconds without a request (default: "
         "never)", 1, real_in(0.0, open_lo=True), metavar="S"),
    Flag(("--print-socket",), "print_socket", "print the socket path a5 uses here and exit", default=False,
         show_default=False),
)


def _open_streams() -> tuple[Any, Any, Any]:
    """New ``sys`` stream objects on descriptors 0, 1 and 2, with the interpreter's rules: stdout line-buffered
    on a terminal, else block-buffered; stderr line-buffered with ``backslashreplace``."""
    enc = sys.__stdout__.encoding if sys.__stdout__ is not None else "utf-8"
    errors = sys.__stdout__.errors if sys.__stdout__ is not None else "strict"
    stdin = open(0, closefd=False, encoding=enc, errors=errors)  # noqa: SIM115 - the client's descriptor
    stdout = open(1, "w", closefd=False, encoding=enc, errors=errors)  # noqa: SIM115
    stderr = open(2, "w", buffering=1, closefd=False, encoding=enc, errors="backslashreplace")  # noqa: SIM115
    return stdin, stdout, stderr


def handle(request: dict[str, Any]) -> int:
    """Run one client's ``a5`` command on descriptors 0, 1, 2 (already the client's) as an ``a5`` process
    would (module docstring); returns its exit status."""
    from a5mi.cli.app import execute, flush_standard_streams, standard_streams
    from a5mi.platform import interrupts

    saved_streams = sys.stdin, sys.stdout, sys.stderr
    saved_env, saved_cwd = dict(os.environ), os.getcwd()
    saved_umask = os.umask(int(request.get("umask", 0o022)) & 0o777)
    streams = _open_streams()
    try:
        sys.stdin, sys.stdout, sys.stderr = streams
        os.environ.clear()
        os.environ.update({str(k): str(v) for k, v in request["env"].items()})
        standard_streams(int(fd) for fd in request.get("closed", ()))
        interrupts.reset()
        try:
            os.chdir(str(request["cwd"]))
        except OSError as exc:
            Console("a5").error(f"cannot enter the working folder '{request['cwd']}': {exc.strerror or exc}")
            return ExitStatus.USAGE
        return execute(_COMMAND[0], [str(a) for a in request["argv"]], Console("a5"))
    finally:
        flush_standard_streams()
        for stream in streams:
            try:
                stream.close()  # closefd=False: the descriptor stays; the client's copy is closed by the server
            except (OSError, ValueError):
                pass
        sys.stdin, sys.stdout, sys.stderr = saved_streams
        os.environ.clear()
        os.environ.update(saved_env)
        os.chdir(saved_cwd)
        os.umask(saved_umask)


#: The ``a5`` command the server runs: :data:`a5mi.commands.render.A5` with the server's
#: :class:`a5mi.converters.files.KeptFiles` (set by :func:`_warm`).
_COMMAND: list[Command] = []


def _warm(console: Console) -> str:
    """Load what every render needs before the first request: the variant and the a5mi plugins, the render
    path's modules; make :data:`_COMMAND`. Returns the variant's name."""
    import dataclasses
    import functools

    from a5mi.cli.app import activate_variant
    from a5mi.commands import render
    from a5mi.converters.files import KeptFiles
    from a5mi.render import session  # noqa: F401 - imported once here

    _COMMAND[:] = [dataclasses.replace(render.A5, run=functools.partial(render.run_render, kept=KeptFiles()))]
    return activate_variant(None)


def run_serve(args: Args, console: Console) -> int:
    from a5mi.serve import protocol, server

    path = Path(args.socket) if args.get("socket") else protocol.socket_path()
    if args.print_socket:
        console.result(str(path))
        return ExitStatus.OK
    log_fd = os.dup(2)  # the server's own stderr, kept apart from the clients' streams

    def log(line: str) -> None:
        try:
            os.write(log_fd, f"a5mi serve: {time.strftime('%H:%M:%S')} {line}\n".encode(errors="replace"))
        except OSError:
            pass

    t0 = time.perf_counter()
    variant = _warm(console)
    try:
        stats = server.serve(path, handle, log, idle_timeout=args.get("idle_timeout"),
                             ready=lambda: log(f"listening on {path} ({variant}, ready in "
                                               f"{time.perf_counter() - t0:.2f} s)"))
    except server.ServeError as exc:
        raise UserError(str(exc)) from None
    finally:
        os.close(log_fd)
    console.note(f"a5mi serve: {stats.served} served, {stats.declined} declined, {stats.refused} refused")
    return ExitStatus.OK


SERVE = Command("serve", "Keep a warm a5mi process that renders this user's a5 commands (docs/SERVE.md); a5 "
                "falls back to rendering in-process when none runs", FLAGS, run_serve,
                epilog="Stop it with Ctrl-C or SIGTERM (the render in progress ends first); the socket is "
                "removed at exit.", exit_ok="it stopped after --idle-timeout, or because its code changed on disk")
