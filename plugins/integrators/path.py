"""The ``a5_path`` integrator: path tracing of the physically based reading of an a5 scene
(docs/EXTENSIONS.md E.13, E.14), one ``@dr.syntax`` kernel built from the kernel library.

Per camera ray (unit direction, tmin 0, index 1) the estimator of pbrt's ``PathIntegrator``::

    L = Σ_vertices β_i · ( w_e Le(hit) + NEE_i )        β_0 = 1,  β_{i+1} = β_i · f |cos θ| / pdf

* every ray adds the emission it finds: the environment when it escapes, an emitter's shape (``a5_area``,
  stock ``area``) when it hits one, weighted ``w_e = p_f² / (p_f² + p_l²)`` against next-event estimation (1
  for camera rays and after a delta lobe): :func:`.kernel.pbr_lights.emission`, ``environment``;
* at every surface vertex ``i <= max_depth`` next-event estimation samples every light once and the
  environment once (:func:`.kernel.pbr_lights.direct`, power heuristic for lights with extent);
* the next direction is sampled from the BSDF (:func:`.kernel.pbr.sample`: Lambert cosine-weighted, mirror,
  dielectric by the ``fresnel`` mode);
* Russian roulette from ``rr_depth`` on: after the ``d``-th scattering (``d >= rr_depth``) the path
  survives with probability ``q = min(max_c β_c, 0.95)`` and ``β`` is divided by ``q`` (unbiased).

``max_depth`` (``-bounces``) is the number of scattering vertices after the first hit: next-event
estimation at vertices ``0 .. max_depth``, and the ray sampled at the last one still adds the emission it
hits (its MIS partner), so ``max_depth = B`` equals Mitsuba's ``path`` with ``max_depth = B + 2`` (path
segments). Rays and shadow rays use :func:`.kernel.intersect.intersect` / ``visible`` (the binary's mesh
rules, exact planes); materials :func:`.kernel.surfaces.surface_at`. Sample numbers are the E.5 keys
(:mod:`.sampling`): 2D dimension ``256·vertex + slot`` stratified over the ``-spp`` passes (slot ``k`` for
light ``k``, 254 the environment, 255 the BSDF) and padded across dimensions (:mod:`.kernel.pbr_sampling`: an
independent permutation of the strata per pixel and dimension), 1D draws (lobe, roulette) TEA hashes of the
pass key.
"""

from __future__ import annotations

from typing import NamedTuple

import drjit as dr
import mitsuba as mi

from a5mi.plugins.integrators.base import E13_FIXED, A5Integrator, camera_rays
from a5mi.plugins.kernel.features import Features, SceneData
from a5mi.plugins.kernel.intersect import intersect
from a5mi.plugins.kernel.pbr import power_heuristic, sample
from a5mi.plugins.kernel.pbr_lights import PbrLights, direct, emission, environment, light_point
from a5mi.plugins.kernel.pbr_lights import lights_of as pbr_lights_of
from a5mi.plugins.kernel.pbr_record import PathRecorder, lobe_code
from a5mi.plugins.kernel.pbr_surface import surface_lobes
from a5mi.plugins.kernel.record import shape_id
from a5mi.plugins.sampling import SamplePass, Stochastic, stochastic
from a5mi.plugins.syntax import syntax


class PathResult(NamedTuple):
    """What :func:`trace_paths` returns per camera ray: the radiance ``color``, the first hit's normal ``n`` and
    distance ``t``, and the rays traced by kind."""

    color: mi.Color3f
    n: mi.Vector3f
    t: mi.Float
    n_reflection: mi.Float
    n_refraction: mi.Float
    n_shadow: mi.Float
#: the E.5 slot of the BSDF sample at a vertex
BSDF_SLOT = 255


