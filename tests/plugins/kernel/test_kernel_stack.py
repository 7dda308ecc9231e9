"""The pending-ray stack (plugins/kernel/stack.py, SPEC B.3's recursion as a loop): its size is part of the
compiled kernel. Dr.Jit 1.5 leaves an uninitialised ``dr.alloc_local``'s size out of the kernel hash, so without
the literal clamp in ``push`` a kernel traced for a 17-entry stack (``-bounces 2`` with 8 glossy samples) was
reused for a 19-entry one (``-bounces 4``) and wrote past its end: a segfault of the next render in the same
process (the wavefront test followed by the golden glossy image did it)."""

from __future__ import annotations

from typing import Any

import drjit as dr
import pytest


@dr.syntax
def _fill(st: tuple, count: Any) -> Any:
    """Push ``count`` rays with weights 0 .. count-1 on top of the camera ray, then pop and sum them all."""
    import mitsuba as mi

    from a5mi.plugins.kernel import stack

    top = mi.UInt32(1)
    i = mi.UInt32(0)
    while i < count:
        top = stack.push(st, top, mi.Bool(True), mi.Point3f(0), mi.Vector3f(0, 0, 1), mi.Color3f(mi.Float(i)),
                         mi.UInt32(0), mi.Float(1), mi.Float(0), mi.UInt32(0))
        i += 1
    total = mi.Float(0)
    while top > 0:
        top -= 1
        total += stack.pop(st, top).weight.x
    return total


def _kernel_hashes(size: int, pushes: int) -> tuple[list[str], float]:
    """Hashes of the kernel that pushes ``pushes`` rays on a ``size``-entry stack and sums the pushed weights."""
    import drjit as dr
    import mitsuba as mi

    from a5mi.plugins.kernel import stack

    n = 40
    o, d = dr.zeros(mi.Point3f, n), dr.zeros(mi.Vector3f, n)
    st = stack.create(size, n, o, d, dr.opaque(mi.UInt32, 4))

    with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
        dr.kernel_history_clear()
        total = _fill(st, dr.opaque(mi.UInt32, pushes))
        dr.eval(total)
        hashes = [str(k["hash"]) for k in dr.kernel_history() if k.get("type") == dr.KernelType.JIT]
    return hashes, float(dr.sum(total).array[0]) if hasattr(dr.sum(total), "array") else float(dr.sum(total))


def test_stack_size_is_part_of_the_kernel(variant: str) -> None:
    small, total_small = _kernel_hashes(17, 16)
    large, total_large = _kernel_hashes(19, 18)
    assert small and large
    assert set(small).isdisjoint(large), "a 17-entry stack's kernel would be reused for 19 entries"
    # the camera ray (weight 1) and the pushed weights 0 .. pushes-1, 40 lanes
    assert total_small == pytest.approx(40 * (1 + sum(range(16))))
    assert total_large == pytest.approx(40 * (1 + sum(range(18))))
