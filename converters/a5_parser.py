"""Parser for the 6.837 scene language (SPEC A.1-A.6): tokens -> :class:`~a5mi.converters.model.Scene`.

One function per block (``parse_camera``, ``parse_lights``, ``parse_background``, ``parse_materials``,
``parse_material``, ``parse_noise``, ``parse_group``, ``parse_transform``), each taking the token stream.
Pure Python: no Mitsuba, no file access beyond the scene text (meshes and textures are the converter's).

Where the sample solution asserted, exited or silently misbehaved, this parser raises a
:class:`~a5mi.converters.errors.SceneSyntaxError` (grammar) or
:class:`~a5mi.converters.errors.SceneSemanticError` (meaning) at the offending token, with a message that says
what was expected and what was found (``expected a number after 'radius', found 'abc'``; at the end of the
file: ``found end of file``). In particular: every keyword is consumed or reported (A.5's "an unknown word
silently ends a Material" is an error at that word); a third ``color`` in ``Noise`` is an error; NaN, inf and
out-of-range numbers are errors; declared counts are compared as objects arrive (nothing is allocated from
them); ``MaterialIndex`` must satisfy ``0 <= I < numMaterials`` (the binary's check was off by one) and must
precede every primitive; degenerate geometry (zero radius, zero-length normal/axis/direction/up, a zero-area
``Triangle``, a singular ``Transform``) is an error.

Accepted as the binary accepted it, with an entry in ``Scene.warnings``: a file name not ending in ``.txt``
(A.0), a block given twice (the later one wins, A.1), no lights (ambient forced to 1, A.1), a ``PointLight``
without ``position`` or ``color`` (0), a ``Noise`` with fewer than two colours (0).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Final, TypeVar

import numpy as np

from a5mi.vecmath32 import camera_basis

from . import ext_parser, keyframes, transforms
from .errors import FileLoc, SceneSemanticError, SceneSyntaxError, shown
from .lexer import NUMBER, Token, read_source, tokenize
from .model import (
    Background,
    Camera,
    DirectionalLight,
    Group,
    Light,
    Material,
    Node,
    Noise,
    Plane,
    PointLight,
    Scene,
    Sphere,
    Transform,
    TransformOp,
    Triangle,
    TriangleMesh,
    Vec3,
)

# %f accepts more (hex floats, "nan", "inf"); we accept plain decimal numbers only.
FLOAT_RE: Final = re.compile(NUMBER)  # ASCII digits, linear (converters/lexer.py)
INT_RE: Final = re.compile(r"[+-]?[0-9]+")
INT_LIMIT: Final = 2**31 - 1
TOP_LEVEL: Final = ("PerspectiveCamera", "Lights", "Background", "Materials", "Group")
OBJECTS: Final = ("Group", "Sphere", "Plane", "Triangle", "TriangleMesh", "Transform")
TRANSFORMS: Final = ("Translate", "Scale", "UniformScale", "XRotate", "YRotate", "ZRotate", "Rotate", "Matrix4f")

_T = TypeVar("_T")


def _quoted(tok: Token | None) -> str:
    return "end of file" if tok is None else f"'{shown(tok.text)}'"


def _one_of(words: tuple[str, ...]) -> str:
    return ", ".join(words[:-1]) + " or " + words[-1]


def _count(n: int, noun: str) -> str:
    """``1 light``, ``2 lights``."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


