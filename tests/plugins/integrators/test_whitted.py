"""a5_whitted (SPEC B.3): tiny scenes, rays built by hand, pixel values computed by hand."""

from __future__ import annotations

import gc
import math

import drjit as dr
import numpy as np
import pytest
from conftest import a5_material as _material
from conftest import rgb as _rgb

INV_SQRT2 = 1.0 / math.sqrt(2.0)




def _sphere(center=(0, 0, 0), radius=1.0, **material) -> dict:
    return {"type": "sphere", "center": list(center), "radius": radius, "bsdf": _material(**material)}


def _plane(mi, z: float, normal_sign: float = 1.0, half: float = 100.0, x: float = 0.0, **material) -> dict:
    """A square of half-size ``half`` at depth z, normal +z (or -z), centred at (x, 0, z)."""
    to_world = mi.ScalarTransform4f().translate([x, 0.0, z])
    if normal_sign < 0:
        to_world = to_world.rotate([1, 0, 0], 180.0)
    return {"type": "rectangle", "to_world": to_world.scale(half), "bsdf": _material(**material)}


def _scene(mi, **objects) -> object:
    return mi.load_dict({"type": "scene", **objects})


def _render(mi, scene, integrator: dict | None = None, o=(0, 0, -5), d=(0, 0, 1)):
    """Trace hand-built camera rays; returns (colour (N,3), aovs dict of (N,) arrays)."""
    integ = mi.load_dict({"type": "a5_whitted", "aovs": "normal,depth,counts", **(integrator or {})})
    o = np.atleast_2d(np.array(o, dtype=np.float64))
    d = np.atleast_2d(np.array(d, dtype=np.float64))
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    ray = mi.Ray3f(mi.Point3f(*(mi.Float(o[:, i]) for i in range(3))),
                   mi.Vector3f(*(mi.Float(d[:, i]) for i in range(3))))
    color, valid, aovs = integ.sample(scene, None, ray)
    assert bool(dr.all(valid))
    return np.array(color, dtype=np.float64).T, {
        name: np.array(a, dtype=np.float64) for name, a in zip(integ.aov_names(), aovs, strict=True)}


# ---------------------------------------------------------------------------------------- local shading


def test_b3_lambert_sphere_directional_light(mi):
    """Hit (0,0,-1), N = (0,0,-1); light travelling (0,-1,1)/√2 gives L = (0,1,-1)/√2, L·N = 1/√2."""
    scene = _scene(mi, s=_sphere(diffuse_color=(0.2, 0.4, 0.6), kd=(1.0, 0.5, 0.25)),
                   l={"type": "directional", "direction": [0, -1, 1], "irradiance": _rgb(0.8, 0.6, 0.4)})
    color, aovs = _render(mi, scene, {"ambient": _rgb(0.1, 0.2, 0.3)})
    expected = np.array([0.1, 0.2, 0.3]) * [0.2, 0.4, 0.6] + INV_SQRT2 * np.array([0.8, 0.6, 0.4]) * [1, .5, .25]
    assert np.allclose(color[0], expected, atol=1e-6)
    assert np.allclose([aovs["nx"][0], aovs["ny"][0], aovs["nz"][0]], [0, 0, -1], atol=1e-6)
    assert aovs["t"][0] == pytest.approx(4.0, abs=1e-5)


def test_b3_light_behind_surface_is_clamped(mi):
    scene = _scene(mi, s=_sphere(diffuse_color=(1, 1, 1)),
                   l={"type": "directional", "direction": [0, 0, -1], "irradiance": _rgb(1, 1, 1)})
    color, _ = _render(mi, scene, {"ambient": _rgb(0.25, 0.25, 0.25)})
    assert np.allclose(color[0], 0.25, atol=1e-7)


def test_b3_no_lights_is_ambient_times_raw_diffuse_color(mi):
    """ambient ⊙ diffuseColor, even when kd (texture / marble stand-in) differs."""
    scene = _scene(mi, s=_sphere(diffuse_color=(0.5, 0.25, 1.0), kd=(0.9, 0.9, 0.9)))
    color, _ = _render(mi, scene, {"ambient": _rgb(1.0, 0.5, 0.5)})
    assert np.allclose(color[0], [0.5, 0.125, 0.5], atol=1e-7)


