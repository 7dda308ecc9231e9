"""The physically based reading of the a5 lights and background (docs/EXTENSIONS.md E.13), for ``@dr.syntax``
kernels: next-event estimation (:func:`sample_light`, :func:`direct`), the emission a ray finds
(:func:`emission`, :func:`environment`) and the pdfs of multiple importance sampling.

The lights (every emitter with a delta flag, every emitter on a shape, every ``a5_area``: :func:`lights_of`):

* point (SPEC A.3), spot (E.1), directional: delta lights. The arriving irradiance (at normal incidence) is the
  emitter's ``sample_direction`` value as written: ``color / (1 + falloff d²)`` (point; times the cone
  profile for a spot; stock ``point`` ``I/d²``), ``irradiance`` for ``directional``. Never hit by a ray.
* an emitter on a shape: ``a5_area`` (E.2 AreaLight on its ``rectangle``, SphereLight on its ``sphere``) or
  a stock ``area``. Read as a surface of radiance ``Le``: for ``a5_area`` ``Le = color / (1 + falloff d²)``
  at distance ``d`` from the point it lights, from both faces (what its ``eval`` / ``eval_direction`` say);
  stock ``area``: its ``radiance``, front face only. Sampled by the shape (``shape.sample_direction``:
  uniform on the parallelogram, ``pdf_ω = d² / (A |cos θ_l|)``; uniform in the cone a sphere subtends,
  ``pdf_ω = 1 / (2π (1 − cos θ_max))``), so the estimate is ``f |cos θ| Le / pdf_ω``; a ray that hits the
  shape sees ``Le`` with the same ``pdf_ω`` for MIS.
* an ``a5_area`` without a shape (a dict written by hand): E.2's reading, the mean of point lights over it;
  delta for MIS (nothing can hit it).
* the environment (``scene.environment()``: stock ``constant`` = the background colour, ``a5_cubemap`` = the
  cube map, SPEC A.4): radiance ``background(ω)`` from every direction at infinity, sampled uniformly on the
  sphere (``pdf = 1/(4π)``) for next-event estimation, seen by every ray that escapes.

Next-event estimation samples **every** light once per vertex (not one light chosen by power), plus the
environment once; an area light's or the environment's sample is weighted by the power heuristic
``w = p_l² / (p_l² + p_f²)`` against the BSDF's pdf ``p_f`` (:func:`.pbr.eval_diffuse`), and a ray the BSDF
sampled that hits it by ``p_f² / (p_f² + p_l²)``; delta lights and rays after a delta lobe weigh 1. The
shadow ray is :func:`.intersect.visible` (the binary's mesh rules, exact planes), stopping at
``dist (1 − 10⁻⁴)`` for a light with extent (its own shape) and running to infinity for a directional light
or the environment.
"""

from __future__ import annotations

from functools import partial
from typing import TYPE_CHECKING, NamedTuple

import drjit as dr
import mitsuba as mi

from a5mi.plugins.kernel.intersect import visible
from a5mi.plugins.kernel.pbr import Lobes, eval_diffuse, power_heuristic
from a5mi.plugins.kernel.pbr_sampling import padded_2d
from a5mi.plugins.kernel.scene import area_samples
from a5mi.plugins.kernel.surfaces import background
from a5mi.plugins.sampling import Stochastic
from a5mi.plugins.syntax import syntax

if TYPE_CHECKING:
    from a5mi.plugins.kernel.features import SceneData

#: kinds of :class:`PbrLights`: a delta light, an emitter on a shape, an ``a5_area`` without a shape (E.2)
DELTA, SURFACE, POINTS = 0, 1, 2
#: solid-angle pdf of the environment's uniform sphere sample
ENV_PDF = 1.0 / (4.0 * dr.pi)
#: the E.5 dimension slot of the environment sample at a vertex (light k uses slot k)
ENV_SLOT = 254


class PbrLights(NamedTuple):
    """The lights of next-event estimation as gatherable arrays: ``emitters``, ``kind`` (:data:`DELTA`,
    :data:`SURFACE`, :data:`POINTS`), ``count`` (opaque), and for the lights on a shape: ``shapes`` (the shapes,
    Python objects), ``slot`` (per light, its shape's index in ``shapes``; 0 for the others) and ``slot_of`` (per
    emitter registry id, the same index). The shapes are called through :func:`drjit.switch` over ``shapes``
    alone, never as a virtual call on a shape pointer: that would trace every shape of the scene, and a
    non-uniformly scaled sphere (an ``instance``) has no ``sample_position`` or ``pdf_direction``."""

    emitters: mi.EmitterPtr
    kind: mi.UInt32
    count: mi.UInt32
    slot: mi.UInt32
    slot_of: mi.UInt32
    shapes: tuple[mi.Shape, ...]


