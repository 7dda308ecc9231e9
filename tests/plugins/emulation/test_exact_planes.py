"""Planes intersected analytically by ``a5_whitted`` (SPEC A.6), checked against hand computation.

The tilted-plane scene: ``Plane { normal 0 1 0.05 offset -1 }`` under a directional light, with a sphere
casting a shadow, rendered with ``-shadows``. The expectation is computed per pixel in float64 from the B.2
camera rays: the plane hit ``t = (offset - n·o)/(n·d)``, Lambert ``ambient ⊙ kd + S max(L·N, 0) c ⊙ kd`` with
``S = 0`` exactly when the shadow ray meets the (analytic) sphere. The 1e7 stand-in of earlier versions drew
false-shadow bands here (23.9 dB against a5soln); a5soln itself renders this scene bit-identically to a5mi.
"""

from __future__ import annotations

import numpy as np

from a5mi.converters.a5_parser import parse_text
from a5mi.converters.describe import describe
from a5mi.platform.imageio import quantize
from a5mi.render.options import RenderOptions
from a5mi.render.session import render

N = 64
SCENE = """PerspectiveCamera { center 0 2 8 direction 0 -0.3 -1 up 0 1 0 angle 40 }
Lights { numLights 1 DirectionalLight { direction 0.3 -1 -0.4 color 0.7 0.7 0.7 } }
Background { color 0.2 0.2 0.5 ambientLight 0.1 0.1 0.1 }
Materials { numMaterials 2 Material { diffuseColor 0.8 0.8 0.8 } Material { diffuseColor 1 0.2 0.2 } }
Group { numObjects 2 MaterialIndex 0 Plane { normal 0 1 0.05 offset -1 }
 MaterialIndex 1 Sphere { center 0 0 0 radius 1 } }
"""


def _camera_rays(model) -> tuple[np.ndarray, np.ndarray]:
    import mitsuba as mi

    from a5mi.plugins.sensors.camera import camera_rays

    jj, ii = np.meshgrid(np.arange(N), np.arange(N), indexing="ij")
    c = model.camera
    ray = camera_rays(c.center, c.direction, c.up, c.angle, mi.Float(ii.ravel()), mi.Float(jj.ravel()), N, N)
    return np.array(ray.o, dtype=np.float64).T, np.array(ray.d, dtype=np.float64).T


def _sphere_t(o: np.ndarray, d: np.ndarray, c: np.ndarray, r: float) -> np.ndarray:
    """Nearest positive hit distance of unit-direction rays with a sphere (inf on a miss)."""
    oc = o - c
    b = np.sum(oc * d, axis=1)
    disc = b * b - (np.sum(oc * oc, axis=1) - r * r)
    with np.errstate(invalid="ignore"):
        s = np.sqrt(disc)
    t0, t1 = -b - s, -b + s
    t = np.where(t0 > 1e-3, t0, np.where(t1 > 1e-3, t1, np.inf))
    return np.where(disc >= 0, t, np.inf)


def test_tilted_plane_has_no_false_shadow_and_matches_hand_computed_lambert(variant: str) -> None:
    model = parse_text(SCENE, "tilted.txt")
    img = quantize(render(describe(model), RenderOptions(width=N, height=N, shadows=True, bounces=4)).image)
    img = img[::-1].reshape(-1, 3).astype(int)  # row 0 = bottom, as the rays
    o, d = _camera_rays(model)
    n = np.array([0, 1, 0.05])
    t_plane = (-1 - o @ n) / (d @ n)
    t_sphere = _sphere_t(o, d, np.zeros(3), 1.0)
    on_plane = (t_plane > 0) & (t_plane < t_sphere)
    p = o + t_plane[:, None] * d
    L = -np.array([0.3, -1, -0.4]) / np.linalg.norm([0.3, -1, -0.4])
    oc = p - 0.0
    b = oc @ L
    miss = b * b - (np.sum(oc * oc, axis=1) - 1.0)  # < 0: the shadow ray misses the sphere
    lit = miss < 0
    clear = np.abs(miss) > 1e-3  # away from the shadow's edge, where float32 and float64 may disagree
    nn = n / np.linalg.norm(n)
    expect = np.where(lit[:, None], 0.1 * 0.8 + max(float(L @ nn), 0.0) * 0.7 * 0.8, 0.1 * 0.8)
    expect8 = np.clip((np.broadcast_to(expect, (len(p), 3)) * 255).astype(int), 0, 255)
    sel = on_plane & clear
    assert sel.sum() > 0.4 * N * N and (sel & ~lit).sum() > 50  # plenty of plane, lit and in shadow
    err = np.abs(img[sel] - expect8[sel]).max(axis=1)
    assert err.max() <= 1, f"{(err > 1).sum()} plane pixels off (false shadow?)"