class A5PathIntegrator(A5Integrator):
    """Path tracing with next-event estimation, MIS and Russian roulette (module docstring).

    ================ ======= ======= ==========================================================
    parameter        type    default meaning
    ================ ======= ======= ==========================================================
    max_depth        int     4       scattering vertices after the first hit (``-bounces``)
    rr_depth         int     5       Russian roulette from this many scatterings on (``-rr_depth``)
    fresnel          string  a5      ``a5`` | ``schlick`` | ``exact`` (SPEC B.3, E.13)
    reflection       bool    true    mirror lobes (``-reflection_off``: none)
    refraction       bool    true    refracted lobes (``-refraction_off``: every material opaque)
    bump             bool    false   bump / normal-mapped shading normal (E.7)
    tmin             float   0.001   tmin of secondary and shadow rays
    aovs             string  ""      ``normal`` (nx, ny, nz), ``depth`` (t) of the first hit,
                                     ``counts`` (n_reflection, n_refraction, n_shadow)
    plane_<id>_*     ...             exact infinite planes, as ``a5_whitted`` (SPEC A.6)
    ================ ======= ======= ==========================================================

    ``shadows``, ``phong``, ``ambient``, ``glossy``, ``glossy_samples`` and ``dispersion`` are accepted (the
    converter writes them for every a5 integrator) and not used: E.13 always traces shadows and has no
    ambient or Phong term; a medium (``medium`` other than ``none``) is refused.
    ``sample(..., sample_pass=)`` takes the E.5 pass like ``a5_whitted``.
    Dict form: ``{'type': 'a5_path', 'max_depth': 8, 'rr_depth': 5}``.
    """

    name = "a5_path"
    aov_groups = ("normal", "depth", "counts")
    options = ("rr_depth",)
    fixed = {**E13_FIXED, "shadows": True}   # E.13: shadows always, no ambient or Phong term
    exposed = ("max_depth", "rr_depth", "fresnel", "reflection", "refraction", "bump", "tmin", "aovs")

    def trace(self, scene: mi.Scene, ray: mi.Ray3f, active: mi.Bool | bool = True,
              sampler: mi.Sampler | None = None, sample_pass: SamplePass | None = None,
              record: PathRecorder | None = None, rng: Stochastic | None = None) -> PathResult:
        """``(radiance, first-hit normal, first-hit t, n_reflection, n_refraction, n_shadow)`` of one path per
        camera ray (module docstring). ``record`` (``a5mi trace``): fill this recorder with every vertex.
        ``rng``: per-lane E.5 keys and pass indices instead of those of ``sample_pass`` (many passes of a pixel
        in one launch)."""
        data = self.scene_data(scene)
        o, d, go = camera_rays(ray, active)
        if rng is None:
            rng = stochastic(sample_pass, sampler, dr.width(go), 1)
        return trace_paths(scene, o, d, go, data, pbr_lights_of(scene), rng,
                           self.features(scene, data, record is not None), dr.opaque(mi.UInt32, self.rr_depth), record)

    def sample(self, scene: mi.Scene, sampler: mi.Sampler | None, ray: mi.Ray3f, medium: mi.Medium | None = None,
               active: mi.Bool | bool = True, sample_pass: SamplePass | None = None,
               ) -> tuple[mi.Color3f, mi.Bool, list[mi.Float]]:
        """Radiance of one path per lane, the ``active`` mask and the AOVs of :meth:`aov_names`."""
        r = self.trace(scene, ray, active, sampler, sample_pass)
        channels = {"normal": [r.n.x, r.n.y, r.n.z], "depth": [r.t],
                    "counts": [r.n_reflection, r.n_refraction, r.n_shadow]}
        return r.color, dr.full(mi.Bool, True, dr.width(r.color)) & active, self.aov_values(channels)

    def to_string(self) -> str:
        return (f"A5PathIntegrator[max_depth={self.max_depth}, rr_depth={self.rr_depth}, fresnel='{self.fresnel}', "
                f"reflection={self.reflection}, refraction={self.refraction}, bump={self.bump}, "
                f"tmin={self.tmin}, aovs='{','.join(self.aovs)}', planes={len(self.planes)}]")


