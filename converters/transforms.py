"""4x4 transforms of SPEC A.6, in float64 numpy, and their composition rules.

Matrices act on column vectors (``p' = M p``). Composition inside a ``Transform`` block starts from the
identity and **post-multiplies** each keyword, ``M = M * T``, so the last keyword listed is applied to the
object first: ``Translate 1 0 0`` then ``Scale 2 2 2`` takes (1,0,0) to (3,0,0). ``Matrix4f { 16 numbers }``
is the exception: the numbers are read **column by column** and the matrix is **pre-multiplied**,
``M = G * M``. Rotations are vecmath's right-handed ones, angles in degrees:

* ``XRotate a``: ``[[1,0,0],[0,c,-s],[0,s,c]]``; ``YRotate a``: ``[[c,0,s],[0,1,0],[-s,0,c]]``;
  ``ZRotate a``: ``[[c,-s,0],[s,c,0],[0,0,1]]`` with ``c = cos a``, ``s = sin a``;
* ``Rotate { axis a }``: Rodrigues, ``R = c I + s [k]x + (1-c) k kᵀ`` with ``k = axis/|axis|``.

Normals map by ``(M⁻¹)ᵀ`` (upper 3x3), SPEC B.3.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Final

import numpy as np

from a5mi.converters.model import Matrix4


def as_array(m: Matrix4 | np.ndarray) -> np.ndarray:
    """A model matrix (row-major tuples) as a float64 (4, 4) array."""
    return np.array(m, dtype=np.float64).reshape(4, 4)


def as_tuple(m: np.ndarray) -> Matrix4:
    """A (4, 4) array as the model's hashable row-major tuple form."""
    return tuple((float(r[0]), float(r[1]), float(r[2]), float(r[3])) for r in np.asarray(m, dtype=np.float64))


def translate(x: float, y: float, z: float) -> np.ndarray:
    """``Translate x y z``."""
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def scale(x: float, y: float, z: float) -> np.ndarray:
    """``Scale x y z``: ``diag(x, y, z, 1)``."""
    return np.diag([x, y, z, 1.0])


def uniform_scale(s: float) -> np.ndarray:
    """``UniformScale s``: ``diag(s, s, s, 1)``."""
    return scale(s, s, s)


def _rot3(r: np.ndarray) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = r
    return m


def x_rotate(degrees: float) -> np.ndarray:
    """``XRotate a`` (degrees, right-handed about +x)."""
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    return _rot3(np.array([[1, 0, 0], [0, c, -s], [0, s, c]]))


def y_rotate(degrees: float) -> np.ndarray:
    """``YRotate a`` (degrees, right-handed about +y)."""
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    return _rot3(np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]))


def z_rotate(degrees: float) -> np.ndarray:
    """``ZRotate a`` (degrees, right-handed about +z)."""
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    return _rot3(np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]))


def rotate(axis: Sequence[float], degrees: float) -> np.ndarray:
    """``Rotate { axis angle }``: ``R = c I + s [k]x + (1-c) k kᵀ``, ``k = axis/|axis|`` (vecmath)."""
    k = np.asarray(axis, dtype=np.float64)
    norm = float(np.linalg.norm(k))
    if norm == 0.0:
        raise ValueError("rotation axis has zero length")
    k = k / norm
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return _rot3(c * np.eye(3) + s * cross + (1 - c) * np.outer(k, k))


def matrix4f_columns(values: Sequence[float]) -> np.ndarray:
    """``Matrix4f { 16 numbers }``: the numbers fill the matrix column by column (first 4 = column 0)."""
    if len(values) != 16:
        raise ValueError(f"Matrix4f needs 16 numbers, got {len(values)}")
    return np.asarray(values, dtype=np.float64).reshape(4, 4).T.copy()


#: ``T(kind, args)`` of each transform keyword of A.6 (``Matrix4f``: the matrix ``G`` it pre-multiplies).
KEYWORDS: Final[dict[str, Callable[[Sequence[float]], np.ndarray]]] = {
    "Translate": lambda a: translate(a[0], a[1], a[2]),
    "Scale": lambda a: scale(a[0], a[1], a[2]),
    "UniformScale": lambda a: uniform_scale(a[0]),
    "XRotate": lambda a: x_rotate(a[0]),
    "YRotate": lambda a: y_rotate(a[0]),
    "ZRotate": lambda a: z_rotate(a[0]),
    "Rotate": lambda a: rotate(a[:3], a[3]),
    "Matrix4f": matrix4f_columns,
}


def apply_keyword(m: np.ndarray, kind: str, args: Sequence[float]) -> np.ndarray:
    """One step of A.6 composition: ``M * T(kind, args)``, except ``Matrix4f``: ``G * M``."""
    if kind not in KEYWORDS:
        raise ValueError(f"unknown transform keyword {kind!r}")
    t = KEYWORDS[kind](args)
    return t @ m if kind == "Matrix4f" else m @ t


def compose(ops: Sequence[tuple[str, Sequence[float]]]) -> np.ndarray:
    """The matrix of a ``Transform`` block's keywords, in file order (A.6)."""
    m = np.eye(4)
    for kind, args in ops:
        m = apply_keyword(m, kind, args)
    return m


