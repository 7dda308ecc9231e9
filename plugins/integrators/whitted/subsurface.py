"""Subsurface scattering in ``a5_whitted`` (``-subsurface dipole|walk``, docs/EXTENSIONS.md E.18).

A material with a ``subsurface`` block (``a5_material``'s ``sss_*`` attributes, ``sss_eta > 0``) loses its
Lambert term ``kd · max(L·N, 0) · lightColor`` to the light that crosses its boundary, scatters inside and
leaves at the hit ``x_o`` toward the eye (its ambient term and its specular children stay as SPEC B.3 has them).
Light enters at a boundary point ``x_i`` with the transmitted a5 irradiance (``F_t = 1 − F_r``, the exact
unpolarised Fresnel reflectance of the index ``η``; ``S`` the shadow test with ``-shadows``)::

    E_t(x_i) = Σ_lights S · F_t(η, L·N_i) · max(L·N_i, 0) · lightColor

* ``dipole`` (Jensen et al. 2001, plugins/media/dipole.py): ``L_sss = F_t(η, cos θ_o) ∫_A R_d(|x_o −
  x_i|) E_t(x_i) dA``, estimated with ``samples`` probe points per pass (pbrt-v3's ``SeparableBSSRDF``
  sampling): an axis (the normal with probability 1/2, each tangent 1/4), a radius from the mixture of six
  ``Gamma(2, λ)`` densities, ``λ`` each channel's ``σ_tr`` and ``σ_t'`` (disc density
  ``p(r) = (1/6) Σ λ² e^{−λ r}/(2π)``), a probe chord of half-length ``9.23/min λ`` along the axis; of its
  hits on the same shape (at most 4) hit ``k`` is taken with probability ``w_k/W``, ``w = mean_c R_d(|x_k −
  x_o|)``, ``W = Σ w`` (pbrt takes one uniformly, weight ``N``; this picks the near side of a thin part far
  more often), weight ``(W/w_k) / p_A(x_k)`` with ``p_A = Σ_axes P_axis p(r_axis) |N_k · axis|``. The a5 ``π``
  is absorbed as in the Lambert term, so a uniformly lit flat face shows ``F_t F_t R_d,total · E`` (a Lambert
  surface of albedo ``R_d,total``).
* ``walk`` (exact for the boundary model): a volumetric random walk from ``x_o``: refracted in with weight
  ``F_t(η, cos θ_o)``; free flights from the mixture of the channels' exponentials (each flight draws a
  channel ``c`` uniformly, then ``s = −ln(1 − ξ)/σ_t,c``; weight ``f/⟨p⟩``: scatter
  ``σ_s e^{−σ_t s}/mean_c(σ_t,c e^{−σ_t,c s})``, boundary ``e^{−σ_t t_b}/mean_c(e^{−σ_t,c t_b})``);
  Henyey-Greenstein directions (``g``); a flight from a scattering vertex starts at the vertex itself, one
  from the boundary (the entry, an internal reflection) ``tmin`` along its direction (the flight's length counts
  from the boundary point), so a vertex however near the boundary finds it: exact at any density (a start
  ``tmin`` ahead of a vertex misses a boundary nearer than ``tmin``, a loss that grows with ``σ_t · tmin``);
  at the boundary the walk adds
  the light that enters there, ``E_t(x_b)/η²`` (the boundary radiates the transmitted irradiance inward
  diffusely: radiance ``E_t/π``, basic radiance ``L/η²`` ``E_t/(π η²)``, a5 scale ``E_t/η²``; the walk
  carries basic radiance, which a smooth boundary transmits with ``F_t`` alone), plus with an environment the
  background seen through the boundary ``F_t · background(refracted)``, and continues internally reflected
  with weight ``F_r``; Russian roulette after 16 events (survival ``min(max w, 0.99)``), at most 1024 events.

Random numbers: TEA hashes ``tea_float(pass_key, counter)`` of the lane's E.5 keys (plugins/sampling.py). The
probe and the walk intersect with Mitsuba's own ``ray_intersect`` (not the binary's octree rules; planes are
not probed: a Plane's subsurface material has no light).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import drjit as dr
import mitsuba as mi

from a5mi.plugins.integrators.whitted.medium_walk import hg_direction
from a5mi.plugins.kernel import lights
from a5mi.plugins.kernel.surfaces import background
from a5mi.plugins.media.dipole import Dipole, dipole, profile
from a5mi.plugins.optics import snell
from a5mi.plugins.params import read_choice
from a5mi.plugins.syntax import syntax

if TYPE_CHECKING:
    from a5mi.plugins.kernel.features import Features, SceneData
    from a5mi.plugins.sampling import Stochastic

METHODS = ("none", "dipole", "walk")
#: Hits of one probe chord considered; events of one walk; Russian roulette from this event on.
PROBE_HITS, MAX_EVENTS, RR_EVENTS = 4, 1024, 16
#: ``P_axis`` of the normal and of each tangent.
AXIS_P = (0.5, 0.25, 0.25)


def method_from_props(props: mi.Properties) -> str:
    """``a5_whitted``'s ``subsurface`` parameter: one of :data:`METHODS` (default ``none``)."""
    return read_choice("a5_whitted", props, "subsurface", "none", METHODS)


