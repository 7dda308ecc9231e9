"""Grading cases: a5 command lines, the image each names and its points (``docs/GRADING.md``).

A ``CASES.toml`` lists the cases as an array of tables::

    [[case]]
    command = "-input scene06_bunny_1k.txt -size 300 300 -output 6f.png -shadows -bounces 4 -jitter -filter"
    points = 25                     # default 25
    name = "6f"                     # default: the -output name without extension
    reference = "scene06.png"       # default: the -output name; the file read from --reference DIR

Commands are in the handout's form: run from inside the scenes folder, ``-input`` names a scene there and
``-output`` a bare file name (written in the student's private working folder). Without a ``CASES.toml`` the
cases are the handout's four test commands (:data:`DEFAULT_COMMANDS`).
"""

from __future__ import annotations

import re
import shlex
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from a5mi.platform.errors import UserError

HANDOUT_FLAGS = "-size 300 300 -shadows -bounces 4 -jitter -filter"
#: The handout's four test commands (SPEC B.1 form), 25 points each.
DEFAULT_COMMANDS: tuple[str, ...] = (
    f"-input scene06_bunny_1k.txt -output 6f.png {HANDOUT_FLAGS}",
    f"-input scene10_sphere.txt -output 10f.png {HANDOUT_FLAGS}",
    f"-input scene11_cube.txt -output 11f.png {HANDOUT_FLAGS}",
    f"-input scene12_vase.txt -output 12f.png {HANDOUT_FLAGS}",
)
DEFAULT_POINTS = 25.0


class CasesError(UserError):
    """A malformed ``CASES.toml``: the message starts with ``FILE:LINE:COL:`` where a position is known."""


@dataclass(frozen=True)
class Case:
    """One case: ``name``, the a5 ``argv`` (without the program), the ``scene`` and ``output`` it names,
    ``points``, the ``reference`` file name (in ``--reference DIR``) and the render ``options`` of the
    reference (a :class:`~a5mi.render.options.RenderOptions`, set by :func:`load_cases`' ``options_of``)."""

    name: str
    argv: tuple[str, ...]
    scene: str
    output: str
    points: float = DEFAULT_POINTS
    reference: str = ""
    options: Any = None

    @property
    def command(self) -> str:
        return shlex.join(self.argv)


def _value(argv: list[str], flag: str) -> str | None:
    """The last value of ``flag`` in an a5 argv (a flag given twice keeps its last value, SPEC B.1)."""
    found = None
    for k, a in enumerate(argv[:-1]):
        if a == flag:
            found = argv[k + 1]
    return found


def make_case(command: str, *, points: float = DEFAULT_POINTS, name: str | None = None,
              reference: str | None = None) -> Case:
    """A :class:`Case` of one a5 command line; raises :class:`CasesError` without ``-input`` / ``-output`` or
    when the output is not a bare file name."""
    argv = shlex.split(command)
    scene, output = _value(argv, "-input"), _value(argv, "-output")
    if scene is None or output is None:
        raise CasesError(f"case '{command}': needs -input SCENE and -output IMAGE")
    if "/" in output or output in (".", ".."):
        raise CasesError(f"case '{command}': -output must be a bare file name (found '{output}')")
    if not points >= 0:
        raise CasesError(f"case '{command}': points must be >= 0 (found {points})")
    return Case(name or Path(output).stem, tuple(argv), scene, output, float(points), reference or output)


def default_cases() -> list[Case]:
    return [make_case(c) for c in DEFAULT_COMMANDS]


def _position(text: str, needle: str) -> tuple[int, int]:
    at = text.find(needle)
    if at < 0:
        return 1, 1
    line = text.count("\n", 0, at) + 1
    return line, at - (text.rfind("\n", 0, at) + 1) + 1


def load_cases(path: str | Path | None, options_of: Callable[[list[str]], Any] | None = None) -> list[Case]:
    """The cases of ``path`` (None: :func:`default_cases`), each with ``options`` = ``options_of(argv)``
    (which raises a :class:`UserError` for a bad a5 command line). Errors carry ``FILE:LINE:COL``."""
    if path is None:
        cases, text, where = default_cases(), "", "default cases"
        positions = [(1, 1)] * len(cases)
    else:
        where = str(path)
        try:
            text = Path(path).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise CasesError(f"cannot read '{path}': {getattr(exc, 'strerror', None) or exc}") from None
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            m = re.search(r"\(at line (\d+), column (\d+)\)", str(exc))
            line, col = (int(m.group(1)), int(m.group(2))) if m else (1, 1)
            msg = re.sub(r"\s*\(at line \d+, column \d+\)", "", str(exc))
            raise CasesError(f"{path}:{line}:{col}: error: {msg}") from None
        entries = data.get("case")
        if not isinstance(entries, list) or not entries:
            raise CasesError(f"{path}:1:1: error: expected at least one [[case]] table with a command")
        cases, positions = [], []
        for k, entry in enumerate(entries):
            command = entry.get("command") if isinstance(entry, dict) else None
            if not isinstance(command, str):
                raise CasesError(f"{path}:1:1: error: case {k + 1} has no command string")
            line, col = _position(text, command)
            positions.append((line, col))
            try:
                points = entry.get("points", DEFAULT_POINTS)
                if not isinstance(points, int | float) or isinstance(points, bool):
                    raise CasesError(f"points must be a number (found {points!r})")
                cases.append(make_case(command, points=float(points), name=entry.get("name"),
                                       reference=entry.get("reference")))
            except CasesError as exc:
                raise CasesError(f"{path}:{line}:{col}: error: {exc}") from None
    names = [c.name for c in cases]
    dup = next((n for n in names if names.count(n) > 1), None)
    if dup is not None:
        raise CasesError(f"{where}: two cases are named '{dup}' (give each a distinct name or -output)")
    if options_of is None:
        return cases
    out = []
    for c, (line, col) in zip(cases, positions, strict=True):
        try:
            out.append(replace(c, options=options_of(list(c.argv))))
        except UserError as exc:
            prefix = f"{path}:{line}:{col}: error: " if path is not None else ""
            raise CasesError(f"{prefix}case '{c.name}': {exc}") from None
    return out


__all__ = ["Case", "CasesError", "DEFAULT_COMMANDS", "DEFAULT_POINTS", "HANDOUT_FLAGS", "default_cases",
           "load_cases", "make_case"]