class TokenStream:
    """The tokens of one scene, a cursor, the source lines (for excerpts) and the collected warnings."""

    def __init__(self, text: str, path: str) -> None:
        self.path = path
        self.lines = text.split("\n")
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
        return self.lines[loc.line - 1] if 0 < loc.line <= len(self.lines) else None

    def syntax_error(self, msg: str, tok: Token | None) -> SceneSyntaxError:
        loc = self.eof_loc if tok is None else tok.loc
        return SceneSyntaxError(msg, loc, self.line_of(loc))

    def semantic_error(self, msg: str, loc: FileLoc) -> SceneSemanticError:
        return SceneSemanticError(msg, loc, self.line_of(loc))

    def warn(self, loc: FileLoc, msg: str) -> None:
        self.warnings.append((loc, msg))

    # -- cursor ------------------------------------------------------------------------------------
    def peek(self) -> Token | None:
        return self.tokens[self.pos] if self.pos < len(self.tokens) else None

    def next(self) -> Token | None:
        tok = self.peek()
        if tok is not None:
            self.pos += 1
        return tok

    def expect(self, word: str, context: str) -> Token:
        """Consume ``word`` or fail with ``expected 'word' <context>, found ...``."""
        tok = self.next()
        if tok is None or tok.text != word:
            raise self.syntax_error(f"expected '{word}' {context}, found {_quoted(tok)}", tok)
        return tok

    def number(self, after: str) -> float:
        """One finite decimal number (``F``)."""
        tok = self.next()
        if tok is None or not FLOAT_RE.fullmatch(tok.text):
            raise self.syntax_error(f"expected a number after '{after}', found {_quoted(tok)}", tok)
        value = float(tok.text)
        if not math.isfinite(value) or abs(value) > 3.4028234663852886e38:
            raise self.syntax_error(f"number out of range after '{after}': '{shown(tok.text)}'", tok)
        return value

    def integer(self, after: str) -> tuple[int, Token]:
        """One decimal integer (``I``) in the C ``int`` range, and its token."""
        tok = self.next()
        if tok is None or not INT_RE.fullmatch(tok.text):
            raise self.syntax_error(f"expected an integer after '{after}', found {_quoted(tok)}", tok)
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
            raise self.syntax_error(f"expected a file name after '{after}', found {_quoted(tok)}", tok)
        return tok


def _nonzero(ts: TokenStream, v: Vec3, what: str, loc: FileLoc) -> None:
    if v[0] == 0.0 and v[1] == 0.0 and v[2] == 0.0:
        raise ts.semantic_error(f"{what} must not be the zero vector", loc)


# -- A.2 ------------------------------------------------------------------------------------------------
def parse_camera(ts: TokenStream, start: Token) -> Camera:
    """``PerspectiveCamera { center V3 direction V3 up V3 angle F }`` in this fixed order (A.2)."""
    ts.expect("{", "after 'PerspectiveCamera'")
    fields: dict[str, Vec3] = {}
    tok = start
    for key in ("center", "direction", "up"):
        tok = ts.expect(key, "in PerspectiveCamera (fields: center, direction, up, angle, in this order)")
        fields[key] = ts.vec3(key)
        if key != "center":
            _nonzero(ts, fields[key], f"camera {key}", tok.loc)
    angle_tok = ts.expect("angle", "in PerspectiveCamera (fields: center, direction, up, angle, in this order)")
    angle = ts.number("angle")
    rad = np.float32(math.pi * float(np.float32(angle)) / 180.0)  # as the camera stores it (B.2)
    tiny = float(np.finfo(np.float32).tiny)  # Mitsuba flushes float32 subnormals to 0
    with np.errstate(over="ignore"):
        focal = np.float32(1.0 / math.tan(float(rad) * 0.5)) if 0.0 < float(rad) < math.pi else np.float32(np.inf)
    if not (0.0 < angle < 180.0 and abs(np.float32(angle)) >= tiny and float(rad) >= tiny and np.isfinite(focal)):
        raise ts.semantic_error(f"camera angle must be between 0 and 180 degrees (in float32), found {angle:g}",
                                angle_tok.loc)
    w = np.asarray(fields["direction"])
    if np.linalg.norm(np.cross(w, np.asarray(fields["up"]))) == 0.0:
        raise ts.semantic_error("camera up must not be parallel to direction", tok.loc)
    try:  # the renderer's float32 basis (SPEC B.2): tiny, huge or nearly parallel vectors fail only there
        camera_basis(fields["direction"], fields["up"])
    except ValueError:
        raise ts.semantic_error("camera direction and up do not define a basis in float32 (the sample solution's "
                                "precision): too small, too large (|x|·|x| > 3.4e38) or nearly parallel",
                                tok.loc) from None
    aperture, focus = ext_parser.parse_camera_lens(ts)  # docs/EXTENSIONS.md E.3; reads the closing '}'
    return Camera(fields["center"], fields["direction"], fields["up"], angle, start.loc, aperture, focus)


