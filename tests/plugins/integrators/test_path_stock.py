"""``-integrator path`` against Mitsuba's stock ``path`` on the ``--stock`` conversion of the same scene
(docs/EXTENSIONS.md E.14), and its error against the number of samples.

The scene is one on which the stock conversion *is* the E.13 reading: a directional light (stock
``directional``, irradiance = colour), a background colour (stock ``constant``), materials with ``kd + ks <= 1``
(``diffuse``; ``conductor`` for the mirror; ``dielectric`` with ``-fresnel exact`` for the glass), every
diffuse face seen from its front, the camera looking down so that no ray reaches the stock plane's edge (4096
units). Per pixel ``z = (a − b)/sqrt(se_a² + se_b²)`` on the channel mean, ``se²`` the channels' mean squared
standard error (the channels of one path are correlated: the variance of their mean is at most that); a
pixel agrees when ``|z| <= 3``
(probability 0.9973 for a normal z); the check asks 99% of the pixels to agree, as the issue's criterion.
The a5 side's sigma is over-estimated (stratified passes, tests/path_helpers.py), which only helps.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from path_helpers import a5_passes, load, stock_passes

SCENE = """
PerspectiveCamera { center 0 4 9 direction 0 -0.45 -1 up 0 1 0 angle 35 }
Lights { numLights 1 DirectionalLight { direction -0.4 -1 -0.5 color 0.9 0.85 0.8 } }
Background { color 0.35 0.45 0.6 ambientLight 0 0 0 }
Materials { numMaterials 4
  PhongMaterial { diffuseColor 0.7 0.7 0.65 }
  PhongMaterial { diffuseColor 0.8 0.25 0.2 }
  PhongMaterial { diffuseColor 0 0 0 specularColor 0.85 0.85 0.85 }
  PhongMaterial { diffuseColor 0 0 0 specularColor 1 1 1 refractionIndex 1.5 }
}
Group { numObjects 4
  MaterialIndex 0
  Plane { normal 0 1 0 offset -1 }
  MaterialIndex 1
  Sphere { center -1.6 0 -0.5 radius 1 }
  MaterialIndex 2
  Sphere { center 0.9 0 -1.5 radius 1 }
  MaterialIndex 3
  Sphere { center 0.6 -0.3 1.2 radius 0.7 }
}
"""


def _compare(mi: Any, size: int, spp: int, bounces: int = 4) -> tuple[float, np.ndarray]:
    desc, scene, _ = load(mi, SCENE, integrator="path", bounces=bounces, fresnel="exact", spp=spp)
    a, sa = a5_passes(mi, scene, scene.integrator(), desc.camera, size, size, spp, seed=3)
    sdesc, sscene, _ = load(mi, SCENE, stock=True, bounces=bounces)
    b, sb = stock_passes(mi, sscene, sdesc.camera, size, size, spp, bounces + 2, seed=4)
    z = (a.mean(axis=2) - b.mean(axis=2)) / np.maximum(np.sqrt((sa ** 2 + sb ** 2).mean(axis=2)), 1e-9)
    return float(np.mean(np.abs(z) <= 3.0)), z


def test_matches_stock_path_fast(mi: Any) -> None:
    """24 x 24 pixels, 64 spp: >= 99% of the pixels within 3 sigma of stock ``path``."""
    share, z = _compare(mi, 24, 64)
    assert share >= 0.99, (share, float(np.abs(z).max()))


@pytest.mark.slow
def test_matches_stock_path_1024spp(mi: Any) -> None:
    """64 x 64 pixels, 1024 spp (the issue's criterion): >= 99% of the pixels within 3 sigma."""
    share, z = _compare(mi, 64, 1024)
    assert share >= 0.99, (share, float(np.abs(z).max()))


def _slope(mi: Any, size: int, spps: tuple[int, ...], replicas: int) -> float:
    """Slope of log RMSE against log spp; the RMSE of a render at ``spp`` = the standard deviation over
    ``replicas`` independent renders (no reference image needed), averaged over pixels and channels."""
    desc, scene, _ = load(mi, SCENE, integrator="path", bounces=4, fresnel="exact")
    integ = scene.integrator()
    rmse = []
    for spp in spps:
        means, _ = a5_passes(mi, scene, integ, desc.camera, size, size, spp, seed=100 + spp, replicas=replicas)
        rmse.append(math.sqrt(float(np.mean(np.var(means, axis=0, ddof=1)))))
    return float(np.polyfit(np.log(spps), np.log(rmse), 1)[0])


def test_error_falls_as_one_over_sqrt_spp(mi: Any) -> None:
    """RMSE against spp (1, 2, 4, 8, 16; 16 independent renders of 16 x 16): the Monte Carlo rate -0.5 or
    steeper, down to the -0.75 of jittered 2D sampling (the E.5 stratification over the passes of the first
    dimensions), with 0.1 for the noise of the fit; a biased or correlated estimator flattens it.
    Measured: -0.59."""
    slope = _slope(mi, 16, (1, 2, 4, 8, 16), 16)
    assert -0.85 <= slope <= -0.4, slope


@pytest.mark.slow
def test_error_slope_up_to_256_spp(mi: Any) -> None:
    """The same from 1 to 256 spp (9 points, 16 renders of 32 x 32)."""
    slope = _slope(mi, 32, (1, 2, 4, 8, 16, 32, 64, 128, 256), 16)
    assert -0.85 <= slope <= -0.4, slope
