"""Photon paths end by Russian roulette, not by a depth cut: an integrating sphere (docs/EXTENSIONS.md E.16, E.17).

Inside a closed sphere of radius ``R`` and Lambert albedo ``a`` with a point light of intensity ``I`` at its
centre every wall point receives the direct irradiance ``E_0 = I/R²`` and, because each wall point sees every
other one with the form factor ``dA/(4πR²)``, the same indirect irradiance from the rest of the wall: the
irradiance is ``E = E_0 Σ_(m≥1) a^(m−1) = E_0/(1 − a)`` and the wall's radiance ``L = (a/π) E_0/(1 − a)``. A
photon of power ``Φ/N`` (``Φ = 4π I``) is stored at its first hit (direct) and at each further hit, which
Russian roulette lets happen with probability ``a`` at unchanged power: the number ``M`` of its indirect hits has
``P(M = m) = a^m (1 − a)``, ``E[M] = a/(1 − a)``, ``Var M = a/(1 − a)²``. A cut after ``D`` hits keeps only
``Σ_(m=1..D−1) a^m``: at ``a = 0.9`` and ``D = 10`` the wall is ``a^10 = 35 %`` too dark.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

A, INTENSITY, RADIUS = 0.9, 1.0, 1.0
#: The wall's radiance (module docstring).
WALL = A / math.pi * INTENSITY / RADIUS**2 / (1.0 - A)


def _sphere(mi: Any, integrator: dict, albedo: float = A, size: int = 8) -> Any:
    """The integrating sphere, seen from its centre (60° field of view, ``size`` x ``size``, one ray a pixel)."""
    return mi.load_dict({
        "type": "scene",
        "integrator": integrator,
        "sensor": {"type": "perspective", "fov": 60.0,
                   "to_world": mi.ScalarTransform4f().look_at([0, 0, 0], [0, 0, 1], [0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "box"}},
                   "sampler": {"type": "independent", "sample_count": 1}},
        "wall": {"type": "sphere", "radius": RADIUS,
                 "bsdf": {"type": "a5_material", "diffuse_color": {"type": "rgb", "value": [albedo] * 3}}},
        "light": {"type": "point", "position": [0.0, 0.0, 0.0],
                  "intensity": {"type": "rgb", "value": [INTENSITY] * 3}},
    })


def _stored(mi: Any, n: int, seed: int, depth: int = 0, albedo: float = A) -> Any:
    scene = _sphere(mi, {"type": "a5_photon", "photon_depth": depth}, albedo)
    return scene.integrator().photon_set(scene, n, seed, 0, (0, 1, 2))


def test_default_has_no_depth_cut_and_stores_the_albedo_series(mi: Any) -> None:
    """20,000 photons: the direct photons carry exactly ``Φ``; the indirect ones ``Φ E[M] = 9 Φ`` within 4
    sigma, ``σ = Φ sqrt(Var M / N)`` (0.75 % of it). Today's former cut at 10 hits stored ``5.5 Φ``."""
    n = 20000
    ps = _stored(mi, n, 3)
    phi = 4.0 * math.pi * INTENSITY
    assert abs(ps.power[ps.kind == 0, 0].sum() - phi) < 1e-3 * phi
    mean_m, var_m = A / (1.0 - A), A / (1.0 - A) ** 2
    sigma = phi * math.sqrt(var_m / n)
    total = ps.power[ps.kind == 2, 0].sum()
    assert abs(total - phi * mean_m) < 4.0 * sigma, (total / phi, mean_m, sigma / phi)


def test_photon_depth_flag_cuts_paths_as_documented(mi: Any) -> None:
    """``photon_depth D = 10``: the indirect power is ``Φ Σ_(m=1..9) a^m`` (min(M, D − 1) hits: mean
    ``Σ a^m``, variance from the truncated distribution), within 4 sigma."""
    n, depth = 20000, 10
    ps = _stored(mi, n, 4, depth)
    phi = 4.0 * math.pi * INTENSITY
    m = np.arange(depth)                                     # indirect hits 0 .. D - 1
    p = np.where(m < depth - 1, A ** m * (1 - A), A ** (depth - 1))
    mean_m, var_m = float((p * m).sum()), float((p * m * m).sum() - (p * m).sum() ** 2)
    sigma = phi * math.sqrt(var_m / n)
    total = ps.power[ps.kind == 2, 0].sum()
    assert abs(total - phi * mean_m) < 4.0 * sigma, (total / phi, mean_m, sigma / phi)
    assert mean_m < 0.62 * A / (1 - A)


