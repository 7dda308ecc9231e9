"""Nesting, long integers, special scene files, numbers and control characters (SPEC A.0):
the lexer and parser answer hostile input with one positioned error, in time linear in its size."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from a5mi.converters import lexer
from a5mi.converters.a5_parser import MAX_NESTING, parse_file, parse_text
from a5mi.converters.errors import EXCERPT_CHARS, SceneError, SceneSyntaxError, shown

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process

HEAD = ("PerspectiveCamera { center 0 0 10 direction 0 0 -1 up 0 1 0 angle 20 }\n"
        "Materials { numMaterials 1 Material { diffuseColor 1 1 1 } }\n")


def _scene(group: str) -> str:
    return HEAD + f"Group {{ numObjects 1 MaterialIndex 0 {group} }}\n"


def _nested(n: int, kind: str) -> str:
    s = "Sphere { center 0 0 0 radius 1 }"
    for _ in range(n):
        s = f"Transform {{ Translate 0 0 0 {s} }}" if kind == "Transform" else f"Group {{ numObjects 1 {s} }}"
    return _scene(s)


@pytest.mark.parametrize("digits", [20_000, 80_000, 1_000_000])
def test_long_number_is_a_positioned_token_limit_error(digits: int) -> None:
    """a number of 20,000+ digits is refused at its first character by the token limit (the old
    regular expressions backtracked quadratically: 14 s for 20,000 digits); the message quotes an excerpt."""
    text = HEAD.replace("angle 20", "angle " + "2" * digits) + "Group { numObjects 0 }"
    with pytest.raises(SceneSyntaxError) as info:
        parse_text(text, "s.txt")
    err = info.value
    assert (err.loc.line, err.loc.col) == (1, HEAD.index("angle 20") + len("angle ") + 1)
    assert f"token of {digits} characters is longer than the limit of {lexer.MAX_TOKEN}" in err.msg
    assert len(err.msg) < 250 and f"({digits} characters)" in err.msg


def test_longest_token_is_accepted_and_patterns_are_linear() -> None:
    """A number of MAX_TOKEN digits still parses (as out of range); the glued-brace pattern fails fast on a
    long non-match (linear: every alternative starts with a different character)."""
    digits = "1" * (lexer.MAX_TOKEN - 1)
    with pytest.raises(SceneSyntaxError, match="number out of range after 'angle'"):
        parse_text(HEAD.replace("angle 20", f"angle {digits}") + "Group { numObjects 0 }", "s.txt")
    with pytest.raises(SceneSyntaxError, match="integer out of range after 'numObjects'"):
        parse_text(HEAD + f"Group {{ numObjects {digits} }}", "s.txt")  # > 4,300 digits no longer reach int()
    assert lexer.NUMBER_THEN_BRACES.fullmatch("9" * 100_000 + "x") is None


def test_nesting_limit() -> None:
    """MAX_NESTING levels parse; one more is a positioned error (not RecursionError), also 500 deep."""
    for kind in ("Group", "Transform"):
        parse_text(_nested(MAX_NESTING, kind), "s.txt")
        for n in (MAX_NESTING + 1, 500, 5000):
            with pytest.raises(SceneError, match=f"{kind} nested more than {MAX_NESTING} deep") as info:
                parse_text(_nested(n, kind), "s.txt")
            assert info.value.loc is not None and info.value.loc.line == 3


@pytest.mark.parametrize("word", ["١", "1_0", "１", "²", "1e1_0", "0x10", "nan", "inf"])
def test_only_ascii_decimal_numbers(word: str) -> None:
    """Unicode digits and underscores (which Python's float() accepts) are not numbers."""
    with pytest.raises(SceneSyntaxError, match="expected a number after 'radius'"):
        parse_text(_scene(f"Sphere {{ center 0 0 0 radius {word} }}"), "s.txt")


@pytest.mark.parametrize("ch", ["\x1c", "\x85", "\u2028", "\u2029", "\x1e"])
def test_control_characters_do_not_cut_the_message(ch: str) -> None:
    """a token holding a line-breaking character is quoted escaped: the message stays one line."""
    with pytest.raises(SceneSyntaxError) as info:
        parse_text(_scene(f"Sph{ch}ere {{ center 0 0 0 radius 1 }}"), "s.txt")
    text = str(info.value)
    assert len(text.splitlines()) == 1
    assert ascii(ch)[1:-1] in text


def test_shown_bounds_and_escapes() -> None:
    assert shown("abc") == "abc"
    assert shown("a" * 1000) == "a" * EXCERPT_CHARS + "... (1000 characters)"
    assert shown("a\u2028b") == "a\\u2028b"


def test_long_line_excerpt_is_a_window() -> None:
    line = "x " * 100_000 + "{bad"
    err = SceneSyntaxError("m", lexer.FileLoc("s.txt", 1, 200_001), line)
    lines = err.excerpt().splitlines()
    assert len(lines[1]) < 2 * EXCERPT_CHARS and lines[2].index("^") - 4 < EXCERPT_CHARS


def test_special_scene_files(tmp_path: Path) -> None:
    """a FIFO or a device as the scene is refused at once, an oversized file by its size."""
    fifo = tmp_path / "f.txt"
    os.mkfifo(fifo)
    with pytest.raises(SceneSyntaxError, match=r"not a regular file \(FIFO\)"):
        parse_file(fifo)
    with pytest.raises(SceneSyntaxError, match=r"not a regular file \(character device\)"):
        parse_file("/dev/zero")
    big = tmp_path / "big.txt"
    with open(big, "wb") as f:
        f.truncate(lexer.MAX_SCENE_BYTES + 1)
    with pytest.raises(SceneSyntaxError, match="more than the limit"):
        parse_file(big)


@pytest.mark.parametrize("angle", ["1e-40", "1e-37", "179.999999999"])
def test_camera_angle_checked_in_float32(angle: str) -> None:
    """(found by the campaign) an angle that is 0 or 180 only in float32 is a positioned error, not an
    internal error of the camera plugin."""
    with pytest.raises(SceneError, match=r"camera angle must be between 0 and 180 degrees \(in float32\)") as info:
        parse_text(_scene("Sphere { center 0 0 0 radius 1 }").replace("angle 20", f"angle {angle}"), "s.txt")
    assert info.value.loc is not None and info.value.loc.line == 1
