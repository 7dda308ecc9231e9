"""The OBJ subset of the starter's Mesh reader and its normal rule (SPEC A.6).

Reading, line by line, as the starter does:

* lines shorter than 3 characters and lines starting with ``#`` are skipped;
* ``v x y z`` adds a vertex, ``vt u v`` a texture coordinate; ``vn`` and every other record are ignored;
* ``f a b c``: a triangle (1-based indices; only the first three are read, so a quad keeps its first
  triangle, with a warning);
* ``f a/ta b/tb c/tc``: slashes become spaces and (v, vt) pairs are read. The ``v/vt/vn`` and ``v//vn``
  forms are therefore *misread* by the sample solution; we read them the same way and warn;
* texture coordinates are attached only if the file has at least one ``vt`` line.

Errors are :class:`SceneSemanticError` at the OBJ file's own ``path:line:col`` (a face index outside the
vertex or texture-coordinate list, a NaN/inf, malformed or out-of-float32-range number), or at the scene's
``obj_file`` keyword when the file is missing or unreadable. Zero-area faces (``(p1 - p0) × (p2 - p0) = 0``)
are accepted with one warning at the first of them: no ray hits them and they add nothing to the smooth
normals, so they render as the sample solution renders them (a lone ``Triangle`` of zero area, written by
hand, is an error in the parser instead).

Normals (:func:`vertex_normals`) are computed, never read. a5soln: more than 120 vertices -> smooth,
area-weighted vertex normals ``n_v = normalize(Σ_{faces f ∋ v} (p1 - p0) × (p2 - p0))`` (unnormalised
cross products, so each face weighs by twice its area), interpolated barycentrically; otherwise flat face
normals. The 2015 starter used 500; pass ``smooth_threshold=500`` for it.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from a5mi.converters.errors import FileLoc, SceneSemanticError
from a5mi.platform.errors import FileReadError
from a5mi.platform.paths import read_regular

#: The largest OBJ file read (1 GiB: ~15 M triangles; the course meshes are under 100 KB).
MAX_OBJ_BYTES = 1 << 30
SMOOTH_THRESHOLD = 120
FLOAT32_MAX = 3.4028234663852886e38
INDEX_LIMIT = 2**31 - 1  # the starter reads indices with %d
NormalMode = Literal["auto", "smooth", "flat"]


@dataclass(eq=False)
class ObjMesh:
    """One OBJ file: ``vertices`` (N, 3) float64, ``faces`` (F, 3) int64 0-based, and, only when the file had
    a ``vt`` line, ``texcoords`` (T, 2) and ``face_texcoords`` (F, 3) 0-based; ``warnings`` as (loc, msg)."""

    path: str
    vertices: np.ndarray
    faces: np.ndarray
    texcoords: np.ndarray | None = None
    face_texcoords: np.ndarray | None = None
    warnings: list[tuple[FileLoc, str]] = field(default_factory=list)


def _columns(line: str) -> list[tuple[str, int]]:
    """Whitespace-separated words of ``line`` with their 1-based columns."""
    out: list[tuple[str, int]] = []
    i, n = 0, len(line)
    while i < n:
        if line[i].isspace():
            i += 1
            continue
        start = i
        while i < n and not line[i].isspace():
            i += 1
        out.append((line[start:i], start + 1))
    return out


def load_obj(path: str | Path, loc: FileLoc | None = None) -> ObjMesh:
    """Read an OBJ file per SPEC A.6 (see the module docstring). ``loc`` is the scene's ``obj_file`` position,
    used when the file itself cannot be read.

    Two readers with one result: :func:`_parse_fast` (whole-file string splits, ``map(float)`` /
    ``map(int)`` over all numbers at once, numpy checks) handles clean files; whenever it sees anything it
    does not handle exactly (a bad or out-of-range number, a face index outside the lists, ``v/vt/vn``,
    mixed face forms, odd whitespace before a record, no faces) it returns None and the line-by-line
    :func:`_parse_slow` reads the file instead and reports the error at its ``path:line:col``. Both use
    Python's own ``float`` / ``int`` on the same words, so the numbers are identical
    (tests/converters/test_obj_fast.py compares them on every course OBJ and on generated odd files)."""
    path = Path(path)
    spath = str(path)
    try:  # a regular file within MAX_OBJ_BYTES (a FIFO would block, /dev/zero never ends)
        text = read_regular(path, MAX_OBJ_BYTES, "mesh file").decode("utf-8", errors="replace")
    except FileReadError as exc:
        raise SceneSemanticError(f"cannot read mesh file '{path}': {exc.reason}", loc) from None
    mesh = _parse_fast(text, spath)
    return mesh if mesh is not None else _parse_slow(text, spath, loc)


def _record_words(lines: list[str], kind: str, width: int) -> tuple[list[str], list[int]] | None:
    """The words of ``lines`` (each starting with ``kind`` + a space), laid out as ``width`` columns per
    line: the ``width - 1`` words after the keyword, plus the indices of lines that had more words (the
    starter ignores them). None when a line has fewer than ``width`` words."""
    n = len(lines)
    words = " ".join(lines).split()
    if len(words) == width * n and words[0::width].count(kind) == n:
        # Each line starts with the keyword; if every keyword sits on a multiple of ``width`` and there
        # are exactly n of them, then, as no number word equals the keyword (float/int rejects it below),
        # every line has exactly ``width`` words.
        del words[0::width]
        return words, []
    rows = [line.split() for line in lines]
    if any(len(r) < width for r in rows):
        return None
    longer = [i for i, r in enumerate(rows) if len(r) > width]
    return [w for r in rows for w in r[1:width]], longer


def _floats(words: list[str], cols: int) -> np.ndarray | None:
    """``float(word)`` for every word, as an (N, cols) float64 array; None if one is not a finite number
    within float32 range (the slow reader reports which)."""
    try:
        a = np.array(list(map(float, words)), dtype=np.float64).reshape(-1, cols)
    except ValueError:
        return None
    with np.errstate(invalid="ignore"):
        if not np.all(np.abs(a) <= FLOAT32_MAX):  # also false for NaN
            return None
    return a


def _float_records(lines: list[str], kind: str, cols: int) -> np.ndarray | None:
    """The first ``cols`` numbers of every ``kind`` line as an (N, cols) array (:func:`_record_words`,
    :func:`_floats`); None when the slow reader must decide."""
    words = _record_words(lines, kind, cols + 1)
    return None if words is None else _floats(words[0], cols)


def _ints(words: list[str]) -> np.ndarray | None:
    """``int(word)`` for every word as int64, None if one is not an integer within ``INDEX_LIMIT``."""
    try:
        a = np.array(list(map(int, words)), dtype=np.int64)
    except (ValueError, OverflowError):
        return None
    if not np.all(np.abs(a) <= INDEX_LIMIT):
        return None
    return a


def split_lines(text: str) -> list[str]:
    """The file's lines: LF, CRLF and a lone CR each end a line (as the scene lexer counts them, SPEC A.1), so
    positions are right whatever editor wrote the file."""
    return text.split("\n") if "\r" not in text else re.split(r"\r\n?|\n", text)


def _parse_fast(text: str, spath: str) -> ObjMesh | None:
    """The whole-file reader of :func:`load_obj`: the same mesh and warnings as :func:`_parse_slow`, or
    None when the file needs the slow reader (see :func:`load_obj`)."""
    lines = split_lines(text)
    v_lines: list[str] = []
    vt_lines: list[str] = []
    f_lines: list[str] = []
    f_nos: list[int] = []
    for no, line in enumerate(lines, start=1):
        c = line[:1]
        if c == "v":
            c2 = line[1:2]
            if c2 == " ":
                v_lines.append(line)
            elif c2 == "t":
                c3 = line[2:3]
                if c3 == " ":
                    vt_lines.append(line)
                elif not c3 or c3.isspace():
                    return None
            elif not c2 or c2.isspace():
                return None
        elif c == "f":
            c2 = line[1:2]
            if c2 == " ":
                f_lines.append(line)
                f_nos.append(no)
            elif not c2 or c2.isspace():
                return None
        elif c.isspace() and line.split(None, 1)[:1] in (["v"], ["vt"], ["f"]):
            return None  # a record after leading whitespace: the slow reader
    if not f_lines:
        return None

    v = _float_records(v_lines, "v", 3)
    if v is None:
        return None
    t: np.ndarray | None = None
    if vt_lines:
        t = _float_records(vt_lines, "vt", 2)
        if t is None:
            return None

    slashed = ["/" in line for line in f_lines]
    n_slashed = sum(slashed)
    if n_slashed not in (0, len(f_lines)):
        return None
    fw = _record_words(f_lines, "f", 4)
    if fw is None:
        return None
    words, longer = fw
    warnings: list[tuple[FileLoc, str]] = []
    if n_slashed:
        if longer:
            return None  # more than 3 pairs, or 'v/vt/vn': the slow reader numbers them
        joined = " ".join(words)
        # Every word must be exactly 'a/b': the separators of the joined words then alternate
        # '/', ' ', '/', ..., '/' (checked on the UTF-8 bytes, where no other character holds 0x20 or 0x2f).
        b = np.frombuffer(joined.encode(), dtype=np.uint8)
        seps = b[(b == 0x2F) | (b == 0x20)]
        expected = np.full(2 * len(words) - 1, 0x2F, dtype=np.uint8)
        expected[1::2] = 0x20
        if not np.array_equal(seps, expected):
            return None
        parts = joined.replace("/", " ").split()
        if len(parts) != 2 * len(words):
            return None  # an empty side ('1/ 2/2 3/3')
        idx = _ints(parts)
        if idx is None:
            return None
        idx = idx.reshape(-1, 3, 2) - 1
        f, ft = np.ascontiguousarray(idx[:, :, 0]), np.ascontiguousarray(idx[:, :, 1])
    else:
        if longer:
            warnings.append((FileLoc(spath, f_nos[longer[0]], 1),
                             "face with more than 3 vertices: only the first triangle is kept (SPEC A.6)"))
        idx = _ints(words)
        if idx is None:
            return None
        f, ft = idx.reshape(-1, 3) - 1, None
    if np.any((f < 0) | (f >= len(v))):
        return None
    zero = np.flatnonzero(~np.any(face_normals(v, f), axis=1))
    if len(zero):
        line = f_lines[zero[0]]
        col = len(line) - len(line[1:].lstrip()) + 1  # the first index word, right after "f" and blanks
        warnings.append((FileLoc(spath, f_nos[zero[0]], col), f"{len(zero)} zero-area face"
                         f"{'s' if len(zero) > 1 else ''} (first here): never hit, as in the sample solution"))
    mesh = ObjMesh(spath, v, f, warnings=warnings)
    if t is not None:
        if ft is None or np.any((ft < 0) | (ft >= len(t))):
            return None
        mesh.texcoords, mesh.face_texcoords = t, ft
    return mesh


def _parse_slow(text: str, spath: str, loc: FileLoc | None) -> ObjMesh:
    """The line-by-line reader of :func:`load_obj` (the reference semantics; positioned errors)."""
    path = spath
    verts: list[tuple[float, float, float]] = []
    tcs: list[tuple[float, float]] = []
    faces: list[tuple[int, int, int]] = []
    ftcs: list[tuple[int, int, int] | None] = []
    face_locs: list[tuple[FileLoc, FileLoc, FileLoc]] = []
    tc_locs: list[tuple[FileLoc, FileLoc, FileLoc] | None] = []
    warnings: list[tuple[FileLoc, str]] = []
    misread_warned = quad_warned = False

    def number(word: str, col: int, line_no: int, what: str, conv: type = float) -> float:
        try:
            value = conv(word)
        except ValueError:
            raise SceneSemanticError(f"expected {what}, found '{word}'", FileLoc(spath, line_no, col)) from None
        if conv is float and not math.isfinite(value):
            raise SceneSemanticError(f"expected a finite number in {what}, found '{word}'",
                                     FileLoc(spath, line_no, col))
        if abs(value) > (FLOAT32_MAX if conv is float else INDEX_LIMIT):
            raise SceneSemanticError(f"{what.removeprefix('a ')} out of range: '{word}'",
                                     FileLoc(spath, line_no, col))
        return value

    for line_no, line in enumerate(split_lines(text), start=1):
        if len(line) < 3 or line.startswith("#"):
            continue
        words = _columns(line)
        if not words:
            continue
        kind = words[0][0]
        if kind == "v":
            if len(words) < 4:
                raise SceneSemanticError(f"expected 3 numbers after 'v', found {len(words) - 1}",
                                         FileLoc(spath, line_no, words[0][1]))
            verts.append(tuple(number(w, c, line_no, "a vertex coordinate") for w, c in words[1:4]))  # type: ignore[arg-type]
        elif kind == "vt":
            if len(words) < 3:
                raise SceneSemanticError(f"expected 2 numbers after 'vt', found {len(words) - 1}",
                                         FileLoc(spath, line_no, words[0][1]))
            tcs.append(tuple(number(w, c, line_no, "a texture coordinate") for w, c in words[1:3]))  # type: ignore[arg-type]
        elif kind == "f":
            if "/" in line:
                if not misread_warned and any(w.count("/") == 2 for w, _ in words[1:]):
                    warnings.append((FileLoc(spath, line_no, words[1][1]),
                                     "'v/vt/vn' face read as the sample solution reads it: slashes become "
                                     "spaces and (v, vt) pairs are taken in order (SPEC A.6)"))
                    misread_warned = True
                # Slashes -> spaces; each number keeps the column of the word it came from.
                nums: list[tuple[str, int]] = []
                for w, c in words[1:]:
                    offset = 0
                    for part in w.split("/"):
                        if part:
                            nums.append((part, c + offset))
                        offset += len(part) + 1
                if len(nums) < 6:
                    raise SceneSemanticError(f"expected 3 'v/vt' pairs after 'f', found {len(nums)} numbers",
                                             FileLoc(spath, line_no, words[0][1]))
                vi = [nums[0], nums[2], nums[4]]
                ti = [nums[1], nums[3], nums[5]]
                ftcs.append(tuple(int(number(w, c, line_no, "a face index", int)) - 1 for w, c in ti))  # type: ignore[arg-type]
                tc_locs.append(tuple(FileLoc(spath, line_no, c) for _, c in ti))  # type: ignore[arg-type]
                extra = len(nums) > 6
            else:
                if len(words) < 4:
                    raise SceneSemanticError(f"expected 3 vertex indices after 'f', found {len(words) - 1}",
                                             FileLoc(spath, line_no, words[0][1]))
                vi = words[1:4]
                ftcs.append(None)
                tc_locs.append(None)
                extra = len(words) > 4
            if extra and not quad_warned:
                warnings.append((FileLoc(spath, line_no, words[0][1]),
                                 "face with more than 3 vertices: only the first triangle is kept (SPEC A.6)"))
                quad_warned = True
            faces.append(tuple(int(number(w, c, line_no, "a face index", int)) - 1 for w, c in vi))  # type: ignore[arg-type]
            face_locs.append(tuple(FileLoc(spath, line_no, c) for _, c in vi))  # type: ignore[arg-type]

    if not faces:
        raise SceneSemanticError(f"expected at least one 'f' face in mesh file '{path}', found none", loc)
    v = np.asarray(verts, dtype=np.float64).reshape(-1, 3)
    f = np.asarray(faces, dtype=np.int64)
    bad = np.argwhere((f < 0) | (f >= len(v)))
    if len(bad):
        i, k = bad[0]
        raise SceneSemanticError(f"face index {f[i, k] + 1} out of range: expected 1 to {len(v)} "
                                 f"({len(v)} vertices)", face_locs[i][k])
    zero = np.flatnonzero(~np.any(face_normals(v, f), axis=1))
    if len(zero):
        warnings.append((face_locs[zero[0]][0], f"{len(zero)} zero-area face{'s' if len(zero) > 1 else ''} "
                         f"(first here): never hit, as in the sample solution"))
    mesh = ObjMesh(spath, v, f, warnings=warnings)
    if tcs:
        t = np.asarray(tcs, dtype=np.float64)
        missing = next((i for i, ft in enumerate(ftcs) if ft is None), None)
        if missing is not None:
            raise SceneSemanticError("expected 'v/vt' face indices (the file has 'vt' lines), found plain "
                                     "'v' indices", face_locs[missing][0])
        ft = np.asarray(ftcs, dtype=np.int64)
        bad = np.argwhere((ft < 0) | (ft >= len(t)))
        if len(bad):
            i, k = bad[0]
            loc_tc = tc_locs[i]
            assert loc_tc is not None
            raise SceneSemanticError(f"texture coordinate index {ft[i, k] + 1} out of range: expected 1 to "
                                     f"{len(t)} ({len(t)} 'vt' lines)", loc_tc[k])
        mesh.texcoords, mesh.face_texcoords = t, ft
    return mesh


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unnormalised ``(p1 - p0) × (p2 - p0)`` per face, shape (F, 3): length = twice the face's area."""
    p = vertices[faces]
    return np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])


