"""Light at a point of a medium, the Henyey-Greenstein phase function and multiple scattering (EXTENSIONS E.8).

:func:`light_at` is ``L(x) = Σ_k V_k T_k lightColor_k · 4π p(cos)`` (the single-scattering light of E.8; ``T_k``
the light's transmittance with ``-media_bounces >= 1``, plugins/media/light.py; the phase factor only for
``g ≠ 0``). The phase function is Henyey-Greenstein's::

    p(cos θ) = (1 − g²) / (4π (1 + g² − 2 g cos θ)^{3/2}),    cos θ = ω_l · ω   (``4π p = 1`` for g = 0)

with ``ω_l`` the direction to the light and ``ω`` the direction the eye path arrives by (eye ray or walk step:
the light's propagation ``−ω_l`` turned into ``−ω`` toward the eye; ``g > 0`` scatters forward).

:func:`scattered` (``-media_bounces N >= 2``) adds the light that has scattered more than once: from a point
``x_i`` of the eye segment a walk of at most ``N − 1`` further vertices, each direction drawn from ``p`` about the
previous one (weight 1), each free flight by the medium's own density (fog: ``t = −ln(1 − ξ)/σ``; volume:
**delta tracking** with the majorant ``μ = density · max(grid)``, a tentative collision accepted with
probability ``σ_t(x)/μ``) up to the nearest surface (a flight that reaches a surface or leaves the volume's box
ends the walk: light reflected by surfaces into the medium is not followed). Each vertex multiplies the weight by
the albedo and adds its :func:`light_at`; in a5 units (``P = π p``, E.8) the walk returns ``M`` with
``S += albedo ⊙ P Σ_i w_i M(x_i)``, ``M = (1/P) Σ_vertices (Π albedo) P L(x_v)``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import drjit as dr
import mitsuba as mi

from a5mi.plugins.kernel.intersect import intersect, visible
from a5mi.plugins.media.light import box_span, shadow_transmittance
from a5mi.plugins.sampling import stratified_2d
from a5mi.plugins.syntax import syntax

if TYPE_CHECKING:
    from a5mi.plugins.emulation.planes import PlaneSet
    from a5mi.plugins.kernel.features import SceneData
    from a5mi.plugins.kernel.scene import Lights
    from a5mi.plugins.media.medium import MediumParams
    from a5mi.plugins.sampling import Stochastic

#: ``π · 1/(4π)``: the isotropic phase function on the a5 lights' scale (E.8).
PHASE = 0.25


def hg_pdf(cos: mi.Float, g: mi.Float) -> mi.Float:
    """Henyey-Greenstein's ``p(cos θ)`` (module docstring)."""
    denom = 1.0 + g * g - 2.0 * g * cos
    return (1.0 - g * g) / (4.0 * dr.pi * denom * dr.sqrt(denom))


def hg_direction(d: mi.Vector3f, g: mi.Float, u: mi.Point2f) -> mi.Vector3f:
    """A direction about ``d`` with density ``p(cos θ)``: ``cos θ = (1 + g² − ((1 − g²)/(1 − g + 2g ξ))²)/(2g)``
    (``1 − 2ξ`` for ``|g| < 10⁻³``), ``φ = 2π ξ'``."""
    sq = (1.0 - g * g) / (1.0 - g + 2.0 * g * u.x)
    cos_t = dr.select(dr.abs(g) < 1e-3, 1.0 - 2.0 * u.x, (1.0 + g * g - sq * sq) / (2.0 * g))
    cos_t = dr.clip(cos_t, -1.0, 1.0)
    sin_t = dr.safe_sqrt(1.0 - cos_t * cos_t)
    sn, cs = dr.sincos(2.0 * dr.pi * u.y)
    return mi.Frame3f(d).to_world(mi.Vector3f(sin_t * cs, sin_t * sn, cos_t))


