"""Photon emission from every light kind (docs/EXTENSIONS.md E.16), in proportion to each light's power.

A photon is a ray ``(o, d)`` with a power ``Φ`` (rgb) and, for the a5 lights, the falloff ``f`` of its light:
an a5 light (SPEC A.3, E.1, E.2) has no inverse-square law, its colour arriving at distance ``r`` is
``color / (1 + f r²)``. Read as an irradiance at normal incidence, that light's radiant intensity toward the
first surface a photon meets at distance ``r`` is ``I = color r² / (1 + f r²)``; so the photon tracer
(plugins/integrators/photon/trace.py) multiplies the power of an a5 photon by ``r² / (1 + f r²)`` at its first hit,
and the
irradiance the photons deposit equals the light loop's ``color cos θ / (1 + f r²)`` exactly. Per kind:

* ``a5_point``: ``o`` = position, ``d`` uniform on the sphere, ``Φ = 4π color / N``;
* ``a5_spot``: ``d`` uniform in the cone of half-angle ``angle`` about the axis,
  ``Φ = 2π (1 − cos angle) color · profile(d) / N`` (the E.1 profile);
* ``a5_area`` on its shape, read as E.13 says (a surface of radiance ``Le = color / (1 + f r²)``, both faces
  of a parallelogram, the outside of a sphere): ``o`` uniform on the surface, ``d`` cosine-weighted about the
  emitting face, ``Φ = π A color / N`` per face (``A`` the area; parallelogram ``2π A color``, sphere
  ``4π² r² color``), and at the first hit the factor ``1 / (1 + f r²)`` (stored as ``falloff = −1 − f``);
* an ``a5_area`` without a shape (E.2's mean of point lights): ``o`` uniform on it, ``d`` uniform on the sphere,
  ``Φ = 4π color / N`` and the point light's first-hit factor;
* caustic photons of a light that is a point: only toward the specular shapes (:func:`_projected`);
* an environment (stock ``constant``, the background colour) and any other light (stock ``point``, ``spot``,
  ``area``, ``directional``, whose ``sample_ray`` draws from a disc covering the scene's bounding sphere):
  Mitsuba's ``sample_ray``, ``Φ = weight / N``.

``N`` photons in all are split over the lights in proportion to their power ``P_l``, measured by
:func:`light_powers` as the mean first-hit power of a pilot of photons (for a5 lights it depends on the scene:
``P = ∫ color r(ω)² / (1 + f r(ω)²) dω``); light ``l`` gets ``N_l = round(N P_l / ΣP)`` photons (at least one
per light of positive power) and its photons carry ``Φ / N_l``.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import drjit as dr
import mitsuba as mi
import numpy as np

from a5mi.plugins.emitters.area_light import A5AreaLight
from a5mi.plugins.emitters.point_light import A5PointLight
from a5mi.plugins.emitters.spot_light import A5SpotLight, profile
from a5mi.plugins.kernel.scene import is_light


class PhotonRays(NamedTuple):
    """Emitted photons (numpy, one row each): ``o``, ``d`` (unit) ``(n, 3)``, ``power`` ``(n, 3)`` (before the
    a5 first-hit factor), ``falloff`` ``(n,)`` (the a5 light's ``f``; NaN: a stock light, no factor) and
    ``light`` ``(n,)`` (index into :func:`photon_lights`)."""

    o: np.ndarray
    d: np.ndarray
    power: np.ndarray
    falloff: np.ndarray
    light: np.ndarray


def _emits_rays(e: mi.Emitter) -> bool:
    """Whether ``e`` implements ``sample_ray`` (the stock environments do; ``a5_cubemap`` does not)."""
    try:
        e.sample_ray(mi.Float(0.0), mi.Float(0.5), mi.Point2f(0.5), mi.Point2f(0.5), True)
    except Exception:   # noqa: BLE001 - Mitsuba raises a plain RuntimeError / NotImplementedError
        return False
    return True


def photon_lights(scene: mi.Scene) -> list[mi.Emitter]:
    """The emitters that emit photons: the lights of the light loop (``is_light``), emitters on shapes and an
    environment whose ``sample_ray`` exists (stock ``constant``, the background colour: rays from a disc
    covering the scene's bounding sphere; an ``a5_cubemap`` emits none, E.16)."""
    out = [e for e in scene.emitters() if is_light(e) or e.get_shape() is not None]
    env = scene.environment()
    if env is not None and not any(e is env for e in out) and _emits_rays(env):
        out.append(env)
    return out


def _rng(n: int, seed: int, stream: int) -> mi.PCG32:
    """A PCG32 of ``n`` lanes for ``(seed, stream)`` (stream: the light and the pass, mixed by the caller)."""
    state = (seed * 0x9E3779B1 + stream * 0x85EBCA77 + 0x2545F491) & 0xFFFFFFFFFFFFFFFF
    return mi.PCG32(n, dr.opaque(mi.UInt64, state), dr.arange(mi.UInt64, n) * 2 + 1)


def scene_ball(scene: mi.Scene) -> tuple[np.ndarray, float]:
    """``(c, R)``: the bounding sphere of the scene's shapes, the lights' positions and the camera's position
    (exact planes are not shapes: the lights and the camera bound the part of them that matters)."""
    box = mi.ScalarBoundingBox3f()
    box.expand(scene.bbox())
    for e in scene.emitters():
        b = e.bbox()     # a point light: its position; infinite or empty for the others
        if b.valid() and all(math.isfinite(float(b.min[i])) and math.isfinite(float(b.max[i])) for i in range(3)):
            box.expand(b)
    for sensor in scene.sensors():
        centre = getattr(sensor, "center", None)     # a5_camera keeps its centre; stock sensors their transform
        if centre is None:
            t = sensor.world_transform().translation()
            centre = tuple(float(dr.slice(t[i], 0)) for i in range(3))
        box.expand(mi.ScalarPoint3f(*centre))
    if not box.valid():
        return np.zeros(3), 1.0
    sphere = box.bounding_sphere()
    return np.array([float(sphere.center[i]) for i in range(3)]), max(float(sphere.radius), 1e-3)


def to_np3(v: object, n: int | None = None) -> np.ndarray:
    """A Dr.Jit 3-vector or colour as a numpy ``(n, 3)`` float64 array, one component at a time (a whole
    ``np.asarray`` ravels it in a kernel whose size is baked in, compiled again for every width)."""
    cols = [np.asarray(v[i], dtype=np.float64) for i in range(3)]   # type: ignore[index]
    m = max(len(c) for c in cols) if n is None else n
    return np.stack([np.broadcast_to(c, (m,)) for c in cols], axis=1)


def to_dr3(cls: type, a: np.ndarray) -> Any:
    """A numpy ``(n, 3)`` array as a Dr.Jit 3-vector or colour of class ``cls`` (float32 columns)."""
    return cls(*(mi.Float(np.ascontiguousarray(a[:, i], dtype=np.float32)) for i in range(3)))


Targets = list[tuple[np.ndarray, float]]


def specular_targets(scene: mi.Scene) -> Targets:
    """Bounding spheres ``(centre, radius)`` of the shapes whose BSDF has a delta lobe (mirror, glass): where
    caustic photons of a point light are sent (:func:`_projected`)."""
    out = []
    for shape in scene.shapes():
        if mi.has_flag(shape.bsdf().flags(), mi.BSDFFlags.Delta):
            bs = shape.bbox().bounding_sphere()
            out.append((np.array([bs.center[i] for i in range(3)], dtype=np.float64), float(bs.radius)))
    return out


def _point_position(e: mi.Emitter) -> np.ndarray | None:
    """The position of a light that is a point (a delta position and a degenerate bounding box), else None."""
    if not mi.has_flag(e.flags(), mi.EmitterFlags.DeltaPosition):
        return None
    box = e.bbox()
    if not box.valid() or any(float(box.max[i] - box.min[i]) > 0.0 for i in range(3)):
        return None
    return np.array([float(box.min[i]) for i in range(3)])


def _projected(e: mi.Emitter, pos: np.ndarray, targets: Targets, n: int, rng: mi.PCG32
               ) -> tuple[mi.Point3f, mi.Vector3f, mi.Color3f]:
    """Caustic photons of the point light ``e`` sent only into the cones ``C_j`` (solid angles ``Ω_j``) that
    subtend the specular shapes' bounding spheres (Jensen's projection map): cone ``j`` is chosen with
    probability ``Ω_j / ΣΩ`` and ``d`` uniform in it, so ``pdf(d) = m(d) / ΣΩ`` with ``m(d)`` the number of
    cones holding ``d``; the power is ``I(d) ΣΩ / m(d)`` (``I`` the radiant intensity: ``color`` (times the
    E.1 profile) for an a5 light, ``sample_direction`` at unit distance for a stock one)."""
    cones = []
    for c, r in targets:
        v = c - pos
        dist = float(np.linalg.norm(v))
        cos_max = -1.0 if dist <= r else math.sqrt(max(0.0, 1.0 - (r / dist) ** 2))
        cones.append((v / max(dist, 1e-30), cos_max, 2.0 * math.pi * (1.0 - cos_max)))
    omegas = np.array([c[2] for c in cones])
    total = float(omegas.sum())
    cdf = np.cumsum(omegas) / total
    u_pick = rng.next_float32()
    u = mi.Point2f(rng.next_float32(), rng.next_float32())
    pick = np.minimum(np.searchsorted(cdf, np.asarray(u_pick, dtype=np.float64), side="right"), len(cones) - 1)
    axis = np.stack([cones[j][0] for j in pick]) if len(pick) else np.zeros((0, 3))
    cos_max = np.array([cones[j][1] for j in pick])
    d = mi.Frame3f(mi.Vector3f(*(mi.Float(axis[:, i]) for i in range(3)))).to_world(
        mi.warp.square_to_uniform_cone(u, mi.Float(cos_max)))
    dr.eval(d)
    d_np = to_np3(d, n)
    m = sum(((d_np @ a) >= cm).astype(np.float64) for a, cm, _ in cones)
    scale = mi.Float(total / np.maximum(m, 1.0))
    o = mi.Point3f(*(float(x) for x in pos)) + dr.zeros(mi.Point3f, n)
    if isinstance(e, A5PointLight):
        intensity = e.color + dr.zeros(mi.Color3f, n)
        if isinstance(e, A5SpotLight):
            intensity *= profile(dr.dot(d, e.axis), e.angle_rad, e.beam_rad)
    else:
        it = dr.zeros(mi.Interaction3f, n)
        it.p = o + d
        _, intensity = e.sample_direction(it, mi.Point2f(0.5), True)
    return o, d, mi.Color3f(intensity) * scale


def _emit_one(e: mi.Emitter, n: int, rng: mi.PCG32, targets: Targets | None = None,
              ) -> tuple[mi.Point3f, mi.Vector3f, mi.Color3f, float]:
    """``n`` photons of light ``e``: origins, directions, power per unit count (``Φ N``) and the falloff
    (NaN for a stock light); module docstring. ``targets``: caustic photons of a point light go toward them
    only (:func:`_projected`)."""
    pos = _point_position(e) if targets else None
    if pos is not None:
        o, d, w = _projected(e, pos, targets, n, rng)
        return o, d, w, float(dr.slice(e.falloff, 0)) if isinstance(e, A5PointLight) else math.nan
    u1, u2, u3 = rng.next_float32(), mi.Point2f(rng.next_float32(), rng.next_float32()), mi.Point2f(
        rng.next_float32(), rng.next_float32())
    if isinstance(e, A5SpotLight):
        cos_a = dr.cos(e.angle_rad)
        local = mi.warp.square_to_uniform_cone(u3, cos_a)
        d = mi.Frame3f(e.axis).to_world(local)
        w = 2.0 * dr.pi * (1.0 - cos_a) * profile(dr.dot(d, e.axis), e.angle_rad, e.beam_rad)
        return mi.Point3f(e.position) + dr.zeros(mi.Point3f, n), d, e.color * w, float(dr.slice(e.falloff, 0))
    if isinstance(e, A5PointLight):
        d = mi.warp.square_to_uniform_sphere(u3)
        return mi.Point3f(e.position) + dr.zeros(mi.Point3f, n), d, e.color * (4.0 * dr.pi), float(
            dr.slice(e.falloff, 0))
    if isinstance(e, A5AreaLight) and e.get_shape() is None:     # E.2's mean of point lights
        o = e.corner + u2.x * e.edge1 + u2.y * e.edge2 if e.kind == "parallelogram" else \
            e.center + e.radius * mi.warp.square_to_uniform_sphere(u2)
        d = mi.warp.square_to_uniform_sphere(u3)
        return o, d, e.color * (4.0 * dr.pi) + dr.zeros(mi.Color3f, n), float(dr.slice(e.falloff, 0))
    if isinstance(e, A5AreaLight):                                # E.13: a surface of radiance Le
        if e.kind == "parallelogram":
            cross = dr.cross(e.edge1, e.edge2)
            area = dr.norm(cross)
            nrm = dr.select(u1 < 0.5, 1.0, -1.0) * (cross / area)
            o = e.corner + u2.x * e.edge1 + u2.y * e.edge2 + 1e-5 * nrm
            w = e.color * (2.0 * dr.pi * area)
        else:
            nrm = mi.warp.square_to_uniform_sphere(u2)
            o = e.center + (e.radius * (1.0 + 1e-4)) * nrm
            w = e.color * (4.0 * dr.pi * dr.pi * e.radius * e.radius)
        d = mi.Frame3f(nrm).to_world(mi.warp.square_to_cosine_hemisphere(u3))
        return o, d, w + dr.zeros(mi.Color3f, n), -1.0 - float(dr.slice(e.falloff, 0))
    ray, weight = e.sample_ray(dr.zeros(mi.Float, n), u1, u2, u3, True)
    return ray.o, ray.d, mi.Color3f(weight), math.nan


def emit(scene: mi.Scene, counts: list[int], seed: int, pass_index: int, targets: Targets | None = None,
         ) -> PhotonRays:
    """``counts[l]`` photons of each light of :func:`photon_lights`, each carrying ``Φ / counts[l]`` (module
    docstring), seeded by ``(seed, pass_index, l)``; ``targets``: the caustic emission of :func:`_projected`."""
    parts = []
    for li, (e, n) in enumerate(zip(photon_lights(scene), counts, strict=True)):
        if n <= 0:
            continue
        o, d, w, f = _emit_one(e, n, _rng(n, seed, (pass_index << 8) + li), targets)
        dr.eval(o, d, w)
        o_np, d_np, w_np = to_np3(o, n), to_np3(d, n), to_np3(w, n) / n
        parts.append((o_np, d_np, w_np, np.full(n, f), np.full(n, li, dtype=np.int32)))
    if not parts:
        z = np.zeros((0, 3))
        return PhotonRays(z, z, z, np.zeros(0), np.zeros(0, dtype=np.int32))
    return PhotonRays(*(np.ascontiguousarray(np.concatenate(c)) for c in zip(*parts, strict=True)))


def first_hit_factor(falloff: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The a5 factor of a photon's first hit at distance ``r``: ``r² / (1 + f r²)`` for a point-like a5 light
    (``falloff = f >= 0``), ``1 / (1 + f r²)`` for an a5 surface light (stored as ``falloff = −1 − f``), 1 for
    a stock light (NaN); 0 for a miss (``r = inf``)."""
    r2 = np.where(np.isfinite(r), r * r, 0.0)
    f = np.nan_to_num(falloff)
    surface = f <= -1.0
    f = np.where(surface, -1.0 - f, f)
    a5 = np.where(surface, np.isfinite(r), r2) / (1.0 + f * r2)
    return np.where(np.isnan(falloff), 1.0, a5)


def split_counts(total: int, powers: list[float]) -> list[int]:
    """``N_l = round(N P_l / ΣP)``, at least 1 for a light with ``P_l > 0`` (module docstring)."""
    s = sum(p for p in powers if p > 0.0)
    if total <= 0 or s <= 0.0:
        return [0] * len(powers)
    return [max(1, round(total * p / s)) if p > 0.0 else 0 for p in powers]


def _luminance(rgb: np.ndarray) -> np.ndarray:
    return rgb @ np.array([0.2126, 0.7152, 0.0722])


def light_powers(scene: mi.Scene, first_distance: object, pilot: int = 4096, seed: int = 0,
                 targets: Targets | None = None) -> list[float]:
    """Each light's power (luminance), the mean first-hit power of ``pilot`` photons; ``first_distance(o, d)``
    gives the distance to the first hit of numpy rays (inf on a miss), so a5 lights get their factor, with
    ``r`` capped at twice the diameter of :func:`scene_ball` (an a5 light over an infinite plane
    has an unbounded power: the share that decides the counts is the power reaching the scene)."""
    cap = 4.0 * scene_ball(scene)[1]
    out = []
    for li, e in enumerate(photon_lights(scene)):
        o, d, w, f = _emit_one(e, pilot, _rng(pilot, seed, 0xFFFFFF00 + li), targets)
        dr.eval(o, d, w)
        o_np, d_np, w_np = to_np3(o, pilot), to_np3(d, pilot), to_np3(w, pilot)
        if math.isnan(f):
            out.append(float(_luminance(w_np).mean()))
            continue
        r = np.minimum(first_distance(o_np, d_np), cap)
        out.append(float((_luminance(w_np) * first_hit_factor(np.full(pilot, f), r)).mean()))
    return out