def uses_smooth_normals(vertex_count: int, normals: NormalMode = "auto",
                        smooth_threshold: int = SMOOTH_THRESHOLD) -> bool:
    """SPEC A.6: ``auto`` is smooth iff ``vertex_count > smooth_threshold`` (120 for a5soln)."""
    if normals not in ("auto", "smooth", "flat"):
        raise ValueError(f"normals must be 'auto', 'smooth' or 'flat', not {normals!r}")
    return normals == "smooth" or (normals == "auto" and vertex_count > smooth_threshold)


def vertex_normals(vertices: np.ndarray, faces: np.ndarray, normals: NormalMode = "auto",
                   smooth_threshold: int = SMOOTH_THRESHOLD) -> np.ndarray | None:
    """Smooth per-vertex normals ``normalize(Σ face cross products)`` (N, 3) if the rule says smooth, else None
    (flat: each triangle shades with its own face normal). A vertex used by no face (or whose faces cancel)
    gets the zero vector."""
    if not uses_smooth_normals(len(vertices), normals, smooth_threshold):
        return None
    acc = np.zeros_like(vertices, dtype=np.float64)
    fn = face_normals(vertices, faces)
    for k in range(3):
        np.add.at(acc, faces[:, k], fn)
    length = np.linalg.norm(acc, axis=1, keepdims=True)
    return np.divide(acc, length, out=np.zeros_like(acc), where=length > 0)


