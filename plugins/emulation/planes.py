"""Exact infinite planes for ``a5_whitted`` (SPEC A.6): intersected analytically inside the kernel.

Mitsuba 3 cannot register Python shapes, so an a5 ``Plane`` travels as three integrator parameters with a
common id (any string; the converter writes ``plane_NNN``)::

    plane_<id>_normal  vector  n, not normalised            (the plane is P·n = offset)
    plane_<id>_offset  float   offset
    plane_<id>_bsdf    bsdf    the plane's material (a nested BSDF object)
    plane_<id>_mirror_normal  vector  optional: the normal mirror rays reflect about (default n/|n|)

SPEC A.6: ``t = (offset - n·o) / (n·d)`` with the unnormalised n, in float32 in the binary's order
(``n·v = (n_x v_x + n_y v_y) + n_z v_z``); a plane is skipped only when ``n·d == 0`` exactly, and it is hit
when ``tmin < t < t_current``. The shading normal (the Lambert term) is ``n/|n|``, never flipped. The mirror
ray is ``d - 2 (d·m) m`` with ``m`` = ``plane_<id>_mirror_normal``, and the refraction (inside/outside test
``d·m > 0``, Snell, Schlick) uses ``m`` too: the a5 converter passes n as written for a plane outside any
Transform, because the binary mirrors and refracts with it (measured against a5soln: a mirror
``normal 0 2 0`` plane, 33.8 dB with the unit normal, a glass one 31.0 dB; both identical with n as
written), so the mirror ray is not a unit vector after such a plane; the binary's Transform normalises the
normals it maps, so transformed planes get ``n_w/|n_w|``. Plane data lives in device arrays (gathered by
index with an opaque count) and, for a set of at most :data:`UNROLL` entries, in per-entry kernel scalars
(:attr:`PlaneSet.entries`): plugins/emulation/plane_hits.py tests such a set unrolled, entry by entry, with
each entry's own kind's code, and a larger one in a loop that serves any number of entries.

**Spheres under a non-similarity transform** travel the same way (an exact analytic primitive of the same
index space, so that plane/sphere ties keep the scene order): ``plane_<id>_center`` point, ``plane_<id>_radius``
float, ``plane_<id>_to_world`` transform (the object-to-world ``M``) and ``plane_<id>_bsdf``. They are
intersected as the binary's ``Transform::intersect`` and ``Sphere::intersect`` do (SPEC A.6, B.3 notes; read
from the binary): the ray goes into object space unnormalised, ``o' = A o + T``, ``d' = A d`` (``A | T`` =
``M⁻¹`` rounded once to float32; vecmath sums ``((0 + a_0 v_0) + a_1 v_1) + a_2 v_2``, plus ``T`` for points),
then in float32 with ``q = o' − c``::

    a = (d'_x² + d'_y²) + d'_z²,   b = 2 (d'·q),   c = q·q − r²,   disc = b² − (4a) c      (miss if disc < 0)
    t₊ = (float)((double)(√disc − b) / (2.0 (double)a)),   t₋ = (float)((double)(−b − √disc) / (2.0 (double)a))
    t  = t₋ if t₋ > tmin else 10000;  if t₊ > tmin: t = t if t₋ >= tmin else t₊;  miss if tmin > t₊ and tmin > t₋

and the hit counts when ``t < t_current`` (strict: the earlier of two coincident spheres wins). The shading
normal is ``normalize(Aᵀ normalize(o' + t d' − c))`` (the binary maps it by ``(M₃⁻¹)ᵀ``); mirror and refracted
rays turn about it. Mitsuba's own sphere under such a ``to_world`` (an instance) misses or speckles: a
``Scale 1 1 0.01`` sphere under ``XRotate 60`` read 21.3 dB from a5soln at 100 x 100 that way.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any, NamedTuple

import drjit as dr
import mitsuba as mi
import numpy as np

_KEY = re.compile(r"^plane_(.+?)_(normal|offset|bsdf_uv|bsdf|mirror_normal|center|radius|to_world)$")


class Entry(NamedTuple):
    """One entry of the set as the tests read it: ``kind`` (a Python int when unrolled, else per lane), the
    plane's ``n`` and ``offset`` and ``inv_len`` (``1/|n|``), and for the other kinds ``a`` (``A``, 9 floats
    row by row), ``tr`` (``T``), ``centre``, ``radius``, ``inv3`` (the normal map, 9 floats); ``order`` (scene
    position) only in a set with :attr:`~.planes.PlaneSet.order`."""

    kind: int | mi.UInt32
    n: tuple[mi.Float, mi.Float, mi.Float]
    offset: mi.Float
    inv_len: mi.Float
    a: tuple[mi.Float, ...] = ()
    tr: tuple[mi.Float, ...] = ()
    centre: tuple[mi.Float, ...] = ()
    radius: mi.Float | None = None
    inv3: tuple[mi.Float, ...] = ()
    order: mi.UInt32 | None = None
    #: An unrolled sphere (kind :data:`SPHERE`): whether its matrix is the identity (its normal is not mapped), a
    #: kernel input, so that a keyframed sphere passing through the identity keeps its kernel
    world: mi.Bool | None = None


#: Entries of a set tested unrolled (:attr:`PlaneSet.entries`), at most: each adds its test to the kernel once
#: for the camera and mirror rays and once per light for the shadow rays; a larger set is walked in a loop.
UNROLL = 8


@dataclass
class PlaneSet:
    """The planes of an ``a5_whitted`` integrator as device arrays (length ``max(count, 1)``); with
    ``spheres`` > 0 also the arrays of the spheres and of the planes inside a ``Transform`` (module docstring; a
    sphere's plane normal is 0, so the plane test never hits it), :attr:`objects`."""

    nx: mi.Float
    ny: mi.Float
    nz: mi.Float
    offset: mi.Float
    inv_len: mi.Float
    mx: mi.Float
    my: mi.Float
    mz: mi.Float
    bsdf: mi.BSDFPtr
    count: mi.UInt32
    size: int
    spheres: int = 0
    #: With spheres or planes inside a ``Transform``: every entry's arrays as one :class:`Entry` (``kind`` per
    #: entry; the plane fields are the arrays above)
    objects: Entry | None = None
    #: ``plane_<id>_bsdf_uv`` (the sample solution's stale texture coordinates, docs/FIDELITY.md): per entry its
    #: scene position (``order``, the id's number), whether it has a textured BSDF and that BSDF (else its own);
    #: None when no entry has one
    order: mi.UInt32 | None = None
    textured: mi.Bool | None = None
    bsdf_uv: mi.BSDFPtr | None = None
    #: A set of at most :data:`UNROLL` entries: each entry's kind and numbers as kernel scalars (opaque
    #: one-element arrays), in scene order; None for a larger set
    entries: tuple[Entry, ...] | None = None


def _vec3(value: Any, key: str) -> tuple[float, float, float]:
    try:
        if isinstance(value, str):
            raise TypeError
        out = tuple(float(value[i]) for i in range(3))
        if len(value) != 3:
            raise TypeError
    except (TypeError, IndexError, ValueError):
        raise ValueError(f"a5_whitted: '{key}' must be a 3-vector, got {value!r}") from None
    return out  # type: ignore[return-value]


class Plane(NamedTuple):
    """One exact primitive of :func:`planes_from_props`: a plane (``normal``, ``offset``, ``mirror``) or, with
    ``sphere`` = ``(M as 16 numbers row by row, centre, radius)``, a non-similarity sphere (``normal`` and
    ``mirror`` zero)."""

    pid: str
    normal: tuple[float, float, float]
    offset: float
    bsdf: Any
    mirror: tuple[float, float, float]
    sphere: tuple[tuple[float, ...], tuple[float, float, float], float] | None = None
    #: A plane inside a ``Transform``: its ``M`` (16 numbers row by row); ``normal``, ``offset`` are then the
    #: object-space plane as written, intersected in object space as the binary does.
    to_world: tuple[float, ...] | None = None
    #: ``plane_<id>_bsdf_uv``: the material's textured BSDF, looked up at a mesh's stale uv (docs/FIDELITY.md)
    bsdf_uv: Any = None


def _order(pid: str) -> tuple[int, int | str]:
    """Scene order of the ids (the converter writes the object index, ``NNN``); other ids after, by name."""
    return (0, int(pid)) if pid.isdigit() else (1, pid)


def _matrix(value: Any, key: str) -> tuple[float, ...]:
    try:
        m = np.array(value.matrix if hasattr(value, "matrix") else value, dtype=np.float64).reshape(4, 4)
    except (TypeError, ValueError):
        raise ValueError(f"a5_whitted: '{key}' must be a 4x4 transform, got {value!r}") from None
    if not np.all(np.isfinite(m)) or np.linalg.det(m[:3, :3]) == 0.0:
        raise ValueError(f"a5_whitted: '{key}' must be finite and invertible")
    return tuple(float(x) for x in m.ravel())


def _sphere(pid: str, parts: dict[str, Any]) -> tuple[tuple[float, ...], tuple[float, float, float], float]:
    missing = [k for k in ("center", "radius") if k not in parts]
    if missing:
        raise ValueError(f"a5_whitted: sphere '{pid}' lacks 'plane_{pid}_{missing[0]}'")
    c = _vec3(parts["center"], f"plane_{pid}_center")
    r = parts["radius"]
    if isinstance(r, bool) or not isinstance(r, (int, float)) or not math.isfinite(r) or r <= 0.0 or \
            not all(math.isfinite(x) for x in c):
        raise ValueError(f"a5_whitted: sphere '{pid}' needs a finite centre and a radius > 0")
    return _matrix(parts["to_world"], f"plane_{pid}_to_world"), c, float(r)


def planes_from_props(props: mi.Properties) -> list[Plane]:
    """The :class:`Plane` s of the ``plane_<id>_*`` parameters, in scene order of their ids.

    Every plane needs ``normal``, ``offset``, ``bsdf``, every sphere ``to_world``, ``center``, ``radius``,
    ``bsdf``; a zero or non-finite normal, a non-finite offset, a singular ``to_world`` or a radius <= 0 is
    a ``ValueError`` naming the parameter."""
    found: dict[str, dict[str, Any]] = {}
    for key in props.keys():
        m = _KEY.match(key)
        if m:
            found.setdefault(m.group(1), {})[m.group(2)] = props.get(key)
    out = []
    for pid in sorted(found, key=_order):
        parts = found[pid]
        bsdf = parts.get("bsdf")
        if "to_world" in parts and "normal" not in parts:
            if not isinstance(bsdf, mi.BSDF):
                raise ValueError(f"a5_whitted: 'plane_{pid}_bsdf' must be a BSDF")
            out.append(Plane(pid, (0.0, 0.0, 0.0), 0.0, bsdf, (0.0, 0.0, 0.0), _sphere(pid, parts),
                             bsdf_uv=_bsdf_uv(pid, parts)))
            continue
        missing = [k for k in ("normal", "offset", "bsdf") if k not in parts]
        if missing:
            raise ValueError(f"a5_whitted: plane '{pid}' lacks 'plane_{pid}_{missing[0]}'")
        n = _vec3(parts["normal"], f"plane_{pid}_normal")
        if not all(math.isfinite(c) for c in n) or not any(n):
            raise ValueError(f"a5_whitted: 'plane_{pid}_normal' must be finite and non-zero, got {n!r}")
        off = parts["offset"]
        if isinstance(off, bool) or not isinstance(off, (int, float)) or not math.isfinite(off):
            raise ValueError(f"a5_whitted: 'plane_{pid}_offset' must be a finite number, got {off!r}")
        if not isinstance(bsdf, mi.BSDF):
            raise ValueError(f"a5_whitted: 'plane_{pid}_bsdf' must be a BSDF, got {type(bsdf).__name__}")
        length = math.sqrt(sum(c * c for c in n))
        mirror = _vec3(parts["mirror_normal"], f"plane_{pid}_mirror_normal") if "mirror_normal" in parts else \
            tuple(c / length for c in n)
        placed = _matrix(parts["to_world"], f"plane_{pid}_to_world") if "to_world" in parts else None
        out.append(Plane(pid, n, float(off), bsdf, mirror, None, placed,  # type: ignore[arg-type]
                         _bsdf_uv(pid, parts)))
    return out


def _bsdf_uv(pid: str, parts: dict[str, Any]) -> Any:
    bsdf = parts.get("bsdf_uv")
    if bsdf is not None and not isinstance(bsdf, mi.BSDF):
        raise ValueError(f"a5_whitted: 'plane_{pid}_bsdf_uv' must be a BSDF, got {type(bsdf).__name__}")
    return bsdf


#: The 16 numbers of the identity: a sphere outside any ``Transform`` (its normal is not mapped).
IDENTITY = tuple(float(x) for x in np.eye(4).ravel())
#: Entry kinds (:attr:`PlaneSet.kind`): a world-space plane, a sphere inside a ``Transform``, a sphere outside
#: any, a plane inside a ``Transform`` (object space).
PLANE, SPHERE, WORLD_SPHERE, PLACED_PLANE = 0, 1, 2, 3


def _det3(m00: Any, m01: Any, m02: Any, m10: Any, m11: Any, m12: Any, m20: Any, m21: Any, m22: Any) -> Any:
    return (m00 * (m11 * m22 - m12 * m21) - m01 * (m10 * m22 - m12 * m20)) + m02 * (m10 * m21 - m11 * m20)


def inverse32(m: np.ndarray) -> np.ndarray:
    """vecmath's ``Matrix4f::inverse`` of ``m`` rounded to float32, in float32: the cofactors as 3x3
    determinants ``m00 (m11 m22 − m12 m21) − m01 (m10 m22 − m12 m20) + m02 (m10 m21 − m11 m20)``, the
    determinant ``m00 c00 + m01 c01 + m02 c02 + m03 c03`` left to right, each cofactor times ``1/det``."""
    e = m.astype(np.float32)
    g = [[e[i, j] for j in range(4)] for i in range(4)]

    def cof(i: int, j: int) -> np.float32:
        rows = [r for r in range(4) if r != i]
        cols = [c for c in range(4) if c != j]
        # vecmath's cyclic argument order: rows i+1.., columns j+1.. (as Matrix4f.cpp writes them out)
        rows = [(i + k) % 4 for k in (1, 2, 3)]
        cols = [(j + k) % 4 for k in (1, 2, 3)]
        sign = np.float32(1.0 if (i + j) % 2 == 0 else -1.0)
        return sign * _det3(*[g[r][c] for r in rows for c in cols])

    c = [[cof(i, j) for j in range(4)] for i in range(4)]
    det = ((g[0][0] * c[0][0] + g[0][1] * c[0][1]) + g[0][2] * c[0][2]) + g[0][3] * c[0][3]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # det 0 in float32: inf/NaN, as the binary
        r = np.float32(1.0) / det
        return np.array([[c[j][i] * r for j in range(4)] for i in range(4)], dtype=np.float32)


def inverse33(m: np.ndarray) -> np.ndarray:
    """vecmath's ``Matrix3f::inverse`` of ``m`` rounded to float32, in float32 (the normal map of the binary's
    ``Transform``: cofactors ``p s − q r``, determinant ``m00 c00 + m01 c01 + m02 c02``, times ``1/det``)."""
    e = m.astype(np.float32)

    def det2(p: Any, q: Any, r: Any, t: Any) -> Any:
        return p * t - q * r

    c = [[det2(e[1, 1], e[1, 2], e[2, 1], e[2, 2]), -det2(e[1, 0], e[1, 2], e[2, 0], e[2, 2]),
          det2(e[1, 0], e[1, 1], e[2, 0], e[2, 1])],
         [-det2(e[0, 1], e[0, 2], e[2, 1], e[2, 2]), det2(e[0, 0], e[0, 2], e[2, 0], e[2, 2]),
          -det2(e[0, 0], e[0, 1], e[2, 0], e[2, 1])],
         [det2(e[0, 1], e[0, 2], e[1, 1], e[1, 2]), -det2(e[0, 0], e[0, 2], e[1, 0], e[1, 2]),
          det2(e[0, 0], e[0, 1], e[1, 0], e[1, 1])]]
    det = (e[0, 0] * c[0][0] + e[0, 1] * c[0][1]) + e[0, 2] * c[0][2]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # det 0 in float32: inf/NaN, as the binary
        r = np.float32(1.0) / det
        return np.array([[c[j][i] * r for j in range(3)] for i in range(3)], dtype=np.float32)


def plane_set(planes: list[Plane]) -> PlaneSet:
    """Device arrays of ``planes`` (as from :func:`planes_from_props`); a dummy entry when there are none."""
    if not planes:
        z = mi.Float([0.0])
        return PlaneSet(z, z, z, z, z, z, z, z, dr.zeros(mi.BSDFPtr, 1), dr.opaque(mi.UInt32, 0), 0, entries=())
    cols = list(zip(*[p[1] for p in planes], strict=True))
    inv = [0.0 if p.sphere is not None else 1.0 / math.sqrt(sum(c * c for c in p[1])) for p in planes]
    ptrs = mi.BSDFPtr([p[3] for p in planes])
    mirror = list(zip(*[p[4] for p in planes], strict=True))
    arrays = [mi.Float(c) for c in cols] + [mi.Float([p[2] for p in planes]), mi.Float(inv)] + \
        [mi.Float(c) for c in mirror]
    dr.make_opaque(ptrs, *arrays)  # literals of a one-plane scene would bake its values into the kernel
    out = PlaneSet(*arrays, ptrs, dr.opaque(mi.UInt32, len(planes)), len(planes))
    if any(p.sphere is not None or p.to_world is not None for p in planes):
        rows = np.zeros((len(planes), 25), dtype=np.float32)
        kinds = []
        for k, p in enumerate(planes):
            m = p.sphere[0] if p.sphere is not None else p.to_world
            if m is not None:
                inverse = inverse32(np.array(m, dtype=np.float64).reshape(4, 4))
                rows[k, :9], rows[k, 9:12] = inverse[:3, :3].ravel(), inverse[:3, 3]
                rows[k, 16:] = inverse33(np.array(m, dtype=np.float64).reshape(4, 4)[:3, :3]).ravel()
            if p.sphere is not None:
                rows[k, 12:15], rows[k, 15] = p.sphere[1], p.sphere[2]
            kinds.append(PLANE if m is None else PLACED_PLANE if p.sphere is None else
                         SPHERE if m != IDENTITY else WORLD_SPHERE)
        sphere_arrays = [mi.Float(rows[:, j].tolist()) for j in range(25)]
        kind = mi.UInt32(kinds)
        dr.make_opaque(kind, *sphere_arrays)
        out.spheres = sum(k != PLANE for k in kinds)
        out.objects = Entry(kind, (out.nx, out.ny, out.nz), out.offset, out.inv_len, tuple(sphere_arrays[:9]),
                            tuple(sphere_arrays[9:12]), tuple(sphere_arrays[12:15]), sphere_arrays[15],
                            tuple(sphere_arrays[16:]))
    if any(p.bsdf_uv is not None for p in planes):
        out.order = mi.UInt32([_order(p.pid)[1] if _order(p.pid)[0] == 0 else 0xFFFFFFFF for p in planes])
        out.textured = mi.Bool([p.bsdf_uv is not None for p in planes])
        out.bsdf_uv = mi.BSDFPtr([p.bsdf if p.bsdf_uv is None else p.bsdf_uv for p in planes])
        dr.make_opaque(out.order, out.textured, out.bsdf_uv)
    if len(planes) <= UNROLL:
        out.entries = tuple(_entry(out, k) for k in range(len(planes)))
    return out


def _entry(ps: PlaneSet, k: int) -> Entry:
    """Entry ``k`` of the device arrays of ``ps`` as kernel scalars: one-element opaque copies (a literal would
    be baked into the kernel, which then could not serve another scene of the same kinds); both sphere kinds
    are :data:`SPHERE`, told apart by :attr:`Entry.world`."""
    def one(arrays: tuple[Any, ...]) -> tuple[Any, ...]:
        out = tuple(type(x)([x[k]]) for x in arrays)
        dr.make_opaque(*out)
        return out

    n, (offset, inv_len) = one((ps.nx, ps.ny, ps.nz)), one((ps.offset, ps.inv_len))
    order = None if ps.order is None else one((ps.order,))[0]
    if ps.spheres == 0:
        return Entry(PLANE, n, offset, inv_len, order=order)
    e = ps.objects
    kind = int(e.kind[k])
    world = None if kind not in (SPHERE, WORLD_SPHERE) else mi.Bool([kind == WORLD_SPHERE])
    if world is not None:
        dr.make_opaque(world)
    return Entry(SPHERE if world is not None else kind, n, offset, inv_len, one(e.a), one(e.tr), one(e.centre),
                 one((e.radius,))[0], one(e.inv3), order, world)


def replace_planes(integrator: Any, moved: dict[str, Any]) -> None:
    """Give the planes ``moved`` (id -> (normal, offset, mirror normal); a sphere or a plane inside a
    ``Transform``: id -> its new 4x4 ``to_world``) of an ``a5_whitted`` integrator new values, keeping their
    BSDFs (keyframed Transforms, docs/EXTENSIONS.md E.11). The device arrays keep their length and are opaque
    (a one-plane array would be a literal of the kernel), so the compiled kernel is reused."""
    planes = []
    for p in integrator.planes:
        if p.pid in moved and p.sphere is not None:
            p = p._replace(sphere=(_matrix(moved[p.pid], f"plane_{p.pid}_to_world"), *p.sphere[1:]))
        elif p.pid in moved and p.to_world is not None:
            p = p._replace(to_world=_matrix(moved[p.pid], f"plane_{p.pid}_to_world"))
        elif p.pid in moved:
            n, off, mirror = moved[p.pid]
            p = p._replace(normal=n, offset=off, mirror=mirror)
        planes.append(p)
    integrator.planes = planes
    ps = plane_set(planes)
    dr.make_opaque(ps.nx, ps.ny, ps.nz, ps.offset, ps.inv_len, ps.mx, ps.my, ps.mz)
    integrator._planes = ps
