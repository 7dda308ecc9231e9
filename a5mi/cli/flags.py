"""One flag table and one parser for ``a5`` and every ``a5mi`` sub-command (SPEC B.1 for the a5 flags).

A :class:`Flag` names its spellings, how many values it takes, how they are converted (with the one-line
:class:`~a5mi.platform.errors.UsageError` messages the CLI prints), its default and its help line. :func:`parse` reads
an argument list in one of two grammars:

* ``a5``: the sample solution's strict grammar (SPEC B.1): single-dash long flags (``-size W H``) in any
  order, a flag given twice keeps its last value, no ``--flag=value``, no positionals. Only the spellings that
  start with one dash (plus ``--debug``, ``--help``, ``--version``) are accepted.
* ``gnu``: the toolbox sub-commands: ``--flag VALUE``, ``--flag=VALUE`` (one-value flags), short ``-o``,
  positionals anywhere, ``--`` ends the flags; the single-dash a5 spellings are accepted as aliases where a
  flag mirrors ``a5`` (``-size`` = ``--size``).

:func:`format_help` writes ``-h``: a usage line, then one line per flag with its meaning and default.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Literal

from a5mi.platform.errors import UsageError
from a5mi.spec import MAX_SIZE

Convert = Callable[[str, list[str]], Any]  # (spelling used, values) -> value


@dataclass(frozen=True)
class Flag:
    """One command-line flag.

    ``names``: every spelling, the preferred one first (``("--size", "-size")``). ``nargs``: values taken
    (0 = a switch, which stores ``const``); ``append``: repeatable, the values collect in a list (default
    empty). ``dest``: the key it sets (a tuple when ``convert`` returns one
    value per key, e.g. ``("width", "height")``). ``default``: the value when absent (None is printed as no
    default). ``metavar``: the values' names in help. ``show_default``: print the default in help.
    """

    names: tuple[str, ...]
    dest: str | tuple[str, ...]
    help: str
    nargs: int = 0
    convert: Convert | None = None
    default: Any = None
    metavar: str = ""
    const: Any = True
    show_default: bool = True
    append: bool = False

    @property
    def dests(self) -> tuple[str, ...]:
        return self.dest if isinstance(self.dest, tuple) else (self.dest,)

    def defaults(self) -> dict[str, Any]:
        if self.append:
            return {self.dests[0]: []}
        if isinstance(self.dest, tuple):
            values = self.default if isinstance(self.default, tuple) else (self.default,) * len(self.dest)
            return dict(zip(self.dest, values, strict=True))
        return {self.dest: self.default}


@dataclass(frozen=True)
class Positional:
    """A positional argument of a sub-command: ``count`` = 1 (required), ``"?"`` (optional), ``"*"`` (any),
    ``"+"`` (at least one) or an exact number > 1 (all collected in a list)."""

    dest: str
    metavar: str
    help: str
    count: int | Literal["?", "*", "+"] = 1


class Args(dict[str, Any]):
    """Parsed values by ``dest``, also as attributes (``args.width``)."""

    def __getattr__(self, name: str) -> Any:
        try:
            return self[name]
        except KeyError:
            raise AttributeError(name) from None


# ------------------------------------------------------------------------------------------ value converters
def integer(lo: int, hi: int) -> Convert:
    """``int`` in ``[lo, hi]``; ASCII digits with an optional sign only (no ``1_0``, no other scripts' digits)."""

    def convert(flag: str, values: list[str]) -> int | tuple[int, ...]:
        out = []
        for text in values:
            body = text[1:] if text[:1] in "+-" else text
            if not (body.isascii() and body.isdigit()) or len(body) > 30:
                raise UsageError(f"{flag} expects an integer, found '{_excerpt(text)}'")
            value = int(text)
            if not lo <= value <= hi:
                raise UsageError(f"{flag} expects an integer in [{lo}, {hi}], found {value}")
            out.append(value)
        return out[0] if len(out) == 1 else tuple(out)

    return convert


def number(flag: str, text: str) -> float:
    """A finite float (``nan`` and ``inf`` are refused)."""
    try:
        if not text.isascii() or "_" in text:
            raise ValueError
        value = float(text)
    except ValueError:
        raise UsageError(f"{flag} expects a number, found '{_excerpt(text)}'") from None
    if not math.isfinite(value):
        raise UsageError(f"{flag} expects a finite number, found '{_excerpt(text)}'")
    return value


def real(flag: str, values: list[str]) -> float:
    return number(flag, values[0])


def real_in(lo: float, hi: float = math.inf, *, open_lo: bool = False) -> Convert:
    """A finite float in ``[lo, hi]`` (``(lo, hi]`` with ``open_lo``)."""

    def convert(flag: str, values: list[str]) -> float:
        value = number(flag, values[0])
        if value < lo or (open_lo and value == lo) or value > hi:
            low = f"more than {lo:g}" if open_lo else f"at least {lo:g}"
            high = "" if math.isinf(hi) else f" and at most {hi:g}"
            raise UsageError(f"{flag} expects a number {low}{high}, found '{_excerpt(values[0])}'")
        return value

    return convert


def choice(options: Sequence[str]) -> Convert:
    def convert(flag: str, values: list[str]) -> str:
        if values[0] not in options:
            raise UsageError(f"{flag} expects one of {', '.join(options)}, found '{_excerpt(values[0])}'")
        return values[0]

    return convert


def text(flag: str, values: list[str]) -> str:
    if values[0] == "":
        raise UsageError(f"{flag} expects a value, found an empty string")
    return values[0]


def _excerpt(s: str, limit: int = 40) -> str:
    """At most ``limit`` characters of a user's argument, for an error line."""
    s = s.encode("unicode_escape").decode("ascii") if not s.isprintable() else s
    return s if len(s) <= limit else s[:limit] + "..."


# ------------------------------------------------------------------------------------------ common flags
DEBUG = Flag(("--debug", "-debug"), "debug", "show tracebacks of errors", default=False, show_default=False)
HELP = Flag(("-h", "--help", "-help"), "help", "show this help and exit", default=False, show_default=False)
VERSION = Flag(("--version",), "version", "print the version and exit", default=False, show_default=False)
QUIET = Flag(("-q", "--quiet"), "quiet", "do not print warnings", default=False, show_default=False)
COMMON: tuple[Flag, ...] = (QUIET, DEBUG, VERSION, HELP)


# ------------------------------------------------------------------------------------------ shared flag concepts
# One spelling, one meaning in every command: ``--size W H`` is always the image size (SPEC B.1's ``-size``),
# ``--json`` always a switch (the result as JSON on stdout instead of text), ``--json-file FILE`` always a file.
def size_flag(default: tuple[int, int] | tuple[None, None], help: str = "image size (width, height)",
              names: tuple[str, ...] = ("--size", "-size")) -> Flag:
    """``--size W H`` (alias ``-size``, SPEC B.1): two integers in [1, ``MAX_SIZE``], dests ``width``, ``height``."""
    return Flag(names, ("width", "height"), help, 2, integer(1, MAX_SIZE), default, "W H")


def json_flag(what: str) -> Flag:
    """``--json``: print ``what`` as JSON on stdout instead of the text (a switch in every command)."""
    return Flag(("--json",), "json", f"print {what} as JSON on stdout instead of text", default=False,
                show_default=False)


def json_file_flag(what: str) -> Flag:
    """``--json-file FILE``: also write ``what`` as JSON to FILE (written atomically), the text still on stdout."""
    return Flag(("--json-file",), "json_file", f"also write {what} as JSON to FILE", 1, text, metavar="FILE")


# ------------------------------------------------------------------------------------------ the parser
def parse(argv: Sequence[str], flags: Sequence[Flag], positionals: Sequence[Positional] = (), *,
          grammar: Literal["a5", "gnu"] = "gnu", see: str = "-h", given: set[str] | None = None) -> Args:
    """Parse ``argv`` against ``flags`` (module docstring for the two grammars). Raises :class:`UsageError`
    with a one-line message; ``see`` names where the user finds help (``a5 -h``). ``given``, when passed,
    receives the dests that ``argv`` set explicitly (to lay one argument list over another)."""
    table: dict[str, Flag] = {}
    for f in flags:
        for name in f.names:
            if grammar == "gnu" or not name.startswith("--") or f in COMMON:
                table[name] = f
    args = Args()
    for f in flags:
        args.update(f.defaults())
    loose: list[str] = []
    k = 0
    only_positionals = False
    while k < len(argv):
        arg = argv[k]
        k += 1
        if only_positionals or not arg.startswith("-") or arg == "-":
            if grammar == "a5":
                raise UsageError(f"unexpected argument '{_excerpt(arg)}' (flags take the form -input F.txt; "
                                 f"see {see})")
            loose.append(arg)
            continue
        if grammar == "gnu" and arg == "--":
            only_positionals = True
            continue
        name, eq, inline = arg.partition("=") if grammar == "gnu" and arg.startswith("--") else (arg, "", "")
        f = table.get(name)
        if f is None:
            raise UsageError(f"unknown flag '{_excerpt(name)}' (see {see})")
        if given is not None:
            given.update(f.dests)
        if eq and f.nargs != 1:
            raise UsageError(f"{name} takes {'no value' if f.nargs == 0 else f'{f.nargs} values'}, "
                             f"not '{name}={_excerpt(inline)}'")
        if f.nargs == 0:
            args[f.dests[0]] = f.const
            continue
        values = [inline] if eq else list(argv[k : k + f.nargs])
        if not eq:
            k += f.nargs
        if len(values) < f.nargs:
            raise UsageError(f"{name} expects {f'{f.nargs} values' if f.nargs > 1 else 'a value'}, found end of "
                             "arguments")
        value = f.convert(name, values) if f.convert is not None else (values[0] if f.nargs == 1 else tuple(values))
        if f.append:
            args[f.dests[0]].append(value)
        elif isinstance(f.dest, tuple):
            args.update(zip(f.dest, value, strict=True))
        else:
            args[f.dest] = value
    if args.get("help") or args.get("version"):
        return args
    _assign_positionals(args, loose, positionals, see)
    return args


def _assign_positionals(args: Args, loose: list[str], positionals: Sequence[Positional], see: str) -> None:
    rest = list(loose)
    for i, p in enumerate(positionals):
        later_required = sum(q.count if isinstance(q, int) else (1 if q.count == "+" else 0)
                             for q in positionals[i + 1 :])
        if p.count == "?":
            args[p.dest] = rest.pop(0) if len(rest) > later_required else None
        elif p.count in ("*", "+"):
            take = max(0, len(rest) - later_required)
            if p.count == "+" and take == 0:
                raise UsageError(f"missing {p.metavar} (see {see})")
            args[p.dest], rest = rest[:take], rest[take:]
        else:
            n = int(p.count)
            if len(rest) < n:
                found = f"found {len(rest)}" if n > 1 else "found none"
                raise UsageError(f"missing {p.metavar}" + (f" ({n} expected, {found})" if n > 1 else "")
                                 + f" (see {see})")
            args[p.dest] = rest[0] if n == 1 else rest[:n]
            rest = rest[n:]
    if rest:
        raise UsageError(f"unexpected argument '{_excerpt(rest[0])}' (see {see})")


# ------------------------------------------------------------------------------------------ help
def _spelling(f: Flag, grammar: str) -> str:
    names = [n for n in f.names if grammar == "gnu" or not n.startswith("--") or f in COMMON]
    return ", ".join(names) + (f" {f.metavar}" if f.metavar else "")


def usage_line(prog: str, flags: Sequence[Flag], positionals: Sequence[Positional] = (), *,
               grammar: str = "gnu", required: Sequence[str] = ()) -> str:
    """``usage: PROG [POSITIONALS] [FLAGS]`` with the required flags spelled out first."""
    parts = []
    for f in flags:
        if f.dests[0] in required:
            parts.append(f"{f.names[0]}{' ' + f.metavar if f.metavar else ''}")
    parts += [{"?": f"[{p.metavar}]", "*": f"[{p.metavar} ...]", "+": f"{p.metavar} [{p.metavar} ...]"}
              .get(str(p.count), p.metavar) for p in positionals]
    parts.append("[options]")
    return f"usage: {prog} " + " ".join(parts)


def format_help(prog: str, summary: str, flags: Sequence[Flag], positionals: Sequence[Positional] = (), *,
                grammar: str = "gnu", required: Sequence[str] = (), epilog: str = "") -> str:
    """``-h`` text: usage, summary, one line per positional and per flag (meaning and default)."""
    lines = [usage_line(prog, flags, positionals, grammar=grammar, required=required), "", summary, ""]
    rows = [(p.metavar, p.help) for p in positionals]
    for f in flags:
        default = ""
        given = [d for d in (f.default if isinstance(f.default, tuple) else (f.default,)) if d is not None]
        if f.show_default and given and f.nargs > 0:
            shown = " ".join(map(str, f.default)) if isinstance(f.default, tuple) else str(f.default)
            default = f" (default: {shown})"
        rows.append((_spelling(f, grammar), f.help + ("" if f.dests[0] not in required else " (required)")
                     + default))
    width = min(28, max((len(a) for a, _ in rows), default=0) + 2)
    for a, b in rows:
        lines.append(f"  {a:<{width}}{b}" if len(a) < width else f"  {a}  {b}")  # one line per flag
    if epilog:
        lines += ["", epilog]
    return "\n".join(lines) + "\n"


__all__ = ["Args", "COMMON", "DEBUG", "Flag", "HELP", "Positional", "QUIET", "VERSION", "choice", "format_help",
           "integer", "json_file_flag", "json_flag", "number", "parse", "real", "size_flag", "text", "usage_line"]