def _vector_then(ts: TokenStream, block: str, fields: tuple[str, str], what: str,
                 read: Callable[[str], _T]) -> tuple[Vec3, _T]:
    """``BLOCK { FIELD0 V3 FIELD1 X }`` in this order, the vector non-zero (``what`` names it in the error)."""
    ts.expect("{", f"after '{block}'")
    where = f"in {block} (fields: {', '.join(fields)})"
    tok = ts.expect(fields[0], where)
    vector = ts.vec3(fields[0])
    _nonzero(ts, vector, what, tok.loc)
    ts.expect(fields[1], where)
    value = read(fields[1])
    ts.expect("}", f"to close {block}")
    return vector, value


# -- A.3 ------------------------------------------------------------------------------------------------
def parse_directional_light(ts: TokenStream, start: Token) -> DirectionalLight:
    """``DirectionalLight { direction V3 color V3 }`` in this order (A.3)."""
    direction, color = _vector_then(ts, "DirectionalLight", ("direction", "color"), "light direction", ts.vec3)
    return DirectionalLight(direction, color, start.loc)


def parse_point_light(ts: TokenStream, start: Token) -> PointLight:
    """``PointLight { position V3 color V3 [falloff F] }``, keywords in any order until ``}`` (A.3)."""
    ts.expect("{", "after 'PointLight'")
    values: dict[str, object] = {}
    while True:
        tok = ts.next()
        if tok is not None and tok.text == "}":
            break
        if tok is None or tok.text not in ("position", "color", "falloff"):
            raise ts.syntax_error(
                f"expected position, color, falloff or '}}' in PointLight, found {_quoted(tok)}", tok
            )
        values[tok.text] = ts.number("falloff") if tok.text == "falloff" else ts.vec3(tok.text)
        if tok.text == "falloff" and values["falloff"] < 0.0:  # type: ignore[operator]
            # colour / (1 + falloff d²) would grow with distance and divide by zero at d = 1/sqrt(-falloff)
            raise ts.semantic_error(f"PointLight falloff must not be negative, found {values['falloff']:g}",
                                    tok.loc)
    for key in ("position", "color"):
        if key not in values:
            ts.warn(start.loc, f"PointLight has no {key}; using 0 0 0 as the sample solution does")
    return PointLight(
        values.get("position", (0.0, 0.0, 0.0)),  # type: ignore[arg-type]
        values.get("color", (0.0, 0.0, 0.0)),  # type: ignore[arg-type]
        float(values.get("falloff", 0.0)),  # type: ignore[arg-type]
        start.loc,
    )


def _block_count(ts: TokenStream, block: str, count_key: str) -> int:
    """``BLOCK { COUNT_KEY I``: the declared count, never negative (A.3, A.5, A.6)."""
    ts.expect("{", f"after '{block}'")
    ts.expect(count_key, f"after '{block} {{'")
    count, count_tok = ts.integer(count_key)
    if count < 0:
        raise ts.semantic_error(f"{count_key} must not be negative, found {count}", count_tok.loc)
    return count


def _check_count(ts: TokenStream, tok: Token, block: str, count_key: str, count: int, found: int, noun: str) -> None:
    """At the block's ``}``: exactly the declared number of items (A.3, A.5, A.6)."""
    if found != count:
        raise ts.syntax_error(f"{block} declares {count_key} {count} but has {_count(found, noun)}, found '}}'", tok)