def test_b3_stock_bsdf_shades_as_diffuse_with_its_reflectance(mi):
    scene = _scene(mi, s={"type": "sphere", "bsdf": {"type": "diffuse", "reflectance": _rgb(0.5, 0.5, 0.5)}},
                   l={"type": "directional", "direction": [0, 0, 1], "irradiance": _rgb(1, 1, 1)})
    color, _ = _render(mi, scene, {"ambient": _rgb(0.2, 0.2, 0.2)})
    assert np.allclose(color[0], 0.2 * 0.5 + 0.5, atol=1e-6)


def _shadow_scene(mi):
    """Floor y = -1 (normal +y) under a sphere at (0,1,0); light straight down; probe the floor at x = 0."""
    floor = {"type": "rectangle", "bsdf": _material(diffuse_color=(0.5, 0.5, 0.5)),
             "to_world": mi.ScalarTransform4f().translate([0, -1, 0]).rotate([1, 0, 0], -90).scale(50)}
    return _scene(mi, floor=floor, s=_sphere(center=(0, 1, 0), diffuse_color=(1, 0, 0)),
                  l={"type": "directional", "direction": [0, -1, 0], "irradiance": _rgb(1, 1, 1)})


@pytest.mark.parametrize("shadows", [False, True])
def test_b3_shadowed_point(mi, shadows):
    scene = _shadow_scene(mi)
    # ray from the side, hitting the floor at (0,-1,0), under the sphere; and one at x = 5 (lit)
    color, aovs = _render(mi, scene, {"ambient": _rgb(0.1, 0.1, 0.1), "shadows": shadows},
                          o=[(-4, 0, 0), (1, 0, 0)], d=[(4, -1, 0), (4, -1, 0)])
    lit = 0.1 * 0.5 + 1.0 * 0.5
    assert np.allclose(color[0], 0.05 if shadows else lit, atol=1e-6)
    assert np.allclose(color[1], lit, atol=1e-6)
    assert np.allclose(aovs["n_shadow"], 1.0 if shadows else 0.0)


def test_b3_zero_term_casts_no_shadow_ray(mi):
    """S only scales ``clamp(L·N) lightColor ⊙ kd``: a light behind the surface (term 0) or a black kd casts no
    shadow ray (``n_shadow`` counts the rays cast) and the colour is the same as with every ray cast."""
    floor = {"type": "rectangle", "bsdf": _material(diffuse_color=(0.5, 0.5, 0.5)),
             "to_world": mi.ScalarTransform4f().translate([0, -1, 0]).rotate([1, 0, 0], -90).scale(50)}
    black = {"type": "rectangle", "bsdf": _material(diffuse_color=(0.0, 0.0, 0.0)),
             "to_world": mi.ScalarTransform4f().translate([0, -0.5, 20]).rotate([1, 0, 0], -90).scale(5)}
    lights = {"up": {"type": "directional", "direction": [0, -1, 0], "irradiance": _rgb(1, 1, 1)},
              "below": {"type": "directional", "direction": [0, 1, 0], "irradiance": _rgb(1, 1, 1)}}
    scene = _scene(mi, floor=floor, black=black, **lights)
    # a floor point (lit from above only), a point on the black patch, a miss
    o, d = [(-4, 0, 0), (-4, 0, 20), (0, 0, 0)], [(4, -1, 0), (4, -1, 0), (0, 1, 0)]
    color, aovs = _render(mi, scene, {"ambient": _rgb(0.1, 0.1, 0.1), "shadows": True}, o=o, d=d)
    assert aovs["n_shadow"].tolist() == [1.0, 0.0, 0.0]
    assert np.allclose(color[0], 0.1 * 0.5 + 0.5, atol=1e-6) and np.allclose(color[1], 0.0, atol=1e-7)
    unshadowed, _ = _render(mi, scene, {"ambient": _rgb(0.1, 0.1, 0.1), "shadows": False}, o=o, d=d)
    assert np.array_equal(color, unshadowed)


