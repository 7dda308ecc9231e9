"""The sample solution's triangle test and shading normal for mesh hits inside ``a5_whitted`` (SPEC A.6, B.3).

Mitsuba finds the triangle; this module then evaluates that triangle as ``a5soln`` does (read from the
binary: ``Transform::intersect``, ``Mesh::intersectTrig``, ``Triangle::intersect``, vecmath's
``Matrix3f::inverse``), in float32 and in the binary's operation order, so that the two renderers agree on
grazing mirror rays: a ray leaving a smooth mesh at a small angle re-meets its own triangle (or a
neighbour) at t ≈ tmin, where a last-bit difference in the normal, the hit distance or the barycentrics
decides between a re-hit and an escape (scene06's bunny: 5 pixels of 90,000 before this rule).

Per face the mesh carries (converters/geometry.py ``triangle_rows``, as face attributes): the world-to-object
matrix ``A | T`` (``face_a5_inv0..2``: rows of A; ``face_a5_inv_t``: T), the float32 object-space vertices
``a, b, c`` (``face_a5_v0..2``) and the binary's corner normals ``n0, n1, n2`` (``face_a5_n0..2``). For a
world ray ``(o, d)`` and ``tmin``::

    o' = ((A_i0 o_x + A_i1 o_y) + A_i2 o_z) + T_i,   d' = (A_i0 d_x + A_i1 d_y) + A_i2 d_z
                                                     (only inside a Transform; else o' = o, d' = d)
    M = [a−b | a−c | d']   (columns),  B = a − o'
    (β, γ, t) = M⁻¹ B      M⁻¹ = cofactorsᵀ · (1/det), cofactor c_ij = ±(p s − q r) of the 2x2 minor,
                           det = (m00 c00 + m01 c01) + m02 c02, rows dotted with B left to right
    hit  iff  β >= 0,  γ >= 0,  β + γ <= 1,  t >= tmin        (the binary's tmin test is NOT strict)
    N' = normalize((α n0 + β n1) + γ n2),  α = (1 − β) − γ
    N  = normalize(Aᵀ N')   (only inside a Transform: (M₃⁻¹)ᵀ with M₃⁻¹ = A)

with ``normalize(v) = v / sqrtf((x² + y²) + z²)`` and no fused multiply-add anywhere (Dr.Jit's ``dr.dot``
and ``dr.norm`` fuse, so they are not used). Not modelled: the binary composes nested ``Transform`` levels
one by one, and inverts M in float32 (here: the composed float64 inverse rounded once).

Inside the render kernel the face data is not read through the mesh's ``eval_attribute_3`` (a virtual call
per attribute: eight per evaluated hit) but from one :class:`RuleTable` per scene: the eleven vectors of
every rule mesh's faces (:data:`ROW_ATTRIBUTES`) copied into one array, found by the hit shape's registry ID
and ``prim_index`` with plain gathers (measured: BENCHMARKS.md). A *row* names a face of the table: its index
plus one, 0 for "not a rule-mesh face".
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import drjit as dr
import mitsuba as mi
import numpy as np

from a5mi.platform.arrays import aligned_float32
from a5mi.plugins.emulation import octree_leaves
from a5mi.plugins.optics import dot32 as dot
from a5mi.plugins.syntax import syntax

#: The face attribute that marks a mesh carrying the data above.
MARKER = "face_a5_v0"
#: The face attributes of one table row, in row order (vectors of 3 floats each).
ROW_ATTRIBUTES = ("face_a5_inv0", "face_a5_inv1", "face_a5_inv2", "face_a5_octree", "face_a5_inv_t",
                  "face_a5_v0", "face_a5_v1", "face_a5_v2", "face_a5_n0", "face_a5_n1", "face_a5_n2")
_SLOT = {name: k for k, name in enumerate(ROW_ATTRIBUTES)}
#: Floats per table row: the 33 of the eleven vectors, padded to whole packets of four, so that a row is
#: read with nine 4-float packet gathers (one vector load per lane each; a ``Vector3f`` gather is three
#: scalar gathers in Dr.Jit's LLVM backend).
ROW_FLOATS = 36
#: Where a row keeps its mesh's number (in row order) and its face index (two of the padding floats).
MESH_SLOT = 33
#: Coincident faces of other rule meshes kept per face (:func:`coincident_faces`), and the largest group of
#: coplanar faces searched for them.
PARTNERS = 4
MAX_GROUP = 4096
#: :attr:`RuleTable.place` of a shape that is not a rule mesh of the converter's (no scene position).
NO_PLACE = 0xFFFFFFFF


@dataclass
class RuleTable:
    """The rule meshes' face data of one scene (module docstring): ``rows`` holds one row of
    :data:`ROW_FLOATS` floats (the :data:`ROW_ATTRIBUTES` vectors, then zeros) per face, every rule mesh's
    faces in turn; ``base[id]`` is the row of face 0 of the shape with registry ID ``id`` (0: that shape
    carries no rule data). ``key`` identifies the attribute buffers it was copied from (a warm animated
    scene updates them, and the table is copied again)."""

    rows: mi.Float
    base: mi.UInt32
    last: mi.UInt32   # len(base) - 1, opaque (a literal would differ between scenes and recompile the kernel)
    key: tuple
    #: :data:`PARTNERS` rows per row: coincident faces of *other* rule meshes (0: none), or None when no face
    #: has one (:func:`coincident`); ``shapes``: the rule meshes, in row order.
    partners: mi.UInt32 | None = None
    shapes: mi.ShapePtr | None = None
    #: Per registry ID like ``base``: a rule mesh's scene position (:data:`NO_PLACE` for other shapes) and
    #: whether it has texture coordinates (the sample solution's stale texture coordinates, docs/FIDELITY.md).
    place: mi.UInt32 | None = None
    has_uv: mi.Bool | None = None
    #: The binary's octree of every rule mesh (plugins/emulation/octree_leaves.py; None past its budget).
    nodes: octree_leaves.NodeTable | None = None


def _shape_id(shape: mi.Shape) -> int:
    return int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape))[0])


def rule_table(scene: mi.Scene, cached: RuleTable | None = None) -> RuleTable | None:
    """The :class:`RuleTable` of ``scene`` (None when no shape carries the binary's triangle data);
    ``cached`` is returned as it is when its attribute buffers are still the scene's."""
    meshes = sorted((s for s in scene.shapes() if isinstance(s, mi.Mesh) and s.has_attribute(MARKER)),
                    key=_scene_order)
    if not meshes:
        return None
    buffers = [[mi.traverse(m)[name] for name in ROW_ATTRIBUTES] for m in meshes]
    key = tuple((_shape_id(m), *(b.index for b in bufs)) for m, bufs in zip(meshes, buffers, strict=True))
    if cached is not None and cached.key == key:
        return cached
    blocks, first = [], 1
    base = np.zeros(max(_shape_id(s) for s in scene.shapes()) + 2, dtype=np.uint32)
    place = np.full_like(base, NO_PLACE)
    has_uv = np.zeros(len(base), dtype=bool)
    for m, bufs in zip(meshes, buffers, strict=True):
        order = _scene_order(m)
        if order[0] == 0:
            place[_shape_id(m)] = order[1]
        has_uv[_shape_id(m)] = m.has_vertex_texcoords()
        faces = m.face_count()
        block = np.zeros((faces, ROW_FLOATS), dtype=np.float32)
        block[:, :3 * len(ROW_ATTRIBUTES)] = np.concatenate(
            [np.asarray(b, dtype=np.float32).reshape(faces, 3) for b in bufs], axis=1)
        block[:, MESH_SLOT], block[:, MESH_SLOT + 1] = len(blocks), np.arange(faces)
        blocks.append(block)
        base[_shape_id(m)] = first
        first += faces
    rows = mi.Float(aligned_float32(np.concatenate(blocks)))  # (unaligned: a random recompile, a5mi/platform/arrays.py)
    ids = mi.UInt32(base.tolist())   # a few entries: a Dr.Jit-owned copy, not numpy memory
    dr.make_opaque(rows, ids)
    table = RuleTable(rows, ids, dr.opaque(mi.UInt32, len(base) - 1), key)
    if axis_lights(scene):   # only shadow rays toward such a light meet the octree's zero-component traversal
        table.nodes = octree_leaves.build([np.stack([np.asarray(b, dtype=np.float32).reshape(-1, 3)
                                                      for b in bufs[_SLOT["face_a5_v0"]:_SLOT["face_a5_v2"] + 1]],
                                                     axis=1) for bufs in buffers])
    table.place, table.has_uv = mi.UInt32(place.tolist()), mi.Bool(has_uv.tolist())
    dr.make_opaque(table.place, table.has_uv)
    partners = coincident_faces(meshes)
    if partners is not None:
        table.partners = mi.UInt32(partners.ravel().tolist())
        table.shapes = mi.ShapePtr(meshes)
        dr.make_opaque(table.partners, table.shapes)
    return table


def axis_lights(scene: mi.Scene) -> bool:
    """Whether some directional light's direction toward the light (``ds.d``, what shadow rays follow) has an
    exactly zero component: the rays for which :attr:`RuleTable.nodes` is built
    (plugins/emulation/octree_leaves.py)."""
    for emitter in scene.emitters():
        flags = emitter.flags()
        if flags & int(mi.EmitterFlags.DeltaDirection) and flags & int(mi.EmitterFlags.Infinite):
            ds, _ = emitter.sample_direction(dr.zeros(mi.Interaction3f, 1), mi.Point2f(0.5, 0.5), True)
            if any(float(ds.d[k][0]) == 0.0 for k in range(3)):
                return True
    return False


def _scene_order(shape: mi.Shape) -> tuple[int, int]:
    """A rule mesh's place in the scene's Group order (its converter id ``mesh_NNN`` / ``triangle_NNN``)."""
    m = re.match(r"^(?:mesh|triangle)_(\d+)$", shape.id())
    return (0, int(m.group(1))) if m else (1, _shape_id(shape))


def coincident_faces(meshes: list[mi.Mesh]) -> np.ndarray | None:
    """Per face of ``meshes`` (in row order), up to :data:`PARTNERS` rows of faces of *other* meshes that lie
    in the same plane (world space: unit normal within 1e-5 up to sign, offset within 1e-4) with overlapping
    bounding boxes: the faces an exact depth tie can occur with (:func:`coincident`). None when there are
    none (the kernel then has no tie code)."""
    tris, owner = [], []
    for k, m in enumerate(meshes):
        params = mi.traverse(m)
        v = np.asarray(params["vertex_positions"], dtype=np.float64).reshape(-1, 3)
        f = np.asarray(params["faces"], dtype=np.int64).reshape(-1, 3)
        tris.append(v[f])
        owner.append(np.full(len(f), k))
    if len(meshes) < 2:
        return None
    t = np.concatenate(tris)
    who = np.concatenate(owner)
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    length = np.linalg.norm(n, axis=1)
    ok = length > 0
    n[ok] /= length[ok, None]
    lead = np.take_along_axis(n, np.argmax(np.abs(n) > 1e-6, axis=1)[:, None], axis=1)
    n *= np.where(lead < 0, -1.0, 1.0)
    off = np.einsum("ij,ij->i", n, t[:, 0])
    keys = np.concatenate([np.round(n * 1e5), np.round(off * 1e4)[:, None]], axis=1)
    keys[~ok] = np.nan
    _, group = np.unique(keys, axis=0, return_inverse=True)
    group = group.ravel()
    lo, hi = t.min(axis=1) - 1e-5, t.max(axis=1) + 1e-5
    out = np.zeros((len(t), PARTNERS), dtype=np.uint32)
    found = False
    order = np.argsort(group, kind="stable")
    bounds = np.flatnonzero(np.diff(group[order])) + 1
    for members in np.split(order, bounds):
        members = members[ok[members]]
        if len(members) < 2 or len(members) > MAX_GROUP or len(set(who[members])) < 2:
            continue
        overlap = np.all((lo[members, None] <= hi[None, members]) & (lo[None, members] <= hi[members, None]), axis=2)
        overlap &= who[members, None] != who[None, members]
        for i, row in zip(members, overlap, strict=True):
            others = members[row][:PARTNERS]
            out[i, :len(others)] = others + 1
            found |= len(others) > 0
    return out if found else None


@syntax
def coincident(table: RuleTable, row: mi.UInt32, t: mi.Float, n: mi.Vector3f, o: mi.Point3f, d: mi.Vector3f,
               t_min: mi.Float, active: mi.Bool) -> tuple[mi.UInt32, mi.Float, mi.Vector3f, mi.Bool]:
    """The binary's Group order among coincident faces (SPEC A.6: objects are tested in scene order and a
    triangle replaces the hit when ``t <= t_current``): each partner of the hit face ``row`` is evaluated by
    :func:`evaluate`; it takes the hit when its ``t`` is smaller, or equal and its mesh comes later (rows are
    in scene order). Returns ``(row, t, N, moved)``, ``moved`` where a partner took the hit. A face's partners
    are listed first (its first 0 ends them), so the loop runs only while some lane has one more: a packet
    whose faces have none evaluates nothing."""
    moved = dr.zeros(mi.Bool, dr.width(t))
    live = mi.Bool(active) & (row > 0)
    first = (dr.maximum(row, 1) - 1) * PARTNERS
    k = dr.zeros(mi.UInt32, dr.width(t))
    other = dr.gather(mi.UInt32, table.partners, first, live)
    while live & (other > 0):
        hit, t_o, n_o = evaluate(table, other, o, d, t_min, live)
        wins = hit & ((t_o < t) | ((t_o == t) & (other > row)))
        row, t, n = dr.select(wins, other, row), dr.select(wins, t_o, t), dr.select(wins, n_o, n)
        moved |= wins
        k += 1
        other = dr.gather(mi.UInt32, table.partners, first + k, live & (k < PARTNERS))
    return row, t, n, moved


def mesh_of(table: RuleTable, row: mi.UInt32, active: mi.Bool) -> tuple[mi.ShapePtr, mi.UInt32]:
    """``(shape, prim_index)`` of table row ``row`` (a table with :attr:`RuleTable.shapes`)."""
    at = (row - 1) * ROW_FLOATS + MESH_SLOT
    mesh = mi.UInt32(dr.gather(mi.Float, table.rows, at, active))
    face = mi.UInt32(dr.gather(mi.Float, table.rows, at + 1, active))
    return dr.gather(mi.ShapePtr, table.shapes, mesh, active), face


def row_of(table: RuleTable, si: mi.SurfaceInteraction3f, active: mi.Bool) -> mi.UInt32:
    """The table row of the face ``si`` hit (0 where ``si`` is a miss, inactive or not on a rule mesh)."""
    m = mi.Bool(active) & si.is_valid()
    sid = dr.minimum(dr.reinterpret_array(mi.UInt32, si.shape), table.last)
    first = dr.gather(mi.UInt32, table.base, sid, m)
    return dr.select(m & (first > 0), first + si.prim_index, 0)


def normalize(v: mi.Vector3f) -> mi.Vector3f:
    """vecmath ``normalized()``: ``v / sqrtf((x² + y²) + z²)``, one division per component."""
    length = dr.sqrt(dot(v, v))
    return mi.Vector3f(v.x / length, v.y / length, v.z / length)


def solve(a: mi.Vector3f, b: mi.Vector3f, c: mi.Vector3f, o: mi.Vector3f,
          d: mi.Vector3f) -> tuple[mi.Float, mi.Float, mi.Float]:
    """``(β, γ, t)`` of ``Triangle::intersect``: ``[a−b | a−c | d]⁻¹ (a − o)`` with vecmath's float32
    cofactor inverse (module docstring), in object space."""
    m00, m01, m02 = a.x - b.x, a.x - c.x, d.x
    m10, m11, m12 = a.y - b.y, a.y - c.y, d.y
    m20, m21, m22 = a.z - b.z, a.z - c.z, d.z

    def det2(p: mi.Float, q: mi.Float, r: mi.Float, s: mi.Float) -> mi.Float:
        return p * s - q * r

    c00, c01, c02 = det2(m11, m12, m21, m22), -det2(m10, m12, m20, m22), det2(m10, m11, m20, m21)
    c10, c11, c12 = -det2(m01, m02, m21, m22), det2(m00, m02, m20, m22), -det2(m00, m01, m20, m21)
    c20, c21, c22 = det2(m01, m02, m11, m12), -det2(m00, m02, m10, m12), det2(m00, m01, m10, m11)
    r = 1.0 / ((m00 * c00 + m01 * c01) + m02 * c02)
    rhs = a - o
    beta = dot(mi.Vector3f(c00 * r, c10 * r, c20 * r), rhs)
    gamma = dot(mi.Vector3f(c01 * r, c11 * r, c21 * r), rhs)
    t = dot(mi.Vector3f(c02 * r, c12 * r, c22 * r), rhs)
    return beta, gamma, t


def evaluate(table: RuleTable, row: mi.UInt32, o: mi.Point3f, d: mi.Vector3f, t_min: mi.Float,
             active: mi.Bool) -> tuple[mi.Bool, mi.Float, mi.Vector3f]:
    """The binary's verdict on face ``row`` of ``table`` for the world ray ``(o, d)``: ``(hit, t, N)`` with
    the binary's hit distance and world shading normal (module docstring). Only lanes in ``active`` with
    ``row > 0`` are meaningful."""
    m = mi.Bool(active) & (row > 0)
    first = (row - 1) * (ROW_FLOATS // 4)
    packets = [dr.gather(mi.Vector4f, table.rows, first + j, m) for j in range(ROW_FLOATS // 4)]
    floats = [packets[i // 4][i % 4] for i in range(ROW_FLOATS)]

    def attr(name: str) -> mi.Vector3f:
        k = 3 * _SLOT[name]
        return mi.Vector3f(floats[k], floats[k + 1], floats[k + 2])

    a0, a1, a2, tr = attr("face_a5_inv0"), attr("face_a5_inv1"), attr("face_a5_inv2"), attr("face_a5_inv_t")
    transformed = attr("face_a5_octree").z == 1.0     # 0: an untransformed mesh, 2: an untransformed Triangle
    ov, dv = mi.Vector3f(o), mi.Vector3f(d)
    o_obj = mi.Vector3f(dot(a0, ov) + tr.x, dot(a1, ov) + tr.y, dot(a2, ov) + tr.z)
    d_obj = mi.Vector3f(dot(a0, dv), dot(a1, dv), dot(a2, dv))
    o_obj = dr.select(transformed, o_obj, ov)
    d_obj = dr.select(transformed, d_obj, dv)
    beta, gamma, t = solve(attr("face_a5_v0"), attr("face_a5_v1"), attr("face_a5_v2"), o_obj, d_obj)
    hit = m & (beta >= 0.0) & (gamma >= 0.0) & ~(beta + gamma > 1.0) & (t >= t_min)
    alpha = (1.0 - beta) - gamma
    n = normalize((alpha * attr("face_a5_n0") + beta * attr("face_a5_n1")) + gamma * attr("face_a5_n2"))
    # (M₃⁻¹)ᵀ N': row i of the transpose is column i of A.
    n_world = normalize(mi.Vector3f((a0.x * n.x + a1.x * n.y) + a2.x * n.z,
                                    (a0.y * n.x + a1.y * n.y) + a2.y * n.z,
                                    (a0.z * n.x + a1.z * n.y) + a2.z * n.z))
    return hit, t, dr.select(transformed, n_world, n)


@syntax
def evaluate_rows(table: RuleTable, row: mi.UInt32, o: mi.Point3f, d: mi.Vector3f, t_min: mi.Float,
                  active: mi.Bool) -> tuple[mi.Bool, mi.Float, mi.Vector3f]:
    """:func:`evaluate` under a per-lane ``if`` on the lanes of ``active`` with ``row > 0``: a packet without
    such a lane (camera rays, rays leaving a plane or a sphere, hits off rule meshes) skips the test. The
    other lanes read ``(False, 0, 0)``, which no caller uses (every result is selected by ``row > 0``)."""
    hit = dr.zeros(mi.Bool, dr.width(row))
    t = dr.zeros(mi.Float, dr.width(row))
    n = dr.zeros(mi.Vector3f, dr.width(row))
    if active & (row > 0):
        hit, t, n = evaluate(table, row, o, d, t_min, active)
    return hit, t, n

