"""Rules of ``Group`` and its objects (SPEC A.6): tokens -> :class:`~.model.Group` tree.

``Group { numObjects I (MaterialIndex I | <object>)* }`` with exactly ``numObjects`` objects; an ``<object>`` is
one of :data:`OBJECT_RULES` (``Group``, ``Sphere``, ``Plane``, ``Triangle``, ``TriangleMesh``, ``Transform``).
``MaterialIndex`` sets the parser's one "current material" (:class:`~.builders.GroupState`): sequential, it
survives nested groups and later ``Group`` blocks, must satisfy ``0 <= I < numMaterials`` (the binary's check
was off by one) and must precede every primitive. ``Transform { <transform>* <object> }`` composes its keywords
as :func:`.transforms.apply_keyword` does (``M = M * T``, ``Matrix4f`` pre-multiplied) and must be invertible.
Degenerate geometry (zero radius, zero-length normal or rotation axis, a zero-area ``Triangle``) is an error at
the object.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Final

import numpy as np

from a5mi.converters import transforms
from a5mi.converters.builders import GroupState
from a5mi.converters.errors import shown
from a5mi.converters.lexer import Token
from a5mi.converters.model import Group, Node, Plane, Sphere, Transform, TransformOp, Triangle, TriangleMesh, Vec3
from a5mi.converters.tokens import (
    TokenStream,
    block_count,
    check_count,
    nonzero,
    one_of,
    plural,
    quoted,
    too_many,
    vector_then,
)

#: Deepest Group / Transform nesting accepted: every later stage walks the tree recursively, and the course
#: scenes nest 3 deep; deeper input is a positioned error instead of Python's RecursionError (SPEC A.6).
MAX_NESTING: Final = 100


def _material_for(ts: TokenStream, state: GroupState, tok: Token) -> int:
    """The current material of primitive ``tok``: set, and valid for the Materials block in effect."""
    if state.current is None:
        raise ts.semantic_error(f"{tok.text} has no material: expected 'MaterialIndex' before it", tok.loc)
    if state.num_materials is not None and state.current >= state.num_materials:
        raise ts.semantic_error(
            f"{tok.text} uses material {state.current}, set before the Materials block at line "
            f"{state.materials_line} replaced the list with {plural(state.num_materials, 'material')}", tok.loc)
    return state.current


# -- primitives --------------------------------------------------------------------------------------------
def parse_sphere(ts: TokenStream, start: Token, state: GroupState) -> Sphere:
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


def parse_plane(ts: TokenStream, start: Token, state: GroupState) -> Plane:
    """``Plane { normal V3 offset F }``: the plane ``P . normal = offset``, normal not normalised."""
    normal, offset = vector_then(ts, "Plane", ("normal", "offset"), "Plane normal", ts.number)
    return Plane(normal, offset, _material_for(ts, state, start), start.loc)


def parse_triangle(ts: TokenStream, start: Token, state: GroupState) -> Triangle:
    """``Triangle { vertex0 V3 vertex1 V3 vertex2 V3 }``; a zero-area triangle (``(b-a)×(c-a) = 0``) is an error."""
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


def parse_triangle_mesh(ts: TokenStream, start: Token, state: GroupState) -> TriangleMesh:
    """``TriangleMesh { obj_file NAME }``; NAME must end in ``.obj`` (A.6)."""
    ts.expect("{", "after 'TriangleMesh'")
    ts.expect("obj_file", "in TriangleMesh")
    name = ts.name("obj_file")
    if not name.text.endswith(".obj"):
        raise ts.syntax_error(f"expected a file name ending in '.obj' after 'obj_file', found "
                              f"'{shown(name.text)}'", name)
    ts.expect("}", "to close TriangleMesh")
    return TriangleMesh(name.text, _material_for(ts, state, start), start.loc, name.loc)


# -- Transform ---------------------------------------------------------------------------------------------
def _vector_args(ts: TokenStream, tok: Token) -> tuple[float, ...]:
    """``Translate V3``, ``Scale V3``."""
    return ts.vec3(tok.text)


def _number_arg(ts: TokenStream, tok: Token) -> tuple[float, ...]:
    """``UniformScale F``, ``XRotate F``, ``YRotate F``, ``ZRotate F`` (degrees)."""
    return (ts.number(tok.text),)


def _rotate_args(ts: TokenStream, tok: Token) -> tuple[float, ...]:
    """``Rotate { V3 F }``: a non-zero axis, then degrees."""
    ts.expect("{", "after 'Rotate'")
    axis = ts.vec3("Rotate")
    degrees = ts.number("Rotate")
    nonzero(ts, axis, "Rotate axis", tok.loc)
    ts.expect("}", "to close Rotate")
    return (*axis, degrees)


def _matrix_args(ts: TokenStream, tok: Token) -> tuple[float, ...]:
    """``Matrix4f { 16 numbers }``, column by column."""
    ts.expect("{", "after 'Matrix4f'")
    args = tuple(ts.number("Matrix4f") for _ in range(16))
    ts.expect("}", "to close Matrix4f (16 numbers)")
    return args


#: The transform keywords of A.6 and how each reads its numbers, in the order the messages list them.
TRANSFORM_ARGS: Final[dict[str, Callable[[TokenStream, Token], tuple[float, ...]]]] = {
    "Translate": _vector_args, "Scale": _vector_args, "UniformScale": _number_arg, "XRotate": _number_arg,
    "YRotate": _number_arg, "ZRotate": _number_arg, "Rotate": _rotate_args, "Matrix4f": _matrix_args}
TRANSFORMS: Final = tuple(TRANSFORM_ARGS)


def parse_transform(ts: TokenStream, start: Token, state: GroupState) -> Transform:
    """``Transform { <transform>* <object> }`` with exactly one object, last (A.6); ``det M ≠ 0``."""
    ts.expect("{", "after 'Transform'")
    ops: list[TransformOp] = []
    m = np.eye(4)
    while True:
        tok = ts.next()
        if tok is None or (tok.text not in TRANSFORM_ARGS and tok.text not in OBJECT_RULES):
            raise ts.syntax_error(f"expected a transform ({one_of(TRANSFORMS)}) or an object "
                                  f"({one_of(OBJECTS)}) in Transform, found {quoted(tok)}", tok)
        if tok.text in OBJECT_RULES:
            child = parse_object(ts, tok, state)
            break
        args = TRANSFORM_ARGS[tok.text](ts, tok)
        ops.append(TransformOp(tok.text, args, tok.loc))
        m = transforms.apply_keyword(m, tok.text, args)
    ts.expect("}", "to close Transform (a Transform holds exactly one object)")
    det = float(np.linalg.det(m[:3, :3]))
    if not math.isfinite(det) or det == 0.0 or not np.all(np.isfinite(m)):
        raise ts.semantic_error(f"expected an invertible Transform, found a matrix with determinant {det:g} "
                                "(a zero scale?)", start.loc)
    return Transform(tuple(ops), transforms.as_tuple(m), child, start.loc)


# -- Group -------------------------------------------------------------------------------------------------
def parse_object(ts: TokenStream, tok: Token, state: GroupState) -> Node:
    """One ``<object>`` of A.6, its keyword ``tok`` already consumed; at most :data:`MAX_NESTING` deep."""
    rule = OBJECT_RULES[tok.text]
    if tok.text not in ("Group", "Transform"):
        return rule(ts, tok, state)
    if state.depth >= MAX_NESTING:
        raise ts.semantic_error(f"{tok.text} nested more than {MAX_NESTING} deep (the limit of a5mi)", tok.loc)
    state.depth += 1
    try:
        return rule(ts, tok, state)
    finally:
        state.depth -= 1


def _material_index(ts: TokenStream, tok: Token, state: GroupState) -> None:
    """``MaterialIndex I``: ``0 <= I < numMaterials`` of the Materials block read before (A.6)."""
    index, index_tok = ts.integer("MaterialIndex")
    n = state.num_materials
    if n is None:
        raise ts.semantic_error("MaterialIndex before any Materials block (Materials must come before "
                                "Group)", tok.loc)
    if not 0 <= index < n:
        raise ts.semantic_error(f"MaterialIndex {index} out of range: expected 0 to {n - 1} "
                                f"({n} materials)", index_tok.loc)
    state.current = index


def parse_group(ts: TokenStream, start: Token, state: GroupState) -> Group:
    """``Group { numObjects I (MaterialIndex I | <object>)* }``: exactly ``numObjects`` objects (A.6)."""
    count = block_count(ts, "Group", "numObjects")
    children: list[Node] = []
    while True:
        tok = ts.next()
        if tok is not None and tok.text == "}":
            check_count(ts, tok, "Group", "numObjects", count, len(children), "object")
            return Group(count, tuple(children), start.loc)
        if tok is not None and tok.text == "MaterialIndex":
            _material_index(ts, tok, state)
            continue
        if tok is None or tok.text not in OBJECT_RULES:
            raise ts.syntax_error(f"expected MaterialIndex, an object ({one_of(OBJECTS)}) or '}}' in Group, "
                                  f"found {quoted(tok)}", tok)
        if len(children) == count:
            raise too_many(ts, tok, "Group", "numObjects", count, "object")
        children.append(parse_object(ts, tok, state))


#: The objects of A.6 and their rules, in the order the messages list them.
OBJECT_RULES: Final[dict[str, Callable[[TokenStream, Token, GroupState], Node]]] = {
    "Group": parse_group, "Sphere": parse_sphere, "Plane": parse_plane, "Triangle": parse_triangle,
    "TriangleMesh": parse_triangle_mesh, "Transform": parse_transform}
OBJECTS: Final = tuple(OBJECT_RULES)