def _counted_block(ts: TokenStream, block: str, count_key: str, noun: str,
                   items: dict[str, Callable[[TokenStream, Token], _T]]) -> tuple[_T, ...]:
    """``BLOCK { COUNT_KEY I <item>* }`` with exactly ``I`` items, each one of ``items`` (A.3, A.5)."""
    count = _block_count(ts, block, count_key)
    out: list[_T] = []
    while True:
        tok = ts.next()
        if tok is not None and tok.text == "}":
            _check_count(ts, tok, block, count_key, count, len(out), noun)
            return tuple(out)
        if tok is None or tok.text not in items:
            raise ts.syntax_error(f"expected {', '.join(items)} or '}}' in {block}, found {_quoted(tok)}", tok)
        if len(out) == count:
            raise ts.syntax_error(f"{block} declares {count_key} {count} but a {noun} follows: expected '}}', "
                                  f"found '{shown(tok.text)}'", tok)
        out.append(items[tok.text](ts, tok))


def parse_lights(ts: TokenStream, start: Token) -> tuple[Light, ...]:
    """``Lights { numLights I <light>* }`` with exactly ``numLights`` lights (A.3)."""
    return _counted_block(ts, "Lights", "numLights", "light",
                          {"DirectionalLight": parse_directional_light, "PointLight": parse_point_light,
                           **ext_parser.LIGHTS})


# -- A.4 ------------------------------------------------------------------------------------------------
def parse_background(ts: TokenStream, start: Token) -> Background:
    """``Background { (color V3 | ambientLight V3 | cubeMap NAME)* }`` in any order (A.4)."""
    ts.expect("{", "after 'Background'")
    color, ambient = (0.5, 0.5, 0.5), (0.0, 0.0, 0.0)
    cube_map: str | None = None
    cube_loc: FileLoc | None = None
    while True:
        tok = ts.next()
        if tok is not None and tok.text == "}":
            return Background(color, ambient, cube_map, cube_loc, start.loc)
        if tok is None:
            raise ts.syntax_error("expected color, ambientLight, cubeMap or '}' in Background, found end of file", tok)
        if tok.text == "color":
            color = ts.vec3("color")
        elif tok.text == "ambientLight":
            ambient = ts.vec3("ambientLight")
        elif tok.text == "cubeMap":
            name = ts.name("cubeMap")
            cube_map, cube_loc = name.text, name.loc
        else:
            raise ts.syntax_error(f"unknown Background keyword '{shown(tok.text)}' (expected color, ambientLight, "
                                  "cubeMap or '}')", tok)


# -- A.5 ------------------------------------------------------------------------------------------------
def parse_noise(ts: TokenStream, start: Token) -> Noise:
    """``Noise { color V3 (twice) octaves I frequency F amplitude F }`` in any order (A.5)."""
    ts.expect("{", "after 'Noise'")
    colors: list[Vec3] = []
    octaves, frequency, amplitude = 0, 1.0, 1.0
    while True:
        tok = ts.next()
        if tok is not None and tok.text == "}":
            break
        if tok is None:
            raise ts.syntax_error("expected color, octaves, frequency, amplitude or '}' in Noise, found end of file",
                                  tok)
        if tok.text == "color":
            if len(colors) == 2:
                raise ts.syntax_error("Noise takes two colors, found a third 'color'", tok)
            colors.append(ts.vec3("color"))
        elif tok.text == "octaves":
            octaves, oct_tok = ts.integer("octaves")
            if not 0 <= octaves <= 31:
                raise ts.semantic_error(f"octaves must be between 0 and 31, found {octaves}", oct_tok.loc)
        elif tok.text == "frequency":
            frequency = ts.number("frequency")
        elif tok.text == "amplitude":
            amplitude = ts.number("amplitude")
        else:
            raise ts.syntax_error(f"unknown Noise keyword '{shown(tok.text)}' (expected color, octaves, frequency, "
                                  "amplitude or '}')", tok)
    if len(colors) < 2:
        ts.warn(start.loc, f"Noise has {len(colors)} of its 2 colors; the missing ones are 0 0 0")
    colors += [(0.0, 0.0, 0.0)] * (2 - len(colors))
    return Noise(colors[0], colors[1], octaves, frequency, amplitude, start.loc)