def _rand(rng: Stochastic, counter: mi.UInt32) -> tuple[mi.Float, mi.UInt32]:
    return mi.sample_tea_float32(rng.pass_key, counter), counter + 1


def _transmitted(cos: mi.Float, eta: mi.Float) -> mi.Float:
    """``F_t = 1 − F_r(η, cos)`` for light arriving from outside at ``cos = |cos θ|``."""
    return 1.0 - mi.fresnel(dr.abs(cos), eta)[0]


@syntax
def irradiance(scene: mi.Scene, data: SceneData, f: Features, p: mi.Point3f, n: mi.Vector3f, eta: mi.Float,
               live: mi.Bool, rng: Stochastic, counter: mi.UInt32) -> tuple[mi.Color3f, mi.UInt32]:
    """``E_t(p)`` (module docstring) at ``p`` with outward normal ``n``: one sample per light."""
    width = dr.width(p)
    fl = f._replace(phong=False)
    it = dr.zeros(mi.SurfaceInteraction3f, width)
    it.p = p
    it.n = n
    it.sh_frame = mi.Frame3f(n)
    acc = dr.zeros(mi.Color3f, width)
    one = mi.Color3f(1.0)
    k = dr.zeros(mi.UInt32, width)
    while live & (k < data.lights.count):
        emitter = dr.gather(mi.EmitterPtr, data.lights.emitters, k, live)
        is_area = dr.gather(mi.UInt32, data.lights.area, k, live) > 0
        u = mi.Point2f(mi.sample_tea_float32(rng.pass_key, counter),
                       mi.sample_tea_float32(rng.pass_key, counter + 1))
        counter += 2
        ls = lights.sample(scene, data, fl, emitter, is_area,
                           lights.ShadingPoint(it, p, live, n, one, one * 0.0, mi.Float(0.0), n), u)
        acc += dr.select(ls.seen, ls.term * _transmitted(dr.dot(ls.d_light, n), eta), 0.0)
        k += 1
    return acc, counter


def _facing(n: mi.Vector3f, d: mi.Vector3f) -> mi.Vector3f:
    """``n`` turned against ``d`` (the side a ray along ``d`` comes from)."""
    return dr.select(dr.dot(n, d) > 0.0, -n, n)


def _disc_pdf(lam: list[mi.Float], r: mi.Float) -> mi.Float:
    return sum(l * l * dr.exp(-l * r) for l in lam) / (6.0 * 2.0 * dr.pi)


@syntax
def _probe(scene: mi.Scene, shape: mi.ShapePtr, origin: mi.Point3f, axis: mi.Vector3f, length: mi.Float,
           live: mi.Bool, dp: Dipole, p: mi.Point3f, rng: Stochastic,
           counter: mi.UInt32) -> tuple[mi.Point3f, mi.Vector3f, mi.Float, mi.Float, mi.UInt32]:
    """One of the hits on ``shape`` of the chord ``origin − t axis``, ``0 < t < length`` (at most
    :data:`PROBE_HITS`), chosen with probability ``w_k / W``, ``w = mean_channels R_d(|x − p|)`` (a weighted
    reservoir): ``(point, geometric normal, W, w of the chosen one, counter)``."""
    width = dr.width(origin)
    total = dr.zeros(mi.Float, width)
    chosen = dr.zeros(mi.Float, width)
    x = dr.zeros(mi.Point3f, width)
    nx = dr.zeros(mi.Vector3f, width)
    o = mi.Point3f(origin)
    rest = mi.Float(length)
    k = dr.zeros(mi.UInt32, width)
    go = mi.Bool(live)
    while go & (k < PROBE_HITS):
        si = scene.ray_intersect(mi.Ray3f(o, -axis, rest), go)
        ok = go & si.is_valid()
        same = ok & (si.shape == shape)
        rd = profile(dp, dr.norm(si.p - p))
        w = dr.select(same, (rd.x + rd.y + rd.z) / 3.0, 0.0)
        total += w
        u, counter = _rand(rng, counter)
        take = same & (w > 0.0) & (u * total < w)
        x = dr.select(take, si.p, x)
        nx = dr.select(take, mi.Vector3f(si.n), nx)
        chosen = dr.select(take, w, chosen)
        step = si.t + 1e-4 * (1.0 + si.t)
        o = mi.Point3f(o - step * axis)
        rest = rest - step
        go = ok & (rest > 0.0)
        k += 1
    return x, nx, total, chosen, counter


