"""SPEC A.0: tokens, 1-based positions, braces, and refusal of empty / binary / non-UTF-8 input."""

from __future__ import annotations

from pathlib import Path

import pytest

from a5mi.converters.errors import FileLoc, SceneError, SceneSyntaxError
from a5mi.converters.lexer import decode, read_source, tokenize

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process


def test_a0_tokens_and_positions_are_1_based() -> None:
    toks = tokenize("Group {\n  numObjects\t3\n}", "s.txt")
    assert [t.text for t in toks] == ["Group", "{", "numObjects", "3", "}"]
    assert [(t.loc.line, t.loc.col) for t in toks] == [(1, 1), (1, 7), (2, 3), (2, 14), (3, 1)]
    assert str(toks[3].loc) == "s.txt:2:14"


def test_a0_crlf_and_tabs_are_whitespace() -> None:
    toks = tokenize("a\r\n\tb c\r\n", "s.txt")
    assert [(t.text, t.loc.line, t.loc.col) for t in toks] == [("a", 1, 1), ("b", 2, 2), ("c", 2, 4)]


@pytest.mark.parametrize("end", ["\r", "\n", "\r\n"])
def test_a0_every_line_end_counts_one_line(end: str) -> None:
    """A lone CR (classic Mac OS), LF and CR LF each end one line: positions as an editor shows them."""
    toks = tokenize(end.join(["a", "  b", "", "c"]), "s.txt")
    assert [(t.text, t.loc.line, t.loc.col) for t in toks] == [("a", 1, 1), ("b", 2, 3), ("c", 4, 1)]


def test_a0_mixed_line_ends_give_the_editor_position(tmp_path: Path) -> None:
    """An error on line 5 of a file with CR, LF and CR LF ends, from the parser and from the byte checks."""
    from a5mi.converters.a5_parser import parse_file

    head = "PerspectiveCamera {\r center 0 0 10\n direction 0 0 -1\r\n up 0 1 0\r\r"
    (tmp_path / "s.txt").write_text(head + "  angle x }\n", newline="")
    with pytest.raises(SceneError) as e:
        parse_file(str(tmp_path / "s.txt"))
    assert (e.value.loc.line, e.value.loc.col) == (6, 9)
    with pytest.raises(SceneSyntaxError) as e:
        decode((head + "  \xff").encode("latin-1"), "s.txt")
    assert (e.value.loc.line, e.value.loc.col) == (6, 3)


def test_a0_brace_glued_to_a_word_is_an_error_at_the_brace() -> None:
    with pytest.raises(SceneSyntaxError) as e:
        tokenize("Sphere {center 0 0 0", "s.txt")
    assert str(e.value) == (
        "s.txt:1:8: error: a brace must be separated from its neighbours by whitespace, found '{center'"
    )
    with pytest.raises(SceneSyntaxError) as e:
        tokenize("x\n  abc}", "s.txt")
    assert e.value.loc == FileLoc("s.txt", 2, 6)


def test_a0_number_glued_to_closing_brace_splits_like_scanf() -> None:
    """scene01 has ``shininess 20}``: %f stops before the brace, so it is the number then '}'."""
    toks = tokenize("shininess 20}}", "s.txt")
    assert [(t.text, t.loc.col, t.glued) for t in toks] == [
        ("shininess", 1, False), ("20", 11, False), ("}", 13, True), ("}", 14, True)
    ]


def test_a0_comments_are_ordinary_words() -> None:
    assert [t.text for t in tokenize("# a comment", "s.txt")] == ["#", "a", "comment"]


def test_a0_empty_binary_and_non_utf8_input_are_refused_with_a_position() -> None:
    with pytest.raises(SceneSyntaxError) as e:
        decode(b" \n\t\n", "e.txt")
    assert str(e.value).startswith("e.txt:1:1: error: empty scene file: expected ")
    assert str(e.value).endswith("found end of file")
    with pytest.raises(SceneSyntaxError) as e:
        decode(b"Group {\n  ab\x00cd", "b.txt")
    assert str(e.value) == "b.txt:2:5: error: binary file: expected scene text, found a NUL byte"
    with pytest.raises(SceneSyntaxError) as e:
        decode(b"Group\n {\xff", "u.txt")
    assert str(e.value) == "u.txt:2:3: error: expected UTF-8 scene text, found the byte 0xff"


def test_a0_unreadable_file_is_a_scene_error(tmp_path: Path) -> None:
    with pytest.raises(SceneError) as e:
        read_source(tmp_path / "missing.txt")
    assert e.value.loc == FileLoc(str(tmp_path / "missing.txt"), 1, 1)
    assert "cannot read scene file" in e.value.msg


def test_error_excerpt_puts_a_caret_under_the_column() -> None:
    err = SceneSyntaxError("unknown Material keyword 'diffuseColour'", FileLoc("s.txt", 14, 5),
                           "    diffuseColour 1 0 0")
    assert err.excerpt() == (
        "s.txt:14:5: error: unknown Material keyword 'diffuseColour'\n"
        "        diffuseColour 1 0 0\n"
        "        ^"
    )
    assert isinstance(err, ValueError) and err.msg.startswith("unknown")