MATERIAL_KEYS: Final = ("diffuseColor", "specularColor", "shininess", "refractionIndex", "texture", "bump", "Noise",
                         *ext_parser.MATERIAL_KEYWORDS, "'}'")


def parse_material(ts: TokenStream, start: Token) -> Material:
    """``Material { ... }`` (or ``PhongMaterial``): keywords of A.5 in any order until ``}``."""
    ts.expect("{", f"after '{start.text}'")
    values: dict[str, object] = {"loc": start.loc}
    while True:
        tok = ts.next()
        if tok is not None and tok.text == "}":
            return Material(**values)  # type: ignore[arg-type]
        if tok is None:
            raise ts.syntax_error(f"expected {_one_of(MATERIAL_KEYS)} in Material, found end of file", tok)
        if tok.text == "diffuseColor":
            values["diffuse_color"] = ts.vec3(tok.text)
        elif tok.text == "specularColor":
            values["specular_color"] = ts.vec3(tok.text)
        elif tok.text == "shininess":
            values["shininess"] = ts.number(tok.text)
        elif tok.text == "refractionIndex":
            if ext_parser.parse_dispersion(ts, tok, values):  # refractionIndex dispersion A B (EXTENSIONS E.10)
                continue
            n = ts.number(tok.text)
            if n < 0.0:
                raise ts.semantic_error(f"refractionIndex must not be negative, found {n:g}", tok.loc)
            values["refraction_index"] = n
        elif tok.text == "texture":
            name = ts.name(tok.text)
            values["texture"], values["texture_loc"] = name.text, name.loc
        elif tok.text == "bump":  # a5soln ignores it; docs/EXTENSIONS.md E.7 with -bump
            name = ts.name(tok.text)
            values["bump"], values["bump_loc"] = name.text, name.loc
        elif tok.text == "Noise":
            if "solid" in values:  # docs/EXTENSIONS.md E.6: one procedural colour source
                raise ts.semantic_error("a Material takes one of Noise, Wood, Turbulence, Veins; found 'Noise' "
                                        "after another", tok.loc)
            values["noise"] = parse_noise(ts, tok)
        elif tok.text in ext_parser.MATERIAL_KEYWORDS:
            ext_parser.parse_material_keyword(ts, tok, values)
        else:
            raise ts.syntax_error(f"unknown Material keyword '{shown(tok.text)}' (expected "
                                  f"{_one_of(MATERIAL_KEYS)})", tok)


def parse_materials(ts: TokenStream, start: Token) -> tuple[Material, ...]:
    """``Materials { numMaterials I Material{...}* }`` with exactly ``numMaterials`` entries (A.5)."""
    return _counted_block(ts, "Materials", "numMaterials", "material",
                          {"Material": parse_material, "PhongMaterial": parse_material})


# -- A.6 ------------------------------------------------------------------------------------------------
class _GroupState:
    """The parser's global "current material" (A.6: sequential, survives nested groups) and the count."""

    def __init__(self, num_materials: int | None) -> None:
        self.num_materials = num_materials
        self.current: int | None = None
        self.materials_line: int | None = None  # line of the Materials block in effect
        self.depth = 0  # Group / Transform nesting of the object being parsed


def _material_for(ts: TokenStream, state: _GroupState, tok: Token) -> int:
    if state.current is None:
        raise ts.semantic_error(f"{tok.text} has no material: expected 'MaterialIndex' before it", tok.loc)
    if state.num_materials is not None and state.current >= state.num_materials:
        raise ts.semantic_error(
            f"{tok.text} uses material {state.current}, set before the Materials block at line "
            f"{state.materials_line} replaced the list with {_count(state.num_materials, 'material')}", tok.loc)
    return state.current


