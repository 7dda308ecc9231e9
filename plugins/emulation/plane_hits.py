"""The plane set's tests inside a kernel (SPEC A.6): planes, planes inside a ``Transform`` and non-similarity
spheres, in the binary's float32 order (the formulas: :mod:`.planes`).

An entry's values reach the arithmetic as an :class:`Entry` from one of two places, and both feed the same
functions (:func:`_plane_t`, :func:`_object_ray`, :func:`_sphere_t`, :func:`_normal`), so they give the same
bits:

* a set of at most :data:`~.planes.UNROLL` entries is *unrolled*: :attr:`.planes.PlaneSet.entries` holds each
  entry's kind as a Python value and its numbers as opaque one-element arrays, which a kernel reads as scalars
  (no gather), and each entry is tested with its own kind's code only. The kernel depends on the kinds in
  scene order (one compiled kernel per such sequence, whatever the values: a keyframed plane reuses it);
* a larger set is walked by a loop over the device arrays, gathering entry ``k`` (:func:`gathered`) and
  running its kind's code under a per-lane ``if`` (the lanes of a packet test the same entry together, so a
  packet runs one kind's arithmetic per entry): one kernel for any number of entries beyond the bound.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

from a5mi.plugins.emulation.planes import PLACED_PLANE, PLANE, SPHERE, WORLD_SPHERE, Entry, PlaneSet
from a5mi.plugins.syntax import syntax


def gathered(ps: PlaneSet, k: mi.UInt32, m: mi.Bool) -> Entry:
    """Entry ``k`` (per lane) of the device arrays, gathered on the lanes ``m`` (a field no test reads is
    never computed: Dr.Jit compiles only what an output needs)."""
    def g(arrays: tuple[mi.Float, ...]) -> tuple[mi.Float, ...]:
        return tuple(dr.gather(mi.Float, x, k, m) for x in arrays)

    n = g((ps.nx, ps.ny, ps.nz))
    order = None if ps.order is None else dr.gather(mi.UInt32, ps.order, k, m)
    if ps.spheres == 0:
        return Entry(PLANE, n, g((ps.offset,))[0], g((ps.inv_len,))[0], order=order)
    e = ps.objects
    return Entry(dr.gather(mi.UInt32, e.kind, k, m), n, g((ps.offset,))[0], g((ps.inv_len,))[0], g(e.a), g(e.tr),
                 g(e.centre), g((e.radius,))[0], g(e.inv3), order)


def _dot(ax: mi.Float, ay: mi.Float, az: mi.Float, v: mi.Vector3f) -> mi.Float:
    """vecmath's ``Vector3f::dot`` order: ``(a_x v_x + a_y v_y) + a_z v_z``."""
    return (ax * v.x + ay * v.y) + az * v.z


def _object_ray(e: Entry, o: mi.Point3f, d: mi.Vector3f) -> tuple[mi.Vector3f, mi.Vector3f]:
    """``(o', d')``: the ray in the entry's object space, ``o' = A o + T``, ``d' = A d`` (vecmath order)."""
    a = e.a
    o_obj = mi.Vector3f(*[_dot(a[3 * i], a[3 * i + 1], a[3 * i + 2], mi.Vector3f(o)) + e.tr[i] for i in range(3)])
    d_obj = mi.Vector3f(*[_dot(a[3 * i], a[3 * i + 1], a[3 * i + 2], d) for i in range(3)])
    return o_obj, d_obj


def half_quotient(x: mi.Float, a: mi.Float) -> mi.Float:
    """The binary's ``(float)((double)x / (2.0 (double)a))`` in float32 arithmetic, bit for bit: ``x / (a + a)``
    (``a + a`` is exact, and a quotient of two floats rounded to double and then to float is the correctly
    rounded float quotient, since 53 >= 2·24 + 2: double rounding is innocuous for division); where ``a + a``
    overflows, ``(x / 2) / a`` (``x / 2`` exact, or the quotient underflows to the same signed 0)."""
    two_a = a + a
    finite = dr.isfinite(two_a) | dr.isnan(a)
    return dr.select(finite, x, x * 0.5) / dr.select(finite, two_a, a)