@syntax
def dipole_radiance(scene: mi.Scene, data: SceneData, f: Features, si: mi.SurfaceInteraction3f,
                    p: mi.Point3f, n_out: mi.Vector3f, live: mi.Bool, sigma_a: mi.Color3f, sigma_s: mi.Color3f,
                    g: mi.Float, eta: mi.Float, samples: mi.UInt32, rng: Stochastic,
                    counter: mi.UInt32) -> tuple[mi.Color3f, mi.UInt32]:
    """``∫ R_d E_t dA`` at ``p`` by probe sampling (module docstring), without the exit ``F_t``."""
    width = dr.width(p)
    dp = dipole(sigma_a, sigma_s, g, eta)
    tr = dr.maximum(dp.sigma_tr, 0.05 * dp.sigma_t)            # a pdf choice: any rate > 0 is unbiased
    lam = [tr.x, tr.y, tr.z, dp.sigma_t.x, dp.sigma_t.y, dp.sigma_t.z]
    lam_min = dr.minimum(dr.minimum(dr.minimum(tr.x, tr.y), tr.z), 1e30)
    length = 9.23 / dr.maximum(lam_min, 1e-30)                 # the 99.9 % radius of Gamma(2, λ_min)
    frame = mi.Frame3f(n_out)
    acc = dr.zeros(mi.Color3f, width)
    j = dr.zeros(mi.UInt32, width)
    while live & (j < samples):
        u0, counter = _rand(rng, counter)
        u1, counter = _rand(rng, counter)
        u2, counter = _rand(rng, counter)
        u3, counter = _rand(rng, counter)
        u4, counter = _rand(rng, counter)
        axis = dr.select(u0 < 0.5, frame.n, dr.select(u0 < 0.75, frame.s, frame.t))
        a1 = dr.select(u0 < 0.5, frame.s, dr.select(u0 < 0.75, frame.t, frame.n))
        a2 = dr.select(u0 < 0.5, frame.t, dr.select(u0 < 0.75, frame.n, frame.s))
        c = mi.UInt32(dr.minimum(u1 * 6.0, 5.0))
        rate = dr.select(c == 0, lam[0], dr.select(c == 1, lam[1], dr.select(c == 2, lam[2], dr.select(
            c == 3, lam[3], dr.select(c == 4, lam[4], lam[5])))))
        r = -(dr.log(1.0 - u2) + dr.log(1.0 - u3)) / rate
        sn, cs = dr.sincos(2.0 * dr.pi * u4)
        centre = p + r * (cs * a1 + sn * a2)
        x, nx, total, chosen, counter = _probe(scene, si.shape, centre + length * axis, axis, 2.0 * length, live,
                                               dp, p, rng, counter)
        ok = live & (chosen > 0.0)
        delta = x - p
        pdf = dr.zeros(mi.Float, width)
        for ax, pa in zip((frame.n, frame.s, frame.t), AXIS_P, strict=True):
            h = dr.dot(delta, ax)
            r_ax = dr.safe_sqrt(dr.squared_norm(delta) - h * h)
            pdf += pa * _disc_pdf(lam, r_ax) * dr.abs(dr.dot(nx, ax))
        n_i = _facing(nx, -n_out)                                  # the probe point's outward side
        e_t, counter = irradiance(scene, data, f, x, n_i, eta, ok, rng, counter)
        rd = profile(dp, dr.norm(delta))
        acc += dr.select(ok & (pdf > 0.0), rd * e_t * (total / dr.maximum(chosen, 1e-30)) / pdf, 0.0)
        j += 1
    return acc / mi.Float(dr.maximum(samples, 1)), counter


def _channel(c: mi.UInt32, v: mi.Color3f) -> mi.Float:
    return dr.select(c == 0, v.x, dr.select(c == 1, v.y, v.z))


