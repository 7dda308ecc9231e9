"""The ``a5_irradiancecache`` integrator: Ward's irradiance cache over the E.13 reading of an a5 scene
(docs/EXTENSIONS.md E.23; Ward, Rubinstein, Clear 1988; Ward, Heckbert 1992).

Per camera ray: the delta-lobe ray tree with the emission it finds and next-event estimation at each diffuse
node (:func:`.irradiance_cache_kernel.camera_tree`), plus, at each diffuse node, ``β kd/π ⊙ E(p, N)`` with the
indirect irradiance ``E`` interpolated from cache records (:mod:`.irradiance_cache_math`,
:mod:`.irradiance_cache_grid`). The cache is filled by a vectorised multi-pass scheme, between kernel launches
on the host:

1. trace the batch's ray trees; read back the diffuse nodes;
2. find the nodes no record covers (``ε_i < a`` for none);
3. pick a well-spread subset of them: one per cell of a grid of ``g`` pixel spacings (cells at the node's own
   scale ``2^round(log2 s)``, split by the normal's dominant axis), ``g`` divided by 4 from ``max_pixels``
   round by round, every node left at ``g = 1``; trace ``M x N`` stratified hemisphere rays from each
   (:func:`.irradiance_cache_kernel.gather`) and add their records;
4. repeat from 2 until every node is covered (a node always covers itself), then interpolate.

The cache lives on the integrator for one render: it is emptied when a call starts one (``sample_pass`` of
pass 0 at render-buffer sample 0, as ``a5mi.render.passes`` hands them) and, without a ``sample_pass``
(``mi.render``, which traces the whole image in one call per pass), at every call. So records made for one
tile serve the next, an ``a5`` render and ``mi.render`` of a converted scene give the same cache for the same
seed, and ``-spp`` passes after the first reuse the records of the first. :meth:`records` returns it for the
``-ic_records`` picture (:mod:`.irradiance_cache_records`).
"""

from __future__ import annotations

import math
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from a5mi.platform.arrays import aligned_float32
from a5mi.plugins.integrators.base import E13_FIXED, A5Integrator, camera_rays
from a5mi.plugins.integrators.irradiance_cache import formulas as icm
from a5mi.plugins.integrators.irradiance_cache.grid import RecordSet
from a5mi.plugins.integrators.irradiance_cache.kernel import camera_tree, gather, node_buffers
from a5mi.plugins.kernel.features import Features, SceneData
from a5mi.plugins.kernel.pbr_lights import lights_of as pbr_lights_of
from a5mi.plugins.params import read_bool, read_int, read_number
from a5mi.plugins.sampling import SamplePass, Stochastic, pixel_keys, stochastic

#: hemisphere rays traced per kernel launch at most
GATHER_RAYS = 1 << 20
#: placement rounds before every remaining node gets its own record
MAX_ROUNDS = 24
#: factor of the placement grid from one round to the next
SHRINK = 0.25


def _floats(a: np.ndarray) -> mi.Float:
    """A Dr.Jit array of ``a`` from 64-byte-aligned memory (a5mi.platform.arrays: the kernel's IR must not depend on
    where numpy put the data)."""
    return mi.Float(aligned_float32(a))


def pixel_angle(scene: mi.Scene) -> float:
    """The angle of one pixel of the scene's first sensor: ``2 / (f sqrt((W−1)(H−1)))`` for ``a5_camera``
    (SPEC B.2, ``f = 1/tan(angle/2)``), ``2 tan(x_fov/2) / W`` for a stock perspective sensor."""
    sensors = scene.sensors()
    if not sensors:
        raise ValueError("a5_irradiancecache: the scene has no sensor; give 'pixel_angle'")
    sensor = sensors[0]
    size = sensor.film().crop_size()
    w, h = int(size.x), int(size.y)
    angle = getattr(sensor, "angle", None)
    if angle is not None:
        f = 1.0 / math.tan(math.radians(float(angle)) * 0.5)
        return 2.0 / (f * math.sqrt(max(w - 1, 1) * max(h - 1, 1)))
    params = mi.traverse(sensor)
    if "x_fov" not in params:
        raise ValueError("a5_irradiancecache: the sensor has no field of view; give 'pixel_angle'")
    x_fov = float(dr.slice(params["x_fov"], 0)) if dr.width(params["x_fov"]) else float(params["x_fov"])
    return 2.0 * math.tan(math.radians(x_fov) * 0.5) / w