def _cross32(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise vecmath ``cross`` in float32: (a.y b.z − a.z b.y, a.z b.x − a.x b.z, a.x b.y − a.y b.x)."""
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1], a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1).astype(np.float32)


def _normalized32(v: np.ndarray) -> np.ndarray:
    """Row-wise vecmath ``normalized()`` in float32: v / sqrtf((x·x + y·y) + z·z), one division per component."""
    length = np.sqrt((v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1]) + v[:, 2] * v[:, 2])
    with np.errstate(invalid="ignore", divide="ignore"):
        return (v / length[:, None]).astype(np.float32)


def binary_corner_normals(vertices: np.ndarray, faces: np.ndarray, normals: NormalMode = "auto",
                          smooth_threshold: int = SMOOTH_THRESHOLD) -> np.ndarray:
    """The three corner normals (F, 3, 3) float32 of each face as the sample solution's ``Mesh`` holds them
    (``Mesh::compute_norm`` and ``Mesh::intersectTrig``, read from the binary; object space).

    All in float32 on the float32 vertices ``v``, with ``c_f = (v[f1] − v[f0]) × (v[f2] − v[f0])``:

    * smooth (:func:`uses_smooth_normals`): ``acc[v] += c_f`` for each face in file order and its corners in
      order (the order of the float32 sums matters), then ``n_v = acc[v] / |acc[v]|``; face f's corners get
      ``n_{f0}, n_{f1}, n_{f2}``;
    * flat: all three corners get ``c_f / |c_f|``.

    The binary interpolates these with its own barycentrics (plugins/emulation/triangle_rule.py). A degenerate face or
    an unused vertex gives NaN components, as in the binary.
    """
    v = np.asarray(vertices, dtype=np.float32)
    f = np.asarray(faces, dtype=np.int64)
    cross = _cross32(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    if not uses_smooth_normals(len(v), normals, smooth_threshold):
        n = _normalized32(cross)
        return np.repeat(n[:, None, :], 3, axis=1)
    acc = np.zeros_like(v)
    # ufunc.at applies unbuffered, in index order: face 0 corners 0, 1, 2, face 1 corners 0, 1, 2, ...
    np.add.at(acc, f.ravel(), np.repeat(cross, 3, axis=0))
    return _normalized32(acc)[f]

