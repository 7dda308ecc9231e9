"""``a5 -integrator path`` (plugins/integrators/path.py, docs/EXTENSIONS.md E.14): seeded Monte Carlo checks.

Every threshold is a number of standard errors of the estimator, the sigma estimated per pixel from the
passes themselves (over-estimated by the E.5 stratification, so conservative): ``k = 5`` for checks of one
number (false alarm < 1e-6), and SPEC-free pixel shares for the image comparisons (test_path_stock.py).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from path_helpers import a5_passes, load

#: A white furnace: an albedo-1 sphere resting on an albedo-1 exact plane under a uniform environment of 0.5;
#: the equilibrium radiance is 0.5 everywhere (the uniform field solves the rendering equation when nothing
#: absorbs), whatever the interreflections between sphere and plane.
FURNACE = """
PerspectiveCamera { center 0 2 8 direction 0 -0.25 -1 up 0 1 0 angle 30 }
Lights { numLights 0 }
Background { color 0.5 0.5 0.5 ambientLight 0 0 0 }
Materials { numMaterials 1 PhongMaterial { diffuseColor KD KD KD } }
Group { numObjects 2
  MaterialIndex 0
  Sphere { center 0 0 0 radius 1 }
  Plane { normal 0 1 0 offset -1 }
}
"""


def _furnace(kd: float) -> str:
    return FURNACE.replace("KD", str(kd))


def _path(mi: Any, text: str, size: int, spp: int, seed: int = 0, **options: Any) -> tuple[np.ndarray, np.ndarray]:
    desc, scene, ro = load(mi, text, integrator="path", **options)
    return a5_passes(mi, scene, scene.integrator(), desc.camera, size, size, spp, seed)


def test_loads_from_a_dict_and_registers(mi: Any) -> None:
    integ = mi.load_dict({"type": "a5_path", "max_depth": 7, "rr_depth": 2, "fresnel": "exact", "aovs": "depth"})
    assert "max_depth=7" in integ.to_string() and "rr_depth=2" in integ.to_string()
    assert integ.aov_names() == ["t"]
    xml = mi.load_string('<integrator type="a5_path" version="3.0.0"><integer name="max_depth" value="3"/>'
                         '<string name="fresnel" value="schlick"/></integrator>')
    assert "max_depth=3" in xml.to_string() and "schlick" in xml.to_string()
    with pytest.raises(Exception, match="rr_depth"):
        mi.load_dict({"type": "a5_path", "rr_depth": -1})
    with pytest.raises(Exception, match="media"):
        mi.load_dict({"type": "a5_path", "medium": "fog"})


def test_options_carry_rr_depth_to_the_path_plugin() -> None:
    from a5mi.render.options import RenderOptions

    assert RenderOptions(integrator="path", rr_depth=3).integrator_params()["rr_depth"] == 3
    assert "rr_depth" not in RenderOptions().integrator_params()        # course dicts unchanged
    assert RenderOptions(integrator="path").plugin == "a5_path"


def test_white_furnace(mi: Any) -> None:
    """Albedo 1 everywhere: every pixel is the environment's 0.5 (deep paths: -bounces 64, roulette from 3);
    checked on the image mean (5 sigma, sigma from the pixels' standard errors) and per pixel (6 sigma)."""
    mean, se = _path(mi, _furnace(1.0), 12, 32, bounces=64, rr_depth=3)
    z = (mean - 0.5) / np.maximum(se, 1e-9)
    total_se = math.sqrt(float(np.sum(se ** 2))) / se.size
    assert abs(float(mean.mean()) - 0.5) <= 5 * total_se + 1e-6, (mean.mean(), total_se)
    assert np.all(np.abs(z) <= 6.0), float(np.abs(z).max())


def test_grey_furnace_single_sphere_is_albedo_times_environment(mi: Any) -> None:
    """A convex sphere alone (no plane): one scattering, then the ray escapes: L = kd · 0.5 exactly in mean."""
    text = _furnace(0.6).replace("numObjects 2", "numObjects 1").replace("Plane { normal 0 1 0 offset -1 }", "")
    mean, se = _path(mi, text, 12, 16, bounces=3)
    hit = mean.max(axis=2) < 0.45                   # sphere pixels (the background is 0.5)
    assert hit.sum() > 10
    z = (mean[hit] - 0.3) / np.maximum(se[hit], 1e-9)
    assert np.all(np.abs(z) <= 6.0) and abs(float(mean[hit].mean()) - 0.3) < 5 * float(se[hit].mean())


def test_russian_roulette_keeps_the_mean(mi: Any) -> None:
    """Roulette from the first scattering on against none (rr_depth 65 > bounces): the same image mean within
    5 sigma of the difference (albedo 0.8, 16 bounces, two seeds)."""
    a, sa = _path(mi, _furnace(0.8), 12, 32, seed=1, bounces=16, rr_depth=1)
    b, sb = _path(mi, _furnace(0.8), 12, 32, seed=2, bounces=16, rr_depth=65)
    n = a.size
    sigma = math.sqrt(float(np.sum(sa ** 2) + np.sum(sb ** 2))) / n
    assert abs(float(a.mean() - b.mean())) <= 5 * sigma, (a.mean(), b.mean(), sigma)
    assert float(sa.mean()) > float(sb.mean())      # roulette trades variance for time


def test_renders_from_the_cli(tmp_path: Any, a5_data: Any) -> None:
    """``a5 -integrator path -spp 2`` writes an image of the course scene; ``-v`` reports the ray counts."""
    import subprocess
    import sys

    out = tmp_path / "p.png"
    p = subprocess.run([sys.executable, "-m", "a5mi", "-input", str(a5_data / "scenes" / "scene03_sphere.txt"),
                        "-output", str(out), "-size", "16", "16", "-integrator", "path", "-spp", "2",
                        "-rr_depth", "2", "-v"], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert out.stat().st_size > 0 and "shadow" in p.stderr


def test_sphere_light_direct_light_is_analytic(mi: Any) -> None:
    """MIS of next-event estimation and BSDF-sampled hits (E.13, E.14): a diffuse floor under a SphereLight of
    radiance Le, -bounces 0 (direct light only): at a floor point p, with D = |c − p|, L = (kd/π) E and
    E = π Le (r/D)² cos θ (the sphere wholly above the horizon), so L = kd Le r² (c_y − p_y) / D³. Every floor
    pixel within 5 sigma, and the floor's sum within 5 sigma of the sum (a double-counted or missing strategy
    is off by up to 2x)."""
    from a5mi.crosscheck import _pixel_rays

    text = """
PerspectiveCamera { center 0 3 6 direction 0 -0.5 -1 up 0 1 0 angle 40 }
Lights { numLights 1 SphereLight { center 0 1.5 0 radius 0.4 color 2 2 2 } }
Background { color 0 0 0 ambientLight 0 0 0 }
Materials { numMaterials 1 PhongMaterial { diffuseColor 0.6 0.6 0.6 } }
Group { numObjects 1 MaterialIndex 0 Plane { normal 0 1 0 offset 0 } }
"""
    size = 16
    desc, scene, _ = load(mi, text, integrator="path", bounces=0)
    mean, se = a5_passes(mi, scene, scene.integrator(), desc.camera, size, size, 32, seed=9)
    ray = _pixel_rays(desc.camera, size, size)
    o, d = np.asarray(ray.o), np.asarray(ray.d)
    t = -o[1] / d[1]
    p = o + t * d
    c, r = np.array([0.0, 1.5, 0.0])[:, None], 0.4
    to_c = c - p
    dist = np.linalg.norm(to_c, axis=0)
    # the camera ray must reach the floor without meeting the light: distance from the sphere's centre to the ray
    oc = c - o
    along = np.sum(oc * d, axis=0)
    miss_light = np.linalg.norm(oc - along * d, axis=0) > r * 1.01
    floor = (d[1] < 0) & miss_light
    expected = (0.6 * 2.0 * r * r * to_c[1] / dist ** 3).reshape(size, size)
    floor = floor.reshape(size, size)
    assert floor.sum() > 100
    z = (mean[..., 0] - expected) / np.maximum(se[..., 0], 1e-9)
    assert np.all(np.abs(z[floor]) <= 5.0), float(np.abs(z[floor]).max())
    # the floor's sum: a BSDF-sampled hit is rare (a few % of the rays), so per pixel its error hides in the
    # noise it makes; summed over the floor a double-counted strategy stands out
    diff = float(np.sum(mean[..., 0][floor] - expected[floor]))
    sigma = float(np.sqrt(np.sum(se[..., 0][floor] ** 2)))
    assert abs(diff) <= 5.0 * sigma, (diff, sigma, float(np.sum(expected[floor])))