def _sphere_t(e: Entry, o_obj: mi.Vector3f, d_obj: mi.Vector3f, t_min: mi.Float,
              m: mi.Bool) -> tuple[mi.Bool, mi.Float]:
    """``(hit, t)`` of ``Sphere::intersect`` for the object-space ray ``(o', d')`` (:mod:`.planes`), before the
    ``t < t_current`` test, on the lanes ``m``."""
    q = o_obj - mi.Vector3f(*e.centre)
    a2 = _dot(d_obj.x, d_obj.y, d_obj.z, d_obj)
    b = _dot(d_obj.x, d_obj.y, d_obj.z, q)
    b = b + b
    cc = _dot(q.x, q.y, q.z, q) - e.radius * e.radius
    disc = b * b - (4.0 * a2) * cc
    root = dr.sqrt(dr.maximum(disc, 0.0))
    t_far = half_quotient(root - b, a2)
    t_near = half_quotient(-b - root, a2)
    t = dr.select(t_min < t_near, t_near, 10000.0)
    t = dr.select(t_far > t_min, dr.select(t_near >= t_min, t, t_far), t)
    hit = m & (disc >= 0.0) & ~((t_min > t_far) & (t_min > t_near))     # NaN: a miss, as in the binary
    return hit, t


def _plane_t(e: Entry, o: mi.Vector3f, d: mi.Vector3f, t_min: mi.Float,
             best: mi.Float) -> tuple[mi.Bool, mi.Float]:
    """``(hit, t)`` of a plane for the ray ``(o, d)``: ``t = (offset − n·o)/(n·d)``, a hit when ``n·d != 0``
    and ``t_min < t < best``."""
    denom = _dot(*e.n, d)
    t = (e.offset - _dot(*e.n, o)) / denom
    return (denom != 0.0) & (t > t_min) & (t < best), t


def _entry_t(e: Entry, kind: int, o: mi.Point3f, d: mi.Vector3f, t_min: mi.Float, best: mi.Float,
             m: mi.Bool) -> tuple[mi.Bool, mi.Float]:
    """``(hit, t)`` of an entry of kind ``kind`` (Python), with ``t < best``, on the lanes ``m``."""
    if kind == PLANE:
        return _plane_t(e, mi.Vector3f(o), d, t_min, best)
    o_obj, d_obj = _object_ray(e, o, d)
    if kind == PLACED_PLANE:
        return _plane_t(e, o_obj, d_obj, t_min, best)
    hit, t = _sphere_t(e, o_obj, d_obj, t_min, m)
    return hit & (t < best), t


def intersect_planes(ps: PlaneSet, o: mi.Point3f, d: mi.Vector3f, t_min: mi.Float, t_max: mi.Float,
                     active: mi.Bool, before: mi.UInt32 | None = None) -> tuple[mi.Bool, mi.Float, mi.UInt32]:
    """Nearest plane (or non-similarity sphere) hit with ``t_min < t < t_max`` (SPEC A.6; spheres by the
    binary's rule): ``(hit, t, plane index)``; ``t = t_max`` and index 0 where nothing is hit. Entries are
    tested in scene order with ``t < best``: of two coincident ones the first wins. ``before`` (a set with
    :attr:`~.planes.PlaneSet.order`): only entries at scene positions ``< before``. Unrolled or a loop (module
    docstring)."""
    if ps.entries is None:
        return _intersect_loop(ps, o, d, t_min, t_max, active, before)
    best = mi.Float(t_max)
    idx = dr.zeros(mi.UInt32, dr.width(d))
    found = dr.full(mi.Bool, False, dr.width(d))
    for k, e in enumerate(ps.entries):
        ok, t = _entry_t(e, e.kind, o, d, t_min, best, active)
        ok &= active
        if before is not None:
            ok &= e.order < before
        best = dr.select(ok, t, best)
        idx = dr.select(ok, k, idx)
        found |= ok
    return found, best, idx


@syntax
def _intersect_loop(ps: PlaneSet, o: mi.Point3f, d: mi.Vector3f, t_min: mi.Float, t_max: mi.Float,
                    active: mi.Bool, before: mi.UInt32 | None) -> tuple[mi.Bool, mi.Float, mi.UInt32]:
    """:func:`intersect_planes` as a loop over the device arrays, each entry's kind under a per-lane ``if``."""
    k = dr.zeros(mi.UInt32, dr.width(d))
    best = mi.Float(t_max)
    idx = dr.zeros(mi.UInt32, dr.width(d))
    found = dr.full(mi.Bool, False, dr.width(d))
    while active & (k < ps.count):
        e = gathered(ps, k, active)
        if dr.hint(ps.spheres > 0, mode="scalar"):
            ok = dr.zeros(mi.Bool, dr.width(d))
            t = mi.Float(best)
            if e.kind == PLANE:
                ok, t = _entry_t(e, PLANE, o, d, t_min, best, active)
            if e.kind == PLACED_PLANE:
                ok, t = _entry_t(e, PLACED_PLANE, o, d, t_min, best, active)
            if (e.kind == SPHERE) | (e.kind == WORLD_SPHERE):
                ok, t = _entry_t(e, SPHERE, o, d, t_min, best, active)
        else:
            ok, t = _entry_t(e, PLANE, o, d, t_min, best, active)
        if dr.hint(before is not None, mode="scalar"):
            ok &= e.order < before
        best = dr.select(ok, t, best)
        idx = dr.select(ok, k, idx)
        found |= ok
        k += 1
    return found, best, idx


