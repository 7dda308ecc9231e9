"""The sample solution's mesh octree rule inside ``a5_whitted``: hits the binary does not see (SPEC A.6).

``a5soln`` intersects meshes through an octree whose traversal breaks when the object-space ray direction
has a component that is exactly zero (the rule and its derivation: ``a5mi.converters.octree``): with
``-0.0`` the mesh is invisible, with ``+0.0`` only the triangles of some leaves are reached. Meshes carry
the rule as face attributes (written by the converter; absent on meshes from elsewhere, which are then
intersected exactly)::

    face_a5_inv0, face_a5_inv1, face_a5_inv2   rows of A = M⁻¹ (world to object, upper 3x3)
    face_a5_octree                             (mask word 0, mask word 1, transformed 0/1; 2: a Triangle)

For a hit on such a face and world direction ``d``: ``d_o = A d`` (vecmath order ``(a_0 d_x + a_1 d_y) +
a_2 d_z``); zero axes ``zmask`` (x=1, y=2, z=4), negative finite axes ``neg``; an untransformed mesh sees
the sign of ``d``'s own zeros, a transformed one only ``+0``. The binary sees the hit unless some zero is
``-0.0``, or bit ``(zmask-1)·8 + neg`` of the mask words (24 bits each) is 0. Rays whose world direction
has no zero component skip all of this (a zero object-space component of a non-axis-aligned world
direction needs an exact cancellation in A d, which this rule does not model).
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

from a5mi.plugins.emulation import octree_leaves, triangle_rule
from a5mi.plugins.syntax import syntax

#: Rays skipped past hits the binary does not see, at most, per query.
MAX_SKIPS = 16
#: Where the Mitsuba ray of a query starts, as a multiple of tmin: one tmin *behind* the origin, so that
#: the triangle the ray leaves is tested by the binary's rule too. For a grazing ray that rule's t on the
#: origin's own triangle is float32 rounding noise of either sign (measured on scene06: 0.00122 and
#: 0.00119, i.e. >= tmin: the binary re-hits; -0.0011 and 0.00098: it escapes), which Mitsuba's own t
#: (exact to a few ulps) never reproduces.
SEARCH_FROM = -1.0


def _signbit(x: mi.Float) -> mi.Bool:
    return (dr.reinterpret_array(mi.UInt32, x) >> 31) == 1


def has_zero(d: mi.Vector3f) -> mi.Bool:
    """True where the direction has a component that is exactly ±0."""
    return (d.x == 0.0) | (d.y == 0.0) | (d.z == 0.0)


def binary_sees(si: mi.SurfaceInteraction3f, d: mi.Vector3f, active: mi.Bool) -> mi.Bool:
    """False where ``si`` is a hit on a mesh face that the binary's octree does not reach for direction
    ``d`` (module docstring); True elsewhere (misses, spheres, meshes without the attributes)."""
    shape = si.shape
    m = mi.Bool(active) & shape.has_attribute("face_a5_octree", active)
    rule = shape.eval_attribute_3("face_a5_octree", si, m)
    a0 = shape.eval_attribute_3("face_a5_inv0", si, m)
    a1 = shape.eval_attribute_3("face_a5_inv1", si, m)
    a2 = shape.eval_attribute_3("face_a5_inv2", si, m)
    do = mi.Vector3f(*[(a.x * d.x + a.y * d.y) + a.z * d.z for a in (a0, a1, a2)])
    untransformed = rule.z == 0.0
    zeros = [do.x == 0.0, do.y == 0.0, do.z == 0.0]
    neg_zero = mi.Bool(False)
    zmask = mi.UInt32(0)
    neg = mi.UInt32(0)
    for k, (z, dk, dok) in enumerate(zip(zeros, (d.x, d.y, d.z), (do.x, do.y, do.z), strict=True)):
        # Untransformed: the object-space direction is d itself, signed zeros included.
        neg_zero |= z & untransformed & _signbit(dk)
        zmask |= dr.select(z, mi.UInt32(1 << k), 0)
        neg |= dr.select(~z & (dok < 0.0), mi.UInt32(1 << k), 0)
    slot = (zmask - 1) * 8 + neg
    word = dr.select(slot < 24, mi.UInt32(rule.x), mi.UInt32(rule.y))
    bit = ((word >> dr.select(slot < 24, slot, slot - 24)) & 1) == 1
    unseen = m & (zmask > 0) & (neg_zero | ~bit)
    return ~unseen


@syntax
def _unseen(si: mi.SurfaceInteraction3f, d: mi.Vector3f, zero: mi.Bool) -> mi.Bool:
    """``zero & ~binary_sees(si, d, zero)`` under a per-lane ``if`` on ``zero`` (directions with a zero
    component): the face attributes' calls, which run masked even for a packet with no such lane, are skipped
    by one without."""
    out = dr.zeros(mi.Bool, dr.width(d))
    if zero:
        out = zero & ~binary_sees(si, d, zero)
    return out


def _rejected(table: triangle_rule.RuleTable | None, si: mi.SurfaceInteraction3f, o: mi.Point3f,
              d: mi.Vector3f, offset: mi.Float, t_min: mi.Float,
              active: mi.Bool) -> tuple[mi.Bool, mi.UInt32, mi.Float, mi.Vector3f]:
    """``(rejected, row, t, N)`` for the hit ``si`` of a ray started at ``o + offset d``: a hit the binary
    does not see (octree rule), a mesh triangle the binary's own test refuses (:mod:`.triangle_rule`; ``row``
    is that face's table row, 0 off rule meshes, and ``t`` and ``N`` are the binary's), or any other shape's
    hit at ``t <= t_min``."""
    valid = mi.Bool(active) & si.is_valid()
    row = mi.UInt32(0)
    t_b, n_b = mi.Float(0.0), mi.Vector3f(0.0)
    out = valid & (offset < t_min) & (si.t + offset <= t_min)
    if table is not None:
        row = triangle_rule.row_of(table, si, valid)
        hit_b, t_b, n_b = triangle_rule.evaluate_rows(table, row, o, d, t_min, row > 0)
        out = dr.select(row > 0, ~hit_b, out)
    zero = valid & has_zero(d)
    out |= _unseen(si, d, zero)
    return out, row, t_b, n_b


@syntax
def intersect(scene: mi.Scene, o: mi.Point3f, d: mi.Vector3f, t_min: mi.Float, active: mi.Bool,
              table: triangle_rule.RuleTable | None = None,
              origin: mi.UInt32 | None = None) -> tuple[mi.SurfaceInteraction3f, mi.Float, mi.UInt32]:
    """Nearest hit with ``t > t_min`` that the binary sees: ``(si, offset, row)``, ``si.t`` measured from
    ``o + offset d`` (so the hit distance is ``si.t + offset``); ``row``: the hit face's row of ``table``
    (:func:`.triangle_rule.rule_table` of ``scene``; 0 off rule meshes, and everywhere when ``table`` is
    None). Mitsuba rays have no tmin: a hit the binary does not see (the octree rule, or a mesh triangle
    that fails the binary's own test, plugins/emulation/triangle_rule.py) restarts the ray just past that hit. On
    meshes that carry the binary's triangle data the hit distance and shading normal are the binary's
    (offset 0, ``si.t`` = its t, ``si.sh_frame`` about its N).

    Where the ray starts: a ray leaving a rule mesh may re-meet the triangle it leaves, because that
    triangle's float32 ``t`` is rounding noise of either sign. ``origin`` (per lane: the row of the face the
    ray leaves, 0 for none) lets that triangle be tested directly: where the binary re-hits it, the Mitsuba
    ray starts ``SEARCH_FROM`` tmin behind the origin (so the triangle is found and evaluated), elsewhere at
    ``o + t_min d``. Without ``origin`` every lane starts behind (the rule's first form: one more Mitsuba
    ray cast for each ray leaving any surface, since it first meets that surface again; BENCHMARKS.md
    measures the difference)."""
    offset = t_min * SEARCH_FROM
    if dr.hint(table is None, mode="scalar"):           # no rule mesh in the scene
        offset = mi.Float(t_min)
    elif dr.hint(origin is not None, mode="scalar"):
        rehit, _, _ = triangle_rule.evaluate_rows(table, origin, o, d, t_min, active)
        offset = dr.select(rehit, offset, t_min)
    si = scene.ray_intersect(mi.Ray3f(o + offset * d, d), active)
    skip, row, t_b, n_b = _rejected(table, si, o, d, offset, t_min, active)
    n = mi.UInt32(0)
    while skip & (n < MAX_SKIPS):
        step = offset + si.t + dr.maximum(1e-6, (offset + si.t) * 1e-6)
        # Past any other shape's hit below tmin the search resumes at tmin itself, as it always did.
        offset = dr.select(row > 0, step, dr.maximum(step, t_min))
        si = scene.ray_intersect(mi.Ray3f(o + offset * d, d), skip)
        again, row_again, t_again, n_again = _rejected(table, si, o, d, offset, t_min, skip)
        row = dr.select(skip, row_again, row)
        t_b = dr.select(skip, t_again, t_b)
        n_b = dr.select(skip, n_again, n_b)
        skip &= again
        n += 1
    row = dr.select(skip, 0, row)
    if dr.hint(table is not None and table.partners is not None, mode="scalar"):
        # exact depth ties between coincident faces of different meshes: the binary's Group order
        row, t_b, n_b, moved = triangle_rule.coincident(table, row, t_b, n_b, o, d, t_min, active)
        shape, face = triangle_rule.mesh_of(table, row, moved)
        si.shape = dr.select(moved, shape, si.shape)
        si.prim_index = dr.select(moved, face, si.prim_index)
    binary = row > 0
    si.t = dr.select(binary, t_b, si.t)
    offset = dr.select(binary, 0.0, offset)
    si.sh_frame = dr.select(binary, mi.Frame3f(n_b), si.sh_frame)
    si.wi = dr.select(binary, si.sh_frame.to_local(-d), si.wi)
    return si, offset, row


def traversal_sees(table: triangle_rule.RuleTable, si: mi.SurfaceInteraction3f, o: mi.Point3f, d: mi.Vector3f,
                   active: mi.Bool) -> mi.Bool:
    """:func:`binary_sees` for one ray: on a rule mesh's face (not a ``Triangle``, which has no octree), whether
    the binary's traversal of ``(o, d)`` reaches a leaf holding it (plugins/emulation/octree_leaves.py); the reach masks
    elsewhere."""
    row = triangle_rule.row_of(table, si, active)
    at = (dr.maximum(row, 1) - 1) * triangle_rule.ROW_FLOATS
    m = mi.Bool(active) & (row > 0)

    def vec(name: str) -> mi.Vector3f:
        k = at + 3 * triangle_rule.ROW_ATTRIBUTES.index(name)
        return mi.Vector3f(*[dr.gather(mi.Float, table.rows, k + c, m) for c in range(3)])

    kind = vec("face_a5_octree").z
    mesh = mi.UInt32(dr.gather(mi.Float, table.rows, at + triangle_rule.MESH_SLOT, m))
    walked = m & (kind != 2.0)
    v0, v1, v2 = vec("face_a5_v0"), vec("face_a5_v1"), vec("face_a5_v2")
    box = (dr.minimum(dr.minimum(v0, v1), v2), dr.maximum(dr.maximum(v0, v1), v2))
    seen = octree_leaves.sees(table.nodes, mesh, box, [vec("face_a5_inv0"), vec("face_a5_inv1"),
                              vec("face_a5_inv2")], vec("face_a5_inv_t"), kind == 1.0, o, d, walked)
    return dr.select(walked, seen, binary_sees(si, d, active))


@syntax
def occluded(scene: mi.Scene, o: mi.Point3f, d: mi.Vector3f, t_min: mi.Float, t_max: mi.Float,
             active: mi.Bool, table: triangle_rule.RuleTable | None = None) -> mi.Bool:
    """SPEC B.3's shadow test against the Mitsuba scene: a hit the binary sees with ``t_min < t < t_max``;
    with ``table`` (its octree node table built) a rule-mesh hit of a ray with a zero component is decided by the
    binary's traversal of that ray (:func:`traversal_sees`), else by the reach masks."""
    # One any-hit query for every lane: it decides the lanes without a zero component, and a zero-component
    # lane that meets nothing at all (most shadow rays) needs no nearest-hit walk to ask which hits the binary
    # sees. Embree's any-hit and nearest-hit queries run the same triangle test on the same interval.
    anything = scene.ray_test(mi.Ray3f(mi.Ray3f(o + t_min * d, d), t_max - t_min), active)
    slow = active & has_zero(d)
    hit = anything & ~slow
    slow &= anything
    offset = mi.Float(t_min)
    n = mi.UInt32(0)
    while slow & (n < MAX_SKIPS):
        si = scene.ray_intersect(mi.Ray3f(mi.Ray3f(o + offset * d, d), t_max - offset), slow)
        found = si.is_valid()
        if dr.hint(table is not None and table.nodes is not None, mode="scalar"):
            seen = found & traversal_sees(table, si, o, d, found)
        else:
            seen = found & binary_sees(si, d, found)
        hit |= seen
        slow &= found & ~seen
        offset = offset + si.t + dr.maximum(1e-6, (offset + si.t) * 1e-6)
        n += 1
    return hit
