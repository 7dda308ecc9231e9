"""A ray segment of ``a5_whitted`` in a participating medium (docs/EXTENSIONS.md E.8, E.9; the medium is
plugins/media/medium.py).

Every ray segment of the Whitted tree that travels in air (medium index 1: camera, mirror and refracted rays
outside glass; none inside glass) from ``t0 = tmin`` to its hit ``t1`` (``∞`` on a miss) is attenuated and
gains in-scattered light (single scattering; the light arrives at a point of the medium as at a surface: the
a5 light's colour, times its shadow test, unattenuated on its way, like the a5 lights have no inverse-square
law; with ``medium_bounces >= 1`` times its transmittance, plugins/media/light.py, and with ``>= 2`` plus the
light scattered more than once, plugins/integrators/whitted/medium_walk.py, which also holds the phase
function of ``g``)::

    node contribution = T · (local or background) + S,    children's weights ⊙= T
    T = exp(−∫ σ_t(t) dt),    S = albedo ⊙ P ∫ σ_t(t) exp(−∫_t0^t σ_t) Σ_k V_k(x(t)) lightColor_k(x(t)) dt

with ``albedo`` the medium's ``color`` (``σ_s = albedo · σ_t``) and ``P = π · 1/(4π) = 1/4``: the isotropic
phase function ``1/(4π)`` times the factor ``π`` by which the a5 Lambert term ``kd · max(L·N, 0) · lightColor``
exceeds the physical ``kd/π``, so fog and surfaces are lit on the same scale. Estimators (``N = steps``, one
jitter ``ξ`` per segment, stratified over the ``-spp`` passes by :func:`.sampling.stratified_2d`, ``u_i = (i +
ξ)/N``):

* Fog (``σ_t = density``): ``T = exp(−σ (t1 − t0))``; distances by inversion of the truncated exponential,
  ``t_i = t0 − ln(1 − u_i (1 − T))/σ``, so ``S = albedo ⊙ P (1 − T) (1/N) Σ_i L(t_i)``: exact for a constant
  ``L`` (closed form ``albedo P (1 − exp(−σ d)) L``), unbiased otherwise;
* Volume (``σ_t = density · grid(x)`` inside the box, 0 outside): the segment clipped to the box ``[ta, tb]``
  is cut in ``N`` equal steps ``Δ = (tb − ta)/N``, sampled at ``t_i = ta + u_i (tb − ta)`` with ``σ_i =
  σ_t(x(t_i))`` held constant over step ``i``: ``T = exp(−Δ Σ_i σ_i)``, ``S = albedo ⊙ P Σ_i exp(−Δ Σ_{j<i} σ_j)
  (1 − exp(−σ_i Δ)) L(t_i)``: exact for a constant density and a constant ``L``.

``L(x) = Σ_k V_k lightColor_k`` (:func:`.medium_walk.light_at`): one sample per light per step
(``sample_direction`` at ``x``; an area light's sample stratified over the steps and passes), shadow rays
(``tmin`` to the light, planes included) when the integrator traces shadows.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import drjit as dr
import mitsuba as mi

from a5mi.plugins.integrators.whitted.medium_walk import PHASE, light_at, scattered
from a5mi.plugins.media.light import box_span
from a5mi.plugins.media.medium import MEDIUM_DIM, MediumParams
from a5mi.plugins.sampling import Stochastic, stratified_2d
from a5mi.plugins.syntax import syntax

if TYPE_CHECKING:
    from a5mi.plugins.kernel.features import SceneData


def _span(med: MediumParams, o: mi.Point3f, d: mi.Vector3f, t0: mi.Float,
          t1: mi.Float) -> tuple[mi.Float, mi.Float]:
    """The part of ``[t0, t1]`` in the medium: all of it (fog) or the part inside the box (volume)."""
    return (mi.Float(t0), mi.Float(t1)) if med.kind == "fog" else box_span(med.box_min, med.box_max, o, d, t0, t1)


def _step(med: MediumParams, o: mi.Point3f, d: mi.Vector3f, ta: mi.Float, u: mi.Float, span: mi.Float,
          frac: mi.Float, n: mi.UInt32, tau: mi.Float, live: mi.Bool) -> tuple[mi.Float, mi.Float, mi.Float]:
    """Step ``u = (i + ξ)/N`` of the module docstring's estimator: ``(t_i, weight_i, optical depth so far)``."""
    if med.kind == "fog":
        t = ta - dr.log(1.0 - u * frac) / dr.maximum(med.density, 1e-30)
        return t, frac / mi.Float(n), tau
    t = ta + u * span
    it = dr.zeros(mi.Interaction3f, dr.width(t))
    it.p = o + t * d
    step_tau = med.density * med.grid.eval_1(it, live) * (span / mi.Float(n))
    return t, dr.exp(-tau) * (1.0 - dr.exp(-step_tau)), tau + step_tau


@syntax
def segment(scene: mi.Scene, data: SceneData, o: mi.Point3f, d: mi.Vector3f, t0: mi.Float, t1: mi.Float,
            active: mi.Bool, shadows: bool, rng: Stochastic, node: mi.UInt32,
            counter: mi.UInt32) -> tuple[mi.Float, mi.Color3f, mi.UInt32]:
    """``(T, S, counter)`` of the segment ``o + t d``, ``t0 <= t <= t1`` (module docstring) in the medium
    ``data.medium``; ``T = 1``, ``S = 0`` on lanes not ``active`` (rays inside glass)."""
    med = data.medium
    width = dr.width(d)
    ta, tb = _span(med, o, d, t0, t1)
    live = active & (tb > ta)
    span = dr.select(live, tb - ta, 0.0)
    n = med.steps
    dim = node * 256 + MEDIUM_DIM
    xi = stratified_2d(rng.pixel_key, rng.pass_key, dim + 255, rng.pass_index, rng.passes, counter).x
    counter += 2
    tau_fog = dr.select(live & (med.density > 0.0), med.density * span, 0.0)   # sigma = 0: no NaN from 0·inf
    frac = 1.0 - dr.exp(-tau_fog)
    tau = dr.zeros(mi.Float, width)
    light = dr.zeros(mi.Color3f, width)
    i = dr.zeros(mi.UInt32, width)
    while live & (i < n):
        u = (mi.Float(i) + xi) / mi.Float(n)
        t, w, tau = _step(med, o, d, ta, u, span, frac, n, tau, live)
        arriving, counter = light_at(scene, data.planes, o + t * d, live, data.lights, data.tmin, shadows, rng,
                                     dim, rng.pass_index * n + i, rng.passes * n, counter, med,
                                     shadows and med.bounces > 0, d, med.g_value != 0.0)
        if dr.hint(med.bounces > 1, mode="scalar"):       # -media_bounces N >= 2: light scattered more than once
            more, counter = scattered(scene, data, o + t * d, d, live & (w > 0.0), shadows, rng, counter)
            arriving += more
        light += w * arriving
        i += 1
    transmittance = _transmittance(med, tau_fog, tau)
    return transmittance, light * med.albedo * PHASE, counter


def _transmittance(med: MediumParams, tau_fog: mi.Float, tau: mi.Float) -> mi.Float:
    """``T = exp(−optical depth)``: the closed form (fog) or the marched sum (volume)."""
    return dr.exp(-(tau_fog if med.kind == "fog" else tau))
