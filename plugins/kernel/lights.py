"""The light loop of SPEC B.3 (and A.3, docs/EXTENSIONS.md E.1, E.2): ``Σ_lights S · clamp(L·N, 0) · lightColor ⊙ kd``.

A *light* is an emitter with a delta flag (``a5_point``, ``a5_spot``, stock ``directional``) or an ``a5_area``
emitter (:func:`is_light`: the one rule). Each is asked ``sample_direction(p)``, which gives ``L``, the colour
arriving at ``p`` and the distance to the light (for the stock ``directional``: ``2 max(R, |p − c|)`` of the
scene's bounding sphere, past every object, as the binary's FLT_MAX). An area light (E.2) is sampled ``S`` times,
stratified over its samples and the ``-spp`` passes (E.5, dimension ``node · 256 + k``), and averaged; its shadow
ray stops short of the light's own shape (``dist · (1 − 10⁻⁴)``). With ``phong`` the handout's highlight
``clamp(L·R)^shininess · lightColor ⊙ ks`` (``R`` the mirror direction, normalised; ``shininess = 0``: 1) is added
per light. An area light seen directly adds its ``eval`` (:func:`emission`). The docs/MISTAKES.md mistakes of the
light loop (``light_dir_flipped``, ``ndotl_unclamped``, ``light_color_ignored``, ``shadow_acne``,
``shadow_beyond_light``, ``shadow_first_light_only``) are compile-time blocks of ``f.mistakes``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import drjit as dr
import mitsuba as mi

from a5mi.plugins.kernel.intersect import visible
from a5mi.plugins.materials import milled
from a5mi.plugins.media import light as media_light
from a5mi.plugins.sampling import Stochastic, stratified_2d
from a5mi.plugins.syntax import syntax

if TYPE_CHECKING:
    from a5mi.plugins.kernel.features import Features, SceneData
    from a5mi.plugins.kernel.raylog import RayLog
    from a5mi.plugins.kernel.record import TreeRecorder


class ShadingPoint(NamedTuple):
    """A hit as the light loop sees it (SPEC B.3): the interaction ``si`` and its point ``p``, the lanes ``hit``,
    the shading normal ``n``, the material's ``kd``, ``specular`` and ``shininess``, the mirror direction
    ``r_view`` (for the Phong highlight) and the hit's BSDF ``bsdf`` (None: ``si.bsdf()``; E.20's milled term)."""

    si: mi.SurfaceInteraction3f
    p: mi.Point3f
    hit: mi.Bool
    n: mi.Vector3f
    kd: mi.Color3f
    specular: mi.Color3f
    shininess: mi.Float
    r_view: mi.Vector3f
    bsdf: mi.BSDFPtr | None = None


class LightSample(NamedTuple):
    """One sample of one light at a hit (:func:`sample`): ``term`` (``clamp(L·N, 0) lightColor ⊙ kd``, plus the
    Phong highlight with ``phong``), ``seen`` (SPEC ``S``), ``d_light`` (SPEC ``L``), ``light_color``, ``dist``
    (the light's distance), ``far`` (a directional light; only with ``shadows``), ``highlight`` (only with
    ``phong``) and ``tested`` (only with ``shadows``: a shadow ray was cast, i.e. the term is not 0)."""

    term: mi.Color3f
    seen: mi.Bool
    d_light: mi.Vector3f
    light_color: mi.Color3f
    dist: mi.Float
    far: mi.Bool | None
    highlight: mi.Float | None
    tested: mi.Bool | None = None


def sample(scene: mi.Scene, data: SceneData, f: Features, emitter: mi.EmitterPtr, is_area: mi.Bool,
           sp: ShadingPoint, u: mi.Point2f) -> LightSample:
    """The light ``emitter`` (``is_area``: an E.2 light) seen from the hit ``sp`` through the unit-square sample
    ``u`` (module docstring); :func:`direct` loops over lights and samples. With ``milled`` (E.20) the term adds
    ``π ρs W(wi, L) cosθ_L lightColor`` of the hit's BSDF (``sp.bsdf``, default ``si.bsdf()``)."""
    si, p, hit, n = sp.si, sp.p, sp.hit, sp.n
    ds, light_color = emitter.sample_direction(si, u, hit)
    d_light = ds.d                                               # SPEC L
    if dr.hint("light_dir_flipped" in f.mistakes, mode="scalar"):   # MISTAKES.md: L = p - light
        d_light = -d_light
    cosine = dr.maximum(dr.dot(d_light, n), 0.0)
    if dr.hint("ndotl_unclamped" in f.mistakes, mode="scalar"):     # MISTAKES.md: L·N not clamped
        cosine = dr.dot(d_light, n)
    if dr.hint("light_color_ignored" in f.mistakes, mode="scalar"):   # MISTAKES.md: cos · kd
        term = cosine * sp.kd
    else:
        term = cosine * light_color * sp.kd
    if dr.hint(f.milled, mode="scalar"):
        term += milled.light_term(si.bsdf() if sp.bsdf is None else sp.bsdf, si, d_light, hit) * light_color
    highlight = None
    if dr.hint(f.phong, mode="scalar"):
        l_dot_r = dr.maximum(dr.dot(d_light, dr.normalize(sp.r_view)), 0.0)
        highlight = dr.select(sp.shininess == 0.0, 1.0, dr.power(l_dot_r, sp.shininess))
        term += highlight * light_color * sp.specular
    seen = mi.Bool(hit)                                          # SPEC S
    far = None
    tested = None
    if dr.hint(f.shadows, mode="scalar"):
        dist = dr.select(is_area, ds.dist * (1.0 - 1e-4), ds.dist)   # not the light's own shape
        far = (emitter.flags() & int(mi.EmitterFlags.Infinite)) != 0   # directional: the binary's FLT_MAX
        tested = mi.Bool(hit)
        if dr.hint(not f.record, mode="scalar"):
            # S only scales the term: where the term is exactly 0 in every channel (the light behind the surface,
            # a black kd) the shadow ray is not cast and S reads 0, which adds the same 0 (a NaN term is still
            # tested). Record mode (a5mi trace) tests every light, as the sample solution does.
            tested &= dr.any(term != 0.0)
        t_shadow = data.tmin
        if dr.hint("shadow_acne" in f.mistakes, mode="scalar"):          # MISTAKES.md: shadow rays from t = 0
            t_shadow = dr.zeros(mi.Float, dr.width(p))
        if dr.hint("shadow_beyond_light" in f.mistakes, mode="scalar"):  # MISTAKES.md: no upper bound on t
            dist = dr.full(mi.Float, dr.inf, dr.width(p))
            far = dr.full(mi.Bool, True, dr.width(p))
        seen = visible(scene, data.planes, p, d_light, t_shadow, dist, far, tested, data.rules)
    return LightSample(term, seen, d_light, light_color, ds.dist, far, highlight, tested)