def test_lossless_paths_end(mi: Any) -> None:
    """Albedo 1: survival is 1 for the first 32 bounces, then at most 0.95 (plugins/integrators/photon/trace.py): a
    photon makes ``33 + G`` hits, ``G`` geometric with mean ``0.95/0.05 = 19`` and variance ``0.95/0.05² = 380``; the
    mean of 2,000 photons within 4 sigma of 52 (and the tracing ends)."""
    from a5mi.plugins.integrators.photon.trace import ROULETTE_CAP, ROULETTE_CAP_DEPTH

    n = 2000
    ps = _stored(mi, n, 5, albedo=1.0)
    q = ROULETTE_CAP
    want = ROULETTE_CAP_DEPTH + 1 + q / (1 - q)
    sigma = math.sqrt(q / (1 - q) ** 2 / n)
    assert abs(len(ps.power) / n - want) < 4.0 * sigma, (len(ps.power) / n, want, sigma)


def _render(mi: Any, integrator: dict) -> float:
    return float(np.asarray(mi.render(_sphere(mi, integrator)))[..., 0].mean())


@pytest.mark.parametrize(("kind", "tolerance"), [("a5_photon", 0.065), ("a5_ppm", 0.03)])
def test_integrating_sphere_radiance(mi: Any, kind: str, tolerance: float) -> None:
    """8 x 8 rays from the centre, 20,000 global photons (``photon``: k = 50; ``ppm``: one pass of radius
    0.1): the image mean is ``L`` within 4 standard deviations of the image mean over map seeds (measured over
    seeds 1-10: 1.6 % for ``photon``, mean 0.996; 0.73 % for ``ppm``, mean 0.995). With the former cut after
    10 hits both read 35 % low."""
    extra = {"k": 50} if kind == "a5_photon" else {"radius": 0.1, "passes": 1}
    got = _render(mi, {"type": kind, "max_depth": 0, "photons": 20000, "caustic_photons": 0, "seed": 1, **extra})
    assert abs(got / WALL - 1.0) < tolerance, got / WALL


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["a5_photon", "a5_ppm"])
def test_integrating_sphere_radiance_slow(mi: Any, kind: str) -> None:
    """As above with 200,000 photons, the mean of four map seeds: within 1 % (4 standard errors)."""
    extra = {"k": 100} if kind == "a5_photon" else {"radius": 0.05, "passes": 1}
    got = [_render(mi, {"type": kind, "max_depth": 0, "photons": 200000, "caustic_photons": 0, "seed": s, **extra})
           for s in range(1, 5)]
    assert abs(np.mean(got) / WALL - 1.0) < 0.01, np.array(got) / WALL


def test_photon_depth_flag_reaches_both_integrators() -> None:
    """``-photon_depth N`` (docs/CLI.md): the flag sets ``RenderOptions.photon_depth``, which both photon
    integrators receive; 0 (no cut) by default, and a negative depth is refused."""
    from a5mi import cli
    from a5mi.commands.render import render_options
    from a5mi.platform.errors import UsageError
    from a5mi.render.options import RenderOptions

    args = cli.parse_a5_args(["-input", "s.txt", "-output", "o.png", "-integrator", "photon", "-photon_depth", "7"])
    assert render_options(args).photon_depth == 7
    for name in ("photon", "ppm"):
        assert RenderOptions(integrator=name).integrator_params()["photon_depth"] == 0
        assert RenderOptions(integrator=name, photon_depth=3).integrator_params()["photon_depth"] == 3
    with pytest.raises(UsageError, match="photon_depth expects an integer in"):
        cli.parse_a5_args(["-input", "s.txt", "-output", "o.png", "-photon_depth", "-1"])
