"""Scene errors with exact source positions (SPEC A.0: the binary asserts or exits; we raise).

``FileLoc(path, line, col)`` is 1-based (tomli/Mitsuba style, not pbrt's 0-based columns) and prints as
``path:line:col``. :class:`SceneError` subclasses :class:`ValueError`, keeps ``msg``, ``loc`` and the
offending ``source_line``, and prints as ``"{loc}: error: {msg}"``; :meth:`SceneError.excerpt` adds the
source line and a caret under the column. Two subclasses say which stage found the problem:

* :class:`SceneSyntaxError`: the lexer and parser (a token that does not fit the grammar, at that token or
  "at end of file");
* :class:`SceneSemanticError`: well-formed input that cannot mean anything (a ``MaterialIndex`` out of range,
  a missing mesh file, a singular transform), at the entity's saved location.
"""

from __future__ import annotations

from dataclasses import dataclass

#: Characters of a token quoted in a message (the rest is elided with its length).
EXCERPT_CHARS = 60


def shown(text: str, limit: int = EXCERPT_CHARS) -> str:
    """``text`` as a message quotes it: non-printable characters escaped (``\\x1c``, ``\\u2028``: a
    terminal or ``splitlines`` would break the one-line message there), at most ``limit`` characters, longer
    text elided as ``abc... (N characters)``."""
    cut = text[:limit]
    out = "".join(ch if ch.isprintable() else ascii(ch)[1:-1] for ch in cut)
    return out if len(text) <= limit else f"{out}... ({len(text)} characters)"


@dataclass(frozen=True)
class FileLoc:
    """A 1-based position in a file: ``str(FileLoc("s.txt", 3, 14)) == "s.txt:3:14"``."""

    path: str
    line: int
    col: int

    def __str__(self) -> str:
        return f"{self.path}:{self.line}:{self.col}"


class SceneError(ValueError):
    """A user error in a scene (or in a file it names), with the position that caused it.

    Parameter ``msg`` (str): what was expected and what was found, without position or "error:" prefix.
    Parameter ``loc`` (FileLoc | None): where; None only when no position exists.
    Parameter ``source_line`` (str | None): the text of the line at ``loc``, for :meth:`excerpt`.
    """

    def __init__(self, msg: str, loc: FileLoc | None = None, source_line: str | None = None) -> None:
        super().__init__(msg)
        self.msg = msg
        self.loc = loc
        self.source_line = source_line

    def __str__(self) -> str:
        if self.loc is None:
            return f"error: {self.msg}"
        return f"{self.loc}: error: {self.msg}"

    def excerpt(self) -> str:
        """``str(self)`` plus the source line and a caret under the column (when the line is known)."""
        if self.loc is None or self.source_line is None:
            return str(self)
        line = self.source_line.rstrip("\r\n").expandtabs(1)
        col = self.loc.col - 1
        if len(line) > 2 * EXCERPT_CHARS:  # a window around the column of a long line
            start = max(0, col - EXCERPT_CHARS // 2)
            line, col = line[start:start + EXCERPT_CHARS], col - start
        return f"{self}\n    {line}\n    {' ' * col}^"


class SceneSyntaxError(SceneError):
    """The text does not follow the grammar of SPEC A (raised by the lexer and the parser)."""


class SceneSemanticError(SceneError):
    """The text is well formed but cannot be rendered as written (bad index, missing file, singular matrix)."""
