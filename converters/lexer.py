"""Tokens with 1-based positions (SPEC A.0).

Rules, as the sample solution reads them with ``%s``: tokens are whitespace-separated words; a brace is a
token of its own and must be separated from its neighbours by whitespace (``{center`` or ``abc}`` is an error
here, at the brace); there is no comment syntax (``#`` is just an unknown word, reported by
the parser). One exception: a number glued to closing braces (``shininess 20}`` in scene01) is split into
the number and the braces, because the binary reads numbers with ``%f``, which stops before the ``}`` (SPEC
A.0 calls ``1}`` broken; the shipped scene01 relies on it). Such tokens have ``glued=True`` so the parser can
warn. Input must be non-empty UTF-8 text without NUL bytes; anything else is a
:class:`~a5mi.converters.errors.SceneSyntaxError` at the first offending byte (a leading
byte-order mark included).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from .errors import FileLoc, SceneSyntaxError

WHITESPACE: Final = frozenset(" \t\r\n\v\f")
BRACES: Final = frozenset("{}")
NUMBER_THEN_BRACES: Final = re.compile(r"([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)(\}+)")


@dataclass(frozen=True)
class Token:
    """One word of the scene text and the position of its first character."""

    text: str
    loc: FileLoc
    glued: bool = False  # a '}' split off a number ("20}"), see the module docstring


def _line_col(data: bytes, offset: int) -> tuple[int, int]:
    """1-based (line, column) of byte ``offset``; the column counts bytes, which is exact for ASCII."""
    line = data.count(b"\n", 0, offset) + 1
    col = offset - (data.rfind(b"\n", 0, offset) + 1) + 1
    return line, col


def decode(data: bytes, path: str) -> str:
    """Bytes -> text, refusing empty, binary (NUL byte) and non-UTF-8 input with a position."""
    if not data.strip():
        raise SceneSyntaxError("empty scene file: expected PerspectiveCamera, Lights, Background, Materials "
                               "or Group, found end of file", FileLoc(path, 1, 1), "")
    if data.startswith(b"\xef\xbb\xbf"):  # the sample solution would read it as part of the first word
        raise SceneSyntaxError("expected scene text, found a UTF-8 byte-order mark (save the file without BOM)",
                               FileLoc(path, 1, 1))
    nul = data.find(b"\x00")
    if nul >= 0:
        line, col = _line_col(data, nul)
        raise SceneSyntaxError("binary file: expected scene text, found a NUL byte", FileLoc(path, line, col))
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line, col = _line_col(data, exc.start)
        raise SceneSyntaxError(
            f"expected UTF-8 scene text, found the byte 0x{data[exc.start]:02x}", FileLoc(path, line, col)
        ) from None


def read_source(path: str | Path) -> str:
    """Read a scene file as text (see :func:`decode`); an unreadable file is an error at ``path:1:1``."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise SceneSyntaxError(f"cannot read scene file: {exc.strerror or exc}", FileLoc(str(path), 1, 1)) from None
    return decode(data, str(path))


def tokenize(text: str, path: str = "<string>") -> list[Token]:
    """Split ``text`` into :class:`Token` s (SPEC A.0); a brace glued to another character is an error."""
    tokens: list[Token] = []
    for line_no, line in enumerate(text.split("\n"), start=1):
        i, n = 0, len(line)
        while i < n:
            if line[i] in WHITESPACE:
                i += 1
                continue
            start = i
            while i < n and line[i] not in WHITESPACE:
                i += 1
            word = line[start:i]
            glued = NUMBER_THEN_BRACES.fullmatch(word)
            if glued:
                tokens.append(Token(glued.group(1), FileLoc(path, line_no, start + 1)))
                for k in range(glued.start(2), len(word)):
                    tokens.append(Token("}", FileLoc(path, line_no, start + k + 1), glued=True))
                continue
            if len(word) > 1 and (BRACES & set(word)):
                brace_at = next(k for k, ch in enumerate(word) if ch in BRACES)
                raise SceneSyntaxError(
                    f"a brace must be separated from its neighbours by whitespace, found '{word}'",
                    FileLoc(path, line_no, start + brace_at + 1),
                    line,
                )
            tokens.append(Token(word, FileLoc(path, line_no, start + 1)))
    return tokens