def transform_points(m: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``M p`` for points (w = 1); ``p`` has shape (..., 3)."""
    p = np.asarray(p, dtype=np.float64)
    return p @ m[:3, :3].T + m[:3, 3]


def normal_matrix(m: np.ndarray) -> np.ndarray:
    """``(A⁻¹)ᵀ``, the 3x3 that maps normals (SPEC B.3); not renormalising is the caller's choice."""
    return np.linalg.inv(m[:3, :3]).T


def look_at(origin: np.ndarray, target: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Mitsuba's ``Transform4f.look_at``: columns ``(left, up', dir, origin)`` with ``dir = normalize(target -
    origin)``, ``left = normalize(up × dir)``, ``up' = dir × left`` (camera looks along +z)."""
    d = np.asarray(target, dtype=np.float64) - np.asarray(origin, dtype=np.float64)
    d /= np.linalg.norm(d)
    left = np.cross(np.asarray(up, dtype=np.float64), d)
    left /= np.linalg.norm(left)
    new_up = np.cross(d, left)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, new_up, d, origin
    return m


def similarity_scale(m: np.ndarray, rtol: float = 1e-9) -> float | None:
    """``s`` when the upper 3x3 is ``s`` times an orthogonal matrix (a similarity), else None."""
    a = m[:3, :3]
    gram = a.T @ a
    s2 = float(np.trace(gram)) / 3.0
    if s2 <= 0.0 or not np.allclose(gram, s2 * np.eye(3), rtol=0.0, atol=rtol * s2):
        return None
    return math.sqrt(s2)


# ------------------------------------------------------------------------------------------- the binary's float32
def _mul32(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """vecmath ``Matrix4f * Matrix4f`` in float32: ``p_ik = (((0 + x_i0 y_0k) + x_i1 y_1k) + x_i2 y_2k)
    + x_i3 y_3k``."""
    out = np.zeros((4, 4), dtype=np.float32)
    for i in range(4):
        for k in range(4):
            acc = np.float32(0.0)
            for j in range(4):
                acc = np.float32(acc + np.float32(x[i, j] * y[j, k]))
            out[i, k] = acc
    return out


def _radians32(degrees: float) -> np.float32:
    """The binary's ``(float)((double)(float)a * π / 180.0)``."""
    return np.float32(float(np.float32(degrees)) * math.pi / 180.0)


def _cos_sin32(degrees: float) -> tuple[np.float32, np.float32]:
    r = float(_radians32(degrees))
    return np.float32(math.cos(r)), np.float32(math.sin(r))


def _keyword32(kind: str, a: Sequence[float]) -> np.ndarray:
    f = [np.float32(x) for x in a]
    m = np.eye(4, dtype=np.float32)
    if kind == "Translate":
        m[:3, 3] = f[:3]
    elif kind == "Scale":
        m[0, 0], m[1, 1], m[2, 2] = f[:3]
    elif kind == "UniformScale":
        m[0, 0] = m[1, 1] = m[2, 2] = f[0]
    elif kind in ("XRotate", "YRotate", "ZRotate"):
        c, s = _cos_sin32(a[0])
        i, j = {"XRotate": (1, 2), "YRotate": (2, 0), "ZRotate": (0, 1)}[kind]
        m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    elif kind == "Rotate":
        x, y, z = f[:3]
        norm = np.float32(math.sqrt(float(np.float32(np.float32(x * x + y * y) + z * z))))
        x, y, z = x / norm, y / norm, z / norm
        c, s = _cos_sin32(a[3])
        t = np.float32(1.0) - c
        m[:3, :3] = [[x * x * t + c, y * x * t - z * s, z * x * t + y * s],
                     [x * y * t + z * s, y * y * t + c, z * y * t - x * s],
                     [x * z * t - y * s, y * z * t + x * s, z * z * t + c]]
    elif kind == "Matrix4f":
        m = np.asarray(f, dtype=np.float32).reshape(4, 4).T.copy()
    else:
        raise ValueError(f"unknown transform keyword {kind!r}")
    return m


def binary_matrix(ops: Sequence[tuple[str, Sequence[float]]]) -> np.ndarray:
    """A ``Transform`` block's matrix as the sample solution builds it (SPEC A.6; read from the binary and
    vecmath): every keyword's matrix in float32 (angles ``(float)((double)a π / 180)``, ``cosf``/``sinf``;
    ``Rotate`` with vecmath's ``rotation(axis, radians)``), composed by float32 products in the A.6 order
    (``M = M T``, ``Matrix4f``: ``M = G M``). A float32 (4, 4) array."""
    m = np.eye(4, dtype=np.float32)
    for kind, args in ops:
        t = _keyword32(kind, args)
        m = _mul32(t, m) if kind == "Matrix4f" else _mul32(m, t)
    return m


def binary_chain(levels: Sequence[Sequence[tuple[str, Sequence[float]]]]) -> np.ndarray | None:
    """The object-to-world matrix of a primitive inside the ``Transform`` blocks ``levels`` (outermost
    first), each as :func:`binary_matrix`, multiplied in float32 (the binary maps a ray through each level
    in turn; one product stands for them: exact for one level). None outside any ``Transform``."""
    if not levels:
        return None
    m = binary_matrix(levels[0])
    for ops in levels[1:]:
        m = _mul32(m, binary_matrix(ops))
    return m.astype(np.float64)
