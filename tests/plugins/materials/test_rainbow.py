"""Rainbows (docs/EXTENSIONS.md E.21): the render kernel's spectral paths through one water droplet against
Descartes' rainbow angles for n(λ), and the bow angles measured on a rendered droplet cloud."""

from __future__ import annotations

import sys
from typing import Any

import numpy as np
import pytest
from helpers import ROOT

from a5mi.converters.a5_parser import parse_text

SCENES = ROOT / "scenes"
sys.path.insert(0, str(SCENES))
import rainbow  # noqa: E402  (scenes/rainbow.py: the demo's generator and measurement)

A, B = rainbow.WATER


def descartes(n: np.ndarray, k: int) -> np.ndarray:
    """The rainbow angle (degrees from the antisolar point) of order ``k`` (internal reflections) for index ``n``:
    the extremal deviation at ``cos² i = (n² − 1)/(k(k + 2))``, ``θ1 = 4r − 2i``, ``θ2 = 180° + 2i − 6r``."""
    i = np.arccos(np.sqrt((n * n - 1.0) / (k * (k + 2))))
    r = np.arcsin(np.sin(i) / n)
    return np.degrees(4 * r - 2 * i) if k == 1 else 180.0 + np.degrees(2 * i - 6 * r)


def _exit_rays(mi: Any, k: int, b: np.ndarray, seed: int, passes: int) -> tuple[np.ndarray, np.ndarray]:
    """Rays along −z at impact parameters ``b`` (in the xz plane) onto the unit water droplet, traced by
    ``a5_whitted`` with the bounce budget ``k + 2``: the one node with no bounce left in air is the ray leaving
    after ``k`` internal reflections. Returns its direction per lane and the lane's wavelength (nm)."""
    import drjit as dr

    from a5mi.converters.describe import describe
    from a5mi.plugins.kernel.record import NODE_LAYOUT, TreeRecorder
    from a5mi.plugins.materials import spectral
    from a5mi.plugins.sampling import SamplePass, pixel_keys
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import build_scene

    text = f"""PerspectiveCamera {{ center 0 0 5 direction 0 0 -1 up 0 1 0 angle 30 }}
Lights {{ numLights 0 }}
Background {{ color 0 0 0 }}
Materials {{ numMaterials 1 Material {{ diffuseColor 0 0 0 specularColor 1 1 1 refractionIndex dispersion {A} {B} }} }}
Group {{ numObjects 1 MaterialIndex 0 Sphere {{ center 0 0 0 radius 1 }} }}
"""
    scene = build_scene(describe(parse_text(text)), RenderOptions(bounces=k + 2))
    lanes = len(b)
    o = mi.Point3f(b.astype(np.float32), np.zeros(lanes, np.float32), np.full(lanes, 5.0, np.float32))
    ray = mi.Ray3f(o, mi.Vector3f(0.0, 0.0, -1.0))
    rec = TreeRecorder(lanes, 32, 1)
    scene.integrator().trace(scene, ray, record=rec, sample_pass=SamplePass(0, 1, passes, seed))
    nodes, _, count = rec.read()
    assert np.all(count <= 32)
    pk, qk = pixel_keys(dr.arange(mi.UInt32, lanes), dr.opaque(mi.UInt32, seed), dr.opaque(mi.UInt32, 1))
    lam = np.asarray(spectral.wavelength(pk, qk, dr.opaque(mi.UInt32, 1), dr.opaque(mi.UInt32, passes)))
    get = {name: nodes[:, :, off:off + w] for name, (off, w) in NODE_LAYOUT.items()}
    exit_node = (get["valid"][..., 0] > 0) & (get["bounces"][..., 0] == 0) & (get["n_medium"][..., 0] == 1.0)
    assert np.all(exit_node.sum(axis=1) == 1)
    return get["d"][exit_node].astype(np.float64), lam.astype(np.float64)