def parse_sphere(ts: TokenStream, start: Token, state: _GroupState) -> Sphere:
    """``Sphere { center V3 radius F }``; the radius must be positive."""
    ts.expect("{", "after 'Sphere'")
    ts.expect("center", "in Sphere (fields: center, radius)")
    center = ts.vec3("center")
    r_tok = ts.expect("radius", "in Sphere (fields: center, radius)")
    radius = ts.number("radius")
    if radius <= 0.0:
        raise ts.semantic_error(f"Sphere radius must be positive, found {radius:g}", r_tok.loc)
    ts.expect("}", "to close Sphere")
    return Sphere(center, radius, _material_for(ts, state, start), start.loc)


def parse_plane(ts: TokenStream, start: Token, state: _GroupState) -> Plane:
    """``Plane { normal V3 offset F }``: the plane ``P . normal = offset``, normal not normalised."""
    normal, offset = _vector_then(ts, "Plane", ("normal", "offset"), "Plane normal", ts.number)
    return Plane(normal, offset, _material_for(ts, state, start), start.loc)


def parse_triangle(ts: TokenStream, start: Token, state: _GroupState) -> Triangle:
    """``Triangle { vertex0 V3 vertex1 V3 vertex2 V3 }``; a zero-area triangle is an error."""
    ts.expect("{", "after 'Triangle'")
    vs: list[Vec3] = []
    for key in ("vertex0", "vertex1", "vertex2"):
        ts.expect(key, "in Triangle (fields: vertex0, vertex1, vertex2)")
        vs.append(ts.vec3(key))
    ts.expect("}", "to close Triangle")
    a, b, c = (np.asarray(v) for v in vs)
    if not np.any(np.cross(b - a, c - a)):
        raise ts.semantic_error("Triangle has zero area", start.loc)
    return Triangle(vs[0], vs[1], vs[2], _material_for(ts, state, start), start.loc)


def parse_triangle_mesh(ts: TokenStream, start: Token, state: _GroupState) -> TriangleMesh:
    """``TriangleMesh { obj_file NAME }``; NAME must end in ``.obj`` (A.6)."""
    ts.expect("{", "after 'TriangleMesh'")
    ts.expect("obj_file", "in TriangleMesh")
    name = ts.name("obj_file")
    if not name.text.endswith(".obj"):
        raise ts.syntax_error(f"expected a file name ending in '.obj' after 'obj_file', found "
                              f"'{shown(name.text)}'", name)
    ts.expect("}", "to close TriangleMesh")
    return TriangleMesh(name.text, _material_for(ts, state, start), start.loc, name.loc)


def parse_transform(ts: TokenStream, start: Token, state: _GroupState) -> Transform:
    """``Transform { <transform>* <object> }`` with exactly one object, last (A.6)."""
    ts.expect("{", "after 'Transform'")
    ops: list[TransformOp] = []
    m = np.eye(4)
    while True:
        tok = ts.next()
        if tok is None or tok.text not in TRANSFORMS + OBJECTS:
            raise ts.syntax_error(f"expected a transform ({_one_of(TRANSFORMS)}) or an object "
                                  f"({_one_of(OBJECTS)}) in Transform, found {_quoted(tok)}", tok)
        if tok.text in OBJECTS:
            child = parse_object(ts, tok, state)
            break
        args: tuple[float, ...]
        if tok.text in ("Translate", "Scale"):
            args = ts.vec3(tok.text)
        elif tok.text == "Rotate":
            ts.expect("{", "after 'Rotate'")
            args = (*ts.vec3("Rotate"), ts.number("Rotate"))
            _nonzero(ts, args[:3], "Rotate axis", tok.loc)  # type: ignore[arg-type]
            ts.expect("}", "to close Rotate")
        elif tok.text == "Matrix4f":
            ts.expect("{", "after 'Matrix4f'")
            args = tuple(ts.number("Matrix4f") for _ in range(16))
            ts.expect("}", "to close Matrix4f (16 numbers)")
        else:
            args = (ts.number(tok.text),)
        ops.append(TransformOp(tok.text, args, tok.loc))
        m = transforms.apply_keyword(m, tok.text, args)
    ts.expect("}", "to close Transform (a Transform holds exactly one object)")
    det = float(np.linalg.det(m[:3, :3]))
    if not math.isfinite(det) or det == 0.0 or not np.all(np.isfinite(m)):
        raise ts.semantic_error(f"expected an invertible Transform, found a matrix with determinant {det:g} "
                                "(a zero scale?)", start.loc)
    return Transform(tuple(ops), transforms.as_tuple(m), child, start.loc)