class A5IrradianceCacheIntegrator(A5Integrator):
    """Irradiance caching with rotation and translation gradients (module docstring, docs/EXTENSIONS.md E.23).

    ================ ======= ======= ==========================================================
    parameter        type    default meaning
    ================ ======= ======= ==========================================================
    error            float   0.3     Ward's ``a`` (``-ic_error``): records serve where ``ε < a``
    samples          int     256     hemisphere rays per record (``-ic_samples``), ``M x N``
                                     strata with ``N ≈ π M``
    min_pixels       float   2.5     a record reaches at least this many pixel spacings ...
    max_pixels       float   15      ... and at most this many (pbrt-v2's pixel spacings)
    gradients        bool    true    interpolate with the rotation and translation gradients
    max_depth        int     4       delta bounces of the camera's ray tree (``-bounces``) and
                                     vertices of a hemisphere path (E.14's budget)
    rr_depth         int     5       Russian roulette of hemisphere paths (``-rr_depth``)
    fresnel          string  a5      ``a5`` | ``schlick`` | ``exact`` (E.13)
    reflection       bool    true    mirror lobes
    refraction       bool    true    refracted lobes
    bump             bool    false   bump / normal-mapped shading normal (E.7)
    tmin             float   0.001   tmin of secondary and shadow rays
    seed             int     0       seed of the hemisphere strata and paths
    pixel_angle      float   0       angle of a pixel (0: from the scene's sensor)
    aovs             string  ""      ``normal``, ``depth``, ``counts`` (as ``a5_whitted``)
    plane_<id>_*     ...             exact infinite planes (SPEC A.6)
    ================ ======= ======= ==========================================================

    ``shadows``, ``phong``, ``ambient``, ``glossy``, ``glossy_samples``, ``dispersion`` are accepted and not
    used (E.13); a medium is refused. Dict form: ``{'type': 'a5_irradiancecache', 'error': 0.2}``.
    """

    name = "a5_irradiancecache"
    aov_groups = ("normal", "depth", "counts")
    options = ("rr_depth", "seed")
    fixed = {**E13_FIXED, "shadows": True}   # E.13: shadows always, no ambient or Phong term
    exposed = ("error", "samples", "min_pixels", "max_pixels", "gradients", "max_depth", "rr_depth", "fresnel",
               "reflection", "refraction", "bump", "tmin", "seed", "pixel_angle", "aovs")

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)   # the shared parameters (plugins/integrators/base.py)
        name = self.name
        self.error = read_number(name, props, "error", 0.3, 0.0, 1.0, open_low=True, closed_high=True)
        self.samples = read_int(name, props, "samples", 256, 6)
        self.strata = icm.strata(self.samples)
        self.min_pixels = read_number(name, props, "min_pixels", 2.5, open_low=True)
        self.max_pixels = read_number(name, props, "max_pixels", 15.0, open_low=True)
        if self.max_pixels < self.min_pixels:
            raise ValueError(f"{name}: 'max_pixels' must be >= 'min_pixels'")
        self.gradients = read_bool(name, props, "gradients", True)
        self.pixel_angle = read_number(name, props, "pixel_angle", 0.0, 0.0, math.pi)
        self.cache = RecordSet(self.error)
        #: what the last render did: ``records``, ``rounds``, ``hemisphere_rays``, ``gather_rays`` (every ray
        #: the hemisphere paths cast: traced and shadow rays), ``nodes`` (diffuse nodes)
        self.stats: dict[str, int] = {}
        self._scene_id = 0

    # ------------------------------------------------------------------ Mitsuba interface

    def records(self) -> RecordSet:
        """The cache of the last render (module docstring)."""
        return self.cache

    def render_extras(self) -> dict[str, Any]:
        """What ``a5mi.render.driver`` keeps of a render besides the images: the cache and its statistics."""
        return {"irradiance_cache": self.cache, "irradiance_cache_stats": dict(self.stats)}

    @property
    def stack_depth(self) -> int:
        """The camera tree traces one level past ``max_depth`` (plugins/integrators/irradiance_cache/kernel.py)."""
        return self.max_depth + 1

    def _setup(self, scene: mi.Scene) -> tuple[SceneData, Any, Features]:
        data = self.scene_data(scene)
        return data, pbr_lights_of(scene), self.features(scene, data)

    def _reset(self, scene: mi.Scene, sample_pass: SamplePass | None) -> None:
        starts = sample_pass is None or (int(sample_pass.first_pixel) == 0 and int(sample_pass.index) == 0)
        if starts or self._scene_id != id(scene):
            self.cache = RecordSet(self.error)
            self.stats = {"records": 0, "rounds": 0, "hemisphere_rays": 0, "gather_rays": 0, "nodes": 0}
            self._scene_id = id(scene)

    def trace(self, scene: mi.Scene, ray: mi.Ray3f, active: mi.Bool | bool = True, sampler: mi.Sampler | None = None,
              sample_pass: SamplePass | None = None) -> tuple[mi.Color3f, np.ndarray, dict[str, list[mi.Float]]]:
        """``(colour without the cache, β kd/π ⊙ E summed per lane (numpy, W x 3), the AOV channels by group:
        normal [nx, ny, nz], depth [t], counts [n_reflection, n_refraction, n_shadow])`` of camera rays ``ray``
        (module docstring); the colour of :meth:`sample` is the sum of the first two."""
        self._reset(scene, sample_pass)
        data, lights, features = self._setup(scene)
        o, d, go = camera_rays(ray, active)
        width = dr.width(go)
        rng = stochastic(sample_pass, sampler, width, 1)
        theta = self.pixel_angle or pixel_angle(scene)
        capacity = 4 * width
        while True:
            nodes = node_buffers(capacity)
            color, n, t, n_refl, n_refr, n_shadow = camera_tree(
                scene, o, d, go, data, lights, rng, features, dr.opaque(mi.Float, theta), nodes,
                dr.opaque(mi.UInt32, capacity))
            dr.eval(color, n, t, n_refl, n_refr, n_shadow, nodes)
            found = int(nodes.count[0])
            if found <= capacity:
                break
            capacity = found
        indirect = self._indirect(scene, data, lights, features, nodes, found, width, sample_pass)
        return color, indirect, {"normal": [n.x, n.y, n.z], "depth": [t], "counts": [n_refl, n_refr, n_shadow]}

    def sample(self, scene: mi.Scene, sampler: mi.Sampler | None, ray: mi.Ray3f, medium: mi.Medium | None = None,
               active: mi.Bool | bool = True, sample_pass: SamplePass | None = None,
               ) -> tuple[mi.Color3f, mi.Bool, list[mi.Float]]:
        """Colour of each camera ray (module docstring), the ``active`` mask and the AOVs of :meth:`aov_names`."""
        color, indirect, channels = self.trace(scene, ray, active, sampler, sample_pass)
        color = color + mi.Color3f(*(_floats(indirect[:, c]) for c in range(3)))
        return color, dr.full(mi.Bool, True, dr.width(color)) & active, self.aov_values(channels)

    # ------------------------------------------------------------------ the cache

    def _indirect(self, scene: mi.Scene, data: SceneData, lights: Any, features: Features, nodes: Any,
                  found: int, width: int, sample_pass: SamplePass | None) -> np.ndarray:
        """``Σ_nodes β kd/π ⊙ E(p, N)`` per lane, after covering every node (module docstring, steps 2-4)."""
        out = np.zeros((width, 3))
        if found == 0:
            return out
        lane = np.asarray(nodes.lane, np.int64)[:found]
        order = np.lexsort((np.asarray(nodes.seq)[:found], lane))
        lane = lane[order]
        p = np.asarray(nodes.p, np.float64).reshape(-1, 3)[order]
        n = np.asarray(nodes.n, np.float64).reshape(-1, 3)[order]
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
        beta = np.asarray(nodes.beta, np.float64).reshape(-1, 3)[order]
        spacing = np.asarray(nodes.spacing, np.float64)[order]
        medium = np.asarray(nodes.n_medium, np.float64)[order]
        key = (0, 0, 0) if sample_pass is None else (int(sample_pass.first_pixel), int(sample_pass.index),
                                                      int(sample_pass.seed) & 0xFFFFFFFF)
        gen = np.random.default_rng([self.seed, *key])
        self.cover(scene, data, lights, features, p, n, spacing, medium, gen)
        E = self.cache.lookup(p, n, self.gradients).E
        np.add.at(out, lane, beta * E)
        self.stats["nodes"] += found
        return out

    def cover(self, scene: mi.Scene, data: SceneData, lights: Any, features: Features, p: np.ndarray,
              n: np.ndarray, spacing: np.ndarray, medium: np.ndarray, gen: np.random.Generator) -> int:
        """Add records until every point ``(p, n)`` (pixel ``spacing``, index ``medium`` on the side of ``n``) is
        covered; returns the rounds run."""
        g = self.max_pixels
        uncovered = np.arange(p.shape[0])
        for rounds in range(MAX_ROUNDS + 1):
            # records are only added: a point covered once stays covered
            uncovered = uncovered[~self.cache.lookup(p[uncovered], n[uncovered], gradients=False).covered]
            if uncovered.size == 0:
                return rounds
            final = rounds == MAX_ROUNDS or g <= 1.0             # the finest grid: every node left
            pick = uncovered if final else uncovered[spread(p[uncovered], n[uncovered], spacing[uncovered], g,
                                                            gen)]
            self.add_records(scene, data, lights, features, p[pick], n[pick], spacing[pick], medium[pick], gen)
            self.stats["rounds"] += 1
            g = max(SHRINK * g, 1.0)
        return MAX_ROUNDS + 1

    def add_records(self, scene: mi.Scene, data: SceneData, lights: Any, features: Features, p: np.ndarray,
                    n: np.ndarray, spacing: np.ndarray, medium: np.ndarray, gen: np.random.Generator) -> None:
        """Trace the stratified hemispheres of new records at ``(p, n)`` (index ``medium`` on their side) and add
        them to the cache."""
        m, nn = self.strata
        per = m * nn
        chunk = max(1, GATHER_RAYS // per)
        for start in range(0, p.shape[0], chunk):
            pk, nk = p[start:start + chunk], n[start:start + chunk]
            k = pk.shape[0]
            dirs = icm.directions(nk, m, nn, gen.random((k, m, nn, 2)))
            cos = np.einsum("kmnx,kx->kmn", dirs, nk).ravel()
            origin = np.repeat(pk, per, axis=0)
            flat = dirs.reshape(-1, 3)
            first = self.stats["hemisphere_rays"]
            lanes = dr.arange(mi.UInt32, k * per) + dr.opaque(mi.UInt32, first & 0xFFFFFFFF)
            pixel_key, pass_key = pixel_keys(lanes, dr.opaque(mi.UInt32, self.seed & 0xFFFFFFFF),
                                             dr.opaque(mi.UInt32, 0))
            rng = Stochastic(pixel_key, pass_key, dr.opaque(mi.UInt32, 0), dr.opaque(mi.UInt32, 1),
                             dr.opaque(mi.UInt32, 1))
            L, r, cast = gather(scene, mi.Point3f(*(_floats(origin[:, i]) for i in range(3))),
                          mi.Vector3f(*(_floats(flat[:, i]) for i in range(3))),
                          _floats(np.maximum(cos, 1e-8) / math.pi),
                          _floats(np.repeat(medium[start:start + chunk], per)), data, lights, rng, features,
                          dr.opaque(mi.UInt32, self.rr_depth))
            dr.eval(L, r, cast)
            L_np = np.nan_to_num(np.asarray(L, np.float64).T.reshape(k, m, nn, 3), nan=0.0, posinf=0.0)
            r_np = np.asarray(r, np.float64).reshape(k, m, nn)
            est = icm.estimate(nk, L_np, r_np)
            grad_r, grad_t = est.grad_r, est.grad_t
            if self.gradients:
                R, grad_t = icm.limit_radius(est.R, est.E, grad_t, r_np.min(axis=(1, 2)),
                                             spacing[start:start + chunk], self.error, self.min_pixels,
                                             self.max_pixels)
            else:
                grad_r, grad_t = np.zeros_like(grad_r), np.zeros_like(grad_t)
                R = np.clip(est.R, self.min_pixels * spacing[start:start + chunk] / self.error,
                            self.max_pixels * spacing[start:start + chunk] / self.error)
            self.cache.add(pk, nk, est.E, R, grad_r, grad_t, spacing[start:start + chunk])
            self.stats["hemisphere_rays"] += k * per
            self.stats["gather_rays"] += int(np.asarray(cast, np.float64).sum())
            self.stats["records"] = len(self.cache)

    def to_string(self) -> str:
        m, nn = self.strata
        return (f"A5IrradianceCacheIntegrator[error={self.error}, samples={self.samples} ({m}x{nn}), "
                f"pixels=[{self.min_pixels}, {self.max_pixels}], gradients={self.gradients}, "
                f"max_depth={self.max_depth}, rr_depth={self.rr_depth}, fresnel='{self.fresnel}', "
                f"reflection={self.reflection}, refraction={self.refraction}, bump={self.bump}, "
                f"tmin={self.tmin}, seed={self.seed}, aovs='{','.join(self.aovs)}', planes={len(self.planes)}]")


def spread(p: np.ndarray, n: np.ndarray, spacing: np.ndarray, g: float, gen: np.random.Generator) -> np.ndarray:
    """Indices of a well-spread subset of points: one, chosen at random, per cell of side ``g · 2^ℓ`` with
    ``ℓ = round(log2 spacing)`` (cells of each scale apart), per dominant axis and sign of the normal."""
    level = np.round(np.log2(np.maximum(spacing, 1e-30))).astype(np.int64)
    cell = np.floor(p / (g * np.exp2(level))[:, None]).astype(np.int64)
    axis = np.argmax(np.abs(n), axis=1)
    face = 2 * axis + (n[np.arange(n.shape[0]), axis] < 0)
    key = ((cell[:, 0] * 73856093) ^ (cell[:, 1] * 19349663) ^ (cell[:, 2] * 83492791)) * 64 + (level + 32) * 8 + face
    perm = gen.permutation(p.shape[0])
    _, first = np.unique(key[perm], return_index=True)
    return np.sort(perm[first])


def register() -> None:
    """Register ``a5_irradiancecache`` with Mitsuba for the active variant."""
    mi.register_integrator("a5_irradiancecache", lambda props: A5IrradianceCacheIntegrator(props))
