"""The distribution-ray-tracing extension (docs/EXTENSIONS.md): analytic checks with stated tolerances.

Soft shadows against an independent numpy quadrature of the E.2 integral (3 standard errors); the thin-lens
blur circle against ``A |z - F| / z`` (5 %); the spot profile against the E.1 law (1e-4); glossy limits
(roughness -> 0 gives the mirror; a white glossy mirror under a constant background returns it, 2 %); the
convergence slope of RMSE against spp (stratified sampling: at least as fast as spp^-1/2).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import positioned_error_test
from helpers import ROOT

from a5mi.converters.a5_parser import parse_text
from a5mi.converters.errors import SceneError

FLOOR_SCENE = """PerspectiveCamera {{ center 0 5 10 direction 0 -0.5 -1 up 0 1 0 angle 30 }}
Lights {{ numLights 1 {light} }}
Background {{ color 0 0 0 ambientLight 0 0 0 }}
Materials {{ numMaterials 1 Material {{ diffuseColor 1 1 1 }} }}
Group {{ numObjects {n} MaterialIndex 0 Plane {{ normal 0 1 0 offset 0 }} {extra} }}
"""


def _scene(mi: Any, text: str, **opts: Any) -> Any:
    from a5mi.converters.describe import describe
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import build_scene

    return build_scene(describe(parse_text(text)), RenderOptions(shadows=True, **opts))


def _floor_values(mi: Any, scene: Any, points: np.ndarray, lanes: int, seed: int = 7) -> np.ndarray:
    """Colour (red) of ``lanes`` independent estimates at each floor point, traced from below (N = +y)."""
    from a5mi.plugins.sampling import SamplePass

    integ = scene.integrator()
    pts = np.repeat(points, lanes, axis=0)
    o = mi.Point3f(pts[:, 0], np.full(len(pts), -1.0), pts[:, 2])
    zero = np.zeros(len(pts), dtype=np.float32)
    d = mi.Vector3f(zero, zero + 1.0, zero)
    color = integ.trace(scene, mi.Ray3f(o, d), sample_pass=SamplePass(0, 0, 1, seed))[0]
    return np.asarray(color.x).reshape(len(points), lanes)


# ------------------------------------------------------------------------------------------------ grammar
# The error sits at the offending keyword (line 2, its column), as the course grammar's errors do.
test_light_errors_are_positioned = positioned_error_test(
    lambda light: FLOOR_SCENE.format(light=light, n=1, extra=""), [
        ("SpotLight { position 0 1 0 direction 0 -1 0 color 1 1 1 ^angle 95 }", "between 0 and 90"),
        ("AreaLight { corner 0 1 0 edge1 1 0 0 ^edge2 2 0 0 color 1 1 1 }", "non-zero area"),
        ("SphereLight { center 0 1 0 ^radius 0 color 1 1 1 }", "radius must be positive"),
        ("AreaLight { corner 0 1 0 edge1 1 0 0 edge2 0 0 1 color 1 1 1 ^samples 0 }", "samples must be"),
    ])


def test_camera_and_material_keywords() -> None:
    text = FLOOR_SCENE.format(light="PointLight { position 0 1 0 color 1 1 1 }", n=1, extra="")
    s = parse_text(text.replace("angle 30 }", "angle 30 aperture 0.2 focusDistance 4 }")
                   .replace("diffuseColor 1 1 1 }", "diffuseColor 1 1 1 roughness 0.3 glossySamples 4 }"))
    assert (s.camera.aperture, s.camera.focus_distance) == (0.2, 4.0)
    assert (s.materials[0].roughness, s.materials[0].glossy_samples) == (0.3, 4)
    with pytest.raises(SceneError, match="roughness must be between 0 and 1"):
        parse_text(text.replace("diffuseColor 1 1 1 }", "diffuseColor 1 1 1 roughness 2 }"))
    with pytest.raises(SceneError, match="expected a number after 'aperture', found '}'"):
        parse_text(text.replace("angle 30 }", "angle 30 aperture }"))
    with pytest.raises(SceneError, match="expected '}' to close PerspectiveCamera"):
        parse_text(text.replace("angle 30 }", "angle 30 lens 2 }"))


# ------------------------------------------------------------------------------------------------ soft shadow
def _visible_cosine_quadrature(p: np.ndarray, corner: np.ndarray, e1: np.ndarray, e2: np.ndarray,
                               c: np.ndarray, r: float, n: int = 1200) -> float:
    """(1/A) ∫ V(p, y) max(L·N, 0) dA(y) over the parallelogram, midpoint rule on n x n, exact ray-sphere V."""
    s = (np.arange(n) + 0.5) / n
    u, v = np.meshgrid(s, s, indexing="ij")
    y = corner + u[..., None] * e1 + v[..., None] * e2
    dvec = y - p
    dist = np.linalg.norm(dvec, axis=-1)
    w = dvec / dist[..., None]
    oc = p - c
    b = np.sum(w * oc, axis=-1)
    disc = b * b - (oc @ oc - r * r)
    t0 = -b - np.sqrt(np.maximum(disc, 0.0))
    blocked = (disc > 0.0) & (t0 > 1e-3) & (t0 < dist)
    return float(np.mean(np.where(blocked, 0.0, np.maximum(w[..., 1], 0.0))))


def test_soft_shadow_matches_quadrature(mi: Any) -> None:
    corner, e1, e2 = np.array([-1.0, 4.0, -1.0]), np.array([2.0, 0, 0]), np.array([0, 0, 2.0])
    c, r = np.array([0.0, 2.0, 0.0]), 0.8
    light = "AreaLight { corner -1 4 -1 edge1 2 0 0 edge2 0 0 2 color 1 1 1 samples 16 }"
    scene = _scene(mi, FLOOR_SCENE.format(light=light, n=2, extra="Sphere { center 0 2 0 radius 0.8 }"))
    points = np.array([[0.0, 0, 0], [0.9, 0, 0.3], [1.6, 0, 0], [4.0, 0, 1.0]])  # umbra, penumbra x2, lit
    values = _floor_values(mi, scene, points, lanes=4000)
    exact = [_visible_cosine_quadrature(p, corner, e1, e2, c, r) for p in points]
    assert exact[0] == 0.0 and 0.05 < exact[1] < exact[2] and exact[3] > 0.3  # the cases are what they claim
    for est, ref in zip(values, exact, strict=True):
        se = est.std(ddof=1) / np.sqrt(est.size)
        assert abs(est.mean() - ref) <= 3.0 * se + 1e-6, (est.mean(), ref, se)


def test_sphere_light_unoccluded_is_cosine_mean(mi: Any) -> None:
    """A SphereLight straight above a floor point: the mean of cos over the cone is ``(1 + cos θmax)/2``."""
    light = "SphereLight { center 0 3 0 radius 1 color 1 1 1 samples 16 }"
    scene = _scene(mi, FLOOR_SCENE.format(light=light, n=1, extra=""))
    est = _floor_values(mi, scene, np.array([[0.0, 0, 0]]), lanes=2000)[0]
    cos_max = np.sqrt(1.0 - (1.0 / 3.0) ** 2)
    se = est.std(ddof=1) / np.sqrt(est.size)
    assert abs(est.mean() - (1.0 + cos_max) / 2.0) <= 3.0 * se + 1e-6


# ------------------------------------------------------------------------------------------------ spot light
def test_spot_profile_follows_the_law(mi: Any) -> None:
    light = "SpotLight { position 0 4 0 direction 0 -1 0 color 1 1 1 angle 30 beamWidth 20 }"
    scene = _scene(mi, FLOOR_SCENE.format(light=light, n=1, extra=""))
    xs = np.linspace(0.0, 3.0, 61)
    got = _floor_values(mi, scene, np.stack([xs, 0 * xs, 0 * xs], axis=1), lanes=1)[:, 0]
    theta = np.degrees(np.arctan2(xs, 4.0))
    law = np.where(theta <= 20, 1.0, np.where(theta < 30, (30 - theta) / 10, 0.0))
    expected = law * 4.0 / np.hypot(xs, 4.0)          # times max(L·N, 0)
    np.testing.assert_allclose(got, expected, atol=1e-4)
    assert got[xs < 1.4].min() > 0.9 and got[xs > 2.4].max() == 0.0


# ------------------------------------------------------------------------------------------------ depth of field
DOF_SCENE = """PerspectiveCamera {{ center 0 0 0 direction 0 0 -1 up 0 1 0 angle 20 {lens} }}
Lights {{ numLights 0 }}
Background {{ color 0 0 0 }}
Materials {{ numMaterials 1 Material {{ diffuseColor 1 1 1 }} }}
Group {{ numObjects 1 MaterialIndex 0 Sphere {{ center 0 0 -{z} radius 0.01 }} }}
"""


def _render_dof(mi: Any, lens: str, z: float, spp: int, size: int = 121) -> np.ndarray:
    from a5mi.converters.describe import describe
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import render

    desc = describe(parse_text(DOF_SCENE.format(lens=lens, z=z)))
    return render(desc, RenderOptions(width=size, height=size, spp=spp, seed=3)).image[..., 0]


def _diameter_px(img: np.ndarray) -> float:
    """Diameter of a uniform disc with the image's radial second moment: ``D = sqrt(8 E[r²])``."""
    yy, xx = np.indices(img.shape)
    total = img.sum()
    cy, cx = (img * yy).sum() / total, (img * xx).sum() / total
    return float(np.sqrt(8.0 * (img * ((yy - cy) ** 2 + (xx - cx) ** 2)).sum() / total))