def _normalize(v: mi.Vector3f) -> mi.Vector3f:
    length = dr.sqrt(_dot(v.x, v.y, v.z, v))
    return mi.Vector3f(v.x / length, v.y / length, v.z / length)


def _normal(e: Entry, kind: int, o: mi.Point3f, d: mi.Vector3f, t: mi.Float) -> mi.Vector3f:
    """The shading normal of an entry of kind ``kind`` (Python) at ``o + t d``: a plane's ``n/|n|``; a plane
    inside a ``Transform`` ``normalize(Aᵀ n)``; a sphere ``normalize(o' + t d' − c)``, mapped by ``Aᵀ`` and
    normalised again inside a ``Transform`` (the binary maps normals by ``(M₃⁻¹)ᵀ``)."""
    if kind == PLANE:
        return mi.Vector3f(e.n[0] * e.inv_len, e.n[1] * e.inv_len, e.n[2] * e.inv_len)
    if kind == PLACED_PLANE:
        n_obj = mi.Vector3f(*e.n)
    else:
        o_obj, d_obj = _object_ray(e, o, d)
        n_obj = _normalize((o_obj + d_obj * t) - mi.Vector3f(*e.centre))
        if kind == WORLD_SPHERE:
            return n_obj
    b = e.inv3
    return _normalize(mi.Vector3f(*[(b[i] * n_obj.x + b[3 + i] * n_obj.y) + b[6 + i] * n_obj.z for i in range(3)]))


def plane_normal(ps: PlaneSet, idx: mi.UInt32, active: mi.Bool, o: mi.Point3f, d: mi.Vector3f,
                 t: mi.Float) -> mi.Vector3f:
    """The shading normal of entry ``idx`` at the hit ``o + t d`` (:func:`_normal`; never flipped toward the
    viewer), on the lanes ``active``."""
    if ps.entries is not None:
        n = dr.zeros(mi.Vector3f, dr.width(d))
        for k, e in enumerate(ps.entries):
            n_k = _normal(e, e.kind, o, d, t)
            if e.world is not None:
                n_k = dr.select(e.world, _normal(e, WORLD_SPHERE, o, d, t), n_k)
            n = dr.select(idx == k, n_k, n)
        return n
    e = gathered(ps, idx, active)
    n = _normal(e, PLANE, o, d, t)
    if ps.spheres > 0:
        n = dr.select(e.kind == PLACED_PLANE, _normal(e, PLACED_PLANE, o, d, t), n)
        n = dr.select(e.kind == SPHERE, _normal(e, SPHERE, o, d, t), n)
        n = dr.select(e.kind == WORLD_SPHERE, _normal(e, WORLD_SPHERE, o, d, t), n)
    return n


def plane_mirror_normal(ps: PlaneSet, idx: mi.UInt32, active: mi.Bool,
                        n: mi.Vector3f | None = None) -> mi.Vector3f:
    """The normal entry ``idx`` mirrors rays about (``plane_<id>_mirror_normal``, :mod:`.planes`); a sphere
    or a plane inside a ``Transform`` mirrors about its shading normal ``n``."""
    m = mi.Vector3f(dr.gather(mi.Float, ps.mx, idx, active), dr.gather(mi.Float, ps.my, idx, active),
                    dr.gather(mi.Float, ps.mz, idx, active))
    if ps.spheres > 0 and n is not None:
        m = dr.select(dr.gather(mi.UInt32, ps.objects.kind, idx, active) != PLANE, n, m)
    return m


def plane_bsdf(ps: PlaneSet, idx: mi.UInt32, active: mi.Bool) -> mi.BSDFPtr:
    """The BSDF of entry ``idx`` (null where ``active`` is false)."""
    return dr.gather(mi.BSDFPtr, ps.bsdf, idx, active)