def test_b3_occluder_beyond_the_point_light_casts_no_shadow(mi):
    """Shadow rays end at the light (0.001 < t < dist): a wall *behind* the point light must not block it.

    Floor point (0,-1,0), light at (0,1,0) (d = 2, L·N = 1), wall y = 3 above the light: lit = kd·colour.
    """
    floor = {"type": "rectangle", "bsdf": _material(diffuse_color=(0.5, 0.5, 0.5)),
             "to_world": mi.ScalarTransform4f().translate([0, -1, 0]).rotate([1, 0, 0], -90).scale(50)}
    wall = {"type": "rectangle", "bsdf": _material(diffuse_color=(1, 1, 1)),
            "to_world": mi.ScalarTransform4f().translate([0, 3, 0]).rotate([1, 0, 0], 90).scale(50)}
    scene = _scene(mi, floor=floor, wall=wall,
                   l={"type": "a5_point", "position": [0, 1, 0], "color": _rgb(1, 1, 1), "falloff": 0.0})
    color, _ = _render(mi, scene, {"shadows": True}, o=[(-4, 0, 0)], d=[(4, -1, 0)])
    assert np.allclose(color[0], 0.5, atol=1e-6)


def test_a3_a5_point_light_falloff(mi):
    """a5_point: colour / (1 + f d²), no inverse square. Light at (0,0,-3), hit (0,0,-1): d = 2, L·N = 1."""
    scene = _scene(mi, s=_sphere(diffuse_color=(1, 1, 1), kd=(0.5, 1.0, 0.25)),
                   l={"type": "a5_point", "position": [0, 0, -3], "color": _rgb(1.0, 0.8, 0.6), "falloff": 0.5})
    color, _ = _render(mi, scene)
    assert np.allclose(color[0], np.array([1.0, 0.8, 0.6]) / (1 + 0.5 * 4) * [0.5, 1.0, 0.25], atol=1e-6)


def test_a3_stock_point_light_is_inverse_square(mi):
    """The stock ``point`` emitter's arriving colour is intensity / d² (what sample_direction returns)."""
    scene = _scene(mi, s=_sphere(diffuse_color=(1, 1, 1)),
                   l={"type": "point", "position": [0, 0, -3], "intensity": _rgb(2, 4, 8)})
    color, _ = _render(mi, scene)
    assert np.allclose(color[0], np.array([2, 4, 8]) / 4.0, atol=1e-5)


def test_b3_phong_option_adds_handout_highlight(mi):
    """R = reflect(d, N) = (0,0,-1); L at 60° from R: highlight cos(60°)^10 ⊙ lightColor ⊙ specularColor."""
    theta = math.radians(60.0)
    light_dir = [0, -math.sin(theta), math.cos(theta)]  # L = (0, sin, -cos): L·N = L·R = cos 60°
    scene = _scene(mi, s=_sphere(diffuse_color=(0.5, 0.5, 0.5), specular_color=(0.2, 0.4, 0.6), shininess=10.0),
                   l={"type": "directional", "direction": light_dir, "irradiance": _rgb(1, 1, 1)})
    base = 0.5 * 0.5  # diffuse; the mirror ray sees black (no background)
    off, _ = _render(mi, scene)
    on, _ = _render(mi, scene, {"phong": True})
    assert np.allclose(off[0], base, atol=1e-6)
    assert np.allclose(on[0], base + 0.5**10 * np.array([0.2, 0.4, 0.6]), atol=1e-6)


# ---------------------------------------------------------------------------------------- background, mirror


def test_b3_miss_returns_background_or_black(mi):
    with_bg = _scene(mi, bg={"type": "constant", "radiance": _rgb(0.2, 0.4, 0.6)})
    color, aovs = _render(mi, with_bg)
    assert np.allclose(color[0], [0.2, 0.4, 0.6], atol=1e-7)
    assert aovs["t"][0] == math.inf and aovs["nx"][0] == aovs["ny"][0] == aovs["nz"][0] == 0.0
    color, _ = _render(mi, _scene(mi, s=_sphere(center=(10, 0, 0))))
    assert np.allclose(color[0], 0.0)


def test_b3_mirror_sees_background(mi):
    """Black mirror sphere: the reflected ray (back along -z) misses and sees the background, ⊙ specularColor."""
    scene = _scene(mi, s=_sphere(diffuse_color=(0, 0, 0), specular_color=(0.5, 0.25, 1.0)),
                   bg={"type": "constant", "radiance": _rgb(0.2, 0.4, 0.6)})
    color, aovs = _render(mi, scene)
    assert np.allclose(color[0], [0.1, 0.1, 0.6], atol=1e-6)
    assert aovs["n_reflection"][0] == 1 and aovs["n_refraction"][0] == 0
    off, aovs = _render(mi, scene, {"reflection": False})
    assert np.allclose(off[0], 0.0) and aovs["n_reflection"][0] == 0


