"""The sample solution's float32 vector operations (vecmath) that the parser and the camera share (SPEC B.2).

A leaf module (numpy only): :mod:`a5mi.converters` checks a camera with :func:`camera_basis` in the precision
the renderer uses (``direction 1e-40 1e-40 -1e-40`` is zero in float32, ``1e20`` components overflow
``x·x``), :mod:`a5mi.plugins.sensors.camera` builds its rays from it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def _normalize32(a: np.ndarray) -> np.ndarray:
    """vecmath ``normalized()`` in float32: a / sqrtf((x·x + y·y) + z·z)."""
    x, y, z = (np.float32(c) for c in a)
    norm = np.sqrt(np.float32(np.float32(x * x + y * y) + z * z))
    return np.array([x / norm, y / norm, z / norm], dtype=np.float32)


def _cross32(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """vecmath ``cross`` in float32: (a.y b.z − a.z b.y, a.z b.x − a.x b.z, a.x b.y − a.y b.x)."""
    a = np.asarray(a, dtype=np.float32)
    b = np.asarray(b, dtype=np.float32)
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]], dtype=np.float32)


def camera_basis(direction: Sequence[float], up: Sequence[float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(w, u, v) of SPEC B.2 in float32 as the binary computes them (read with gdb from its camera):
    w = normalize(direction), u = normalize(direction × up), v = normalize(u × direction), the cross products
    taken with the direction *as written* (equal to SPEC's w × up and u × w up to rounding; the last bits of v
    decide grazing mirror re-hits of planes, docs/FIDELITY.md).

    ``direction`` and ``up`` need not be unit or perpendicular. Raises ``ValueError`` when they are
    parallel (or either is zero), where the binary would produce NaN rays.
    """
    d = np.asarray([float(c) for c in direction], dtype=np.float32)
    upv = np.asarray([float(c) for c in up], dtype=np.float32)
    if d.shape != (3,) or upv.shape != (3,):
        raise ValueError("camera direction and up must have 3 components")
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        w = _normalize32(d)
        u = _normalize32(_cross32(d, upv))
        v = _normalize32(_cross32(u, d))
    if not all(np.all(np.isfinite(a)) and np.any(a != 0) for a in (w, u, v)):
        raise ValueError(f"camera direction {d.tolist()} and up {upv.tolist()} do not define a basis")
    return w, u, v


__all__ = ["camera_basis"]