@syntax
def light_at(scene: mi.Scene, planes: PlaneSet, x: mi.Point3f, live: mi.Bool, lights: Lights, tmin: mi.Float,
             shadows: bool, rng: Stochastic, dim: mi.UInt32, index: mi.UInt32, count: mi.UInt32,
             counter: mi.UInt32, med: MediumParams, attenuate: bool, wdir: mi.Vector3f,
             hg: bool) -> tuple[mi.Color3f, mi.UInt32]:
    """``L(x)`` (module docstring): one sample of each light, sample ``index`` of ``count`` of dimension
    ``dim + k``; ``attenuate``: times ``T_light``; ``hg``: times ``4π p(ω_l · wdir)``; returns ``(L, counter)``."""
    width = dr.width(x)
    acc = dr.zeros(mi.Color3f, width)
    k = dr.zeros(mi.UInt32, width)
    while live & (k < lights.count):
        emitter = dr.gather(mi.EmitterPtr, lights.emitters, k, live)
        is_area = dr.gather(mi.UInt32, lights.area, k, live) > 0
        u = stratified_2d(rng.pixel_key, rng.pass_key, dim + k, index, count, counter)
        counter += 2
        it = dr.zeros(mi.Interaction3f, width)
        it.p = x
        ds, light_color = emitter.sample_direction(it, u, live)
        seen = mi.Bool(live)
        if dr.hint(shadows, mode="scalar"):
            dist = dr.select(is_area, ds.dist * (1.0 - 1e-4), ds.dist)   # not the light's own shape
            far = (emitter.flags() & int(mi.EmitterFlags.Infinite)) != 0
            seen = visible(scene, planes, x, ds.d, tmin, dist, far, live)
            if dr.hint(attenuate, mode="scalar"):
                tr, counter = shadow_transmittance(med, x, ds.d, tmin, ds.dist, is_area, far, seen, rng, counter)
                light_color = light_color * tr
        if dr.hint(hg, mode="scalar"):
            light_color = light_color * (4.0 * dr.pi * hg_pdf(dr.dot(ds.d, wdir), med.g))
        acc += dr.select(seen, mi.Color3f(light_color), 0.0)
        k += 1
    return acc, counter


def _rand(rng: Stochastic, counter: mi.UInt32) -> tuple[mi.Float, mi.UInt32]:
    return mi.sample_tea_float32(rng.pass_key, counter), counter + 1


@syntax
def _delta_tracking(med: MediumParams, o: mi.Point3f, d: mi.Vector3f, t_end: mi.Float, active: mi.Bool,
                    rng: Stochastic, counter: mi.UInt32) -> tuple[mi.Float, mi.Bool, mi.UInt32]:
    """``(t, collided, counter)``: a free flight in the volume from ``o`` along ``d`` up to ``t_end``."""
    width = dr.width(t_end)
    mu = med.density * med.grid_max
    inv_mu = dr.rcp(dr.maximum(mu, 1e-30))
    t = dr.zeros(mi.Float, width)
    collided = dr.full(mi.Bool, False, width)
    live = active & (mu > 0.0)
    while live:
        xi, counter = _rand(rng, counter)
        t = t - dr.log(1.0 - xi) * inv_mu
        live &= t < t_end
        it = dr.zeros(mi.Interaction3f, width)
        it.p = o + t * d
        sigma = med.density * med.grid.eval_1(it, live)
        u, counter = _rand(rng, counter)
        hit = live & (u * mu < sigma)
        collided |= hit
        live &= ~hit
    return t, collided, counter


@syntax
def scattered(scene: mi.Scene, data: SceneData, x: mi.Point3f, d: mi.Vector3f, live: mi.Bool, shadows: bool,
              rng: Stochastic, counter: mi.UInt32) -> tuple[mi.Color3f, mi.UInt32]:
    """``M(x)`` of the module docstring: the walk from the eye-segment point ``x`` (eye ray ``d``)."""
    med = data.medium
    width = dr.width(x)
    acc = dr.zeros(mi.Color3f, width)
    weight = dr.full(mi.Color3f, 1.0 / PHASE, width)
    pos = mi.Point3f(x)
    wdir = mi.Vector3f(d)
    alive = mi.Bool(live)
    k = dr.zeros(mi.UInt32, width)
    zero_u = dr.zeros(mi.UInt32, width)
    while alive & (k + 1 < med.bounces_opaque):
        u1, counter = _rand(rng, counter)
        u2, counter = _rand(rng, counter)
        wdir = hg_direction(wdir, med.g, mi.Point2f(u1, u2))
        hit = intersect(scene, data.planes, data.rules, pos, wdir, data.tmin, zero_u)
        t_end = dr.select(hit.hit, hit.t, dr.inf)
        if dr.hint(med.kind == "fog", mode="scalar"):
            u3, counter = _rand(rng, counter)
            t = -dr.log(1.0 - u3) / dr.maximum(med.density, 1e-30)
            collided = alive & (med.density > 0.0) & (t < t_end)
        else:
            _, tb = box_span(med.box_min, med.box_max, pos, wdir, mi.Float(0.0), t_end)
            t, collided, counter = _delta_tracking(med, pos, wdir, tb, alive, rng, counter)
        alive &= collided
        pos = mi.Point3f(dr.select(alive, pos + t * wdir, pos))
        weight = weight * med.albedo
        arriving, counter = light_at(scene, data.planes, pos, alive, data.lights, data.tmin, shadows, rng,
                                     zero_u, zero_u, zero_u + 1, counter, med, shadows, wdir,
                                     med.g_value != 0.0)
        acc += dr.select(alive, weight * PHASE * arriving, 0.0)
        k += 1
    return acc, counter
