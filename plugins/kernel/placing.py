"""docs/MISTAKES.md's normal-transform mistakes, ``normal_by_m`` and ``normal_not_normalised``, in ``a5_whitted``.

SPEC B.3 notes: a ``Transform`` (SPEC A.6, its accumulated placing matrix ``M``, upper 3x3) maps an object's unit
normal ``n_o`` by ``(M⁻¹)ᵀ`` and normalises it: ``n_w = normalize(M⁻ᵀ n_o)``. The two mistakes change that step:

* ``normal_by_m``: ``N = normalize(M n_o)``, and as ``n_o ∝ Mᵀ n_w``, ``N = normalize(M Mᵀ n_w)``; no change
  when ``M`` is a similarity (``M Mᵀ = s² I``);
* ``normal_not_normalised``: ``N = M⁻ᵀ n_o = n_w / |Mᵀ n_w|`` (``|M⁻ᵀ n_o| = 1 / |Mᵀ n_w|`` since ``|n_o| = 1``);
  no change when ``M`` is orthonormal (a rotation);
* both: ``N = M n_o = M Mᵀ n_w / |Mᵀ n_w|``.

So each is a function of ``n_w`` (the kernel's SPEC N) and the hit primitive's ``M``. The kernel already holds
``A = M⁻¹`` (the binary's world-to-object map, float32) of every placed primitive: the rule-table row of the mesh
face hit (``face_a5_inv0..2``, meshes and ``Triangle`` s, plugins/emulation/triangle_rule.py) and ``inv3`` of the
plane set's ``objects`` (spheres and planes inside a ``Transform``, plugins/emulation/planes.py). With
``C = adj(A) = det(A) M`` (columns ``a1×a2, a2×a0, a0×a1`` of A's rows ``a_i``) and ``u = Cᵀ n_w = det(A) Mᵀ n_w``:

    M⁻ᵀ n_o = n_w |det A| / |u|,      M n_o = C u / (|det A| |u|)

then normalised unless ``normal_not_normalised``. Where no ``A`` exists (world planes, whose normal as written
is kept for the mirror ray; primitives outside any ``Transform``; Mitsuba's own shapes) ``M = I``: both maps
return ``n_w`` unchanged.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

from a5mi.plugins.emulation.planes import PLANE, PlaneSet
from a5mi.plugins.emulation.triangle_rule import ROW_ATTRIBUTES, ROW_FLOATS, RuleTable

#: The mistakes of this module (docs/MISTAKES.md).
NORMAL_MISTAKES: tuple[str, ...] = ("normal_by_m", "normal_not_normalised")


def makes(mistakes: tuple[str, ...]) -> bool:
    """Whether ``mistakes`` (:attr:`.features.Features.mistakes`) has one of :data:`NORMAL_MISTAKES`."""
    return any(m in NORMAL_MISTAKES for m in mistakes)


def _inverse_rows(planes: PlaneSet, rules: RuleTable | None, on_plane: mi.Bool, plane: mi.UInt32, row: mi.UInt32,
                  hit: mi.Bool) -> list[mi.Vector3f]:
    """The rows of ``A = M⁻¹`` (upper 3x3) of the primitive hit; the identity where it has none."""
    rows = [mi.Vector3f(1, 0, 0), mi.Vector3f(0, 1, 0), mi.Vector3f(0, 0, 1)]
    if rules is not None:               # a rule mesh's face: A as the binary's triangle test holds it
        m = hit & ~on_plane & (row > 0)
        at = (dr.maximum(row, 1) - 1) * ROW_FLOATS
        for i in range(3):
            k = at + 3 * ROW_ATTRIBUTES.index(f"face_a5_inv{i}")
            got = mi.Vector3f(*[dr.gather(mi.Float, rules.rows, k + c, m) for c in range(3)])
            rows[i] = dr.select(m, got, rows[i])
    objects = planes.objects
    if planes.spheres > 0 and objects is not None:  # a sphere or a placed plane of the set: its Transform's A
        m = hit & on_plane
        m &= dr.gather(mi.UInt32, objects.kind, plane, m) != PLANE
        for i in range(3):
            got = mi.Vector3f(*[dr.gather(mi.Float, objects.inv3[3 * i + c], plane, m) for c in range(3)])
            rows[i] = dr.select(m, got, rows[i])
    return rows


def mistaken_normal(mistakes: tuple[str, ...], planes: PlaneSet, rules: RuleTable | None, on_plane: mi.Bool,
                    plane: mi.UInt32, row: mi.UInt32, n: mi.Vector3f, hit: mi.Bool) -> mi.Vector3f:
    """The student's N at a hit whose SPEC N is ``n`` (module docstring): ``M n_o`` with ``normal_by_m`` else
    ``M⁻ᵀ n_o``, normalised unless ``normal_not_normalised``; ``M`` from the hit's rule-table ``row`` or plane-set
    entry ``plane`` (``on_plane``); lanes without ``hit`` keep ``n``."""
    a0, a1, a2 = _inverse_rows(planes, rules, on_plane, plane, row, hit)
    c0, c1, c2 = dr.cross(a1, a2), dr.cross(a2, a0), dr.cross(a0, a1)     # columns of adj(A) = det(A) M
    det = dr.abs(dr.dot(a0, c0))
    u = mi.Vector3f(dr.dot(c0, n), dr.dot(c1, n), dr.dot(c2, n))          # det(A) Mᵀ n_w
    length = dr.norm(u)
    if "normal_by_m" in mistakes:
        v = (c0 * u.x + c1 * u.y + c2 * u.z) / (det * length)             # M n_o
    else:
        v = n * (det / length)                                            # M⁻ᵀ n_o
    if "normal_not_normalised" not in mistakes:
        v = dr.normalize(v)
    return dr.select(hit, v, n)
