"""The command layer: ``a5`` (the sample solution's command line) and ``a5mi`` (the toolbox).

One flag table and parser (:mod:`.flags`), one dispatcher, error guard, console and scene prologue
(:mod:`.app`), and one module per command. :data:`SUBCOMMANDS` maps each ``a5mi`` sub-command to the
:class:`~a5mi.cli.app.Command` that implements it (imported on use, so ``a5mi compare`` never loads the
renderer). Libraries return data; only this package prints.
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence

from a5mi.cli.app import EXIT_STATUS_TABLE, Command, Console, exception_summary, execute
from a5mi.cli.flags import Args
from a5mi.platform.errors import ExitStatus

#: ``a5mi`` sub-command -> its one-line summary for ``a5mi -h``; the command is ``COMMAND`` (the name upper-cased,
#: ``-`` as ``_``) of the module ``a5mi.commands.NAME`` (:func:`command`).
SUBCOMMANDS: dict[str, str] = {
    "render": "render a scene (the a5 flags)",
    "convert": "convert a scene to Mitsuba XML (+ PLY meshes)",
    "compare": "PSNR, mean error, share of pixels > 2/255 of two images (+ diff)",
    "fidelity": "re-render the reference images and print the fidelity table",
    "crosscheck": "a5 Whitted vs Mitsuba's path tracer on the same rays",
    "converge": "time and RMSE per spp of the extension's sampling (EXTENSIONS E.5)",
    "bench": "time the stages (cold/warm), optionally against a5soln",
    "grade": "grade a class's ray tracers: sandboxed, on Dask, HTML/CSV/JSON report",
    "render-xml": "render any Mitsuba XML with the a5mi plugins registered",
    "completion": "print a bash/zsh completion script",
    "difftest": "random scenes rendered by a5mi and another a5 binary, compared",
    "trace": "the ray tree of one pixel with every term, checked against the render",
    "animate": "render an Animation block's frames (here or on Dask) + a video",
    "photons": "photon maps drawn over the image, counts per surface; --ppm: progressive passes on Dask",
    "view": "live page on 127.0.0.1: render, reference, heatmap, controls, reload on save, ray tree of a pixel",
    "simulate": "simulate rising smoke (stable fluids) into .vol grid frames",
    "serve": "a warm process that renders this user's a5 commands (a5 falls back to in-process without it)",
    "diagnose": "name the mistake (docs/MISTAKES.md) that explains how an image differs from the reference",
}

A5MI_USAGE = """\
usage: a5mi COMMAND [ARGS]   (a5mi --version; a5mi COMMAND -h or a5mi help COMMAND for a command's flags)

The a5mi toolbox: the MIT 6.837 assignment-5 renderer on Mitsuba 3 and the tools around it.

commands:
{commands}

exit status (every command; 1 only from a command that gives a verdict):
{statuses}"""


def command(name: str) -> Command:
    """The :class:`Command` of sub-command ``name`` (a KeyError for an unknown name)."""
    if name not in SUBCOMMANDS:
        raise KeyError(name)
    module = name.replace("-", "_")
    return getattr(importlib.import_module(f"a5mi.commands.{module}"), module.upper())


def parse_a5_args(argv: Sequence[str]) -> Args:
    """The ``a5`` command line parsed and validated as ``a5`` does before it reads any file (raises
    :class:`~a5mi.platform.errors.UsageError`): for tests and tools that take a5 command lines."""
    from a5mi.commands.render import A5

    return A5.parse(argv)


def run(argv: Sequence[str]) -> int:
    """``a5 ARGS``: render a scene (SPEC B.1). Returns the exit status (:class:`~a5mi.platform.errors.ExitStatus`)."""
    from a5mi.commands.render import A5

    return execute(A5, argv)


def run_a5mi(argv: Sequence[str]) -> int:
    """``a5mi COMMAND ARGS``: dispatch through :data:`SUBCOMMANDS`; ``a5mi help COMMAND`` = ``a5mi COMMAND -h``.
    Returns the exit status (:class:`~a5mi.platform.errors.ExitStatus`)."""
    console = Console("a5mi")
    if argv and argv[0] == "--version":
        from a5mi import __version__

        console.result(f"a5mi {__version__}")
        return ExitStatus.OK
    if argv[:1] == ["help"] and len(argv) > 1:
        argv = [argv[1], "-h", *argv[2:]]
    if not argv or argv[0] in ("-h", "--help", "-help", "help"):
        commands = "\n".join(f"  {name:<12}{summary}" for name, summary in SUBCOMMANDS.items())
        statuses = "\n".join(f"  {status:<12}{meaning}" for status, meaning in EXIT_STATUS_TABLE)
        text = A5MI_USAGE.format(commands=commands, statuses=statuses)
        if argv:
            console.result(text)
            return ExitStatus.OK
        console.note(text)
        return ExitStatus.USAGE
    name, rest = argv[0], argv[1:]
    if name not in SUBCOMMANDS:
        console.error(f"unknown command '{name[:40]}' (expected one of {', '.join(SUBCOMMANDS)})")
        return ExitStatus.USAGE
    return execute(command(name), rest)


__all__ = ["SUBCOMMANDS", "command", "exception_summary", "parse_a5_args", "run", "run_a5mi"]