@syntax
def trace_paths(scene: mi.Scene, ray_o: mi.Point3f, ray_d: mi.Vector3f, active: mi.Bool, data: SceneData,
                lights: PbrLights, rng: Stochastic, f: Features,
                rr_depth: mi.UInt32, rec: PathRecorder | None = None) -> PathResult:
    """The estimator of the module docstring for a batch of camera rays; returns ``(L, first-hit normal,
    first-hit t, n_reflection, n_refraction, n_shadow)``. ``f`` is baked into the kernel; ``data``, ``lights``,
    ``rng`` and ``rr_depth`` are opaque. ``rec`` (with ``f.record``, ``a5mi trace``): the
    :class:`~.kernel.pbr_record.PathRecorder` each vertex is scattered into."""
    width = dr.width(ray_d)
    o, d = mi.Point3f(ray_o), mi.Vector3f(ray_d)
    beta = dr.full(mi.Color3f, 1.0, width)
    result = dr.zeros(mi.Color3f, width)
    n_medium = dr.full(mi.Float, 1.0, width)
    depth = dr.zeros(mi.UInt32, width)
    prev_pdf = dr.zeros(mi.Float, width)
    prev_delta = dr.full(mi.Bool, True, width)
    origin = dr.zeros(mi.UInt32, width)
    t_min = dr.zeros(mi.Float, width)
    counter = dr.zeros(mi.UInt32, width)
    aov_n = dr.zeros(mi.Vector3f, width)
    aov_t = dr.full(mi.Float, dr.inf, width)
    n_refl = dr.zeros(mi.Float, width)
    n_refr = dr.zeros(mi.Float, width)
    n_shadow = dr.zeros(mi.Float, width)
    alive = mi.Bool(active)

    while alive:
        si, t_hit, p, n, hit, on_plane, plane_idx, row, bsdf = intersect(scene, data.planes, data.rules, o, d,
                                                                         t_min, origin)
        # ---- the emission this ray finds, MIS-weighted against next-event estimation at the vertex it left
        emitted = dr.zeros(mi.Color3f, width)
        if dr.hint(f.environment, mode="scalar"):
            le, pdf_l = environment(scene, d, alive & ~hit)
            w = dr.select(prev_delta, 1.0, power_heuristic(prev_pdf, pdf_l))
            emitted += dr.select(alive & ~hit, beta * le * w, 0.0)
        if dr.hint(f.area_lights, mode="scalar"):
            le, pdf_l = emission(scene, lights, si, alive & hit & ~on_plane, o, d, t_hit)
            w = dr.select(prev_delta, 1.0, power_heuristic(prev_pdf, pdf_l))
            emitted += dr.select(alive & hit, beta * le * w, 0.0)
        result += emitted
        if dr.hint(f.record, mode="scalar"):
            rec.vertex(depth, alive, valid=True, hit=hit, on_plane=on_plane, plane=plane_idx,
                       shape=shape_id(si.shape), t=t_hit, p=p, beta=beta, emitted=emitted)
        first = alive & hit & (depth == 0)
        aov_n = dr.select(first, n, aov_n)
        aov_t = dr.select(first, t_hit, aov_t)
        alive &= hit & (depth <= data.max_depth)

        # ---- the BSDF of the hit, next-event estimation, the next direction
        b, n = surface_lobes(data, f, bsdf, si, n, d, n_medium, on_plane, plane_idx, alive)
        nee, counter, n_shadow = direct(scene, data, lights, f.environment, si, p, b, alive,
                                        rng, depth * 256, counter, n_shadow)
        result += dr.select(alive, beta * nee, 0.0)
        if dr.hint(f.record, mode="scalar"):
            rec.vertex(depth, alive, nee=beta * nee)
        u_lobe = mi.sample_tea_float32(rng.pass_key, counter)
        u = light_point(rng, depth * 256 + BSDF_SLOT, counter + 1)
        counter += 3
        s = sample(b, n_medium, u_lobe, u, alive)
        through = dr.dot(s.wo, b.n_face) < 0.0
        if dr.hint(f.record, mode="scalar"):
            rec.vertex(depth, alive, lobe=lobe_code(s.valid, s.delta, through, alive), pdf=s.pdf, weight=s.weight)
        beta = dr.select(alive, beta * s.weight, beta)
        alive &= s.valid
        n_refl += dr.select(alive & ~through, 1.0, 0.0)
        n_refr += dr.select(alive & through, 1.0, 0.0)
        prev_pdf, prev_delta = s.pdf, s.delta
        o, d, n_medium, origin = mi.Point3f(p), mi.Vector3f(s.wo), mi.Float(s.n_medium), mi.UInt32(row)
        t_min = mi.Float(data.tmin)
        depth += 1

        # ---- Russian roulette from rr_depth scatterings on: survive with q = min(max β, 0.95), β /= q
        q = dr.minimum(dr.max(beta), 0.95)
        roulette = alive & (depth >= rr_depth)
        survive = mi.sample_tea_float32(rng.pass_key, counter) < q
        counter += 1
        if dr.hint(f.record, mode="scalar"):
            rec.vertex(depth - 1, alive, q=dr.select(roulette, q, 1.0), survived=~roulette | survive)
        beta = dr.select(roulette & survive, beta / q, beta)
        alive &= ~roulette | survive
        alive &= dr.max(beta) > 0.0

    return PathResult(result, aov_n, aov_t, n_refl, n_refr, n_shadow)


def register() -> None:
    """Register ``a5_path`` with Mitsuba for the active variant."""
    mi.register_integrator("a5_path", lambda props: A5PathIntegrator(props))
