"""The physically based reading of docs/EXTENSIONS.md E.13 (plugins/kernel/pbr.py, pbr_lights.py): seeded
analytic checks. Monte Carlo thresholds are 5 standard errors of the estimator, its sigma estimated from the
same samples (a false alarm has probability < 1e-6 per check)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from conftest import a5_material, rgb

N = 200_000


def _rng(mi: Any, n: int, seed: int, dims: int = 3) -> list[Any]:
    import drjit as dr

    idx = dr.arange(mi.UInt32, n)
    return [mi.sample_tea_float32(idx, mi.UInt32(seed * 16 + k)) for k in range(dims)]


def _vec(mi: Any, v: tuple[float, float, float], n: int) -> Any:
    import drjit as dr

    return mi.Vector3f(*v) + dr.zeros(mi.Vector3f, n)


def _lobes(mi: Any, kd: tuple, ks: tuple, ior: float, d: tuple, n_medium: float = 1.0, fresnel: str = "a5",
           count: int = N) -> Any:
    import drjit as dr

    from a5mi.plugins.kernel.pbr import lobes

    n = _vec(mi, (0.0, 0.0, 1.0), count)
    dd = dr.normalize(_vec(mi, d, count))
    return lobes(fresnel, mi.Color3f(*kd), mi.Color3f(*ks), mi.Float(ior), dd, n, n, mi.Float(n_medium),
                 dr.full(mi.Bool, True, count)), dd


def _within(samples: np.ndarray, expected: float, k: float = 5.0) -> None:
    mean = float(samples.mean())
    se = float(samples.std(ddof=1)) / math.sqrt(samples.size)
    assert abs(mean - expected) <= k * se + 1e-7, (mean, expected, se)


def test_lambert_integrates_to_albedo(mi: Any) -> None:
    """∫ f |cos θ| dω over the sphere = kd, by uniform-sphere quadrature: (1/N) Σ f|cos| · 4π."""
    from a5mi.plugins.kernel.pbr import eval_diffuse

    b, _ = _lobes(mi, (0.8, 0.5, 0.2), (0.0, 0.0, 0.0), 0.0, (0.3, -0.2, -1.0))
    u1, u2, _ = _rng(mi, N, 1)
    wo = mi.warp.square_to_uniform_sphere(mi.Point2f(u1, u2))
    value, pdf = eval_diffuse(b, wo)
    est = np.asarray(value) * 4.0 * math.pi
    for c, kd in enumerate((0.8, 0.5, 0.2)):
        _within(est[c], kd)
    _within(np.asarray(pdf) * 4.0 * math.pi, 1.0)          # the pdf integrates to 1 (P_d = 1)


def test_lambert_lights_the_side_the_ray_comes_from(mi: Any) -> None:
    """Two-sided: a ray from below (d·N > 0) sees the lower hemisphere lit; the upper gives 0."""
    import drjit as dr

    from a5mi.plugins.kernel.pbr import eval_diffuse

    b, _ = _lobes(mi, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0), 0.0, (0.0, 0.0, 1.0), count=1)
    below, _ = eval_diffuse(b, mi.Vector3f(0.0, 0.0, -1.0))
    above, _ = eval_diffuse(b, mi.Vector3f(0.0, 0.0, 1.0))
    assert dr.allclose(below, 1.0 / math.pi) and dr.all(above == 0.0)


def test_sampled_density_matches_pdf(mi: Any) -> None:
    """The Lambert lobe's samples fall in cos θ bins with the mass the pdf gives (∫ cos/π = b² − a²), and the
    returned pdf is eval_diffuse's for the sampled direction (P_d · cos θ/π with a mirror lobe beside it)."""
    from a5mi.plugins.kernel.pbr import eval_diffuse, sample

    b, _ = _lobes(mi, (0.6, 0.6, 0.6), (0.3, 0.3, 0.3), 0.0, (0.2, 0.1, -1.0))
    u0, u1, u2 = _rng(mi, N, 2)
    s = sample(b, mi.Float(1.0), u0, mi.Point2f(u1, u2), True)
    diffuse = ~np.asarray(s.delta)
    p_d = float(np.asarray(b.p_d)[0])
    assert p_d == pytest.approx(0.6 / 0.9, rel=1e-6)
    _within(diffuse.astype(float), p_d)                     # lobe chosen with P_d
    cos = np.asarray(s.wo.z)[diffuse]
    edges = np.linspace(0.0, 1.0, 11)
    counts, _ = np.histogram(cos, edges)
    expect = (edges[1:] ** 2 - edges[:-1] ** 2) * diffuse.sum()
    sigma = np.sqrt(expect * (1 - expect / diffuse.sum()))
    assert np.all(np.abs(counts - expect) <= 5 * sigma), (counts, expect)
    _, pdf_eval = eval_diffuse(b, s.wo)
    np.testing.assert_allclose(np.asarray(s.pdf)[diffuse], np.asarray(pdf_eval)[diffuse], rtol=1e-5)
    assert np.all(np.asarray(s.pdf)[~diffuse] == 0.0)


