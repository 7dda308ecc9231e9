"""The token stream of the scene grammar (SPEC A.0) and the rule helpers every block of SPEC A uses.

:class:`TokenStream` is a cursor over the lexer's tokens (``peek``, ``next``, ``expect`` and the typed reads
``number`` = ``F``, ``integer`` = ``I``, ``vec3`` = ``V3``, ``name`` = ``NAME``), the source lines (for the
excerpt under an error) and the warnings collected while parsing. Every read that fails raises a
:class:`~.errors.SceneSyntaxError` at the offending token, or at the end of the file, saying what was expected
and what was found (``expected a number after 'radius', found 'abc'``).

A block is read by rules: :func:`keyword_block` takes a table ``keyword -> rule``, each rule a small function
``rule(ts, tok, builder)`` that reads the keyword's values and stores them in a typed builder
(:mod:`.builders`); :func:`counted_block` reads ``BLOCK { COUNT_KEY I <item>* }`` (A.3, A.5, A.6).

This module knows no keyword of the grammar: the rules live in :mod:`.a5_parser`, :mod:`.group_parser`,
:mod:`.ext_parser` and :mod:`.keyframes`, which all import it, and it imports only :mod:`.lexer` and
:mod:`.errors`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Collection, Iterator, Mapping
from typing import Final, TypeVar

from a5mi.converters.errors import FileLoc, SceneSemanticError, SceneSyntaxError, shown
from a5mi.converters.lexer import NUMBER, Token, split_lines, tokenize

#: ``F``: ``%f`` accepts more (hex floats, "nan", "inf"); the grammar takes plain decimal numbers only.
FLOAT_RE: Final = re.compile(NUMBER)  # ASCII digits, linear (converters/lexer.py)
#: ``I``: a decimal integer in the C ``int`` range.
INT_RE: Final = re.compile(r"[+-]?[0-9]+")
INT_LIMIT: Final = 2**31 - 1
#: The largest float32 (``FLT_MAX``): a larger number would be infinite in the renderer.
FLOAT_LIMIT: Final = 3.4028234663852886e38

Vec3 = tuple[float, float, float]
_T = TypeVar("_T")
_B = TypeVar("_B")
#: A keyword's rule: reads the values after keyword ``tok`` and stores them in the builder.
Rule = Callable[["TokenStream", Token, _B], None]


def quoted(tok: Token | None) -> str:
    """``'word'`` (as :func:`~.errors.shown` quotes it), or ``end of file``."""
    return "end of file" if tok is None else f"'{shown(tok.text)}'"


def quoted_raw(tok: Token | None) -> str:
    """``'word'`` as written, or ``end of file`` (the extension blocks' messages quote the raw text)."""
    return "end of file" if tok is None else f"'{tok.text}'"


def one_of(words: tuple[str, ...]) -> str:
    """``a, b or c``."""
    return ", ".join(words[:-1]) + " or " + words[-1]


def plural(n: int, noun: str) -> str:
    """``1 light``, ``2 lights``."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


class TokenStream:
    """The tokens of one scene, a cursor, the source lines (for excerpts) and the collected warnings."""

    def __init__(self, text: str, path: str) -> None:
        self.path = path
        self.lines = split_lines(text)
        self.tokens = tokenize(text, path)
        self.pos = 0
        self.warnings: list[tuple[FileLoc, str]] = []
        self.eof_loc = FileLoc(path, len(self.lines), len(self.lines[-1]) + 1)
        for tok in self.tokens:
            if tok.glued:
                self.warn(tok.loc, "'}' glued to the number before it: read as two tokens, as the sample "
                          "solution's %f does (SPEC A.0 asks for whitespace)")

    # -- errors ------------------------------------------------------------------------------------
    def line_of(self, loc: FileLoc) -> str | None:
        """The source line at ``loc`` (for the excerpt under an error), None outside the text."""
        return self.lines[loc.line - 1] if 0 < loc.line <= len(self.lines) else None

    def syntax_error(self, msg: str, tok: Token | None) -> SceneSyntaxError:
        """A grammar error at ``tok``, or at the end of the file when ``tok`` is None."""
        loc = self.eof_loc if tok is None else tok.loc
        return SceneSyntaxError(msg, loc, self.line_of(loc))

    def semantic_error(self, msg: str, loc: FileLoc) -> SceneSemanticError:
        """A meaning error at ``loc`` (well-formed input that cannot be rendered as written)."""
        return SceneSemanticError(msg, loc, self.line_of(loc))

    def warn(self, loc: FileLoc, msg: str) -> None:
        """Record a warning: input the sample solution accepted that probably means something else."""
        self.warnings.append((loc, msg))

    # -- cursor ------------------------------------------------------------------------------------
    def peek(self) -> Token | None:
        """The next token without consuming it (None at the end of the file)."""
        return self.tokens[self.pos] if self.pos < len(self.tokens) else None

    def next(self) -> Token | None:
        """Consume and return the next token (None at the end of the file)."""
        tok = self.peek()
        if tok is not None:
            self.pos += 1
        return tok

    def expect(self, word: str, context: str) -> Token:
        """Consume ``word`` or fail with ``expected 'word' <context>, found ...``."""
        tok = self.next()
        if tok is None or tok.text != word:
            raise self.syntax_error(f"expected '{word}' {context}, found {quoted(tok)}", tok)
        return tok

    def number(self, after: str) -> float:
        """One finite decimal number (``F``) within the float32 range."""
        return self.number_at(after)[0]

    def number_at(self, after: str) -> tuple[float, Token]:
        """:meth:`number` and its token (for an error at the number)."""
        tok = self.next()
        if tok is None or not FLOAT_RE.fullmatch(tok.text):
            raise self.syntax_error(f"expected a number after '{after}', found {quoted(tok)}", tok)
        value = float(tok.text)
        if not math.isfinite(value) or abs(value) > FLOAT_LIMIT:
            raise self.syntax_error(f"number out of range after '{after}': '{shown(tok.text)}'", tok)
        return value, tok

    def integer(self, after: str) -> tuple[int, Token]:
        """One decimal integer (``I``) in the C ``int`` range, and its token."""
        tok = self.next()
        if tok is None or not INT_RE.fullmatch(tok.text):
            raise self.syntax_error(f"expected an integer after '{after}', found {quoted(tok)}", tok)
        value = int(tok.text)
        if abs(value) > INT_LIMIT:
            raise self.syntax_error(f"integer out of range after '{after}': '{shown(tok.text)}'", tok)
        return value, tok

    def vec3(self, after: str) -> Vec3:
        """Three numbers (``V3``)."""
        return (self.number(after), self.number(after), self.number(after))

    def name(self, after: str) -> Token:
        """One word (``NAME``), which may not be a brace."""
        tok = self.next()
        if tok is None or tok.text in ("{", "}"):
            raise self.syntax_error(f"expected a file name after '{after}', found {quoted(tok)}", tok)
        return tok


# ------------------------------------------------------------------------------------------ rule helpers
def nonzero(ts: TokenStream, v: Vec3, what: str, loc: FileLoc) -> None:
    """``what must not be the zero vector`` at ``loc`` unless some component of ``v`` is non-zero."""
    if v[0] == 0.0 and v[1] == 0.0 and v[2] == 0.0:
        raise ts.semantic_error(f"{what} must not be the zero vector", loc)


def keyword_block(ts: TokenStream, rules: Mapping[str, Rule[_B]], builder: _B,
                  unknown: Callable[[Token | None], SceneSyntaxError]) -> Token:
    """``(KEYWORD values)* }`` after the block's ``{``: each keyword in ``rules``, in any order, handled by its
    rule on ``builder``; any other token (or the end of the file) raises ``unknown(tok)``. Returns the ``}``."""
    while True:
        tok = ts.next()
        if tok is not None and tok.text == "}":
            return tok
        rule = None if tok is None else rules.get(tok.text)
        if rule is None or tok is None:
            raise unknown(tok)
        rule(ts, tok, builder)


def unknown_keyword(ts: TokenStream, block: str, keys: tuple[str, ...]) -> Callable[[Token | None],
                                                                                     SceneSyntaxError]:
    """The error of :func:`keyword_block` for the course's blocks (A.4, A.5): ``unknown BLOCK keyword 'x'
    (expected a, b or '}')``, or ``expected a, b or '}' in BLOCK, found end of file``."""
    expected = one_of((*keys, "'}'"))

    def error(tok: Token | None) -> SceneSyntaxError:
        if tok is None:
            return ts.syntax_error(f"expected {expected} in {block}, found end of file", tok)
        return ts.syntax_error(f"unknown {block} keyword '{shown(tok.text)}' (expected {expected})", tok)

    return error


def vector_then(ts: TokenStream, block: str, fields: tuple[str, str], what: str,
                read: Callable[[str], _T]) -> tuple[Vec3, _T]:
    """``BLOCK { FIELD0 V3 FIELD1 X }`` in this order, the vector non-zero (``what`` names it in the error)."""
    ts.expect("{", f"after '{block}'")
    where = f"in {block} (fields: {', '.join(fields)})"
    tok = ts.expect(fields[0], where)
    vector = ts.vec3(fields[0])
    nonzero(ts, vector, what, tok.loc)
    ts.expect(fields[1], where)
    value = read(fields[1])
    ts.expect("}", f"to close {block}")
    return vector, value


def block_count(ts: TokenStream, block: str, count_key: str) -> int:
    """``BLOCK { COUNT_KEY I``: the declared count, never negative (A.3, A.5, A.6)."""
    ts.expect("{", f"after '{block}'")
    ts.expect(count_key, f"after '{block} {{'")
    count, count_tok = ts.integer(count_key)
    if count < 0:
        raise ts.semantic_error(f"{count_key} must not be negative, found {count}", count_tok.loc)
    return count


def check_count(ts: TokenStream, tok: Token, block: str, count_key: str, count: int, found: int, noun: str) -> None:
    """At the block's ``}`` (``tok``): exactly the declared number of items (A.3, A.5, A.6)."""
    if found != count:
        raise ts.syntax_error(f"{block} declares {count_key} {count} but has {plural(found, noun)}, found '}}'", tok)


def too_many(ts: TokenStream, tok: Token, block: str, count_key: str, count: int, noun: str) -> SceneSyntaxError:
    """An item ``tok`` after the declared ``count`` items (A.3, A.5, A.6): ``... but a light follows``."""
    article = "an" if noun[:1] in "aeiou" else "a"
    return ts.syntax_error(f"{block} declares {count_key} {count} but {article} {noun} follows: expected '}}', "
                           f"found '{shown(tok.text)}'", tok)


def counted_block(ts: TokenStream, block: str, count_key: str, noun: str,
                  items: Mapping[str, Callable[[TokenStream, Token], _T]]) -> tuple[_T, ...]:
    """``BLOCK { COUNT_KEY I <item>* }`` with exactly ``I`` items, each one of ``items`` (A.3, A.5)."""
    count = block_count(ts, block, count_key)
    out: list[_T] = []
    while True:
        tok = ts.next()
        if tok is not None and tok.text == "}":
            check_count(ts, tok, block, count_key, count, len(out), noun)
            return tuple(out)
        if tok is None or tok.text not in items:
            raise ts.syntax_error(f"expected {', '.join(items)} or '}}' in {block}, found {quoted(tok)}", tok)
        if len(out) == count:
            raise too_many(ts, tok, block, count_key, count, noun)
        out.append(items[tok.text](ts, tok))


def block_keys(ts: TokenStream, block: str, keys: Collection[str]) -> Iterator[Token]:
    """The keys of ``BLOCK { (KEY value)* }`` (the ``{`` already read) up to its ``}``: each one of ``keys``, in
    any order, at most once (docs/EXTENSIONS.md blocks). The caller reads each key's value before asking for the
    next key."""
    seen: set[str] = set()
    while (tok := ts.next()) is None or tok.text != "}":
        if tok is None or tok.text not in keys:
            raise ts.syntax_error(f"expected {', '.join(keys)} or '}}' in {block}, found {quoted_raw(tok)}", tok)
        if tok.text in seen:
            raise ts.syntax_error(f"{block} gives '{tok.text}' twice", tok)
        seen.add(tok.text)
        yield tok