def test_planes_are_integrator_parameters_any_mitsuba_user_can_set(variant: str) -> None:
    """``plane_<id>_normal/offset/bsdf`` on ``a5_whitted`` in a plain ``mi.load_dict`` scene: the hit distance
    of a ray straight down onto ``normal 0 2 0 offset -1`` (y = -0.5) from y = 3 is 3.5, exactly."""
    import mitsuba as mi

    import a5mi.plugins

    a5mi.plugins.register_all()
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "a5_whitted", "aovs": "depth,normal",
                       "plane_floor_normal": [0, 2, 0], "plane_floor_offset": -1.0,
                       "plane_floor_bsdf": {"type": "a5_material"}},
        "light": {"type": "directional", "direction": [0, -1, 0]},
    })
    integ = scene.integrator()
    assert [p[0] for p in integ.planes] == ["floor"]
    _c, normal, t, *_ = integ.trace(scene, mi.Ray3f(mi.Point3f(0, 3, 0), mi.Vector3f(0, -1, 0)))
    assert float(t[0]) == 3.5 and np.allclose(np.array(normal).ravel(), [0, 1, 0])
    # Parallel to the plane (n·d == 0): skipped, the ray misses.
    _c, _n, t, *_ = integ.trace(scene, mi.Ray3f(mi.Point3f(0, 3, 0), mi.Vector3f(1, 0, 0)))
    assert np.isinf(float(t[0]))


def test_plane_parameters_are_checked(variant: str) -> None:
    import mitsuba as mi
    import pytest

    import a5mi.plugins

    a5mi.plugins.register_all()
    bad = [({"plane_a_normal": [0, 0, 0], "plane_a_offset": 0.0, "plane_a_bsdf": {"type": "a5_material"}},
            "must be finite and non-zero"),
           ({"plane_a_normal": [0, 1, 0], "plane_a_bsdf": {"type": "a5_material"}}, "lacks 'plane_a_offset'")]
    for params, msg in bad:
        with pytest.raises(Exception, match=msg):
            mi.load_dict({"type": "a5_whitted", **params})


def test_sphere_quotient_is_the_binarys_double_division_bit_for_bit(mi) -> None:
    """``Sphere::intersect``'s ``(float)((double)x / (2.0 (double)a))`` (SPEC A.6) done in float32 as
    ``x / (a + a)`` (double rounding is innocuous for a quotient, 53 >= 2·24 + 2; ``(x/2)/a`` where ``a + a``
    overflows): the same bits as the double expression, against NumPy for normal floats and against the kernel's
    own double arithmetic for every class of input (random bit patterns: subnormals, infinities, NaN)."""
    import drjit as dr

    from a5mi.plugins.emulation.plane_hits import half_quotient

    rng = np.random.default_rng(7)
    n = 400_000
    bits = rng.integers(0, 2**32, (2, n), dtype=np.uint64).astype(np.uint32).view(np.float32)
    special = np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 1e-45, 3e38, -3e38, 1.0, -2.5], dtype=np.float32)
    x = np.concatenate([bits[0], (rng.standard_normal(n) * 10).astype(np.float32), special])
    a = np.concatenate([np.abs(bits[1]), np.abs(rng.standard_normal(n)).astype(np.float32),
                        np.array([1, 1, 1, 1, 1, 1e38, 1e38, 3e38, 3e38, 1.7e38], dtype=np.float32)])
    got = np.asarray(half_quotient(mi.Float(x), mi.Float(a)))
    kernel = np.asarray(mi.Float(mi.Float64(mi.Float(x)) / (2.0 * mi.Float64(mi.Float(a)))))
    dr.eval()

    def same(p: np.ndarray, q: np.ndarray) -> np.ndarray:
        return (p.view(np.uint32) == q.view(np.uint32)) | (np.isnan(p) & np.isnan(q))

    assert same(got, kernel).all()
    tiny = np.float32(np.finfo(np.float32).tiny)
    with np.errstate(all="ignore"):
        exact = (x.astype(np.float64) / (2.0 * a.astype(np.float64))).astype(np.float32)
        normal = (np.abs(x) >= tiny) & (a >= tiny) & (np.abs(exact) >= tiny) & np.isfinite(x) & np.isfinite(a)
    assert normal.sum() > n and same(got[normal], exact[normal]).all()