#: Deepest Group / Transform nesting accepted: every later stage walks the tree recursively, and the course
#: scenes nest 3 deep; a positioned error instead of Python's RecursionError (issue 19).
MAX_NESTING: Final = 100


def parse_object(ts: TokenStream, tok: Token, state: _GroupState) -> Node:
    """One ``<object>`` of A.6, its keyword ``tok`` already consumed; at most :data:`MAX_NESTING` deep."""
    if tok.text in ("Group", "Transform"):
        if state.depth >= MAX_NESTING:
            raise ts.semantic_error(f"{tok.text} nested more than {MAX_NESTING} deep (the limit of a5mi)", tok.loc)
        state.depth += 1
        try:
            return _parse_object(ts, tok, state)
        finally:
            state.depth -= 1
    return _parse_object(ts, tok, state)


def _parse_object(ts: TokenStream, tok: Token, state: _GroupState) -> Node:
    if tok.text == "Group":
        return parse_group(ts, tok, state)
    if tok.text == "Sphere":
        return parse_sphere(ts, tok, state)
    if tok.text == "Plane":
        return parse_plane(ts, tok, state)
    if tok.text == "Triangle":
        return parse_triangle(ts, tok, state)
    if tok.text == "TriangleMesh":
        return parse_triangle_mesh(ts, tok, state)
    return parse_transform(ts, tok, state)


def parse_group(ts: TokenStream, start: Token, state: _GroupState) -> Group:
    """``Group { numObjects I (MaterialIndex I | <object>)* }``: exactly ``numObjects`` objects (A.6)."""
    count = _block_count(ts, "Group", "numObjects")
    children: list[Node] = []
    while True:
        tok = ts.next()
        if tok is not None and tok.text == "}":
            _check_count(ts, tok, "Group", "numObjects", count, len(children), "object")
            return Group(count, tuple(children), start.loc)
        if tok is not None and tok.text == "MaterialIndex":
            index, index_tok = ts.integer("MaterialIndex")
            n = state.num_materials
            if n is None:
                raise ts.semantic_error("MaterialIndex before any Materials block (Materials must come before "
                                        "Group)", tok.loc)
            if not 0 <= index < n:
                raise ts.semantic_error(f"MaterialIndex {index} out of range: expected 0 to {n - 1} "
                                        f"({n} materials)", index_tok.loc)
            state.current = index
            continue
        if tok is None or tok.text not in OBJECTS:
            raise ts.syntax_error(f"expected MaterialIndex, an object ({_one_of(OBJECTS)}) or '}}' in Group, "
                                  f"found {_quoted(tok)}", tok)
        if len(children) == count:
            raise ts.syntax_error(f"Group declares numObjects {count} but an object follows: expected '}}', "
                                  f"found '{shown(tok.text)}'", tok)
        children.append(parse_object(ts, tok, state))


