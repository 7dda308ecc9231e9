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
normals it maps, so transformed planes get ``n_w/|n_w|``. Plane data lives in device arrays gathered by
index with an opaque count, so scenes with any number of planes share one compiled kernel.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

import drjit as dr
import mitsuba as mi

from .syntax import syntax

_KEY = re.compile(r"^plane_(.+?)_(normal|offset|bsdf|mirror_normal)$")


@dataclass
class PlaneSet:
    """The planes of an ``a5_whitted`` integrator as device arrays (length ``max(count, 1)``)."""

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


Plane = tuple[str, tuple[float, float, float], float, Any, tuple[float, float, float]]


def planes_from_props(props: mi.Properties) -> list[Plane]:
    """``[(id, normal, offset, bsdf, mirror normal), ...]`` from the ``plane_<id>_*`` parameters, by id.

    Every plane needs all three parameters; a zero or non-finite normal or a non-finite offset is a
    ``ValueError`` naming the parameter."""
    found: dict[str, dict[str, Any]] = {}
    for key in props.keys():
        m = _KEY.match(key)
        if m:
            found.setdefault(m.group(1), {})[m.group(2)] = props.get(key)
    out = []
    for pid in sorted(found):
        parts = found[pid]
        missing = [k for k in ("normal", "offset", "bsdf") if k not in parts]
        if missing:
            raise ValueError(f"a5_whitted: plane '{pid}' lacks 'plane_{pid}_{missing[0]}'")
        n = _vec3(parts["normal"], f"plane_{pid}_normal")
        if not all(math.isfinite(c) for c in n) or not any(n):
            raise ValueError(f"a5_whitted: 'plane_{pid}_normal' must be finite and non-zero, got {n!r}")
        off = parts["offset"]
        if isinstance(off, bool) or not isinstance(off, (int, float)) or not math.isfinite(off):
            raise ValueError(f"a5_whitted: 'plane_{pid}_offset' must be a finite number, got {off!r}")
        bsdf = parts["bsdf"]
        if not isinstance(bsdf, mi.BSDF):
            raise ValueError(f"a5_whitted: 'plane_{pid}_bsdf' must be a BSDF, got {type(bsdf).__name__}")
        length = math.sqrt(sum(c * c for c in n))
        mirror = _vec3(parts["mirror_normal"], f"plane_{pid}_mirror_normal") if "mirror_normal" in parts else \
            tuple(c / length for c in n)
        out.append((pid, n, float(off), bsdf, mirror))
    return out


def plane_set(planes: list[Plane]) -> PlaneSet:
    """Device arrays of ``planes`` (as from :func:`planes_from_props`); a dummy entry when there are none."""
    if not planes:
        z = mi.Float([0.0])
        return PlaneSet(z, z, z, z, z, z, z, z, dr.zeros(mi.BSDFPtr, 1), dr.opaque(mi.UInt32, 0), 0)
    cols = list(zip(*[p[1] for p in planes], strict=True))
    inv = [1.0 / math.sqrt(sum(c * c for c in p[1])) for p in planes]
    ptrs = mi.BSDFPtr([p[3] for p in planes])
    mirror = list(zip(*[p[4] for p in planes], strict=True))
    arrays = [mi.Float(c) for c in cols] + [mi.Float([p[2] for p in planes]), mi.Float(inv)] + \
        [mi.Float(c) for c in mirror]
    dr.make_opaque(ptrs, *arrays)  # literals of a one-plane scene would bake its values into the kernel
    return PlaneSet(*arrays, ptrs, dr.opaque(mi.UInt32, len(planes)), len(planes))


def _dot(ax: mi.Float, ay: mi.Float, az: mi.Float, v: mi.Vector3f) -> mi.Float:
    """vecmath's ``Vector3f::dot`` order: ``(a_x v_x + a_y v_y) + a_z v_z``."""
    return (ax * v.x + ay * v.y) + az * v.z


@syntax
def intersect_planes(ps: PlaneSet, o: mi.Point3f, d: mi.Vector3f, t_min: mi.Float, t_max: mi.Float,
                     active: mi.Bool) -> tuple[mi.Bool, mi.Float, mi.UInt32]:
    """Nearest plane hit with ``t_min < t < t_max`` (SPEC A.6): ``(hit, t, plane index)``; ``t = t_max``
    and index 0 where no plane is hit."""
    k = dr.zeros(mi.UInt32, dr.width(d))
    best = mi.Float(t_max)
    idx = dr.zeros(mi.UInt32, dr.width(d))
    found = dr.full(mi.Bool, False, dr.width(d))
    while active & (k < ps.count):
        nx = dr.gather(mi.Float, ps.nx, k)
        ny = dr.gather(mi.Float, ps.ny, k)
        nz = dr.gather(mi.Float, ps.nz, k)
        off = dr.gather(mi.Float, ps.offset, k)
        denom = _dot(nx, ny, nz, d)
        t = (off - _dot(nx, ny, nz, mi.Vector3f(o))) / denom
        ok = (denom != 0.0) & (t > t_min) & (t < best)
        best = dr.select(ok, t, best)
        idx = dr.select(ok, k, idx)
        found |= ok
        k += 1
    return found, best, idx


def plane_normal(ps: PlaneSet, idx: mi.UInt32, active: mi.Bool) -> mi.Vector3f:
    """The shading normal ``n/|n|`` of plane ``idx`` (never flipped toward the viewer)."""
    inv = dr.gather(mi.Float, ps.inv_len, idx, active)
    return mi.Vector3f(dr.gather(mi.Float, ps.nx, idx, active) * inv,
                       dr.gather(mi.Float, ps.ny, idx, active) * inv,
                       dr.gather(mi.Float, ps.nz, idx, active) * inv)


def plane_mirror_normal(ps: PlaneSet, idx: mi.UInt32, active: mi.Bool) -> mi.Vector3f:
    """The normal plane ``idx`` mirrors rays about (``plane_<id>_mirror_normal``, module docstring)."""
    return mi.Vector3f(dr.gather(mi.Float, ps.mx, idx, active), dr.gather(mi.Float, ps.my, idx, active),
                       dr.gather(mi.Float, ps.mz, idx, active))


def plane_bsdf(ps: PlaneSet, idx: mi.UInt32, active: mi.Bool) -> mi.BSDFPtr:
    """The BSDF of plane ``idx`` (null where ``active`` is false)."""
    return dr.gather(mi.BSDFPtr, ps.bsdf, idx, active)


def replace_planes(integrator: Any, moved: dict[str, tuple[tuple[float, float, float], float,
                                                          tuple[float, float, float]]]) -> None:
    """Give the planes ``moved`` (id -> (normal, offset, mirror normal)) of an ``a5_whitted`` integrator new
    values, keeping their BSDFs (keyframed Transforms, docs/EXTENSIONS.md E.11). The device arrays keep their
    length and are opaque (a one-plane array would be a literal of the kernel), so the compiled kernel is
    reused."""
    planes = [(pid, *moved[pid][:2], bsdf, moved[pid][2]) if pid in moved else (pid, n, off, bsdf, mirror)
              for pid, n, off, bsdf, mirror in integrator.planes]
    integrator.planes = planes
    ps = plane_set(planes)
    dr.make_opaque(ps.nx, ps.ny, ps.nz, ps.offset, ps.inv_len, ps.mx, ps.my, ps.mz)
    integrator._planes = ps
