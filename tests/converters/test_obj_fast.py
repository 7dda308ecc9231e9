"""SPEC A.6: the whole-file OBJ reader (``_parse_fast``) gives exactly what the line-by-line reader
(``_parse_slow``, the reference) gives: vertices, faces, texture coordinates, warnings and errors, on every
course OBJ and on generated odd files; ``load_obj`` falls back to the slow reader for anything else."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from a5mi import data_dir
from a5mi.converters.errors import FileLoc, SceneSemanticError
from a5mi.converters.obj import ObjMesh, _parse_fast, _parse_slow, load_obj

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process

COURSE_OBJS = sorted(data_dir().rglob("*.obj"))


def _same(a: ObjMesh, b: ObjMesh) -> None:
    """Identical meshes: values, dtypes, shapes, texcoords and warnings (locations included)."""
    for name in ("vertices", "faces", "texcoords", "face_texcoords"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            assert x.dtype == y.dtype and x.shape == y.shape, name
            np.testing.assert_array_equal(x, y, err_msg=name)
    assert a.warnings == b.warnings
    assert a.path == b.path


def _outcome(fn, *args: object) -> ObjMesh | str:
    try:
        return fn(*args)
    except SceneSemanticError as exc:
        return str(exc)


def _check(text: str, path: str = "m.obj") -> ObjMesh | None:
    """The fast reader either declines (None) or matches the slow one exactly; load_obj-equivalent result."""
    fast = _parse_fast(text, path)
    slow = _outcome(_parse_slow, text, path, None)
    if fast is not None:
        assert not isinstance(slow, str), f"fast accepted a file the slow reader rejects: {slow}"
        _same(fast, slow)
    return fast


def test_a6_course_objs_are_found(a5_data: Path) -> None:
    """The parametrised test below is empty without the course data: this one fails instead of skipping."""
    assert len(COURSE_OBJS) >= 5, f"expected the course OBJ files under {a5_data}"


@pytest.mark.course_data
@pytest.mark.parametrize("path", COURSE_OBJS, ids=lambda p: str(p.relative_to(data_dir())))
def test_a6_fast_reader_matches_slow_on_every_course_obj(path: Path) -> None:
    text = path.read_bytes().decode("utf-8", errors="replace")
    fast = _check(text, str(path))
    assert fast is not None, "every course OBJ is clean: the fast reader must handle it"
    _same(load_obj(path), fast)


def test_a6_fast_reader_handles_crlf_comments_other_records_quads_and_zero_area() -> None:
    text = ("# c\r\nmtllib x.mtl\r\no thing\r\nv 0 0 0\r\nv 1 0 0 1\r\nv 2 0 0\r\nv 0 1 0\r\nvn 0 0 1\r\n"
            "usemtl m\r\ns off\r\nf 1 2 3\r\nf 1  2\t4 3\r\nf 1 2 4\r\n")
    mesh = _check(text)
    assert mesh is not None
    assert mesh.faces.tolist() == [[0, 1, 2], [0, 1, 3], [0, 1, 3]]
    assert mesh.vertices.tolist() == [[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0]]
    assert mesh.warnings == [
        (FileLoc("m.obj", 12, 1), "face with more than 3 vertices: only the first triangle is kept (SPEC A.6)"),
        (FileLoc("m.obj", 11, 3), "1 zero-area face (first here): never hit, as in the sample solution"),
    ]


def test_a6_lone_cr_line_endings_are_lines_with_their_positions() -> None:
    """An OBJ written with lone CR line ends (classic Mac) is read line by line, and an error names its line."""
    mesh = _check("v 0 0 0\rv 1 0 0\rv 0 1 0\rf 1 2 3\r")
    assert mesh is not None and mesh.faces.tolist() == [[0, 1, 2]]
    with pytest.raises(SceneSemanticError) as err:
        _parse_slow("v 0 0 0\rv 1 0 0\rv 0 1 0\rf 1 2 9\r", "m.obj", None)
    assert (err.value.loc.line, err.value.loc.col) == (4, 7), err.value


def test_a6_fast_reader_uv_pairs() -> None:
    mesh = _check("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0 0\nvt 0.5 1\nf 1/3 2/1 3/2\n")
    assert mesh is not None and mesh.face_texcoords is not None and mesh.texcoords is not None
    assert mesh.face_texcoords.tolist() == [[2, 0, 1]] and mesh.texcoords[2].tolist() == [0.5, 1.0]


@pytest.mark.parametrize("text", [
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",                       # index out of range
    "v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n",                     # NaN
    "v 0 0 0\nv 1 0 0\nv 1e39 1 0\nf 1 2 3\n",                    # beyond float32
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 b 3\n",                       # word for an index
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999999\n",  # huge index
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1/1 2/1/1 3/1/1\n",  # v/vt/vn: misread, warned
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1//1 2//1 3//1\n",     # v//vn
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1 2 3\n",              # plain faces with vt lines
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/2\n",        # vt index out of range
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1 2/1 3/1\nf 1 2 3\n",       # mixed face forms
    "v 0 0 0\nv 1 0 0\nv 0 1 0\n  f 1 2 3\n",                    # record after leading blanks
    "v\t0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",                     # tab after the keyword
    "v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",                        # too few numbers
    "v 0 0 0\nv 1 0 0\nv 0 1 0\n",                               # no faces
    "v 1 2 3 v\nv 1 2\nv 0 0 0\nf 1 2 3\n",                      # a keyword among the numbers
])
def test_a6_fast_reader_declines_what_only_the_slow_reader_positions(text: str) -> None:
    """Each of these needs a position (error) or the slow reader's quirks: the fast reader returns None
    and load_obj's result is the slow reader's."""
    assert _check(text) is None


def test_a6_load_obj_uses_the_slow_reader_for_errors(tmp_path: Path) -> None:
    p = tmp_path / "m.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1  2 4\n")
    with pytest.raises(SceneSemanticError) as e:
        load_obj(p)
    assert str(e.value) == f"{p}:5:8: error: face index 4 out of range: expected 1 to 3 (3 vertices)"


_WORDS = st.sampled_from(["0", "1", "2", "3", "-1", "0.5", "1e3", "1e39", "nan", "inf", "x", "1/1", "2/3",
                          "1/1/1", "1//1", "/2", "4/", "1_0", "+2", "3.", "\u0661", "v", "vt", "f", "#"])
_SEP = st.sampled_from([" ", "  ", "\t", " \t", "\x0b", "\u00a0"])
_HEAD = st.sampled_from(["v", "vt", "f", "vn", "#", "", " v", " f", "g", "o", "usemtl", "v\t", "f\t"])


@st.composite
def _obj_text(draw: st.DrawFn) -> str:
    """Mostly valid little meshes with random damage: odd words, separators, records, CRLF, blank lines."""
    n = draw(st.integers(3, 6))
    lines = [f"v {draw(st.integers(-3, 3))} {draw(st.integers(-3, 3))} {draw(st.integers(-3, 3))}"
             for _ in range(n)]
    uv = draw(st.booleans())
    if uv:
        lines += [f"vt {draw(st.integers(0, 2))} {draw(st.integers(0, 2))}" for _ in range(3)]
    for _ in range(draw(st.integers(1, 4))):
        idx = [draw(st.integers(1, n)) for _ in range(draw(st.sampled_from([3, 3, 3, 4, 5])))]
        lines.append("f " + " ".join(f"{i}/{draw(st.integers(1, 3))}" if uv else str(i) for i in idx))
    for _ in range(draw(st.integers(0, 3))):  # damage
        k = draw(st.integers(0, len(lines) - 1))
        words = [draw(_WORDS) for _ in range(draw(st.integers(0, 5)))]
        line = draw(_SEP).join([draw(_HEAD), *words])
        if draw(st.booleans()):
            lines[k] = line
        else:
            lines.insert(k, line)
    eol = draw(st.sampled_from(["\n", "\r\n", "\r"]))
    return eol.join(lines) + draw(st.sampled_from(["", eol, eol + eol]))


@settings(max_examples=examples(400))
@given(_obj_text())
def test_a6_fast_reader_matches_slow_on_generated_files(text: str) -> None:
    _check(text)


def test_a6_fast_reader_takes_a_clean_uv_file() -> None:
    """The fast path is really used: a clean file with every handled feature goes through it."""
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\nf 2/2 4/1 3/3\n"
    mesh = _check(text)
    assert mesh is not None and mesh.faces.tolist() == [[0, 1, 2], [1, 3, 2]]
