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

Limits (SPEC A.0): a token has at most :data:`MAX_TOKEN` characters (SPEC A.0: the sample solution's token
buffer, 1024 bytes in later versions) and a scene file at most :data:`MAX_SCENE_BYTES`; the scene is read only
if it is a regular file (:func:`a5mi.platform.paths.read_regular`: a FIFO or ``/dev/zero`` is refused). Tokens are
found with one C-level regular expression per line and every pattern is linear in the token length, so
hostile input costs time proportional to its size.

Line ends (SPEC A.0): ``\r\n``, a lone ``\r`` (classic Mac OS) and ``\n`` each end one line, in any mix, so
positions count lines as an editor shows them (:func:`split_lines`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from a5mi.converters.errors import FileLoc, SceneSyntaxError, shown
from a5mi.platform.errors import FileReadError
from a5mi.platform.paths import read_regular

WHITESPACE: Final = frozenset(" \t\r\n\v\f")
BRACES: Final = frozenset("{}")
#: ASCII digits only; each alternative starts differently, so matching is linear (no nested ambiguity).
NUMBER: Final = r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"
NUMBER_THEN_BRACES: Final = re.compile(rf"({NUMBER})(\}}+)")
WORD: Final = re.compile(r"[^ \t\r\n\v\f]+")
#: The longest token (SPEC A.0: the sample solution's token buffer holds 1023 characters and a NUL).
MAX_TOKEN: Final = 1023
#: The largest scene file read (the course scenes are under 10 KB; meshes live in OBJ files).
MAX_SCENE_BYTES: Final = 16 << 20
#: One line end: CR LF, a lone CR or LF (the alternatives are tried in this order, so CR LF is one end).
LINE_END: Final = re.compile(r"\r\n|\r|\n")
_LINE_END_BYTES: Final = re.compile(rb"\r\n|\r|\n")


@dataclass(frozen=True)
class Token:
    """One word of the scene text and the position of its first character."""

    text: str
    loc: FileLoc
    glued: bool = False  # a '}' split off a number ("20}"), see the module docstring


def split_lines(text: str) -> list[str]:
    """The lines of ``text`` without their ends (:data:`LINE_END`: CR LF, lone CR and LF each end one line);
    ``n`` line ends give ``n + 1`` lines, as ``str.split``."""
    return LINE_END.split(text)


def _line_col(data: bytes, offset: int) -> tuple[int, int]:
    """1-based (line, column) of byte ``offset`` (line ends as :func:`split_lines`); the column counts bytes,
    which is exact for ASCII."""
    line, start = 1, 0
    for m in _LINE_END_BYTES.finditer(data, 0, offset):
        line, start = line + 1, m.end()
    return line, offset - start + 1


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
        data = read_regular(Path(path), MAX_SCENE_BYTES, "scene file")
    except FileReadError as exc:
        raise SceneSyntaxError(f"cannot read scene file: {exc.reason}", FileLoc(str(path), 1, 1)) from None
    return decode(data, str(path))


def tokenize(text: str, path: str = "<string>") -> list[Token]:
    """Split ``text`` into :class:`Token` s (SPEC A.0); a brace glued to another character is an error."""
    tokens: list[Token] = []
    for line_no, line in enumerate(split_lines(text), start=1):
        for m in WORD.finditer(line):
            start, word = m.start(), m.group()
            if len(word) > MAX_TOKEN:
                raise SceneSyntaxError(f"token of {len(word)} characters is longer than the limit of {MAX_TOKEN} "
                                       f"(SPEC A.0: the sample solution's token buffer): '{shown(word)}'",
                                       FileLoc(path, line_no, start + 1))
            glued = NUMBER_THEN_BRACES.fullmatch(word)
            if glued:
                tokens.append(Token(glued.group(1), FileLoc(path, line_no, start + 1)))
                for k in range(glued.start(2), len(word)):
                    tokens.append(Token("}", FileLoc(path, line_no, start + k + 1), glued=True))
                continue
            if len(word) > 1 and (BRACES & set(word)):
                brace_at = next(k for k, ch in enumerate(word) if ch in BRACES)
                raise SceneSyntaxError(
                    f"a brace must be separated from its neighbours by whitespace, found '{shown(word)}'",
                    FileLoc(path, line_no, start + brace_at + 1),
                )
            tokens.append(Token(word, FileLoc(path, line_no, start + 1)))
    return tokens