def test_b3_mirror_threshold_is_euclidean_length(mi):
    """|(0.0006, 0.0006, 0.0006)| = 0.00104 > 0.001 reflects; (0.0005, 0.0005, 0.0005) (0.00087) does not."""
    for spec, expected in ((0.0006, 1), (0.0005, 0)):
        scene = _scene(mi, s=_sphere(diffuse_color=(0, 0, 0), specular_color=(spec, spec, spec)))
        _, aovs = _render(mi, scene)
        assert aovs["n_reflection"][0] == expected


def test_b3_bounces_zero_is_ambient_plus_shadowed_lambert(mi):
    scene = _scene(mi, s=_sphere(diffuse_color=(0.5, 0.5, 0.5), specular_color=(1, 1, 1), refraction_index=1.5),
                   l={"type": "directional", "direction": [0, 0, 1], "irradiance": _rgb(0.5, 0.5, 0.5)},
                   bg={"type": "constant", "radiance": _rgb(1, 1, 1)})
    color, aovs = _render(mi, scene, {"max_depth": 0, "shadows": True, "ambient": _rgb(0.2, 0.2, 0.2),
                                      "aovs": "normal,depth,counts"})
    assert np.allclose(color[0], 0.2 * 0.5 + 0.5 * 0.5, atol=1e-6)
    assert aovs["n_reflection"][0] == aovs["n_refraction"][0] == 0 and aovs["n_shadow"][0] == 1


# ---------------------------------------------------------------------------------------- refraction

GLASS = {"diffuse_color": (0, 0, 0), "specular_color": (1, 1, 1), "refraction_index": 1.5}


def _slab_scene(mi, *, second_face: bool):
    """Glass face z = 0 (normal +z, toward the camera at z = +5), optional exit face z = -1 (normal -z),
    white wall at z = -2 seen only through ambient 1 (no lights, no background)."""
    objects = {"front": _plane(mi, 0.0, **GLASS),
               "wall": _plane(mi, -2.0, diffuse_color=(1, 1, 1))}
    if second_face:
        objects["back"] = _plane(mi, -1.0, normal_sign=-1.0, **GLASS)
    return _scene(mi, **objects)


@pytest.mark.parametrize("mode", ["a5", "schlick", "exact"])
def test_b3_fresnel_normal_incidence_single_face(mi, mode):
    """colour = (1 - R) ⊙ wall with R = 0.04 at normal incidence from air, in every mode."""
    scene = _slab_scene(mi, second_face=False)
    color, _ = _render(mi, scene, {"fresnel": mode, "ambient": _rgb(1, 1, 1), "max_depth": 1},
                       o=(0, 0, 5), d=(0, 0, -1))
    assert np.allclose(color[0], 0.96, atol=1e-6)


@pytest.mark.parametrize(("mode", "expected"), [("a5", 0.96), ("schlick", 0.96 * 0.96), ("exact", 0.96 * 0.96)])
def test_b3_fresnel_leaving_glass(mi, mode, expected):
    """Exit face: n = 1.5, nt = 1. The binary's R0 = ((1-1)/(1+1))² = 0, so a5 transmits everything there."""
    scene = _slab_scene(mi, second_face=True)
    color, _ = _render(mi, scene, {"fresnel": mode, "ambient": _rgb(1, 1, 1), "max_depth": 2},
                       o=(0, 0, 5), d=(0, 0, -1))
    assert np.allclose(color[0], expected, atol=1e-6)


@pytest.mark.parametrize("mode", ["a5", "schlick", "exact"])
def test_b3_fresnel_grazing_incidence(mi, mode):
    theta = math.radians(80.0)
    c = math.cos(theta)
    if mode == "exact":
        cos_t = math.sqrt(1 - (math.sin(theta) / 1.5) ** 2)
        rs = (c - 1.5 * cos_t) / (c + 1.5 * cos_t)
        rp = (1.5 * c - cos_t) / (1.5 * c + cos_t)
        r = 0.5 * (rs * rs + rp * rp)
    else:
        r = 0.04 + 0.96 * (1 - c) ** 5
    scene = _slab_scene(mi, second_face=False)
    color, _ = _render(mi, scene, {"fresnel": mode, "ambient": _rgb(1, 1, 1), "max_depth": 1},
                       o=(-5 * math.tan(theta), 0, 5), d=(math.sin(theta), 0, -c))
    assert np.allclose(color[0], 1 - r, rtol=1e-4)


