"""The ``a5_ppm`` integrator: probabilistic progressive photon mapping (Knaus and Zwicker 2011; EXTENSIONS E.17).

Pass ``i = 1, 2, ...`` is an independent photon-mapping image: its own photon maps
(plugins/integrators/photon/integrator.py, seeded by ``(seed, i)``) and a radius shared by every point,

    r_1 = radius  (0: 1/50 of the bounding-sphere radius of the shapes, lights and camera),
    r_(i+1)² = r_i² (i + α) / (i + 1),   so   r_i² = r_1² Π_(j=1)^(i-1) (j + α)/(j + 1)

(``α`` = ``alpha``, default 2/3); the caustic and global estimates take every photon within ``r_i``
(plugins/integrators/photon/maps.py ``PhotonMap.radius``); the direct light is the light loop's, as in
``a5_photon``. The image is the mean of the passes: its variance falls as ``1/i^α`` per pass while the radius'
bias falls as ``r_i² ~ i^(α−1)``, so the mean converges (consistent).

Pass of a call: ``first_pass + SamplePass.index`` (the ``-spp`` passes of ``a5``; ``first_pass`` lets a
worker render pass ``k`` alone, a5mi/photons/passes.py); ``mi.render`` (no SamplePass) averages
``passes`` passes, ``first_pass .. first_pass + passes − 1``, inside one ``sample()`` call.
"""

from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi
import numpy as np

from a5mi.plugins.integrators.base import camera_rays
from a5mi.plugins.integrators.photon.emit import scene_ball, to_dr3
from a5mi.plugins.integrators.photon.integrator import A5PhotonIntegrator, Maps
from a5mi.plugins.params import read_int, read_number
from a5mi.plugins.sampling import SamplePass


def radius_at(r1: float, alpha: float, i: int) -> float:
    """``r_i`` of the module docstring (``i`` counted from 1)."""
    r2 = r1 * r1
    for j in range(1, i):
        r2 *= (j + alpha) / (j + 1)
    return math.sqrt(r2)


class A5PPMIntegrator(A5PhotonIntegrator):
    """Probabilistic progressive photon mapping (module docstring). ``a5_photon``'s parameters (``k`` and
    ``final_gather`` unused) and ``radius`` float (0: automatic), ``alpha`` float (2/3), ``first_pass`` int
    (0), ``passes`` int (1, for calls without a SamplePass)."""

    name = "a5_ppm"
    exposed = (*A5PhotonIntegrator.exposed, "radius", "alpha", "first_pass", "passes")

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)   # a5_photon's parameters
        self.radius = read_number(self.name, props, "radius", 0.0)
        self.alpha = read_number(self.name, props, "alpha", 2.0 / 3.0, 0.0, 1.0, open_low=True)
        self.first_pass = read_int(self.name, props, "first_pass", 0, 0)
        self.passes = read_int(self.name, props, "passes", 1, 1)
        self.final_gather = 0

    def initial_radius(self, scene: mi.Scene) -> float:
        """``r_1``: ``radius``, or 1/50 of the radius of the bounding sphere of the shapes, lights and camera
        (plugins/integrators/photon/emit.py ``scene_ball``)."""
        if self.radius > 0.0:
            return self.radius
        return scene_ball(scene)[1] / 50.0

    def estimate(self, maps: Maps, x: np.ndarray, n: np.ndarray, kd: np.ndarray, pass_index: int) -> np.ndarray:
        r = radius_at(self._r1, self.alpha, pass_index + 1)
        return maps.caustic.radius(x, n, kd, r, self.filter) + maps.indirect.radius(x, n, kd, r, self.filter)

    def pass_seed(self, sample_pass: SamplePass | None) -> tuple[int, int]:
        if sample_pass is None:
            return self.seed, self.first_pass
        return int(sample_pass.seed) & 0xFFFFFFFF, self.first_pass + int(sample_pass.index)

    def sample(self, scene: mi.Scene, sampler: mi.Sampler | None, ray: mi.Ray3f, medium: mi.Medium | None = None,
               active: mi.Bool | bool = True, sample_pass: SamplePass | None = None,
               ) -> tuple[mi.Color3f, mi.Bool, list[mi.Float]]:
        """One pass (with a SamplePass), or the mean of ``passes`` passes (without one)."""
        self._r1 = self.initial_radius(scene)
        if sample_pass is not None:
            return super().sample(scene, sampler, ray, medium, active, sample_pass)
        o, d, act = camera_rays(ray, active)
        width = dr.width(act)
        total, counted = np.zeros((width, 3)), np.zeros((width, 3))
        for k in range(self.first_pass, self.first_pass + self.passes):
            maps = self.build_maps(scene, self.seed, k)
            color, counts = self.radiance(scene, o, d, act, maps, None, sampler, self.seed, k)
            total += color
            counted += counts
        return to_dr3(mi.Color3f, total / self.passes), act, self.count_aovs(counted / self.passes)


def register() -> None:
    """Register ``a5_ppm`` with Mitsuba for the active variant."""
    mi.register_integrator("a5_ppm", lambda props: A5PPMIntegrator(props))