# -- A.1 ------------------------------------------------------------------------------------------------
def parse_tokens(ts: TokenStream) -> Scene:
    """The top level (A.1): any sequence of the five blocks; a repeated block replaces the earlier one."""
    fields: dict[str, object] = {}
    seen: dict[str, Token] = {}
    # One "current material" for the whole file (A.6: it persists, also into a later Group block).
    state = _GroupState(None)
    group_materials: object = None  # the Materials list the (last) Group was parsed with
    while (tok := ts.next()) is not None:
        if tok.text in ext_parser.MEDIA:  # docs/EXTENSIONS.md E.8, E.9: at most one medium
            if "medium" in fields:
                raise ts.semantic_error(f"a scene has at most one medium (Fog or Volume); {tok.text} follows the "
                                        f"one at line {seen['medium'].loc.line}", tok.loc)
            seen["medium"] = tok
            fields["medium"] = ext_parser.MEDIA[tok.text](ts, tok)
            continue
        if tok.text not in TOP_LEVEL and tok.text != keyframes.KEYWORD:
            raise ts.syntax_error(f"expected {_one_of(TOP_LEVEL)}, found '{shown(tok.text)}'", tok)
        if tok.text in seen and not (tok.text == "Materials" and "Group" in seen):
            ts.warn(tok.loc, f"second {tok.text} block replaces the one at line {seen[tok.text].loc.line}")
        seen[tok.text] = tok
        if tok.text == "PerspectiveCamera":
            fields["camera"] = parse_camera(ts, tok)
        elif tok.text == "Lights":
            fields["lights"] = parse_lights(ts, tok)
            if not fields["lights"]:
                ts.warn(tok.loc, "no lights: the ambient light is forced to 1 1 1 (as the sample solution does)")
        elif tok.text == "Background":
            fields["background"] = parse_background(ts, tok)
        elif tok.text == "Animation":  # docs/EXTENSIONS.md E.11
            fields["animation"] = keyframes.parse_animation(ts, tok)
        elif tok.text == "Materials":
            fields["materials"] = parse_materials(ts, tok)
            state.num_materials = len(fields["materials"])  # type: ignore[arg-type]
            state.materials_line = tok.loc.line
            if "Group" in seen:
                ts.warn(tok.loc, "Materials block after the Group: the group keeps the materials it was parsed "
                                 "with (as the sample solution does)")
        else:
            fields["root"] = parse_group(ts, tok, state)
            group_materials = fields.get("materials")
    if "root" in fields and group_materials is not None:
        fields["materials"] = group_materials
    for block, key in (("PerspectiveCamera", "camera"), ("Group", "root")):
        if key not in fields:
            raise ts.syntax_error(f"expected a {block} block somewhere in the file, found end of file", None)
    if "Lights" not in seen:
        ts.warn(ts.eof_loc, "no Lights block: the ambient light is forced to 1 1 1 (as the sample solution does)")
    scene = Scene(path=ts.path, warnings=tuple(ts.warnings), **fields)  # type: ignore[arg-type]
    keyframes.check(ts, scene)  # E.11: the tracks' targets exist (the whole scene is known only now)
    return scene


def parse_text(text: str, path: str = "<string>") -> Scene:
    """Parse scene text; ``path`` is used in positions and to resolve relative file names later."""
    if not isinstance(text, str):
        raise TypeError(f"parse_text expects str, not {type(text).__name__}")
    if not text.strip():
        raise SceneSyntaxError("empty scene file: expected " + _one_of(TOP_LEVEL) + ", found end of file",
                               FileLoc(path, 1, 1), "")
    ts = TokenStream(text, path)
    if not path.endswith(".txt") and path != "<string>":
        ts.warn(FileLoc(path, 1, 1), "scene file name does not end in '.txt' (the sample solution refuses it)")
    return parse_tokens(ts)


def parse_file(path: str | Path) -> Scene:
    """Read and parse a scene file (SPEC A); see :func:`parse_text`."""
    return parse_text(read_source(path), str(path))