def test_b3_refraction_switch_off_means_r_equals_one(mi):
    scene = _slab_scene(mi, second_face=False)
    color, aovs = _render(mi, scene, {"refraction": False, "ambient": _rgb(1, 1, 1)},
                          o=(0, 0, 5), d=(0, 0, -1))
    assert np.allclose(color[0], 0.0)  # only the mirror ray, which sees black
    assert aovs["n_refraction"][0] == 0 and aovs["n_reflection"][0] == 1


def test_b3_total_internal_reflection(mi):
    """Enter at normal incidence, then meet an exit face tilted 60°: 1.5 sin 60° > 1, so R = 1 and no
    refracted ray. Everything then reaches the blue background; the red wall behind stays unseen."""
    tilt = mi.ScalarTransform4f().translate([0, 0, -1]).rotate([0, 1, 0], 120.0).scale(50)  # normal (.87,0,-.5)
    scene = _scene(mi, front=_plane(mi, 0.0, **GLASS),
                   back={"type": "rectangle", "to_world": tilt, "bsdf": _material(**GLASS)},
                   wall=_plane(mi, -3.0, half=0.5, diffuse_color=(1, 0, 0)),
                   bg={"type": "constant", "radiance": _rgb(0, 0, 1)})
    color, aovs = _render(mi, scene, {"ambient": _rgb(1, 1, 1), "aovs": "normal,depth,counts", "max_depth": 4},
                          o=(0, 0, 5), d=(0, 0, -1))
    assert np.allclose(color[0], [0, 0, 1], atol=1e-6)
    assert aovs["n_refraction"][0] == 1        # entering only; none at the TIR face
    assert aovs["n_reflection"][0] == 2        # front-face mirror ray + the internal reflection


# ---------------------------------------------------------------------------------------- class AOV

MIRROR = {"diffuse_color": (0, 0, 0), "specular_color": (1, 1, 1)}


def _classes(mi, scene, integrator: dict | None = None, **ray) -> tuple[np.ndarray, np.ndarray]:
    """The ``class`` AOV of hand-built rays, and the colour (which asking for the AOV must not change)."""
    color, aovs = _render(mi, scene, {"aovs": "class", **(integrator or {})}, **ray)
    plain, _ = _render(mi, scene, {"aovs": "", **(integrator or {})}, **ray)
    np.testing.assert_array_equal(color, plain)
    return aovs["class"], color


def test_b3_class_miss_is_0_and_diffuse_is_1(mi):
    """The camera ray misses (a background does not count as a hit) -> 0; a diffuse sphere -> 1."""
    scene = _scene(mi, s=_sphere(diffuse_color=(0.5, 0.5, 0.5)),
                   bg={"type": "constant", "radiance": _rgb(0.2, 0.4, 0.6)})
    cls, _ = _classes(mi, scene, o=[(0, 0, -5), (5, 0, -5)], d=[(0, 0, 1), (0, 0, 1)])
    np.testing.assert_array_equal(cls, [1, 0])


def test_b3_class_glass_sphere_is_2_at_every_budget(mi):
    """A sphere with refraction_index > 0 hit by the camera ray is glass, with or without secondary rays."""
    scene = _scene(mi, s=_sphere(**GLASS))
    for budget in (0, 4):
        for refraction in (True, False):
            cls, _ = _classes(mi, scene, {"max_depth": budget, "refraction": refraction})
            assert cls[0] == 2


def test_b3_class_mirror_seeing_glass_is_2_within_the_budget_else_1(mi):
    """A mirror sphere at the origin reflects the camera ray (from z = -5 along +z) back along -z onto a glass
    sphere at z = -10, behind the camera. The mirror ray is the last level with max_depth 1 (still counted:
    2); with max_depth 0 the glass sphere lies beyond the bounce budget (1); with reflection off too (1)."""
    scene = _scene(mi, m=_sphere(**MIRROR), g=_sphere(center=(0, 0, -10), **GLASS))
    expected = [({"max_depth": 1}, 2), ({"max_depth": 4}, 2), ({"max_depth": 0}, 1),
                ({"max_depth": 4, "reflection": False}, 1)]
    for integrator, want in expected:
        cls, _ = _classes(mi, scene, integrator)
        assert cls[0] == want, integrator
    # the same mirror without the glass sphere behind the camera is opaque
    cls, _ = _classes(mi, _scene(mi, m=_sphere(**MIRROR)))
    assert cls[0] == 1