@pytest.mark.parametrize("k", [1, 2])
def test_single_droplet_bow_angle_is_descartes(mi: Any, k: int) -> None:
    """4096 lanes, impact parameters around the rainbow ray, each with its own wavelength (seeded): the angle of
    the kernel's exit ray from the antisolar direction, ``acos(−d_out · d_in)``, equals the geometric optics
    of the sphere for that lane's ``n(λ) = A + B/λ²`` (``4r − 2i`` / ``180° + 2i − 6r``, 2e-4°), never passes
    Descartes' extremal angle (by more than 2e-4°, float32), and reaches it within 1e-3° for lanes near the
    extremum; red bows lie outside violet ones for the primary, inside for the secondary."""
    lanes = 4096
    b = np.linspace(0.78, 0.93, lanes) if k == 1 else np.linspace(0.90, 0.98, lanes)
    d_out, lam = _exit_rays(mi, k, b, seed=11, passes=8)
    n = A + B / (lam * 1e-3) ** 2
    theta = np.degrees(np.arccos(np.clip(-d_out @ np.array([0.0, 0.0, -1.0]), -1, 1)))
    i, r = np.arcsin(b), np.arcsin(b / n)
    geometric = np.degrees(4 * r - 2 * i) if k == 1 else 180.0 + np.degrees(2 * i - 6 * r)
    np.testing.assert_allclose(theta, geometric, atol=2e-4)
    bound = descartes(n, k)
    sign = 1.0 if k == 1 else -1.0          # the primary is a maximum of θ, the secondary a minimum
    assert np.max(sign * (theta - bound)) < 2e-4
    assert np.min(np.abs(theta - bound)) < 1e-3
    red, violet = lam > 650.0, lam < 420.0
    assert red.sum() > 50 and violet.sum() > 50
    if k == 1:
        assert descartes(n[red], 1).min() > descartes(n[violet], 1).max()
    else:
        assert descartes(n[red], 2).max() < descartes(n[violet], 2).min()
    # the analytic angles of water (E.21): about 42° and 51°
    assert 40.5 < descartes(np.array([A + B / 0.55 ** 2]), 1)[0] < 42.5 < descartes(np.array([A + B / 0.55 ** 2]), 2)[0]


def test_measurement_finds_the_edges_of_a_synthetic_profile() -> None:
    """rainbow.measure on a seeded synthetic 600 x 600 image (the demo's camera), lit pixels drawn with the
    probability 0.02 inside 42° (the primary, falling to 0 at its outer edge), 0 in Alexander's band and 0.01
    beyond 51° (the secondary's inner edge), NaN pixels sprinkled in: the edges come back within one bin."""
    rng = np.random.default_rng(3)
    theta = rainbow.angles(600, 600)
    p = np.where(theta < 42.0, 0.02, np.where(theta < 51.0, 0.0, 0.01))
    lit = rng.uniform(size=theta.shape) < p
    img = np.zeros((*theta.shape, 3))
    img[lit] = rng.uniform(-0.5, 5.0, (int(lit.sum()), 3))
    img[rng.uniform(size=theta.shape) < 1e-4] = np.nan
    primary, secondary = rainbow.measure(img, theta)
    assert abs(primary - 42.0) <= rainbow.BIN_DEG and abs(secondary - 51.0) <= rainbow.BIN_DEG, (primary, secondary)


def test_rays_that_hit_a_sphere_light_stay_finite(mi: Any) -> None:
    """Rays leaving the droplet towards the sun hit the SphereLight's sphere (E.2: they see its colour); the light
    loop at that hit samples the same light from its own surface, where the sampled point can be the hit point
    itself (distance 0): the term is 0 there, not 0/0 (before: 41 NaN colours in 2·10⁵ rays, seeded)."""
    from a5mi.converters.describe import describe
    from a5mi.plugins.sampling import SamplePass
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import build_scene

    text = f"""PerspectiveCamera {{ center 0 0 5 direction 0 0 -1 up 0 1 0 angle 30 }}
Lights {{ numLights 1 SphereLight {{ center 0 0 10000 radius 524 color 3000 3000 3000 samples 1 }} }}
Background {{ color 0 0 0 }}
Materials {{ numMaterials 1 Material {{ diffuseColor 0 0 0 specularColor 1 1 1 refractionIndex dispersion {A} {B} }} }}
Group {{ numObjects 1 MaterialIndex 0 Sphere {{ center 0 0 0 radius 1 }} }}
"""
    scene = build_scene(describe(parse_text(text)), RenderOptions(bounces=4))
    n = 200000
    rng = np.random.default_rng(0)
    b, ph = np.sqrt(rng.uniform(0, 1, n)), rng.uniform(0, 2 * np.pi, n)
    xy = (b * np.cos(ph)).astype(np.float32), (b * np.sin(ph)).astype(np.float32)
    o = mi.Point3f(*xy, np.full(n, 5.0, np.float32))
    color = np.asarray(scene.integrator().trace(scene, mi.Ray3f(o, mi.Vector3f(0.0, 0.0, -1.0)),
                                                sample_pass=SamplePass(0, 0, 4, 3))[0])
    assert np.isfinite(color).all()
    assert (np.abs(color).max(axis=0) > 0.0).sum() > 300    # rays that reach the sun through the droplet see it
