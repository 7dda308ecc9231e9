"""``-integrator photon``: emission, photon tracing, the kd-tree estimates (docs/EXTENSIONS.md E.16).

Monte Carlo checks are seeded; each threshold is a number of standard deviations of its estimator, the
sigma computed from the estimator's own distribution as stated in each test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from a5mi.render.options import RenderOptions


def _box(mi, light: dict, albedo: float, depth: int) -> tuple:
    """A closed cube [-1, 1]^3 of Lambert albedo ``albedo`` with one light inside, and an a5_photon."""
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "a5_photon", "photon_depth": depth},
        "box": {"type": "cube", "bsdf": {"type": "a5_material",
                                         "diffuse_color": {"type": "rgb", "value": [albedo] * 3}}},
        "light": light,
    })
    return scene, scene.integrator()


def test_closed_box_conserves_flux_along_the_albedo_series(mi) -> None:
    """Stored power = Φ E[M], M = the number of diffuse hits of a photon: P(M = m) = a^(m-1)(1 - a) for m < D,
    P(M = D) = a^(D-1) (Russian roulette with survival a, D = photon_depth). Sigma = Φ sqrt(Var M / N)."""
    a, depth, n, intensity = 0.5, 12, 40000, 2.0
    scene, integ = _box(mi, {"type": "point", "position": [0.1, -0.2, 0.3],
                             "intensity": {"type": "rgb", "value": [intensity] * 3}}, a, depth)
    ps = integ.photon_set(scene, n, 7, 0, (0, 1, 2))
    m = np.arange(1, depth + 1)
    p = np.where(m < depth, a ** (m - 1) * (1 - a), a ** (depth - 1))
    mean_m, var_m = float((p * m).sum()), float((p * m * m).sum() - (p * m).sum() ** 2)
    phi = 4.0 * math.pi * intensity
    sigma = phi * math.sqrt(var_m / n)
    total = ps.power[:, 0].sum()
    assert abs(total - phi * mean_m) < 4.0 * sigma, (total, phi * mean_m, sigma)
    assert abs(ps.power[ps.kind == 0, 0].sum() - phi) < 1e-3 * phi   # every photon's first hit: Φ exactly
    assert set(np.unique(ps.kind)) == {0, 2}                           # no specular surface: no caustic photon


def test_a5_point_light_deposits_its_falloff_rule(mi) -> None:
    """An a5 point light (no inverse-square law, SPEC A.3) at the centre of the cube: the first-hit flux is
    color ∫ r² dω = color Σ_faces ∫ (1/r) dA = 6 color ∫∫_[-1,1]² (1 + x² + y²)^(-1/2); sigma from the
    photons' own spread (std of 4π color r² over N photons, / sqrt N)."""
    n = 30000
    scene, integ = _box(mi, {"type": "a5_point", "position": [0.0, 0.0, 0.0],
                             "color": {"type": "rgb", "value": [0.7, 0.7, 0.7]}}, 0.5, 1)
    ps = integ.photon_set(scene, n, 3, 0, (0, 1, 2))
    g = (np.arange(4000) + 0.5) / 4000 * 2 - 1
    x, y = np.meshgrid(g, g)
    want = 0.7 * 6 * float((1.0 / np.sqrt(1 + x * x + y * y)).mean() * 4.0)
    per = ps.power[:, 0] * n
    assert len(per) == n
    sigma = per.std() / math.sqrt(n)
    assert abs(per.mean() - want) < 4.0 * sigma, (per.mean(), want, sigma)


@pytest.mark.parametrize("filter_name", ["none", "cone", "epanechnikov"])
def test_knn_estimate_of_a_uniform_photon_density(filter_name: str) -> None:
    """Photons uniform on the plane z = 0 with density ρ and power φ each: irradiance E = ρ φ and L = kd/π E.
    Sigma of a k-nearest estimate ~ E/sqrt(k - 2) (the (k - 1)/(π r²) estimate of a Poisson density has
    variance ρ²/(k - 2)); the mean over 400 points is checked to 4 sigma/sqrt(400)."""
    from a5mi.plugins.integrators.photon.maps import PhotonMap

    rng = np.random.default_rng(11)
    n, side, phi, k = 200000, 10.0, 0.01, 60
    pos = np.column_stack([rng.random(n) * side, rng.random(n) * side, np.zeros(n)])
    down = np.tile([0.0, 0.0, -1.0], (n, 1))
    pm = PhotonMap(pos, down, np.full((n, 3), phi))
    q = np.column_stack([2 + rng.random(400) * 6, 2 + rng.random(400) * 6, np.zeros(400)])
    up = np.tile([0.0, 0.0, 1.0], (400, 1))
    kd = np.full((400, 3), 0.6)
    est = pm.knn(q, up, kd, k, filter_name)[:, 0]
    want = 0.6 / math.pi * (n / side ** 2) * phi
    assert abs(est.mean() / want - 1.0) < 4.0 / math.sqrt((k - 2) * 400)
    back = pm.knn(q, -up, kd, k, filter_name)       # photons arriving on the other side count for nothing
    assert np.all(back == 0.0)
    ranged = pm.radius(q, up, kd, 0.4, filter_name)[:, 0]
    assert abs(ranged.mean() / want - 1.0) < 4.0 / math.sqrt(math.pi * 0.16 * n / side ** 2 * 400)


def test_split_counts_follow_the_powers(mi) -> None:
    from a5mi.plugins.integrators.photon.emit import split_counts

    assert split_counts(1000, [1.0, 3.0, 0.0]) == [250, 750, 0]
    assert split_counts(10, [1e-9, 1.0]) == [1, 10]
    assert split_counts(10, [0.0, 0.0]) == [0, 0]


def test_bad_parameters_are_refused(mi) -> None:
    for bad in ({"k": 0}, {"filter": "gauss"}, {"photons": -1}, {"aovs": "normal"}, {"fresnel": "x"}):
        with pytest.raises(Exception, match="a5_photon: "):
            mi.load_dict({"type": "a5_photon", **bad})
    with pytest.raises(Exception, match="alpha"):
        mi.load_dict({"type": "a5_ppm", "alpha": 1.5})


def test_options_pass_the_photon_parameters() -> None:
    p = RenderOptions(integrator="photon", photons=7, caustic_photons=8, photon_k=9, photon_filter="cone",
                      final_gather=3, seed=4).integrator_params()
    assert (p["photons"], p["caustic_photons"], p["k"], p["filter"], p["final_gather"], p["seed"]) == (
        7, 8, 9, "cone", 3, 4)
    assert "phong" not in p
    q = RenderOptions(integrator="ppm", ppm_radius=0.2, ppm_alpha=0.5).integrator_params()
    assert (q["radius"], q["alpha"]) == (0.2, 0.5) and "k" not in q
    assert "photons" not in RenderOptions().integrator_params()