def _kind(e: mi.Emitter) -> int | None:
    if e.get_shape() is not None:
        return SURFACE
    if mi.has_flag(e.flags(), mi.EmitterFlags.Delta):
        return DELTA
    return POINTS if area_samples(e) is not None else None


def lights_of(scene: mi.Scene) -> PbrLights:
    """The :class:`PbrLights` of ``scene`` (module docstring), in ``scene.emitters()`` order; the environment
    is not among them (:func:`direct` samples it when asked)."""
    emitters = scene.emitters()
    idx, kinds, slots, shapes, slot_of = [], [], [], [], {}
    for i, e in enumerate(emitters):
        kind = _kind(e)
        if kind is None:
            continue
        idx.append(i)
        kinds.append(kind)
        slots.append(len(shapes) if kind == SURFACE else 0)
        if kind == SURFACE:
            slot_of[_registry_id(e)] = len(shapes)
            shapes.append(e.get_shape())
    table = [0] * (max(slot_of, default=0) + 1)
    for rid, slot in slot_of.items():
        table[rid] = slot
    if not idx:
        return PbrLights(dr.zeros(mi.EmitterPtr, 1), mi.UInt32([DELTA]), dr.opaque(mi.UInt32, 0), mi.UInt32([0]),
                         mi.UInt32(table), ())
    ptrs = dr.gather(mi.EmitterPtr, scene.emitters_dr(), mi.UInt32(idx))
    dr.eval(ptrs)
    return PbrLights(ptrs, mi.UInt32(kinds), dr.opaque(mi.UInt32, len(idx)), mi.UInt32(slots), mi.UInt32(table),
                     tuple(shapes))


def _registry_id(emitter: mi.Emitter) -> int:
    """The registry id of an emitter (what ``dr.reinterpret_array(mi.UInt32, ptr)`` gives for its pointer)."""
    return int(dr.reinterpret_array(mi.UInt32, mi.EmitterPtr(emitter))[0])


def _sample_on(shape: mi.Shape, si: mi.SurfaceInteraction3f, u: mi.Point2f, active: mi.Bool) -> mi.DirectionSample3f:
    return shape.sample_direction(si, u, active)


def _pdf_on(shape: mi.Shape, it: mi.Interaction3f, ds: mi.DirectionSample3f, active: mi.Bool) -> mi.Float:
    return shape.pdf_direction(it, ds, active)


class LightSample(NamedTuple):
    """One light sample at a point (:func:`sample_light`): unit direction ``d`` toward the light, ``dist`` to
    it, ``weight`` (``Le / pdf_ω`` for a light with extent, the arriving irradiance for a delta light),
    ``pdf`` (solid angle; 0 for a delta light), ``delta``, ``far`` (a directional light: shadow test to
    infinity) and ``shadow_dist`` (where the shadow ray stops)."""

    d: mi.Vector3f
    dist: mi.Float
    weight: mi.Color3f
    pdf: mi.Float
    delta: mi.Bool
    far: mi.Bool
    shadow_dist: mi.Float


def sample_light(lights: PbrLights, k: mi.UInt32, si: mi.SurfaceInteraction3f, u: mi.Point2f,
                 active: mi.Bool) -> LightSample:
    """Light ``k`` of ``lights`` seen from ``si.p`` through the unit-square sample ``u`` (module docstring)."""
    emitter = dr.gather(mi.EmitterPtr, lights.emitters, k, active)
    kind = dr.gather(mi.UInt32, lights.kind, k, active)
    on_shape = active & (kind == SURFACE)
    if lights.shapes:
        slot = dr.gather(mi.UInt32, lights.slot, k, on_shape)
        ds_s = dr.switch(slot, [partial(_sample_on, shape) for shape in lights.shapes], si, u, on_shape)
    else:  # no light on a shape: nothing to sample
        ds_s = dr.zeros(mi.DirectionSample3f, dr.width(si.p))
    le = mi.Color3f(emitter.eval_direction(si, ds_s, on_shape))
    ok = on_shape & (ds_s.pdf > 0.0)
    ds_e, value = emitter.sample_direction(si, u, active & ~on_shape)
    d = dr.select(on_shape, ds_s.d, ds_e.d)
    dist = dr.select(on_shape, ds_s.dist, ds_e.dist)
    weight = dr.select(on_shape, dr.select(ok, le / dr.select(ok, ds_s.pdf, 1.0), 0.0), mi.Color3f(value))
    far = ~on_shape & ((emitter.flags() & int(mi.EmitterFlags.Infinite)) != 0)
    shadow_dist = dr.select(kind == DELTA, dist, dist * (1.0 - 1e-4))
    return LightSample(d, dist, dr.select(active, weight, 0.0), dr.select(ok, ds_s.pdf, 0.0), ~on_shape, far,
                       shadow_dist)


def light_point(rng: Stochastic, dim: mi.UInt32, counter: mi.UInt32) -> mi.Point2f:
    """A unit-square sample of dimension ``dim``: stratified over the ``-spp`` passes, padded across dimensions
    (:func:`.pbr_sampling.padded_2d`), draws ``counter``, ``counter + 1``."""
    return padded_2d(rng, dim, rng.pass_index, rng.passes, counter)