def test_b3_class_aov_names_and_order(mi):
    assert mi.load_dict({"type": "a5_whitted", "aovs": "class"}).aov_names() == ["class"]
    integ = mi.load_dict({"type": "a5_whitted", "aovs": "counts,class,depth,normal"})
    assert integ.aov_names() == ["nx", "ny", "nz", "t", "class", "n_reflection", "n_refraction", "n_shadow"]
    assert "class" in str(integ)


# ---------------------------------------------------------------------------------------- plugin surface


def test_b3_aov_names_and_traverse(mi):
    integ = mi.load_dict({"type": "a5_whitted"})
    assert integ.aov_names() == []
    assert mi.load_dict({"type": "a5_whitted", "aovs": "depth, normal"}).aov_names() == ["nx", "ny", "nz", "t"]
    integ = mi.load_dict({"type": "a5_whitted", "aovs": "normal,depth,counts", "max_depth": 7, "fresnel": "exact"})
    assert integ.aov_names() == ["nx", "ny", "nz", "t", "n_reflection", "n_refraction", "n_shadow"]
    params = mi.traverse(integ)
    assert params["max_depth"] == 7 and params["fresnel"] == "exact" and params["shadows"] is False


@pytest.mark.parametrize(("key", "value"), [("max_depth", -1), ("fresnel", "fast"), ("tmin", -0.5),
                                             ("shadows", 3), ("ambient", "red"),
                                             ("aovs", "normal,colour"), ("aovs", 3)])
def test_b3_bad_parameters_name_the_parameter(mi, key, value):
    with pytest.raises((ValueError, RuntimeError), match=f"'{key}'"):
        mi.load_dict({"type": "a5_whitted", key: value})


def test_b3_second_scene_reuses_the_kernel(mi):
    """Different colours, ambient and bounce budget (3 vs 4), same structure: one compiled kernel."""

    def render(k: float, depth: int) -> str:
        scene = _scene(mi, s=_sphere(diffuse_color=(k, 0.5, 0.25), specular_color=(0.5, k, 0.5)),
                       l={"type": "directional", "direction": [0, -1, k], "irradiance": _rgb(k, k, 1)},
                       bg={"type": "constant", "radiance": _rgb(0.1, k, 0.3)})
        integ = mi.load_dict({"type": "a5_whitted", "max_depth": depth, "ambient": _rgb(k, k, k)})
        ray = mi.Ray3f(mi.Point3f(mi.Float(0.0, 0.5, 3.0), 0, -5), mi.Vector3f(0, 0, 1))
        dr.kernel_history()  # clear
        color, _, aovs = integ.sample(scene, None, ray)
        dr.eval(color, aovs)
        dr.sync_thread()
        kernels = [h for h in dr.kernel_history() if h["type"] == dr.KernelType.JIT]
        main = max(kernels, key=lambda h: h["operation_count"])
        del scene, integ
        gc.collect()
        return main["hash"]

    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        gc.collect()
        first = render(0.3, 4)
        second = render(0.7, 3)
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
    assert first == second


@pytest.mark.parametrize("aovs", ["", "normal,depth"])
def test_b3_works_under_mi_render_with_a_stock_sensor(mi, aovs):
    """mi.render drives sample() through the trampoline; the film gets RGB, plus the four AOVs only when the
    ``aovs`` parameter asks for them (so a Mitsuba user's ``mi.render`` gives a plain RGB image)."""
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "a5_whitted", "ambient": _rgb(0.5, 0.5, 0.5), "aovs": aovs},
        "sensor": {"type": "perspective", "fov": 5.0,
                   "to_world": mi.ScalarTransform4f().look_at([0, 0, -5], [0, 0, 0], [0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 3, "height": 3, "rfilter": {"type": "box"}}},
        "s": _sphere(diffuse_color=(1.0, 0.5, 0.25)),
    })
    img = np.array(mi.render(scene, spp=1), dtype=np.float64)
    assert img.shape == ((3, 3, 7) if aovs else (3, 3, 3))
    assert np.allclose(img[..., :3], [0.5, 0.25, 0.125], atol=1e-6)   # no lights: ambient ⊙ diffuseColor
    if aovs:
        assert np.all(img[..., 5] < -0.95)                             # nz of the front of the sphere
        assert np.all(np.abs(img[..., 6] - 4.0) < 0.05)                # t
