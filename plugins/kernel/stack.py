"""The pending rays of a depth-first ray tree, one stack per lane (SPEC B.3's recursion as a loop).

SPEC B.3 recurses into a mirror and a refracted child; a kernel walks that tree depth-first with per-lane
``dr.alloc_local`` arrays instead, so its size does not grow with the bounce budget (a Python recursion unrolled
into the trace grows as 2^bounces). Each entry is a ray still to trace: origin, direction, path weight, bounces
left, index of the medium it travels in, its tmin, and the rule-table row of the mesh face it leaves (0: none;
plugins/emulation/octree_rule.py), plus, with dispersion (docs/EXTENSIONS.md E.10), a "weighted by w(λ) already" flag.
"""

from __future__ import annotations

from typing import NamedTuple

import drjit as dr
import mitsuba as mi


class PendingRay(NamedTuple):
    """A popped entry (module docstring); ``weighted`` is None without the dispersion flag."""

    o: mi.Point3f
    d: mi.Vector3f
    weight: mi.Color3f
    bounces: mi.UInt32
    n_medium: mi.Float
    t_min: mi.Float
    origin: mi.UInt32
    weighted: mi.UInt32 | None


#: A stack: one ``dr.alloc_local`` array per field of :class:`PendingRay` (the flag's only with dispersion). A
#: plain tuple, carried as loop state by Dr.Jit's symbolic loops (a write inside a loop must be traced through
#: it; a NamedTuple holding the tuple and a flag broke that: outputs referred to a discarded recording).
RayStack = tuple

def create(size: int, width: int, o: mi.Point3f, d: mi.Vector3f, max_depth: mi.UInt32,
           weighted: bool = False) -> RayStack:
    """``size`` entries per lane; entry 0 holds the camera ray ``(o, d)`` with weight 1, ``max_depth`` bounces,
    medium index 1, tmin 0, no origin face (and flag 0 when ``weighted``)."""
    types = (mi.Point3f, mi.Vector3f, mi.Color3f, mi.UInt32, mi.Float, mi.Float, mi.UInt32)
    # (the flag is UInt32 0/1: a Bool local array miscompiles on LLVM)
    arrays = tuple(dr.alloc_local(t, size) for t in (*types, *((mi.UInt32,) if weighted else ())))
    zero_u = dr.zeros(mi.UInt32, width)
    first = (mi.Point3f(o), mi.Vector3f(d), dr.full(mi.Color3f, 1.0, width), zero_u + max_depth,
             dr.full(mi.Float, 1.0, width), dr.zeros(mi.Float, width), zero_u)
    for array, value in zip(arrays, (*first, *((dr.zeros(mi.UInt32, width),) if weighted else ())), strict=True):
        array[zero_u] = value
    return arrays


def pop(stack: RayStack, top: mi.UInt32) -> PendingRay:
    """Entry ``top`` of every lane (the caller has decremented ``top``)."""
    values = [array[top] for array in stack]
    return PendingRay(*values[:7], values[7] if len(stack) > 7 else None)


def push(stack: RayStack, top: mi.UInt32, mask: mi.Bool, o: mi.Point3f, d: mi.Vector3f, w: mi.Color3f,
         bounces: mi.UInt32, n_medium: mi.Float, t_min: mi.Float, origin: mi.UInt32,
         weighted: mi.UInt32 | None = None) -> mi.UInt32:
    """Push a child ray onto the stacks of the lanes in ``mask`` (``weighted``: its flag, with dispersion);
    returns the new stack pointer."""
    values = (o, d, w, bounces, n_medium, t_min, origin, *((weighted,) if len(stack) > 7 else ()))
    # The size as a literal in the kernel: Dr.Jit 1.5 leaves an uninitialised ``alloc_local``'s size out of the
    # kernel hash, so a kernel built for a smaller stack (e.g. -bounces 2) was reused for a larger one (-bounces
    # 4) and wrote past its end (a segfault). The clamp never binds at the sizes of ``features.stack_size``.
    slot = dr.minimum(top, mi.UInt32(len(stack[0]) - 1))
    for array, value in zip(stack, values, strict=True):
        array.write(value, slot, mask)
    return top + dr.select(mask, 1, 0)