def sample_point(rng: Stochastic, node: mi.UInt32, k: mi.UInt32, j: mi.UInt32, n_samples: mi.UInt32,
                 counter: mi.UInt32) -> mi.Point2f:
    """E.2's sample ``j`` of ``n_samples`` of light ``k`` at ray-tree node ``node``, stratified over the samples
    and the ``-spp`` passes (E.5 dimension ``node · 256 + k``, draws ``counter``, ``counter + 1``)."""
    return stratified_2d(rng.pixel_key, rng.pass_key, node * 256 + k, rng.pass_index * n_samples + j,
                         rng.passes * n_samples, counter)


@syntax
def direct(scene: mi.Scene, data: SceneData, f: Features, sp: ShadingPoint, local: mi.Color3f, rng: Stochastic,
           node: mi.UInt32, counter: mi.UInt32, n_shadow: mi.Float, rec: TreeRecorder | None = None,
           at: mi.UInt32 | None = None, log: RayLog | None = None) -> tuple[mi.Color3f, mi.UInt32, mi.Float]:
    """The light loop of SPEC B.3 at the hit ``sp`` (module docstring): ``local + Σ_lights (1/S) Σ_samples
    S·term``, with ``counter`` advanced by two draws per light sample and ``n_shadow`` by the shadow rays traced;
    returns ``(local, counter, n_shadow)``. ``node``: the ray-tree node (E.5 dimensions); ``rec`` / ``at``: record
    mode's recorder and node number; ``log``: ray-log mode's :class:`~.raylog.RayLog`."""
    p, hit = sp.p, sp.hit
    k = dr.zeros(mi.UInt32, dr.width(p))
    while hit & (k < data.lights.count):
        emitter = dr.gather(mi.EmitterPtr, data.lights.emitters, k, hit)
        # E.2: S stratified samples of an area light (S = 1 and the sample unused for the others)
        n_samples = dr.gather(mi.UInt32, data.lights.samples, k, hit)
        is_area = dr.gather(mi.UInt32, data.lights.area, k, hit) > 0
        acc = dr.zeros(mi.Color3f, dr.width(p))
        j = dr.zeros(mi.UInt32, dr.width(p))
        while hit & (j < n_samples):
            u = mi.Point2f(0.5)
            if dr.hint(f.area_lights, mode="scalar"):
                u = sample_point(rng, node, k, j, n_samples, counter)
            counter += 2
            ls = sample(scene, data, f, emitter, is_area, sp, u)
            if dr.hint(f.ray_log and f.shadows, mode="scalar"):   # ray-log mode: the shadow ray as cast
                log.shadow(ls.tested, p, ls.d_light, data.tmin, dr.select(is_area, ls.dist * (1.0 - 1e-4), ls.dist),
                           ls.far, n_shadow)
            if dr.hint(f.shadows, mode="scalar"):
                n_shadow += dr.select(ls.tested, 1.0, 0.0)
            term = ls.term
            seen = ls.seen
            if dr.hint("shadow_first_light_only" in f.mistakes, mode="scalar"):   # MISTAKES.md: S of light 0 only
                seen = ls.seen | (hit & (k > 0))
            if dr.hint(f.media_light, mode="scalar"):   # E.8, E.9: the light attenuated on its way
                tr, counter = media_light.shadow_transmittance(data.medium, p, ls.d_light, data.tmin, ls.dist,
                                                               is_area, ls.far, ls.seen, rng, counter)
                term = term * tr
            acc += dr.select(seen, term, 0.0)
            if dr.hint(f.record, mode="scalar"):
                record(rec, scene, data, f, at, k, sp, ls, is_area, n_samples)
            j += 1
        local += acc * (1.0 / mi.Float(dr.maximum(n_samples, 1)))
        k += 1
    return local, counter, n_shadow


