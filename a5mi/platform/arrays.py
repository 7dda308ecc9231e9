"""numpy arrays handed to Dr.Jit (a leaf module: numpy only).

Dr.Jit maps numpy memory zero-copy and bakes the pointer's alignment into the kernel IR (``align 64`` or
``align 4``), so the same kernel would hash differently, and recompile, depending on where numpy's
allocator put an array: every per-scene array that enters a reused kernel goes through
:func:`aligned_float32` (the driver's camera rays, the warm animated scene's geometry, the triangle rule's
table in plugins/emulation/triangle_rule.py) and :func:`aligned_uint32` (the octree node table,
plugins/emulation/octree_leaves.py).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt


def _aligned(a: npt.ArrayLike, dtype: type[np.generic], align: int) -> np.ndarray:
    src = np.asarray(a, dtype=dtype).ravel()
    raw = np.empty(src.nbytes + align, np.uint8)
    offset = (-raw.ctypes.data) % align
    out = raw[offset : offset + src.nbytes].view(dtype)
    out[:] = src
    return out


def aligned_float32(a: npt.ArrayLike, align: int = 64) -> npt.NDArray[np.float32]:
    """A float32 copy of ``a`` (flattened) whose data starts on an ``align``-byte boundary."""
    return _aligned(a, np.float32, align)


def aligned_uint32(a: npt.ArrayLike, align: int = 64) -> npt.NDArray[np.uint32]:
    """A uint32 copy of ``a`` (flattened) whose data starts on an ``align``-byte boundary."""
    return _aligned(a, np.uint32, align)


__all__ = ["aligned_float32", "aligned_uint32"]
