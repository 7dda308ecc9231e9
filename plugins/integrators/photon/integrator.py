"""The ``a5_photon`` integrator: photon mapping with a global and a caustic map (Jensen 1996, 2001; EXTENSIONS E.16).

Pre-pass: the photon maps of a scene are built on the first ``sample()`` call for that scene and seed (and
kept, keyed by the scene object, the seed and the pass, so every tile and ``-spp`` pass of a render reads the
same maps; ``mi.render`` makes one ``sample()`` call). ``photons`` photons are emitted for the global map and
``caustic_photons`` for the caustic map (plugins/integrators/photon/emit.py, plugins/integrators/photon/trace.py).

A camera path follows mirror and dielectric bounces (``ks``, reflection or refraction by the ``-fresnel``
``R``, chosen at random) up to ``max_depth`` hits; at every hit on a material with ``kd > 0`` it adds, times
its path weight ``β``:

    L = L_e + L_direct + L_caustic + L_indirect

* ``L_e``: the emission of an area light's shape or of the environment seen directly (E.13);
* ``L_direct``: next-event estimation of E.13 (plugins/kernel/pbr_lights.py ``direct``: one sample of every
  light and of the environment, the Lambert BSDF ``kd/π``, shadow rays always), every sample at MIS weight 1:
  the light the BSDF would find by sampling is not estimated again here (direct photons are not used);
* ``L_caustic``: the caustic map's estimate (``k`` nearest, their disc at most ``max_radius`` wide when it is
  > 0, plugins/integrators/photon/maps.py);
* ``L_indirect``: the global map's estimate (photons after a diffuse bounce), or with ``final_gather = M``:
  ``(kd/M) Σ_i L_full(y_i)`` over ``M`` cosine-weighted rays to diffuse points ``y_i``, ``L_full`` the estimate
  from every stored photon there.

The ambient term is off (the physically based reading of the scene); ``phong``, ``glossy`` and ``dispersion``
are accepted and not used (materials are smooth; ``roughness`` is ignored).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import drjit as dr
import mitsuba as mi
import numpy as np

from a5mi.plugins.integrators.base import E13_FIXED, A5Integrator, camera_rays
from a5mi.plugins.integrators.photon.emit import emit, light_powers, specular_targets, split_counts, to_dr3, to_np3
from a5mi.plugins.integrators.photon.maps import FILTERS, PhotonMap
from a5mi.plugins.integrators.photon.trace import CAUSTIC, INDIRECT, PhotonSet, first_distance, trace_photons
from a5mi.plugins.integrators.photon.walk import camera_step, facing
from a5mi.plugins.kernel import pbr, pbr_lights
from a5mi.plugins.kernel.features import SceneData
from a5mi.plugins.kernel.intersect import intersect, mirror_normal
from a5mi.plugins.kernel.surfaces import surface_at
from a5mi.plugins.params import read_choice, read_int, read_number
from a5mi.plugins.sampling import SamplePass, stochastic


class Maps(NamedTuple):
    """The photon maps of one scene, seed and pass: ``caustic``, ``indirect`` (global, after a diffuse
    bounce) and ``full`` (every stored photon, for the final gather; None without it)."""

    caustic: PhotonMap
    indirect: PhotonMap
    full: PhotonMap | None


def _np3(v: Any) -> np.ndarray:
    return to_np3(v)


class A5PhotonIntegrator(A5Integrator):
    """Photon mapping (module docstring). Parameters: ``max_depth`` int (4, camera path hits = ``-bounces``),
    ``photon_depth`` int (0: photons end by Russian roulette alone; N > 0: cut after N hits, biased),
    ``photons`` int (100000), ``caustic_photons`` int (100000), ``k`` int (50), ``max_radius`` float (0: none;
    else the k-nearest disc's largest radius), ``filter``
    ``none``/``cone``/``epanechnikov`` (none), ``final_gather`` int (0: off; else rays per point), ``shadows``
    bool (false), ``fresnel`` ``a5``/``schlick``/``exact`` (a5), ``reflection``, ``refraction`` bool (true),
    ``seed`` int (0: the photon maps' seed when no pass gives one), ``tmin`` float (0.001), ``bump`` bool
    (false); and the scene part of ``a5_whitted``'s parameters (``ambient``, ``plane_<id>_*``, accepted,
    ``phong``, ``glossy``, ``glossy_samples``, ``dispersion``; ``aovs`` "" or ``counts``: the camera
    path's n_reflection, n_refraction, n_shadow)."""

    name = "a5_photon"
    aov_groups = ("counts",)
    options = ("seed",)
    fixed = E13_FIXED   # smooth, non-dispersive materials; no ambient or Phong term
    exposed = ("max_depth", "photon_depth", "photons", "caustic_photons", "k", "max_radius", "final_gather", "seed",
               "filter", "fresnel", "shadows", "reflection", "refraction", "tmin")

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)   # the shared parameters (plugins/integrators/base.py)
        self.photon_depth = read_int(self.name, props, "photon_depth", 0, 0)   # 0: Russian roulette alone
        self.photons = read_int(self.name, props, "photons", 100000, 0)
        self.caustic_photons = read_int(self.name, props, "caustic_photons", 100000, 0)
        self.k = read_int(self.name, props, "k", 50, 1)
        self.final_gather = read_int(self.name, props, "final_gather", 0, 0)
        self.max_radius = read_number(self.name, props, "max_radius", 0.0)   # 0: the k-nearest disc unbounded
        self.filter = read_choice(self.name, props, "filter", "none", FILTERS)
        self._maps: dict[tuple[int, int, int], Maps] = {}

    # ------------------------------------------------------------------ scene values

    def _pbr_lights(self, scene: mi.Scene) -> pbr_lights.PbrLights:
        """The E.13 lights of ``scene`` for next-event estimation."""
        return pbr_lights.lights_of(scene)

    def photon_set(self, scene: mi.Scene, n: int, seed: int, pass_index: int, keep: tuple[int, ...],
                   shapes: bool = False) -> PhotonSet:
        """``n`` photons emitted (in proportion to the lights' powers) and traced; the stored ones of ``keep``
        (caustic photons only: point lights aim at the specular shapes, plugins/integrators/photon/emit.py)."""
        data = self.scene_data(scene)
        f = self.features(scene, data)
        targets = specular_targets(scene) if keep == (CAUSTIC,) else None
        counts = split_counts(n, light_powers(scene, first_distance(scene, data), seed=seed, targets=targets))
        rays = emit(scene, counts, seed, pass_index, targets)
        return trace_photons(scene, data, f, rays, self.photon_depth, seed, pass_index, n, keep, shapes)

    def build_maps(self, scene: mi.Scene, seed: int, pass_index: int) -> Maps:
        """The :class:`Maps` of the module docstring (global photons, then caustic photons: two streams)."""
        g = self.photon_set(scene, self.photons, seed, 2 * pass_index, (0, CAUSTIC, INDIRECT))
        c = self.photon_set(scene, self.caustic_photons, seed, 2 * pass_index + 1, (CAUSTIC,))
        ind = g.select(g.kind == INDIRECT)
        full = PhotonMap(g.pos, g.dir, g.power) if self.final_gather else None
        return Maps(PhotonMap(c.pos, c.dir, c.power), PhotonMap(ind.pos, ind.dir, ind.power), full)

    def maps(self, scene: mi.Scene, seed: int, pass_index: int) -> Maps:
        """The maps of ``(scene, seed, pass)``, built on first use (the last four kept)."""
        key = (id(scene), seed, pass_index)
        if key not in self._maps:
            while len(self._maps) >= 4:
                self._maps.pop(next(iter(self._maps)))
            self._maps[key] = self.build_maps(scene, seed, pass_index)
        return self._maps[key]

    # ------------------------------------------------------------------ radiance estimates

    def estimate(self, maps: Maps, x: np.ndarray, n: np.ndarray, kd: np.ndarray, pass_index: int) -> np.ndarray:
        """``L_caustic + L_indirect`` at diffuse points (without the final gather's ``L_indirect``)."""
        out = maps.caustic.knn(x, n, kd, self.k, self.filter, max_radius=self.max_radius)
        if not self.final_gather:
            out += maps.indirect.knn(x, n, kd, self.k, self.filter, max_radius=self.max_radius)
        return out

    def gather(self, scene: mi.Scene, data: SceneData, f: Any, maps: Maps, x: np.ndarray, n: np.ndarray,
               kd: np.ndarray, rng: mi.PCG32 | None) -> np.ndarray:
        """Final gather (module docstring): ``(kd/M) Σ_i L_full(y_i)``."""
        m, count = self.final_gather, len(x)
        if count == 0 or maps.full is None:
            return np.zeros((count, 3))
        xs, ns = np.repeat(x, m, axis=0), np.repeat(n, m, axis=0)
        r = mi.PCG32(count * m, dr.opaque(mi.UInt64, 0x5851F42D4C957F2D), dr.arange(mi.UInt64, count * m) * 2 + 1) \
            if rng is None else rng
        u = mi.Point2f(r.next_float32(), r.next_float32())
        d = mi.Frame3f(to_dr3(mi.Vector3f, ns)).to_world(mi.warp.square_to_cosine_hemisphere(u))
        h = intersect(scene, data.planes, data.rules, to_dr3(mi.Point3f, xs), d,
                      data.tmin + dr.zeros(mi.Float, count * m), dr.zeros(mi.UInt32, count * m))
        s = surface_at(h.bsdf, h.si, h.hit, h.n, f, None, mi.UInt32(1))
        n_y = facing(d, s.n)
        dr.eval(h.p, h.hit, s.kd, n_y)
        hit = np.asarray(h.hit, dtype=bool) & (_np3(s.kd).max(axis=1) > 0.0)
        lum = np.zeros((count * m, 3))
        lum[hit] = maps.full.knn(_np3(h.p)[hit], _np3(n_y)[hit], _np3(s.kd)[hit], self.k, self.filter,
                                 max_radius=self.max_radius)
        return kd * lum.reshape(count, m, 3).mean(axis=1)

    # ------------------------------------------------------------------ camera paths

    def radiance(self, scene: mi.Scene, o: mi.Point3f, d: mi.Vector3f, active: mi.Bool, maps: Maps,
                 sample_pass: SamplePass | None, sampler: mi.Sampler | None, seed: int,
                 pass_index: int) -> tuple[np.ndarray, np.ndarray]:
        """The colour of each camera ray (module docstring) and its rays traced (n_reflection, n_refraction,
        n_shadow), as numpy ``(width, 3)`` arrays."""
        width = dr.width(d)
        data = self.scene_data(scene)
        f = self.features(scene, data)
        rng = stochastic(sample_pass, sampler, width, 1)
        first = 0 if sample_pass is None else int(sample_pass.first_pixel)
        state = (seed * 0x9E3779B97F4A7C15 + pass_index * 0xD1B54A32D192ED03 + 7) % (1 << 64)
        walk = mi.PCG32(width, dr.opaque(mi.UInt64, state),
                        (dr.arange(mi.UInt64, width) + dr.opaque(mi.UInt64, first)) * 2 + 1)
        beta = mi.Color3f(1.0) + dr.zeros(mi.Color3f, width)
        live = dr.full(mi.Bool, True, width) & active
        color = np.zeros((width, 3))
        counter = dr.zeros(mi.UInt32, width)
        n_shadow = dr.zeros(mi.Float, width)
        n_refl, n_refr = dr.zeros(mi.Float, width), dr.zeros(mi.Float, width)
        t_min = dr.zeros(mi.Float, width)
        origin = dr.zeros(mi.UInt32, width)
        n_medium = dr.full(mi.Float, 1.0, width)
        lights = self._pbr_lights(scene)
        for depth in range(self.max_depth + 1):
            h = intersect(scene, data.planes, data.rules, o, d, t_min, origin)
            hit = h.hit & live
            local = dr.zeros(mi.Color3f, width)
            if f.environment:
                local += dr.select(live & ~h.hit, pbr_lights.environment(scene, d, live & ~h.hit)[0], 0.0)
            if f.area_lights:
                local += pbr_lights.emission(scene, lights, h.si, hit & ~h.on_plane, o, d, h.t)[0]
            s = surface_at(h.bsdf, h.si, hit, h.n, f, None, mi.UInt32(1))
            n_f = facing(d, s.n)
            diffuse = hit & (dr.max(s.kd) > 0.0)
            lambert = pbr.lobes(self.fresnel, s.kd, dr.zeros(mi.Color3f, width), mi.Float(0.0), d, s.n, s.n,
                                n_medium, diffuse, False, False)
            lambert = lambert._replace(p_d=dr.select(lambert.p_d > 0.0, 1e-30, 0.0))   # MIS weight 1
            nee, counter, n_shadow = pbr_lights.direct(scene, data, lights, f.environment, h.si,
                                                       h.p, lambert, diffuse, rng,
                                                       dr.opaque(mi.UInt32, depth * 256), counter, n_shadow)
            local += nee
            step = camera_step(self.fresnel, d, s.n, mirror_normal(data.planes, h.on_plane, h.plane, s.n), s.specular,
                               s.ior, n_medium, hit, walk.next_float32(), self.refraction, self.reflection)
            go = hit & step.alive & (depth < self.max_depth)
            refracted = go & (dr.dot(step.d, h.n) * dr.dot(d, h.n) > 0.0)
            n_refl += dr.select(go & ~refracted, 1.0, 0.0)
            n_refr += dr.select(refracted, 1.0, 0.0)
            contrib = beta * local
            dr.eval(contrib, h.p, n_f, s.kd, diffuse, beta, step.d, step.factor, go, counter, n_shadow, n_refl, n_refr,
                    step.n_medium)
            color += _np3(contrib)
            mask = np.asarray(diffuse, dtype=bool)
            if mask.any():
                x, nn, kd = _np3(h.p)[mask], _np3(n_f)[mask], _np3(s.kd)[mask]
                est = self.estimate(maps, x, nn, kd, pass_index)
                if self.final_gather:
                    est += self.gather(scene, data, f, maps, x, nn, kd, None)
                color[mask] += _np3(beta)[mask] * est
            if not np.asarray(go, dtype=bool).any():
                break
            beta = beta * step.factor
            live = go
            o, d, t_min, origin, n_medium = h.p, step.d, data.tmin + dr.zeros(mi.Float, width), h.row, step.n_medium
        counts = np.stack([np.asarray(n_refl), np.asarray(n_refr), np.asarray(n_shadow)], axis=1)
        return color, counts.astype(np.float64)

    def pass_seed(self, sample_pass: SamplePass | None) -> tuple[int, int]:
        """``(seed, pass index)`` of a call: the pass's, or the ``seed`` parameter and pass 0."""
        if sample_pass is None:
            return self.seed, 0
        return int(sample_pass.seed) & 0xFFFFFFFF, 0

    def sample(self, scene: mi.Scene, sampler: mi.Sampler | None, ray: mi.Ray3f, medium: mi.Medium | None = None,
               active: mi.Bool | bool = True, sample_pass: SamplePass | None = None,
               ) -> tuple[mi.Color3f, mi.Bool, list[mi.Float]]:
        """The colour of one camera ray per lane (module docstring) and the ``active`` mask; no AOVs."""
        o, d, act = camera_rays(ray, active)
        seed, k = self.pass_seed(sample_pass)
        color, counts = self.radiance(scene, o, d, act, self.maps(scene, seed, k), sample_pass, sampler, seed, k)
        return to_dr3(mi.Color3f, color), act, self.count_aovs(counts)

    def count_aovs(self, counts: np.ndarray) -> list[mi.Float]:
        """The AOVs of :meth:`aov_names` (none, or the ``counts`` group) from the per-lane ray counts."""
        return [mi.Float(counts[:, i].astype(np.float32)) for i in range(3)] if self.aovs else []

    def to_string(self) -> str:
        return (f"{type(self).__name__}[max_depth={self.max_depth}, photons={self.photons}, "
                f"caustic_photons={self.caustic_photons}, k={self.k}, filter='{self.filter}', "
                f"final_gather={self.final_gather}, shadows={self.shadows}, fresnel='{self.fresnel}']")


def register() -> None:
    """Register ``a5_photon`` with Mitsuba for the active variant."""
    mi.register_integrator("a5_photon", lambda props: A5PhotonIntegrator(props))