def test_blur_circle_has_thin_lens_diameter(mi: Any) -> None:
    size, a, f, z = 121, 0.4, 5.0, 8.0
    img = _render_dof(mi, f"aperture {a} focusDistance {f}", z, spp=256, size=size)
    # world size of one pixel spacing on the focus plane: 2 F tan(angle/2) / (W - 1) (SPEC B.2)
    pixel = 2.0 * f * np.tan(np.radians(10.0)) / (size - 1)
    expected = a * abs(z - f) / z / pixel
    assert abs(_diameter_px(img) - expected) <= 0.05 * expected, (_diameter_px(img), expected)


def test_focus_plane_is_sharp_and_aperture_zero_is_pinhole(mi: Any) -> None:
    sharp = _render_dof(mi, "aperture 0.4 focusDistance 5", 5.0, spp=16, size=61)
    pinhole = _render_dof(mi, "", 5.0, spp=1, size=61)
    assert _diameter_px(sharp) <= _diameter_px(pinhole) + 0.5
    zero = _render_dof(mi, "aperture 0 focusDistance 5", 5.0, spp=4, size=61)
    assert np.array_equal(zero, _render_dof(mi, "", 5.0, spp=4, size=61))


# ------------------------------------------------------------------------------------------------ glossy
GLOSSY_SCENE = """PerspectiveCamera {{ center 0 0 6 direction 0 0 -1 up 0 1 0 angle 30 }}
Lights {{ numLights 1 PointLight {{ position 3 3 5 color 1 1 1 }} }}
Background {{ color {bg} ambientLight 0 0 0 }}
Materials {{ numMaterials 2 Material {{ diffuseColor 0 0 0 specularColor 1 1 1 {gloss} }}
  Material {{ diffuseColor 0.9 0.4 0.1 }} }}
Group {{ numObjects 3 MaterialIndex 0 Plane {{ normal 0 0 1 offset -2 }}
  MaterialIndex 1 Sphere {{ center 0.8 0 1 radius 0.6 }} Sphere {{ center -0.9 0.3 0 radius 0.5 }} }}
"""