def test_sample_weight_is_unbiased(mi: Any) -> None:
    """E[weight] over the lobes = kd + ks·R (a mirror: R = 1): the sum of the lobe weights."""
    from a5mi.plugins.kernel.pbr import sample

    b, _ = _lobes(mi, (0.5, 0.2, 0.1), (0.3, 0.4, 0.0), 0.0, (0.0, 0.5, -1.0))
    u0, u1, u2 = _rng(mi, N, 3)
    s = sample(b, mi.Float(1.0), u0, mi.Point2f(u1, u2), True)
    w = np.asarray(s.weight)
    for c, expected in enumerate((0.8, 0.6, 0.1)):
        _within(w[c], expected)


@pytest.mark.parametrize("mode", ["a5", "schlick", "exact"])
@pytest.mark.parametrize(("d", "n_medium", "ior"), [((0.3, 0.0, -1.0), 1.0, 1.5), ((0.5, 0.2, 1.0), 1.5, 1.5),
                                                     ((0.1, 0.0, -1.0), 1.0, 2.4)])
def test_fresnel_modes_match_common(mi: Any, mode: str, d: tuple, n_medium: float, ior: float) -> None:
    """R is plugins/common.fresnel_weight of the same mode; reflect ks·R, refract ks(1 − R)(n/nt)²."""
    import drjit as dr

    from a5mi.plugins.optics import fresnel_weight, snell

    ks = (0.9, 0.8, 0.7)
    b, dd = _lobes(mi, (0.0, 0.0, 0.0), ks, ior, d, n_medium, mode, count=1)
    n = mi.Vector3f(0.0, 0.0, 1.0)
    leaving = dr.dot(dd, n) > 0.0
    n_side = dr.select(leaving, -n, n)
    nt = dr.select(leaving, 1.0, ior)
    t, exists = snell(dd, n_side, mi.Float(n_medium), nt)
    assert bool(exists[0])
    r = fresnel_weight(mode, dd, n_side, t, mi.Float(n_medium), nt)
    assert dr.allclose(b.r_fresnel, r)
    eta2 = (n_medium / float(nt[0])) ** 2
    for c in range(3):
        assert float(b.w_r[c][0]) == pytest.approx(ks[c] * float(r[0]), rel=1e-6)
        assert float(b.w_t[c][0]) == pytest.approx(ks[c] * (1 - float(r[0])) * eta2, rel=1e-5)
    assert dr.allclose(b.t_dir, t) and float(b.nt[0]) == pytest.approx(float(nt[0]))


def test_total_internal_reflection_reflects_all(mi: Any) -> None:
    """Leaving glass past the critical angle: R = 1, no refracted lobe, the medium index unchanged."""
    from a5mi.plugins.kernel.pbr import sample

    b, _ = _lobes(mi, (0.0, 0.0, 0.0), (1.0, 1.0, 1.0), 1.5, (1.0, 0.0, 0.2), 1.5, count=4)
    assert np.allclose(np.asarray(b.r_fresnel), 1.0) and np.allclose(np.asarray(b.w_t), 0.0)
    s = sample(b, mi.Float(1.5), mi.Float([0.1, 0.5, 0.9, 0.99]), mi.Point2f(0.5, 0.5), True)
    assert np.all(np.asarray(s.delta)) and np.allclose(np.asarray(s.n_medium), 1.5)
    assert np.allclose(np.asarray(s.weight), 1.0)


def _light_scene(mi: Any, emitter: dict) -> Any:
    return mi.load_dict({"type": "scene", "light": emitter,
                         "floor": {"type": "rectangle", "bsdf": a5_material(diffuse_color=(0.5, 0.5, 0.5)),
                                   "to_world": mi.ScalarTransform4f().translate([0.0, 0.0, -50.0])}})


def _it(mi: Any, p: tuple, n: int) -> Any:
    import drjit as dr

    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.p = mi.Point3f(*p) + dr.zeros(mi.Point3f, n)
    si.n = _vec(mi, (0.0, 0.0, 1.0), n)
    si.sh_frame = mi.Frame3f(si.n)
    return si