def record(rec: TreeRecorder, scene: mi.Scene, data: SceneData, f: Features, at: mi.UInt32, k: mi.UInt32,
           sp: ShadingPoint, ls: LightSample, is_area: mi.Bool, n_samples: mi.UInt32) -> None:
    """Record mode: light ``k``'s values at node ``at`` of the hit ``sp`` (an area light keeps its last sample's
    ray and verdict); with shadows also the occluder's identity (a nearest-hit query of its own)."""
    p, hit, n = sp.p, sp.hit, sp.n
    if dr.hint(f.shadows, mode="scalar"):
        dist = dr.select(is_area, ls.dist * (1.0 - 1e-4), ls.dist)
        rec.occluder(scene, data.planes, at, k, p, ls.d_light, data.tmin, dist, ls.far, hit)
    if dr.hint(f.phong, mode="scalar"):
        rec.light(at, k, highlight=ls.highlight)
    rec.light(at, k, valid=hit, L=ls.d_light, n_dot_l=dr.dot(ls.d_light, n), light_color=ls.light_color,
              dist=ls.dist, visible=ls.seen, tested=f.shadows,
              term=ls.term * (1.0 / mi.Float(dr.maximum(n_samples, 1))))


def emission(scene: mi.Scene, si: mi.SurfaceInteraction3f, on_shape: mi.Bool, local: mi.Color3f) -> mi.Color3f:
    """``local`` plus the ``eval`` of an area light's shape (E.2) hit by the ray, on the lanes ``on_shape``
    (hits not on a plane)."""
    emitter = si.emitter(scene, on_shape)
    sees_light = on_shape & (emitter != None)  # noqa: E711 - a Dr.Jit pointer comparison
    return dr.select(sees_light, local + mi.Color3f(emitter.eval(si, sees_light)), local)