def _render_glossy(mi: Any, gloss: str, bg: str = "0.2 0.3 0.5", spp: int = 16) -> np.ndarray:
    from a5mi.converters.describe import describe
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import render

    return render(describe(parse_text(GLOSSY_SCENE.format(gloss=gloss, bg=bg))),
                  RenderOptions(width=64, height=64, spp=spp, seed=1, bounces=2)).image


def test_glossy_converges_to_mirror(mi: Any) -> None:
    mirror = _render_glossy(mi, "", spp=1)
    errors = [float(np.sqrt(np.mean((_render_glossy(mi, f"roughness {a} glossySamples 4") - mirror) ** 2)))
              for a in (0.3, 0.1, 0.01, 0.0001)]
    assert all(b < a for a, b in zip(errors, errors[1:], strict=False)), errors
    assert errors[-1] < 2e-3, errors


def test_glossy_white_mirror_returns_constant_background(mi: Any) -> None:
    """Nothing in front of the mirror: every reflected ray sees the background B, except the lobe samples
    that point below the surface (dropped, EXTENSIONS E.4). For GGX at normal incidence those are the
    microfacets with θm > 45°: ``P = α²/(1 + α²)``, so the mirror returns ``B/(1 + α²)`` (1 %: the camera
    rays are up to 15° off normal)."""
    from a5mi.converters.describe import describe
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import render

    for alpha in (0.05, 0.2):
        text = GLOSSY_SCENE.format(gloss=f"roughness {alpha} glossySamples 8", bg="0.5 0.5 0.5")
        text = text.replace("numObjects 3", "numObjects 1").split("MaterialIndex 1")[0] + "}\n"
        img = render(describe(parse_text(text)), RenderOptions(width=32, height=32, spp=8, seed=2, bounces=1)).image
        expected = 0.5 / (1.0 + alpha * alpha)
        assert abs(float(img.mean()) - expected) <= 0.01 * expected, (alpha, float(img.mean()), expected)
        assert abs(float(img.mean()) - 0.5) <= 0.02 * 0.5 + 0.5 * alpha * alpha