@syntax
def direct(scene: mi.Scene, data: SceneData, lights: PbrLights, env: bool, si: mi.SurfaceInteraction3f,
           p: mi.Point3f, b: Lobes, active: mi.Bool, rng: Stochastic, dim: mi.UInt32, counter: mi.UInt32,
           n_shadow: mi.Float) -> tuple[mi.Color3f, mi.UInt32, mi.Float]:
    """Next-event estimation at the hit ``si`` (point ``p``, BSDF ``b``, lanes ``active``): one sample of every
    light and, with ``env``, one of the environment, each MIS-weighted (module docstring); shadow rays from
    ``data.tmin`` past the scene's shapes and ``data.planes``. Light ``k`` uses
    E.5 dimension ``dim + k``, the environment ``dim + ENV_SLOT``. Returns ``(Σ f |cos θ| weight · w, counter,
    n_shadow)`` (``counter`` advanced by two draws per sample, ``n_shadow`` by the shadow rays traced)."""
    go = active & (b.p_d > 0.0)
    result = dr.zeros(mi.Color3f, dr.width(p))
    k = dr.zeros(mi.UInt32, dr.width(p))
    while go & (k < lights.count):
        u = light_point(rng, dim + k, counter)
        counter += 2
        ls = sample_light(lights, k, si, u, go)
        f, pdf_f = eval_diffuse(b, ls.d)
        w = dr.select(ls.delta, 1.0, power_heuristic(ls.pdf, pdf_f))
        contrib = f * ls.weight * w
        test = go & (dr.max(contrib) > 0.0)
        seen = visible(scene, data.planes, p, ls.d, data.tmin, ls.shadow_dist, ls.far, test)
        n_shadow += dr.select(test, 1.0, 0.0)
        result += dr.select(seen, contrib, 0.0)
        k += 1
    if dr.hint(env, mode="scalar"):
        u = light_point(rng, dim + ENV_SLOT, counter)
        counter += 2
        d = mi.warp.square_to_uniform_sphere(u)
        f, pdf_f = eval_diffuse(b, d)
        contrib = f * background(scene, d, go) * (power_heuristic(mi.Float(ENV_PDF), pdf_f) / ENV_PDF)
        test = go & (dr.max(contrib) > 0.0)
        seen = visible(scene, data.planes, p, d, data.tmin, mi.Float(dr.inf), mi.Bool(True), test)
        n_shadow += dr.select(test, 1.0, 0.0)
        result += dr.select(seen, contrib, 0.0)
    return result, counter, n_shadow


def emission(scene: mi.Scene, lights: PbrLights, si: mi.SurfaceInteraction3f, on_shape: mi.Bool, o: mi.Point3f,
             d: mi.Vector3f, t: mi.Float) -> tuple[mi.Color3f, mi.Float]:
    """``(Le, pdf_ω)`` of the emitter on the shape a ray ``o + t d`` (unit ``d``) hits at ``si``, on the lanes
    ``on_shape`` (hits not on a plane): the radiance arriving at ``o`` (``a5_area``: ``color / (1 + falloff
    t²)``) and the solid-angle pdf with which :func:`sample_light` would have chosen that point from ``o``."""
    emitter = si.emitter(scene, on_shape)
    has = on_shape & (emitter != None)  # noqa: E711 - a Dr.Jit pointer comparison
    width = dr.width(d)
    it = dr.zeros(mi.Interaction3f, width)
    it.p = mi.Point3f(o)
    it.time = si.time
    ds = dr.zeros(mi.DirectionSample3f, width)
    ds.p, ds.n, ds.uv, ds.time = si.p, si.n, si.uv, si.time
    ds.d, ds.dist, ds.emitter = mi.Vector3f(d), mi.Float(t), emitter
    le = mi.Color3f(emitter.eval_direction(it, ds, has))
    if lights.shapes:
        slot = dr.gather(mi.UInt32, lights.slot_of, dr.reinterpret_array(mi.UInt32, emitter), has)
        pdf = dr.switch(slot, [partial(_pdf_on, shape) for shape in lights.shapes], it, ds, has)
    else:  # no light on a shape: no emitter to find
        pdf = dr.zeros(mi.Float, width)
    return dr.select(has, le, 0.0), dr.select(has, pdf, 0.0)


def environment(scene: mi.Scene, d: mi.Vector3f, miss: mi.Bool) -> tuple[mi.Color3f, mi.Float]:
    """``(Le, pdf_ω)`` of the environment for an escaping ray of direction ``d`` (lanes ``miss``): the background
    (SPEC A.4) and :data:`ENV_PDF`. Call only when the scene has an environment."""
    return background(scene, d, miss), mi.Float(ENV_PDF)
