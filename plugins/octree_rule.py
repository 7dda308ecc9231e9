"""The sample solution's mesh octree rule inside ``a5_whitted``: hits the binary does not see (issue 12).

``a5soln`` intersects meshes through an octree whose traversal breaks when the object-space ray direction
has a component that is exactly zero (the rule and its derivation: ``a5mi.converters.octree``): with
``-0.0`` the mesh is invisible, with ``+0.0`` only the triangles of some leaves are reached. Meshes carry
the rule as face attributes (written by the converter; absent on meshes from elsewhere, which are then
intersected exactly)::

    face_a5_inv0, face_a5_inv1, face_a5_inv2   rows of A = M⁻¹ (world to object, upper 3x3)
    face_a5_octree                             (mask word 0, mask word 1, transformed 0/1)

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

#: Rays skipped past hits the binary does not see, at most, per query.
MAX_SKIPS = 16


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


@dr.syntax
def intersect(scene: mi.Scene, o: mi.Point3f, d: mi.Vector3f, t_min: mi.Float,
              active: mi.Bool) -> tuple[mi.SurfaceInteraction3f, mi.Float]:
    """Nearest hit with ``t > t_min`` that the binary sees: ``(si, offset)``, ``si.t`` measured from
    ``o + offset d`` (so the hit distance is ``si.t + offset``). Mitsuba rays have no tmin: the ray starts
    at ``o + t_min d``; a hit the binary does not see restarts it just past that hit."""
    offset = mi.Float(t_min)
    si = scene.ray_intersect(mi.Ray3f(o + offset * d, d), active)
    skip = active & si.is_valid() & has_zero(d)
    skip &= ~binary_sees(si, d, skip)
    n = mi.UInt32(0)
    while skip & (n < MAX_SKIPS):
        offset = offset + si.t + dr.maximum(1e-6, (offset + si.t) * 1e-6)
        si = scene.ray_intersect(mi.Ray3f(o + offset * d, d), skip)
        skip &= si.is_valid()
        skip &= ~binary_sees(si, d, skip)
        n += 1
    return si, offset


@dr.syntax
def occluded(scene: mi.Scene, o: mi.Point3f, d: mi.Vector3f, t_min: mi.Float, t_max: mi.Float,
             active: mi.Bool) -> mi.Bool:
    """SPEC B.3's shadow test against the Mitsuba scene: a hit the binary sees with ``t_min < t < t_max``."""
    slow = active & has_zero(d)
    hit = scene.ray_test(mi.Ray3f(mi.Ray3f(o + t_min * d, d), t_max - t_min), active & ~slow)
    offset = mi.Float(t_min)
    n = mi.UInt32(0)
    while slow & (n < MAX_SKIPS):
        si = scene.ray_intersect(mi.Ray3f(mi.Ray3f(o + offset * d, d), t_max - offset), slow)
        found = si.is_valid()
        seen = found & binary_sees(si, d, found)
        hit |= seen
        slow &= found & ~seen
        offset = offset + si.t + dr.maximum(1e-6, (offset + si.t) * 1e-6)
        n += 1
    return hit