def test_sphere_light_irradiance_and_mis_pdf(mi: Any) -> None:
    """A SphereLight of radiance c, radius r, centre at distance D straight above a point: irradiance
    E = π c (r/D)² (falloff 0), estimated by Σ weight·cos θ / N; a ray toward each sampled point hits the sphere
    and emission() returns c and the same solid-angle pdf (the MIS pair)."""
    import drjit as dr

    from a5mi.plugins.kernel.pbr_lights import SURFACE, emission, lights_of, sample_light

    r, big_d, c = 0.5, 2.0, 3.0
    light = {"type": "sphere", "center": [0.0, 0.0, big_d], "radius": r, "bsdf": a5_material(),
             "emitter": {"type": "a5_area", "shape": "sphere", "center": [0.0, 0.0, big_d], "radius": r,
                         "color": rgb(c, c, c)}}
    scene = _light_scene(mi, light)
    lights = lights_of(scene)
    assert dr.slice(lights.count) == 1 and int(lights.kind[0]) == SURFACE
    n = 50_000
    u1, u2, _ = _rng(mi, n, 4)
    si = _it(mi, (0.0, 0.0, 0.0), n)
    ls = sample_light(lights, dr.zeros(mi.UInt32, n), si, mi.Point2f(u1, u2), dr.full(mi.Bool, True, n))
    assert not np.any(np.asarray(ls.delta))
    est = np.asarray(ls.weight)[0] * np.asarray(ls.d.z)
    _within(est, math.pi * c * (r / big_d) ** 2)
    ray = mi.Ray3f(si.p, ls.d)
    hit = scene.ray_intersect(ray)
    assert np.all(np.asarray(hit.is_valid()))
    le, pdf = emission(scene, lights, hit, hit.is_valid(), si.p, ls.d, hit.t)
    np.testing.assert_allclose(np.asarray(le)[0], c, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(pdf), np.asarray(ls.pdf), rtol=1e-3)


def test_area_light_falloff_and_pdf(mi: Any) -> None:
    """A parallelogram AreaLight (E.2) read as radiance color/(1 + falloff d²) from both faces: its estimate
    of the irradiance under a small square far away tends to c A cos²/(d²(1 + f d²)); pdf = d²/(A cos θ_l)."""
    import drjit as dr

    from a5mi.plugins.kernel.pbr_lights import emission, lights_of, sample_light

    h, side, c, f = 10.0, 0.2, 2.0, 0.05
    e1, e2 = [side, 0.0, 0.0], [0.0, side, 0.0]
    corner = [-side / 2, -side / 2, h]
    to_world = mi.ScalarTransform4f().translate([0.0, 0.0, h]).scale([side / 2, side / 2, 1.0])
    light = {"type": "rectangle", "to_world": to_world, "bsdf": a5_material(),
             "emitter": {"type": "a5_area", "shape": "parallelogram", "corner": corner, "edge1": e1, "edge2": e2,
                         "color": rgb(c, c, c), "falloff": f}}
    scene = _light_scene(mi, light)
    lights = lights_of(scene)
    n = 20_000
    u1, u2, _ = _rng(mi, n, 5)
    si = _it(mi, (0.0, 0.0, 0.0), n)
    ls = sample_light(lights, dr.zeros(mi.UInt32, n), si, mi.Point2f(u1, u2), dr.full(mi.Bool, True, n))
    dist = np.asarray(ls.dist)
    np.testing.assert_allclose(np.asarray(ls.pdf), dist ** 2 / (side * side * (h / dist)), rtol=1e-4)
    est = np.asarray(ls.weight)[0] * np.asarray(ls.d.z)
    assert est.mean() == pytest.approx(c * side * side / (h * h * (1 + f * h * h)), rel=1e-3)
    hit = scene.ray_intersect(mi.Ray3f(si.p, ls.d))
    le, pdf = emission(scene, lights, hit, hit.is_valid(), si.p, ls.d, hit.t)
    np.testing.assert_allclose(np.asarray(le)[0], c / (1 + f * dist ** 2), rtol=1e-4)
    np.testing.assert_allclose(np.asarray(pdf), np.asarray(ls.pdf), rtol=1e-3)


def test_point_light_is_delta_with_falloff_as_written(mi: Any) -> None:
    """A PointLight: delta, weight = color / (1 + falloff d²) (SPEC A.3), pdf 0."""
    import drjit as dr

    from a5mi.plugins.kernel.pbr_lights import DELTA, lights_of, sample_light

    scene = _light_scene(mi, {"type": "a5_point", "position": [0.0, 3.0, 4.0], "color": rgb(1.0, 2.0, 3.0),
                              "falloff": 0.5})
    lights = lights_of(scene)
    assert int(lights.kind[0]) == DELTA
    ls = sample_light(lights, mi.UInt32(0), _it(mi, (0.0, 0.0, 0.0), 1), mi.Point2f(0.5, 0.5), mi.Bool(True))
    assert bool(ls.delta[0]) and float(ls.pdf[0]) == 0.0 and float(ls.dist[0]) == pytest.approx(5.0)
    assert dr.allclose(ls.weight, mi.Color3f(1.0, 2.0, 3.0) / 13.5)