@syntax
def walk_radiance(scene: mi.Scene, data: SceneData, f: Features, p: mi.Point3f, d: mi.Vector3f,
                  n_out: mi.Vector3f, live: mi.Bool, sigma_a: mi.Color3f, sigma_s: mi.Color3f, g: mi.Float,
                  eta: mi.Float, samples: mi.UInt32, rng: Stochastic,
                  counter: mi.UInt32) -> tuple[mi.Color3f, mi.UInt32]:
    """The random walk of the module docstring from ``p`` (eye ray ``d``), the exit ``F_t`` included; the
    mean of ``samples`` walks."""
    width = dr.width(p)
    sigma_t = sigma_a + sigma_s
    t_in, _ = snell(d, n_out, mi.Float(1.0), eta)
    w_in = _transmitted(dr.dot(d, n_out), eta)
    total = dr.zeros(mi.Color3f, width)
    j = dr.zeros(mi.UInt32, width)
    while live & (j < samples):
        x = mi.Point3f(p)
        wd = mi.Vector3f(t_in)
        w = mi.Color3f(1.0)
        acc = dr.zeros(mi.Color3f, width)
        events = dr.zeros(mi.UInt32, width)
        alive = mi.Bool(live)
        on_wall = mi.Bool(True)
        while alive & (events < MAX_EVENTS):
            uc, counter = _rand(rng, counter)
            st_c = _channel(mi.UInt32(dr.minimum(uc * 3.0, 2.0)), sigma_t)    # this flight's channel
            u, counter = _rand(rng, counter)
            s = -dr.log(1.0 - u) / dr.maximum(st_c, 1e-30)
            lead = dr.select(on_wall, data.tmin, 0.0)                       # off the wall, not off a vertex
            si = scene.ray_intersect(mi.Ray3f(x + lead * wd, wd), alive)
            alive &= si.is_valid()
            t_b = si.t + lead
            scatter = alive & (s < t_b)
            at_wall = alive & ~scatter
            tt = dr.select(scatter, s, t_b)
            tr = dr.exp(-sigma_t * tt)
            p_dist = dr.select(scatter, (sigma_t.x * tr.x + sigma_t.y * tr.y + sigma_t.z * tr.z) / 3.0,
                               (tr.x + tr.y + tr.z) / 3.0)
            w = w * dr.select(scatter, sigma_s * tr, tr) / dr.maximum(p_dist, 1e-30)
            x = mi.Point3f(dr.select(scatter, x + s * wd, si.p))
            nb = _facing(mi.Vector3f(si.n), -wd)                             # outward: the side the walk leaves by
            e_t, counter = irradiance(scene, data, f, x, nb, eta, at_wall, rng, counter)
            fr = mi.fresnel(dr.abs(dr.dot(wd, nb)), 1.0 / eta)[0]
            out, _ = snell(wd, -nb, eta, mi.Float(1.0))
            light = e_t / (eta * eta)                             # basic radiance of the inward emission
            if dr.hint(f.environment, mode="scalar"):
                light += (1.0 - fr) * background(scene, out, at_wall & (fr < 1.0))
            acc += dr.select(at_wall, w * light, 0.0)
            u2, counter = _rand(rng, counter)
            u3, counter = _rand(rng, counter)
            wd = dr.select(scatter, hg_direction(wd, g, mi.Point2f(u2, u3)), wd - 2.0 * dr.dot(wd, nb) * nb)
            w = dr.select(at_wall, w * fr, w)
            on_wall = mi.Bool(at_wall)
            events += 1
            q = dr.minimum(dr.maximum(dr.maximum(w.x, w.y), w.z), 0.99)
            u4, counter = _rand(rng, counter)
            roulette = events >= RR_EVENTS
            alive &= ~roulette | (u4 < q)
            w = dr.select(roulette, w / dr.maximum(q, 1e-30), w)
            alive &= dr.maximum(dr.maximum(w.x, w.y), w.z) > 0.0
        total += acc
        j += 1
    return w_in * total / mi.Float(dr.maximum(samples, 1)), counter


def shade(scene: mi.Scene, data: SceneData, f: Features, bsdf: mi.BSDFPtr, si: mi.SurfaceInteraction3f,
          p: mi.Point3f, d: mi.Vector3f, n: mi.Vector3f, hit: mi.Bool, kd: mi.Color3f, local: mi.Color3f,
          rng: Stochastic, counter: mi.UInt32) -> tuple[mi.Color3f, mi.Color3f, mi.UInt32]:
    """``(kd, local, counter)``: on the lanes whose material has a subsurface medium, ``kd = 0`` (no Lambert
    term) and ``local += L_sss`` by ``f.subsurface`` (module docstring)."""
    eta = bsdf.eval_attribute_1("sss_eta", si, hit)
    sss = hit & (eta > 0.0)
    sigma_a = bsdf.eval_attribute_3("sss_sigma_a", si, sss)
    sigma_s = bsdf.eval_attribute_3("sss_sigma_s", si, sss)
    g = bsdf.eval_attribute_1("sss_g", si, sss)
    samples = mi.UInt32(bsdf.eval_attribute_1("sss_samples", si, sss))
    eta = dr.select(sss, eta, 1.0)
    n_out = _facing(n, d)
    if f.subsurface == "dipole":
        rad, counter = dipole_radiance(scene, data, f, si, p, n_out, sss, sigma_a, sigma_s, g, eta, samples, rng,
                                       counter)
        rad = rad * _transmitted(dr.dot(d, n_out), eta)
    else:
        rad, counter = walk_radiance(scene, data, f, p, d, n_out, sss, sigma_a, sigma_s, g, eta, samples, rng,
                                     counter)
    return dr.select(sss, 0.0, kd), dr.select(sss, local + rad, local), counter