# ------------------------------------------------------------------------------------------------ convergence
@pytest.mark.slow
def test_rmse_falls_at_least_as_spp_to_the_minus_half(mi: Any) -> None:
    from a5mi.bench.convergence import convergence

    figures = convergence(ROOT / "scenes" / "soft_shadows.txt", size=40, spps=(1, 2, 4, 8, 16), reference_spp=256)
    assert figures["slope"] <= -0.45, figures


# ------------------------------------------------------------------------------------------------ stock mapping
def _types(d: Any) -> set[str]:
    out: set[str] = set()
    if isinstance(d, list):
        for v in d:
            out |= _types(v)
    if isinstance(d, dict):
        if isinstance(d.get("type"), str):
            out.add(d["type"])
        for v in d.values():
            out |= _types(v)
    return out


@pytest.mark.parametrize(("scene", "a5_types", "stock_types"), [
    ("soft_shadows", {"a5_area", "rectangle", "sphere"}, {"area", "rectangle", "sphere"}),
    ("spot", {"a5_spot"}, {"spot"}),
    ("dof", {"a5_camera"}, {"thinlens"}),
    ("glossy", {"a5_material"}, {"roughconductor", "roughdielectric"}),
])
def test_stock_mapping_loads_and_renders(mi: Any, scene: str, a5_types: set[str], stock_types: set[str],
                                         tmp_path: Path) -> None:
    """Both conversions load; the stock one renders with Mitsuba's path tracer (finite, not black); the XML of
    the stock conversion loads with the stock loader."""
    from a5mi.converters import materials
    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.converters.to_mitsuba import to_dict
    from a5mi.converters.to_xml import write_xml
    from a5mi.render.options import RenderOptions

    desc = describe(parse_file(ROOT / "scenes" / f"{scene}.txt"), stock=True)
    options = RenderOptions(width=24, height=24, spp=4)
    a5 = to_dict(desc, options)
    stock = to_dict(desc, options, stock=True)
    bsdfs = [materials.bsdf(m, False, stock=s) for m in desc.materials for s in (False, True)]  # loaded in to_dict
    assert a5_types <= _types(a5) | _types(bsdfs) and stock_types <= _types(stock) | _types(bsdfs)
    mi.load_dict(a5)
    img = np.asarray(mi.render(mi.load_dict(stock), spp=4))
    assert np.all(np.isfinite(img)) and img.mean() > 0.005
    xml = tmp_path / f"{scene}.xml"
    write_xml(desc, xml, options, stock=True)
    mi.load_file(str(xml))
