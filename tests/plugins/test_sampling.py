"""``a5_whitted``'s ``-spp`` samples (plugins/sampling.py, docs/EXTENSIONS.md E.5): each pixel's estimate
converges to the pixel's value, not to a seed-dependent one.

With the E.5 cyclic shifts alone, two dimensions of one pixel (the thin lens and an area light, say) paired
stratum ``s`` with ``s + c`` for one per-pixel ``c``: on a defocused soft shadow (DOF below, 32 x 32) the mean
|difference| of two seeds hardly fell (0.69 % of the mean at 256 passes, 0.59 % at 1,024: slope −0.12) and
the mean ``z²`` of the per-pixel differences rose from 0.38 to 1.42 (4 % of them beyond 3 sigma); with the
permuted strata 0.33 % and 0.13 % (slope −0.66), ``z²`` 0.13 and 0.07. Checks, seeded, thresholds in standard
errors of the estimator:

* the mean over ``M = 256`` samples of the product ``u_A · u_B`` of the lens dimension and a light dimension
  (integral 1/4) is within the independent-sample sigma ``sqrt((1/9 - 1/16) / M)`` per pixel: the mean of
  ``z²`` over 256 pixels below 2 (it was 8.2; 1 for independent samples, sd of that mean ``sqrt(2/256) = 0.09``; padded
  stratification only lowers it);
* ``a5_whitted`` on DOF, all passes of a pixel in one call: the per-pixel difference of two seeds within the
  passes' own sigma (``z = Δ / sqrt(s₁²/N + s₂²/N)``, sample variances of the passes: ``E[z²] = 1`` for
  independent passes, sd of the mean over 1,024 pixels ``sqrt(2/1024) = 0.044``; stratified passes only lower
  it), so mean ``z²`` below 1.2; and the mean |difference| falls with the passes, log-log slope below −0.4 from
  256 to 1,024 (−0.5 for Monte Carlo, lower with stratification; it was +0.03).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from path_helpers import load

#: a defocused soft shadow: thin lens (aperture 0.8, focused at 4, the shadows at ~8) and one area light of two
#: samples a pass, so lens and light dimensions interact in every penumbra pixel
DOF = """
PerspectiveCamera { center 0 1.2 8 direction 0 -0.1 -1 up 0 1 0 angle 35 aperture 0.8 focusDistance 4 }
Lights { numLights 1
  AreaLight { corner -1.5 4 -1.5 edge1 3 0 0 edge2 0 0 1.5 color 0.8 0.8 0.75 samples 2 }
}
Background { color 0.15 0.2 0.3 ambientLight 0.15 0.15 0.15 }
Materials { numMaterials 3
  Material { diffuseColor 0.9 0.9 0.9 }
  Material { diffuseColor 0.9 0.2 0.2 }
  Material { diffuseColor 0.2 0.8 0.3 }
}
Group { numObjects 4
  MaterialIndex 0
  Plane { normal 0 1 0 offset 0 }
  MaterialIndex 1
  Sphere { center -1.8 0.6 3 radius 0.6 }
  MaterialIndex 2
  Sphere { center 0 0.6 0 radius 0.6 }
  Sphere { center 2.2 0.6 -4 radius 0.6 }
}
"""


def _keys(mi: Any, pixels: int, passes: int, seed: int) -> tuple[Any, Any, Any]:
    """``(pixel, pass, Stochastic)`` of lanes ``(pass, pixel)`` (pixel fastest), pass ``k`` of ``passes``."""
    import drjit as dr

    from a5mi.plugins.sampling import Stochastic, pixel_keys

    lane = np.arange(passes * pixels)
    pixel, k = mi.UInt32(lane % pixels), mi.UInt32(lane // pixels)
    pk, pass_key = pixel_keys(pixel, mi.UInt32(seed), k)
    return pixel, k, Stochastic(pk, pass_key, k, dr.opaque(mi.UInt32, passes), dr.opaque(mi.UInt32, 1))


def test_lens_and_light_samples_of_a_pixel_are_independent(mi: Any) -> None:
    from a5mi.plugins.kernel.lights import sample_point
    from a5mi.plugins.sampling import LENS_DIM, stratified_2d

    pixels, m = 256, 256
    _pixel, k, rng = _keys(mi, pixels, m, 7)
    lens = stratified_2d(rng.pixel_key, rng.pass_key, mi.UInt32(LENS_DIM), k, mi.UInt32(m), mi.UInt32(0x7FFFFFF0))
    light = sample_point(rng, mi.UInt32(0), mi.UInt32(0), mi.UInt32(0), mi.UInt32(1), mi.UInt32(0))
    for u in (lens.x, lens.y, light.x, light.y):   # each dimension stays stratified: 16 samples per column of
        col = np.floor(np.asarray(u, np.float64).reshape(m, pixels) * 16).astype(int)   # the 16 x 16 grid
        for p in range(pixels):                    # (float32 rounding of (s + ξ)/16 may reach the next one)
            assert np.abs(np.bincount(col[:, p], minlength=16) - 16).sum() <= 2, p
    prod = (np.asarray(lens.x, np.float64) * np.asarray(light.x, np.float64)).reshape(m, pixels)
    sigma = math.sqrt((1.0 / 9.0 - 1.0 / 16.0) / m)
    z2 = ((prod.mean(axis=0) - 0.25) / sigma) ** 2
    assert z2.mean() < 2.0, z2.mean()


def _two_seeds(mi: Any, text: str, size: int, passes: int) -> tuple[np.ndarray, np.ndarray, float]:
    """``(difference of the per-pixel means of seeds 1 and 2, its sigma, the image mean)`` of ``a5_whitted
    -shadows -bounces 4`` on ``text``, ``passes`` passes per pixel in one call (the E.5 wavefront lanes)."""
    import drjit as dr

    from a5mi.crosscheck import _pixel_rays
    from a5mi.plugins.sampling import SamplePass
    from a5mi.render.passes import _lens_rays

    desc, scene, _ = load(mi, text, shadows=True, bounces=4)
    n = size * size
    stats = []
    for seed in (1, 2):
        ray = _pixel_rays(desc.camera, size, size, repeat=passes)
        lane = dr.arange(mi.UInt32, n * passes)
        k = lane // n
        ray = _lens_rays(ray, desc.camera, lane - k * n, seed, k, passes)
        rgb, _, _ = scene.integrator().sample(scene, None, mi.RayDifferential3f(ray), None, mi.Bool(True),
                                              sample_pass=SamplePass(0, 0, passes, seed, passes, n))
        dr.eval(rgb)
        c = np.asarray(rgb, np.float64).reshape(3, passes, n)
        stats.append((c.mean(axis=1), c.var(axis=1, ddof=1) / passes))
    (m1, v1), (m2, v2) = stats
    return m1 - m2, np.sqrt(v1 + v2), float((m1 + m2).mean() / 2)


def _check_converges(mi: Any, text: str, size: int, passes: tuple[int, int]) -> None:
    errors = []
    for n in passes:
        diff, sigma, _mean = _two_seeds(mi, text, size, n)
        lit = sigma > 0
        z2 = (diff[lit] / sigma[lit]) ** 2
        assert z2.mean() < 1.2, (n, z2.mean())
        errors.append(np.abs(diff).mean())
    slope = math.log(errors[1] / errors[0]) / math.log(passes[1] / passes[0])
    assert slope < -0.4, (errors, slope)


def test_whitted_renders_of_two_seeds_agree_and_converge(mi: Any) -> None:
    _check_converges(mi, DOF, 32, (256, 1024))


@pytest.mark.slow
def test_whitted_glossy_and_dispersion_converge(mi: Any) -> None:
    """The same with the gloss and dispersion dimensions: a glossy wall reflecting an area-lit soft shadow, and
    a dispersive glass sphere (E.10 wavelength) over one, 32 x 32, 1,024 against 4,096 passes (mean ``z²`` was
    2.73 at 1,024)."""
    area = "AreaLight { corner -1.5 4 -1.5 edge1 3 0 0 edge2 0 0 1.5 color 0.8 0.8 0.75 samples 2 }"
    wall = f"""
PerspectiveCamera {{ center 0 1.5 6 direction 0 -0.2 -1 up 0 1 0 angle 40 }}
Lights {{ numLights 1 {area} }}
Background {{ color 0.1 0.1 0.15 ambientLight 0.05 0.05 0.05 }}
Materials {{ numMaterials 3
  Material {{ diffuseColor 0.2 0.2 0.2 specularColor 0.6 0.6 0.6 roughness 0.2 glossySamples 2 }}
  Material {{ diffuseColor 0.9 0.6 0.5 }}
  Material {{ diffuseColor 0 0 0 specularColor 1 1 1 refractionIndex dispersion 1.6 0.012 }}
}}
Group {{ numObjects 4
  MaterialIndex 0
  Plane {{ normal 0 0 1 offset -2 }}
  MaterialIndex 1
  Plane {{ normal 0 1 0 offset 0 }}
  Sphere {{ center -0.9 0.8 -0.5 radius 0.8 }}
  MaterialIndex 2
  Sphere {{ center 1 0.6 1 radius 0.6 }}
}}
"""
    _check_converges(mi, wall, 32, (1024, 4096))
