"""Subsurface scattering (docs/EXTENSIONS.md E.18): the dipole's formulas, its integration, the random walk.

* the implementation's ``R_d(r)`` equals Jensen et al. 2001's formula (written again here) on a grid of ``r``
  (1e-4 relative: float32), and its integral over the plane equals the closed-form ``R_d,total`` to 1 %;
* a uniformly lit half-space (a sphere of radius 1000) under ``-subsurface dipole`` shows
  ``F_t(0)² R_d,total`` (4 sigma of the sample mean, sigma from the lanes' spread);
* albedo 0 (``sigma_s 0``): no subsurface light, exactly, with either method; without ``-subsurface`` the
  material is the course's Lambert surface;
* ``-subsurface walk`` inside a sphere under a constant background against Mitsuba's ``volpath`` with a stock
  ``dielectric`` and a ``homogeneous`` interior medium: region means within 4 combined standard errors.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from conftest import positioned_error_test
from test_media import _scene, _trace

from a5mi.converters.a5_parser import parse_text
from a5mi.converters.subsurface import presets

HALF_SPACE = """PerspectiveCamera {{ center 0 5 0 direction 0 -1 0 up 0 0 -1 angle 20 }}
Lights {{ numLights 1 DirectionalLight {{ direction 0 -1 0 color 1 1 1 }} }}
Background {{ color 0 0 0 ambientLight 0 0 0 }}
Materials {{ numMaterials 1 Material {{ diffuseColor 0.5 0.5 0.5 {sss} }} }}
Group {{ numObjects 1 MaterialIndex 0 Sphere {{ center 0 -1000 0 radius 1000 }} }}
"""
MEDIUM = "subsurface { sigma_a 0.05 0.2 1 sigma_s 2 2 2 eta 1.3 samples 8 }"


def _reference_profile(sigma_a: float, sigma_sp: float, eta: float, r: np.ndarray) -> np.ndarray:
    """Jensen et al. 2001, eq. 4 with ``z_v = z_r + 4AD``, ``D = 1/(3 σ_t')``, written independently."""
    sigma_tp = sigma_a + sigma_sp
    alpha = sigma_sp / sigma_tp
    sigma_tr = np.sqrt(3.0 * sigma_a * sigma_tp)
    fdr = -1.440 / eta**2 + 0.710 / eta + 0.668 + 0.0636 * eta
    a = (1.0 + fdr) / (1.0 - fdr)
    z_r = 1.0 / sigma_tp
    z_v = z_r + 4.0 * a / (3.0 * sigma_tp)
    d_r, d_v = np.hypot(r, z_r), np.hypot(r, z_v)
    return alpha / (4 * np.pi) * (z_r * (sigma_tr * d_r + 1) * np.exp(-sigma_tr * d_r) / d_r**3
                                  + z_v * (sigma_tr * d_v + 1) * np.exp(-sigma_tr * d_v) / d_v**3)


def _profile(mi: Any, sigma_a: tuple[float, ...], sigma_s: tuple[float, ...], eta: float, r: np.ndarray) -> np.ndarray:
    from a5mi.plugins.media.dipole import profile_color

    c = profile_color(mi.Color3f(*map(float, sigma_a)), mi.Color3f(*map(float, sigma_s)), mi.Float(0.0), mi.Float(eta),
                      mi.Float(r.astype(np.float32)))
    return np.stack([np.asarray(c.x), np.asarray(c.y), np.asarray(c.z)], axis=-1).astype(np.float64)


# --------------------------------------------------------------------------------------------------- grammar
test_subsurface_errors_are_positioned = positioned_error_test(
    lambda block: HALF_SPACE.format(sss=block), [
        ("subsurface { preset ^jelly }", "unknown subsurface preset 'jelly'"),
        ("subsurface { ^sigma_a -1 0 0 sigma_s 1 1 1 }", "sigma_a must not be negative"),
        ("subsurface { preset marble ^eta 0 }", "eta must be between 0.01 and 100"),
        ("subsurface { preset marble ^eta 1e-30 }", "eta must be between 0.01 and 100"),
        ("subsurface { preset marble ^eta 1e30 }", "eta must be between 0.01 and 100"),
        ("subsurface { preset marble ^g 1 }", "g must be between -1 and 1"),
        ("^subsurface { sigma_a 1 1 1 }", "needs a preset or 'sigma_s'"),
        ("subsurface { preset marble ^preset skin1 }", "gives 'preset' twice"),
    ])


def test_presets_and_scale() -> None:
    """A preset gives Jensen's ``σ_s'`` and ``σ_a`` (mm⁻¹) times ``scale`` (mm per scene unit), ``η = 1.3``;
    a keyword after it overrides one value."""
    m = parse_text(HALF_SPACE.format(sss="subsurface { preset skin1 scale 10 sigma_a 1 2 3 }")).materials[0]
    assert m.subsurface is not None
    np.testing.assert_allclose(m.subsurface.sigma_s, np.array(presets()["skin1"][0]) * 10)
    np.testing.assert_allclose(m.subsurface.sigma_a, [10, 20, 30])
    assert m.subsurface.eta == 1.3 and m.subsurface.g == 0.0


# -------------------------------------------------------------------------------------------- dipole formulas
@pytest.mark.parametrize("name", ["marble", "skin1", "ketchup"])
def test_profile_is_jensens_formula(mi: Any, name: str) -> None:
    """``R_d(r)`` on 200 radii from 0 to ``10/σ_tr`` of each channel against eq. 4, 1e-4 relative (float32)."""
    sigma_sp, sigma_a = presets()[name]
    sigma_tr = np.sqrt(3 * np.array(sigma_a) * (np.array(sigma_a) + sigma_sp))
    for c in range(3):
        r = np.linspace(0.0, 10.0 / sigma_tr[c], 200)
        got = _profile(mi, sigma_a, sigma_sp, 1.3, r)[:, c]
        np.testing.assert_allclose(got, _reference_profile(sigma_a[c], sigma_sp[c], 1.3, r), rtol=1e-4)


@pytest.mark.parametrize(("name", "eta"), [("marble", 1.3), ("skin1", 1.3), ("ketchup", 1.5), ("apple", 1.2)])
def test_total_reflectance_is_the_integral(mi: Any, name: str, eta: float) -> None:
    """``∫ R_d 2πr dr`` of the implementation (trapezoid on 20000 log-spaced radii up to ``60/σ_tr``) equals
    ``(α'/2)(1 + e^{−4/3 A sqrt(3(1−α'))}) e^{−sqrt(3(1−α'))}`` to 1 %."""
    from a5mi.plugins.media.dipole import dipole, total_reflectance

    sigma_sp, sigma_a = (np.array(v) for v in presets()[name])
    dp = dipole(sigma_a, sigma_sp, 0.0, eta, xp=np)
    r = np.concatenate([[0.0], np.geomspace(1e-4 * dp.z_r.min(), 60.0 / dp.sigma_tr.min(), 20000)])
    rd = _profile(mi, tuple(sigma_a), tuple(sigma_sp), eta, r)
    integral = np.trapezoid(rd * 2 * np.pi * r[:, None], r, axis=0)
    np.testing.assert_allclose(integral, total_reflectance(dp.alpha, eta, xp=np), rtol=0.01)


# ----------------------------------------------------------------------------------------------- rendering
def _down(n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` rays straight down onto the top of the half-space, spread over a 0.1-wide square off the axis: the
    ray through the very top meets the sphere's pole, where the binary's sphere test (SPEC B.3,
    plugins/emulation/planes.py)
    shadows the hit point with its own surface (a5soln renders that pixel black under -shadows too)."""
    xz = (np.random.default_rng(1).random((n, 2)) - 0.5) * 0.1 + 0.01
    return np.column_stack([xz[:, 0], np.full(n, 0.5), xz[:, 1]]), np.tile([0.0, -1.0, 0.0], (n, 1))


def test_dipole_half_space_is_total_reflectance(mi: Any) -> None:
    """The top of a sphere of radius 1000 lit head-on, seen head-on: ``F_t(0)² R_d,total · E`` (E = 1), the
    mean of 2048 lanes (8 probes each) within 4 standard errors per channel."""
    from a5mi.plugins.media.dipole import dipole, total_reflectance

    o, d = _down(2048)
    got = _trace(mi, _scene(HALF_SPACE.format(sss=MEDIUM), subsurface="dipole"), o, d, seed=5)
    dp = dipole(np.array([0.05, 0.2, 1.0]), np.array([2.0, 2.0, 2.0]), 0.0, 1.3, xp=np)
    ft = 1.0 - ((1.3 - 1.0) / (1.3 + 1.0)) ** 2
    expected = ft * ft * total_reflectance(dp.alpha, 1.3, xp=np)
    se = got.std(axis=0, ddof=1) / np.sqrt(len(got))
    assert np.all(np.abs(got.mean(axis=0) - expected) < 4.0 * se), (got.mean(axis=0), expected, se)


@pytest.mark.parametrize("method", ["dipole", "walk"])
def test_albedo_zero_gives_no_subsurface_light(mi: Any, method: str) -> None:
    """``sigma_s 0``: ``α' = 0`` (dipole) and no scattering event (walk; the unscattered light through 2000
    units of ``σ_a = 1`` underflows): exactly black; without ``-subsurface`` the course's Lambert ``kd · cos``."""
    text = HALF_SPACE.format(sss="subsurface { sigma_a 1 1 1 sigma_s 0 0 0 }")
    o, d = _down(64)
    assert np.all(_trace(mi, _scene(text, subsurface=method), o, d) == 0.0)
    np.testing.assert_allclose(_trace(mi, _scene(text), o, d), 0.5, rtol=1e-6)


# ------------------------------------------------------------------------------------------ walk vs volpath
SPHERE = """PerspectiveCamera {{ center 0 0 5 direction 0 0 -1 up 0 1 0 angle 30 }}
Lights {{ numLights 0 }}
Background {{ color 1 1 1 ambientLight 0 0 0 }}
Materials {{ numMaterials 1 Material {{ diffuseColor 0 0 0
    subsurface {{ sigma_a {sa} sigma_s {ss} eta {eta} samples 1 }} }} }}
Group {{ numObjects 1 MaterialIndex 0 Sphere {{ center 0 0 0 radius 1 }} }}
"""


def _fresnel(cos_i: np.ndarray, eta: float) -> np.ndarray:
    """Unpolarised dielectric reflectance from outside (``η`` inside / outside)."""
    cos_t = np.sqrt(1.0 - (1.0 - cos_i**2) / eta**2)
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (rs**2 + rp**2)


def _volpath(mi: Any, sa: np.ndarray, ss: np.ndarray, eta: float, o: np.ndarray, d: np.ndarray,
             seed: int) -> np.ndarray:
    """Mitsuba's volpath: a stock ``dielectric`` sphere with a ``homogeneous`` interior under a constant
    environment of radiance 1."""
    st = sa + ss
    scene = mi.load_dict({
        "type": "scene", "integrator": {"type": "volpath", "max_depth": -1},
        "env": {"type": "constant", "radiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}},
        "sphere": {"type": "sphere", "radius": 1.0,
                   "bsdf": {"type": "dielectric", "int_ior": eta, "ext_ior": 1.0},
                   "interior": {"type": "homogeneous", "sigma_t": {"type": "rgb", "value": (st / st.max()).tolist()},
                                "scale": float(st.max()), "albedo": {"type": "rgb", "value": (ss / st).tolist()}}}})
    sampler = mi.load_dict({"type": "independent"})
    sampler.seed(seed, len(o))
    ray = mi.RayDifferential3f(mi.Point3f(*o.T.astype(np.float32)), mi.Vector3f(*d.T.astype(np.float32)))
    rgb = scene.integrator().sample(scene, sampler, ray, None, mi.Bool(True))[0]
    return np.stack([np.asarray(rgb.x), np.asarray(rgb.y), np.asarray(rgb.z)], axis=-1).astype(np.float64)


def _walk_vs_volpath(mi: Any, reps: int) -> None:
    sa, ss, eta = np.array([0.2, 0.1, 0.05]), np.array([1.0, 1.5, 2.0]), 1.3
    rng = np.random.default_rng(2)
    b = np.sqrt(rng.uniform(0.0, 0.49, 16))                          # impact parameters in the disc r < 0.7
    phi = rng.uniform(0.0, 2 * np.pi, 16)
    o = np.repeat(np.c_[b * np.cos(phi), b * np.sin(phi), np.full(16, 5.0)], reps, axis=0)
    d = np.tile([0.0, 0.0, -1.0], (len(o), 1))
    text = SPHERE.format(sa=" ".join(map(str, sa)), ss=" ".join(map(str, ss)), eta=eta)
    a5 = _trace(mi, _scene(text, subsurface="walk"), o, d, seed=9)
    a5 += _fresnel(np.sqrt(1.0 - np.repeat(b, reps) ** 2), eta)[:, None]   # the surface's mirror of the sky
    ref = _volpath(mi, sa, ss, eta, o, d, seed=4)
    se = np.sqrt(a5.var(axis=0, ddof=1) / len(a5) + ref.var(axis=0, ddof=1) / len(ref))
    diff = a5.mean(axis=0) - ref.mean(axis=0)
    assert np.all(np.abs(diff) < 4.0 * se), (a5.mean(axis=0), ref.mean(axis=0), se)


def test_walk_matches_volpath(mi: Any) -> None:
    """16 rays into the sphere's central disc, 128 samples each (both renderers): the region mean of the walk
    plus the analytic Fresnel mirror of the sky equals volpath's within 4 combined standard errors."""
    _walk_vs_volpath(mi, 128)


@pytest.mark.slow
def test_walk_matches_volpath_slow(mi: Any) -> None:
    """As :func:`test_walk_matches_volpath` with 4096 samples per ray (standard error about 0.001)."""
    _walk_vs_volpath(mi, 4096)


#: A sphere seen head-on through one pixel: the camera ray meets it at exactly normal incidence (cos = 1), where
#: Mitsuba's Fresnel term computes ``(1 − cos²) · η⁻²`` = ``0 · inf`` = NaN for η = 1e-30 (what made eta's range).
HEAD_ON = """PerspectiveCamera { center 0 0 5 direction 0 0 -1 up 0 1 0 angle 30 }
Lights { numLights 1 PointLight { position 1 2 3 color 0.6 0.6 0.6 } }
Background { color 0.2 0.3 0.4 ambientLight 0.1 0.1 0.1 }
Materials { numMaterials 1 Material { diffuseColor 0.5 0.5 0.5 subsurface { preset marble eta %s } } }
Group { numObjects 1 MaterialIndex 0 Sphere { center 0 0 0 radius 1 } }
"""


@pytest.mark.parametrize("method", ["dipole", "walk"])
@pytest.mark.parametrize("eta", ["0.01", "100"])
def test_eta_at_its_bounds_renders_finite_at_normal_incidence(render_text: Any, method: str, eta: str) -> None:
    """The ends of eta's range, on the one pixel that sees the sphere head-on: a finite, lit colour."""
    img = render_text(HEAD_ON % eta, width=1, height=1, subsurface=method)
    assert np.isfinite(img).all() and img.max() > 0.0
